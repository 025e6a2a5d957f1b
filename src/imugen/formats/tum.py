"""TUM trajectories (``timestamp tx ty tz qx qy qz qw``) for evo's APE/RPE.

``truth.tum`` (the route's truth at the navigation rate), one file per sequence with its
free-inertial navigation (``SEQ.tum``: strapdown from the true initial state, in the truth's
Earth model) and, when the aided tables are given, one with its aided navigation
(``SEQ.aided.tum``: the filter's output at the aided table's epochs, after alignment).
Positions of the IMU in the route's ENU frame, attitude ``q_nb`` (body FLU to ENU) scalar
last, time in seconds from the route's first sample. ``evo_ape tum truth.tum SEQ.tum`` and
``evo_ape tum truth.tum SEQ.aided.tum`` compare them (evo associates by timestamp: the aided
epochs that fall on the truth's navigation-rate grid are compared).
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
    """Write the free-inertial trajectory of one sequence as ``folder.tum`` and, when the
    sequence carries its aided navigation, that as ``folder.aided.tum``."""
    from imugen.tables import truth as ttruth

    idx, p, q = nav(seq)
    path = folder.with_suffix(".tum")
    with open(path, "w") as fh:
        write_rows(fh, tum_rows(truth.time_s[idx], p, q), FMT)
    out = [path]
    if seq.aided is not None:
        a = seq.aided
        out.append(folder.with_suffix(".aided.tum"))
        with open(out[-1], "w") as fh:
            rows = tum_rows(
                a[ttruth.TIME].to_numpy(), a[list(ttruth.POS)].to_numpy(),
                a[list(ttruth.QUAT)].to_numpy(),
            )  # fmt: skip
            write_rows(fh, rows, FMT)
    return out
