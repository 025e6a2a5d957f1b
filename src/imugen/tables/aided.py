"""Aided navigation error table: the second output of ``imugen aid``.

One row per sequence and evaluation epoch of the aided filter (GNSS epochs on the evaluation
grid of ``navigate``, plus the last epoch of every run without a fix, so the error at the end
of each outage is exact), sorted by ``sequence`` then time; epochs before the filter's
alignment are omitted:

- ``sequence`` int64, ``time_s`` (s);
- ``err_e_m``, ``err_n_m``, ``err_u_m``: filter position minus truth (m, East/North/Up at the
  true position), ``err_along_m``, ``err_cross_m`` (along and across the true track, positive
  left, m), ``err_att_rad``: angle of the rotation from the true to the estimated attitude (as
  :mod:`imugen.tables.nav`);
- ``sd_e_m``, ``sd_n_m``, ``sd_u_m``: the filter's reported position 1-sigma (m), rotated to
  the same local level as the errors (correlations ignored:
  :func:`imugen.local_errors.local_sd`), so that consistency can be checked downstream
  (``err / sd`` should be standard normal);
- ``gnss_used`` int8: 1 when a GNSS position update was applied at the epoch;
- ``state`` int8: scenario state of the epoch (:mod:`imugen.tables.gnss`);
- ``since_fix_s``: time since the last epoch with a fix (0 with a fix; NaN before the first).

Metadata (JSON under ``b"imugen"``): ``stage``, ``truth``, ``shard``, ``gnss``, ``grade``,
``route``, ``receiver``, ``options``, ``tuning_level``, ``eval_rate_hz``, ``units``.
"""

from __future__ import annotations

from pathlib import Path

import pandas as pd

from imugen.io import read_meta as read_meta
from imugen.io import write_parquet
from imugen.tables._parquet import SEQUENCE, TIME, read_table
from imugen.tables.nav import ERR_ATT, ERR_POS, ERR_TRACK

SD_POS = ("sd_e_m", "sd_n_m", "sd_u_m")
"""Reported position 1-sigma columns, metres, ENU."""
GNSS_USED = "gnss_used"
STATE = "state"
SINCE_FIX = "since_fix_s"
COLUMNS = (SEQUENCE, TIME, *ERR_POS, *ERR_TRACK, ERR_ATT, *SD_POS, GNSS_USED, STATE, SINCE_FIX)
UNITS = {
    SEQUENCE: "1",
    TIME: "s",
    **dict.fromkeys(ERR_POS, "m"),
    **dict.fromkeys(ERR_TRACK, "m"),
    ERR_ATT: "rad",
    **dict.fromkeys(SD_POS, "m"),
    GNSS_USED: "1",
    STATE: "imugen.scenarios.KINDS code",
    SINCE_FIX: "s",
}
WHAT = "aided navigation error table"


def write(df: pd.DataFrame, meta: dict, out) -> Path:
    """Write the aided error table with its metadata (``units`` added) atomically."""
    return write_parquet(df[list(COLUMNS)], {**meta, "units": UNITS}, out)


def read(path, columns=None, filters=None) -> pd.DataFrame:
    """Columns (default all) of an aided navigation error table, rows kept by ``filters``."""
    return read_table(path, columns, filters, WHAT).to_pandas()
