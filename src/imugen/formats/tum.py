"""TUM trajectories (``timestamp tx ty tz qx qy qz qw``) for evo's APE/RPE.

``truth.tum`` (the route's truth at the navigation rate) and one file per sequence with its
free-inertial navigation (strapdown from the true initial state, in the truth's Earth model),
positions in the route's ENU frame, attitude ``q_nb`` scalar last, time in seconds.
``evo_ape tum truth.tum SEQ.tum`` compares them.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from imugen.formats.common import write_rows
from imugen.formats.convert import quat_scalar_last
from imugen.formats.source import Sequence, TruthArrays

FMT = "%.9f" + " %.6f" * 3 + " %.9f" * 4


def tum_rows(time_s, p, q_wxyz) -> np.ndarray:
    """(n, 8) TUM rows."""
    return np.column_stack([time_s, p, quat_scalar_last(q_wxyz)])


def write_truth(truth: TruthArrays, path: Path, every: int) -> Path:
    with open(path, "w") as fh:
        s = slice(None, None, every)
        write_rows(fh, tum_rows(truth.time_s[s], truth.p_n[s], truth.q_nb[s]), FMT)
    return path


def write(seq: Sequence, truth: TruthArrays, folder: Path, nav=None, **_) -> list[Path]:
    """Write the free-inertial trajectory of one sequence as ``folder.tum``."""
    idx, p, q = nav(seq)
    path = folder.with_suffix(".tum")
    with open(path, "w") as fh:
        write_rows(fh, tum_rows(truth.time_s[idx], p, q), FMT)
    return [path]
