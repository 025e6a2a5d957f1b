"""Per-sequence metrics table: the output of ``imugen evaluate`` (one file per grade).

One row per sequence: ``sequence``; ``rmse_{east,north,up}_m`` and ``rmse_total_m`` (RMSE of
the position error over the evaluation epochs, m; East/North/Up at the true position);
``final_{east,north,up,horizontal,3d}_m`` (error at the last epoch, m); ``final_pct_distance``
(final horizontal error, % of the horizontal distance travelled); ``rmse_along_m``,
``rmse_cross_m`` (RMSE of the along- and cross-track errors, m) and ``final_along_m``,
``final_cross_m`` (their signed values at the last epoch, cross positive to the left, m), absent
when the navigation tables had no track columns; ``epochs``; optional columns of
:mod:`imugen.evaluate.stage` (``drift_*``, ``aided_*``, ``outage_*``, ``time_to_10m_s``).
Metadata (JSON under ``b"imugen"``): ``stage``, ``grade``, ``distance_horizontal_m``,
``extent_m``, ``units``, ``vertical_channel`` (the navigation tables' record, which
``imugen tables`` uses to say why free-inertial figures are meaningless).
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

from imugen.core.errors import InputError
from imugen.core.io import read_meta as read_meta
from imugen.core.io import write_parquet
from imugen.tables import SEQUENCE
from imugen.tables._parquet import read_table

AXES = ("east", "north", "up")
RMSE = tuple(f"rmse_{a}_m" for a in AXES)
RMSE_TOTAL = "rmse_total_m"
FINAL = tuple(f"final_{a}_m" for a in AXES)
FINAL_HORIZONTAL = "final_horizontal_m"
FINAL_3D = "final_3d_m"
FINAL_PCT = "final_pct_distance"
RMSE_TRACK = ("rmse_along_m", "rmse_cross_m")
FINAL_TRACK = ("final_along_m", "final_cross_m")
EPOCHS = "epochs"
WHAT = "metrics table"

if TYPE_CHECKING:  # pandas is imported by the readers' to_pandas only when used
    import pandas as pd


def write(df: pd.DataFrame, meta: dict, out) -> Path:
    """Write the metrics (``sequence`` as a column or as the index) atomically."""
    if df.index.name == SEQUENCE:
        df = df.reset_index()
    return write_parquet(df, meta, out)


def read(path) -> pd.DataFrame:
    """The metrics table with ``sequence`` as a column (InputError if it is not one)."""
    df = read_table(path, what=WHAT).to_pandas()
    if SEQUENCE not in df.columns and df.index.name == SEQUENCE:
        df = df.reset_index()
    if SEQUENCE not in df.columns or RMSE_TOTAL not in df.columns:
        raise InputError(path, f"is not a metrics table (needs {SEQUENCE}, {RMSE_TOTAL})")
    return df
