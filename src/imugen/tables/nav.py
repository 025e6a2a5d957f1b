"""Navigation error table: the output of ``imugen navigate``.

One row per sequence and evaluation epoch (every ``round(rate / eval_rate_hz)`` samples from
``t_0``): ``sequence`` (int64, the shard's id), ``time_s`` (s), position error
``err_e_m``, ``err_n_m``, ``err_u_m`` (navigation minus truth, m, ENU of the route origin) and
attitude error ``err_att_rad`` (angle of the rotation from the true to the computed attitude).
Metadata (JSON under ``b"imugen"``): ``stage``, ``truth`` and ``shard`` (file names),
``truth_sha256``, ``grade``, ``eval_rate_hz``, ``increments``, ``units``.
"""

from __future__ import annotations

from pathlib import Path

import pandas as pd

from imugen.io import read_meta as read_meta
from imugen.io import write_parquet
from imugen.tables._parquet import SEQUENCE, TIME, read_table

ERR_POS = ("err_e_m", "err_n_m", "err_u_m")
"""Position error columns, metres, ENU."""
ERR_ATT = "err_att_rad"
COLUMNS = (SEQUENCE, TIME, *ERR_POS, ERR_ATT)
UNITS = {SEQUENCE: "1", TIME: "s", **dict.fromkeys(ERR_POS, "m"), ERR_ATT: "rad"}
WHAT = "navigation error table"


def write(df: pd.DataFrame, meta: dict, out) -> Path:
    """Write the error table with its metadata (``units`` added) atomically."""
    return write_parquet(df, {**meta, "units": UNITS}, out)


def read(path, columns=None, filters=None) -> pd.DataFrame:
    """Columns (default all) of a navigation error table, rows kept by ``filters``."""
    return read_table(path, columns, filters, WHAT).to_pandas()
