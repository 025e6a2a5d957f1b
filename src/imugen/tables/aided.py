"""Aided navigation table: the second output of ``imugen aid`` (errors and full filter state).

One row per sequence and evaluation epoch of the aided filter (GNSS epochs on the evaluation
grid of ``navigate``, plus the last epoch of every run without a fix, so the error at the end
of each outage is exact), sorted by ``sequence`` then time; epochs before the filter's
alignment are omitted. Every value is the filter's output after the epoch's updates.

Errors and scenario context:

- ``sequence`` int64, ``time_s`` (s);
- ``err_e_m``, ``err_n_m``, ``err_u_m``: filter position minus truth (m, East/North/Up at the
  true position), ``err_along_m``, ``err_cross_m`` (along and across the true track, positive
  left, m), ``err_att_rad``: angle of the rotation from the true to the estimated attitude (as
  :mod:`imugen.tables.nav`);
- ``sd_e_m``, ``sd_n_m``, ``sd_u_m``: the filter's reported position 1-sigma (m), rotated to
  the same local level as the errors (correlations ignored:
  :func:`imugen.navigate.local_errors.local_sd`), so that consistency can be checked downstream
  (``err / sd`` should be standard normal);
- ``gnss_used`` int8: 1 when a GNSS position update was applied at the epoch;
- ``state`` int8: scenario state of the epoch (:mod:`imugen.tables.gnss`);
- ``since_fix_s``: time since the last epoch with a fix (0 with a fix; NaN before the first).

Navigation state (the filter's estimate; names as :mod:`imugen.tables.truth` where the truth
has the quantity; conventions of :mod:`imugen`: ENU navigation frame, FLU body frame):

- ``e_m``, ``n_m``, ``u_m``: IMU position (m, ENU of the route origin; the truth's names);
- ``v_e_mps``, ``v_n_mps``, ``v_u_mps``: IMU velocity in n (m/s);
- ``q_w``, ``q_x``, ``q_y``, ``q_z``: attitude ``q_nb`` (body to navigation), scalar first;
- ``gyro_bias_{x,y,z}_radps``, ``accel_bias_{x,y,z}_mps2``: estimated sensor biases (body
  axes; measured = true + bias, as the shards' bias series);
- ``sd_v_{e,n,u}_mps``, ``sd_att_{e,n,u}_rad`` (attitude error ``psi`` resolved in n),
  ``sd_gyro_bias_{x,y,z}_radps``, ``sd_accel_bias_{x,y,z}_mps2``: their 1-sigma.

On a ``geodetic`` truth the state columns are in its navigation coordinates (ECEF position,
velocity, ``q_eb``), and the velocity and attitude sigmas are along East, North, Up at the
estimated position (as the position sigmas of the first group).

Tables written before the state columns existed hold the first group only; :func:`read` with
``columns=None`` returns whatever the file holds.

Metadata (JSON under ``b"imugen"``): ``stage``, ``truth``, ``shard``, ``gnss``, ``grade``,
``route``, ``receiver``, ``options``, ``tuning_level``, ``eval_rate_hz``, ``units``.
"""

from __future__ import annotations

import json
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from types import SimpleNamespace

import pyarrow as pa

from imugen.core.io import METADATA_KEY
from imugen.core.io import read_meta as read_meta
from imugen.tables import SEQUENCE, TIME
from imugen.tables._parquet import block_writer, names, read_table
from imugen.tables.nav import ERR_ATT, ERR_POS, ERR_TRACK
from imugen.tables.truth import POS, QUAT, VEL

SD_POS = ("sd_e_m", "sd_n_m", "sd_u_m")
"""Reported position 1-sigma columns, metres, ENU."""
GNSS_USED = "gnss_used"
STATE = "state"
SINCE_FIX = "since_fix_s"
ERRORS = (SEQUENCE, TIME, *ERR_POS, *ERR_TRACK, ERR_ATT, *SD_POS, GNSS_USED, STATE, SINCE_FIX)
"""The error and context columns (every aided table holds them)."""
GYRO_BIAS = tuple(f"gyro_bias_{a}_radps" for a in "xyz")
ACCEL_BIAS = tuple(f"accel_bias_{a}_mps2" for a in "xyz")
SD_VEL = tuple(f"sd_v_{a}_mps" for a in "enu")
SD_ATT = tuple(f"sd_att_{a}_rad" for a in "enu")
SD_GYRO_BIAS = tuple(f"sd_{c}" for c in GYRO_BIAS)
SD_ACCEL_BIAS = tuple(f"sd_{c}" for c in ACCEL_BIAS)
STATE_COLUMNS = (
    *POS, *VEL, *QUAT, *GYRO_BIAS, *ACCEL_BIAS, *SD_VEL, *SD_ATT, *SD_GYRO_BIAS, *SD_ACCEL_BIAS,
)  # fmt: skip
"""The filter's navigation state and sigmas."""
COLUMNS = (*ERRORS, *STATE_COLUMNS)
INT8 = (GNSS_USED, STATE)
UNITS = {
    SEQUENCE: "1",
    TIME: "s",
    **dict.fromkeys(ERR_POS, "m"),
    **dict.fromkeys(ERR_TRACK, "m"),
    ERR_ATT: "rad",
    **dict.fromkeys(SD_POS, "m"),
    GNSS_USED: "1",
    STATE: "imugen.aid.scenarios.KINDS code",
    SINCE_FIX: "s",
    **dict.fromkeys(POS, "m"),
    **dict.fromkeys((*VEL, *SD_VEL), "m/s"),
    **dict.fromkeys(QUAT, "1"),
    **dict.fromkeys((*GYRO_BIAS, *SD_GYRO_BIAS), "rad/s"),
    **dict.fromkeys((*ACCEL_BIAS, *SD_ACCEL_BIAS), "m/s^2"),
    **dict.fromkeys(SD_ATT, "rad"),
}
WHAT = "aided navigation table"


def _type(c: str) -> pa.DataType:
    return pa.int64() if c == SEQUENCE else pa.int8() if c in INT8 else pa.float64()


def _schema(meta: dict) -> pa.Schema:
    md = {METADATA_KEY: json.dumps({**meta, "units": UNITS}).encode()}
    return pa.schema([pa.field(c, _type(c)) for c in COLUMNS], metadata=md)


@contextmanager
def writer(out, meta: dict | None = None) -> Iterator[SimpleNamespace]:
    """Stream the table to ``out`` atomically: yields ``w`` with ``w.put(cols)``.

    ``cols`` maps every column of :data:`COLUMNS` to a 1-D array (a DataFrame works); each
    block becomes one row group, so a job holds one block, never the whole table. ``w.meta``
    is settable until the first ``put``. A table with no block put is written empty.
    """
    with block_writer(out, meta, _schema) as w:
        yield w


def write(df, meta: dict, out) -> Path:
    """Write the aided table held in a DataFrame (or a dict of columns) atomically."""
    with writer(out, meta) as w:
        w.put(df)
    return Path(out)


def read(path, columns=None, filters=None):
    """Columns (default all the file holds) of an aided navigation table, rows kept by
    ``filters``."""
    return read_table(path, columns, filters, WHAT).to_pandas()


def has_state(path) -> bool:
    """Whether the table holds the navigation state columns (tables of this version do)."""
    have = set(names(path, WHAT))
    return all(c in have for c in STATE_COLUMNS)
