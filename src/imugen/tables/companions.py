"""Companion-sensor table: the third output of ``imugen aid`` (one file per route, grade, shard).

One row per sequence, sensor and epoch, sorted by ``sequence``, then ``sensor``, then time
(long format: each sensor at its own rate; the other sensor's columns are NaN, or 0 ticks):

- ``sequence`` int64, ``time_s`` (end of the epoch's interval, an IMU sample time, s),
  ``sensor`` int8 (:data:`imugen.aid.companions.KINDS`: 1 odometer, 2 barometer);
- odometer: ``odo_ticks`` int64 (ticks counted over the interval), ``odo_speed_mps``
  (``ticks * tick_m / interval``), ``odo_true_speed_mps`` (true mean forward speed of the
  vehicle reference over the interval), ``odo_error_mps`` (measured minus true);
- barometer: ``baro_altitude_m`` (measured ellipsoidal height), ``baro_true_altitude_m``,
  ``baro_drift_m`` (the true Gauss-Markov drift), ``baro_error_m`` (measured minus true:
  drift plus white noise).

Sidecar ``<stem>.labels.parquet``: one row per sequence, ``sequence`` and the drawn parameters
of each enabled sensor: ``odo_preset_id``, ``odo_rate_hz``, ``odo_scale_factor``,
``odo_scale_factor_sd``, ``odo_white_mps``, ``odo_tick_m``, ``odo_phase``;
``baro_preset_id``, ``baro_rate_hz``, ``baro_white_m``, ``baro_bias_sd_m``, ``baro_bias_tau_s``.
Metadata (JSON under ``b"imugen"``): ``stage``, ``odometer``, ``barometer`` (preset names or
null), ``odometer_rate_hz``, ``barometer_rate_hz``, ``seed``, ``route``, ``grade``, ``units``.
The file exists (possibly with no rows) whenever the aid stage runs.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from imugen.core.errors import InputError
from imugen.core.io import read_meta as read_meta
from imugen.core.io import write_parquet
from imugen.tables import SEQUENCE, TIME
from imugen.tables._parquet import read_table

SENSOR = "sensor"
ODOMETER, BAROMETER = 1, 2
"""``sensor`` codes (as :data:`imugen.aid.companions.KINDS`)."""
ODO_TICKS = "odo_ticks"
ODO_SPEED = "odo_speed_mps"
ODO_TRUE = "odo_true_speed_mps"
ODO_ERROR = "odo_error_mps"
BARO_ALT = "baro_altitude_m"
BARO_TRUE = "baro_true_altitude_m"
BARO_DRIFT = "baro_drift_m"
BARO_ERROR = "baro_error_m"
ODO_COLUMNS = (ODO_TICKS, ODO_SPEED, ODO_TRUE, ODO_ERROR)
BARO_COLUMNS = (BARO_ALT, BARO_TRUE, BARO_DRIFT, BARO_ERROR)
COLUMNS = (SEQUENCE, TIME, SENSOR, *ODO_COLUMNS, *BARO_COLUMNS)
UNITS = {
    SEQUENCE: "1",
    TIME: "s",
    SENSOR: "imugen.aid.companions.KINDS code",
    ODO_TICKS: "1",
    **dict.fromkeys((ODO_SPEED, ODO_TRUE, ODO_ERROR), "m/s"),
    **dict.fromkeys(BARO_COLUMNS, "m"),
}
WHAT = "companion-sensor table"


def labels_path(path) -> Path:
    """``<stem>.labels.parquet`` beside the table."""
    path = Path(path)
    return path.with_name(path.name.removesuffix(".parquet") + ".labels.parquet")


def frame(ids, odometer=None, barometer=None) -> pd.DataFrame:
    """Rows for :class:`imugen.aid.companions.CompanionData` of the sequences ``ids`` (either may
    be None)."""
    ids = np.asarray(ids, np.int64)
    parts = []
    for code, d in ((ODOMETER, odometer), (BAROMETER, barometer)):
        if d is None:
            continue
        M, J = d.value.shape
        out = {
            SEQUENCE: np.repeat(ids, J),
            TIME: np.tile(d.time_s, M),
            SENSOR: np.full(M * J, code, np.int8),
        }
        nan = np.full(M * J, np.nan)
        odo = code == ODOMETER
        out[ODO_TICKS] = d.ticks.ravel().astype(np.int64) if odo else np.zeros(M * J, np.int64)
        for c, v in zip(ODO_COLUMNS[1:], (d.value, d.true, d.error), strict=True):
            out[c] = np.asarray(v, float).ravel() if odo else nan
        for c, v in zip(BARO_COLUMNS, (d.value, d.true, d.bias, d.error), strict=True):
            out[c] = nan if odo else np.asarray(v, float).ravel()
        parts.append(pd.DataFrame(out))
    if not parts:
        return empty()
    df = pd.concat(parts, ignore_index=True)
    return df.sort_values([SEQUENCE, SENSOR, TIME], kind="stable", ignore_index=True)[list(COLUMNS)]


def empty() -> pd.DataFrame:
    """A table with the columns and types and no rows."""
    types = {SEQUENCE: np.int64, SENSOR: np.int8, ODO_TICKS: np.int64}
    return pd.DataFrame({c: np.zeros(0, types.get(c, float)) for c in COLUMNS})


def write(df: pd.DataFrame, labels: pd.DataFrame, meta: dict, out) -> Path:
    """Write the table and its labels sidecar atomically (sidecar first; both with metadata)."""
    meta = {**meta, "units": UNITS}
    write_parquet(labels, meta, labels_path(out))
    return write_parquet(df[list(COLUMNS)], meta, out)


def read(path, columns=None, filters=None) -> pd.DataFrame:
    """Columns (default all) of a companion table, rows kept by ``filters``."""
    return read_table(path, columns, filters, WHAT).to_pandas()


def read_odometer(path, columns=None, filters=None) -> pd.DataFrame:
    """The odometer rows: ``columns`` (default ``sequence``, ``time_s`` and the ``odo_*``
    columns), rows also kept by ``filters``."""
    cols = list(columns or (SEQUENCE, TIME, *ODO_COLUMNS))
    return read(path, cols, [(SENSOR, "==", ODOMETER), *(filters or [])])


def read_barometer(path, columns=None, filters=None) -> pd.DataFrame:
    """The barometer rows: ``columns`` (default ``sequence``, ``time_s`` and the ``baro_*``
    columns), rows also kept by ``filters``."""
    cols = list(columns or (SEQUENCE, TIME, *BARO_COLUMNS))
    return read(path, cols, [(SENSOR, "==", BAROMETER), *(filters or [])])


def read_labels(path) -> pd.DataFrame:
    """Per-sequence drawn companion parameters (InputError if the sidecar is missing)."""
    lp = labels_path(path)
    if not lp.exists():
        raise InputError(lp, "companion labels sidecar missing (incomplete aid output?)")
    return read_table(lp, what="companion labels table").to_pandas()
