"""TUM trajectories (``timestamp tx ty tz qx qy qz qw``) for evo's APE/RPE.

``truth.tum`` (the route's truth at the navigation rate), one file per sequence with its
free-inertial navigation (``SEQ.tum``: strapdown from the true initial state, in the truth's
Earth model) and, when the aided tables are given, one with its aided navigation
(``SEQ.aided.tum``: the filter's output at the aided table's epochs, after alignment).
Positions of the IMU in the route's ENU frame, attitude ``q_nb`` (body FLU to ENU) scalar
last, time in seconds from the route's first sample. ``evo_ape tum truth.tum SEQ.tum`` and
``evo_ape tum truth.tum SEQ.aided.tum`` compare them (evo associates by timestamp: the aided
epochs that fall on the truth's navigation-rate grid are compared).

A sequence simulated with a mounting (misaligned IMU, lever arm: labels
:data:`imugen.tables.shard.MOUNTING` not all zero) navigates the IMU's point and axes, not the
vehicle's: it gets its own truth ``SEQ.truth.tum`` (the IMU's true trajectory, same grid as
``truth.tum``): ``evo_ape tum SEQ.truth.tum SEQ.tum`` (or ``SEQ.aided.tum``) is its
navigation error.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from imugen.export.common import write_rows
from imugen.export.convert import quat_scalar_last
from imugen.export.source import Sequence, TruthArrays, mounting_of

FMT = "%.9f" + " %.6f" * 3 + " %.9f" * 4


def tum_rows(time_s, p, q_wxyz) -> np.ndarray:
    """(n, 8) TUM rows."""
    return np.column_stack([time_s, p, quat_scalar_last(q_wxyz)])


def write_truth(truth: TruthArrays, path: Path, every: int) -> Path:
    with open(path, "w") as fh:
        s = slice(None, None, every)
        write_rows(fh, tum_rows(truth.time_s[s], truth.p_n[s], truth.q_nb[s]), FMT)
    return path


def mounted(labels: dict) -> bool:
    """True when a sequence's IMU is mounted off the vehicle's point or axes."""
    m = mounting_of(labels)
    return m is not None and bool(np.any(m[0] != 0) or np.any(m[1] != 0))


def write(
    seq: Sequence, truth: TruthArrays, folder: Path, nav=None, every: int = 1, **_
) -> list[Path]:
    """Write the free-inertial trajectory of one sequence as ``folder.tum``; for a mounted IMU
    (``truth`` is then the IMU's) its truth as ``folder.truth.tum``; and, when the sequence
    carries its aided navigation, that as ``folder.aided.tum``."""
    from imugen.tables import truth as ttruth

    idx, p, q = nav(seq)
    path = folder.parent / f"{folder.name}.tum"
    with open(path, "w") as fh:
        write_rows(fh, tum_rows(truth.time_s[idx], p, q), FMT)
    out = [path]
    if mounted(seq.labels):
        out.append(write_truth(truth, folder.parent / f"{folder.name}.truth.tum", every))
    if seq.aided is not None:
        a = seq.aided
        out.append(folder.parent / f"{folder.name}.aided.tum")
        with open(out[-1], "w") as fh:
            rows = tum_rows(
                a[ttruth.TIME].to_numpy(), a[list(ttruth.POS)].to_numpy(),
                a[list(ttruth.QUAT)].to_numpy(),
            )  # fmt: skip
            write_rows(fh, rows, FMT)
    return out
