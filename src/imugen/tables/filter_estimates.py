"""Filter-estimates table: the aided filter's state and covariance at every filter epoch.

Written by ``imugen aid --estimates-out`` beside the aided table (issue 26): one row per
sequence and filter epoch (every GNSS epoch of the receiver's rate, whether a fix came or not)
from the filter's start (alignment) on, after the epoch's updates; sorted by ``sequence`` then
time. What a learner takes as inputs (the filter's view) or uses to form the **filter-aware
target** (:func:`corrected_increments`, :mod:`imugen.dataset`).

Columns (conventions of :mod:`imugen`: ENU navigation frame, FLU body frame, SI):

- ``sequence`` int64, ``time_s`` (s), ``sample`` int64 (the IMU row of the epoch), ``flags``
  int16 (the filter's update bits, :data:`imugen.aid.filter.FLAGS`);
- ``e_m``, ``n_m``, ``u_m``; ``v_e_mps``, ``v_n_mps``, ``v_u_mps``; ``q_w``, ``q_x``,
  ``q_y``, ``q_z`` (``q_nb``, scalar first): the IMU's estimated position, velocity and
  attitude (names of :mod:`imugen.tables.truth`; on a ``geodetic`` truth ECEF and ``q_eb``, as
  :mod:`imugen.tables.aided`), float64;
- ``gyro_bias_{x,y,z}_radps``, ``accel_bias_{x,y,z}_mps2``: estimated biases (measured = true +
  bias); ``gyro_sf_{x,y,z}``, ``accel_sf_{x,y,z}``: estimated scale factors (measured = (1 +
  s) true); ``gyro_cc_{ab}``, ``accel_cc_{ab}`` (pairs ``xy, xz, yx, yz, zx, zy``: row, column
  of :data:`imugen.aid.filter.CC_PAIRS`): estimated cross-coupling; ``gnss_bias_{e,n,u}_m``:
  the receiver's position bias state (navigation axes). NaN where the filter has no such
  state;
- ``sd_*``: the 1-sigma of **every error state** (the square root of the diagonal of the
  filter's covariance ``P``; correlations are not written), NaN where the filter has no such
  state: ``sd_p_{e,n,u}_m``, ``sd_v_{e,n,u}_mps``, ``sd_att_{e,n,u}_rad`` (attitude error
  ``psi`` resolved in n, ``C_hat = Exp(psi) C``), ``sd_`` + each bias, scale-factor,
  cross-coupling and GNSS-bias column above, ``sd_odo_sf``, ``sd_baro_bias_m``,
  ``sd_mount_{pitch,yaw}_rad``, ``sd_lever_{x,y,z}_m``, ``sd_odo_tick_{start,end}_m``. Position,
  velocity and attitude sigmas are along the navigation axes (on a ``geodetic`` truth along
  the local East, North, Up at the estimate).

Values other than the navigation state are float32. Metadata (JSON under ``b"imugen"``):
``stage``, ``truth``, ``shard``, ``grade``, ``route``, ``options``, ``tuning_level``, ``dt_s``
(the IMU interval), ``units``.
"""

from __future__ import annotations

import json
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pyarrow as pa

from imugen.core.io import METADATA_KEY
from imugen.core.io import read_meta as read_meta
from imugen.tables import SEQUENCE, TIME
from imugen.tables._parquet import block_writer, read_table
from imugen.tables.truth import POS, QUAT, VEL

SAMPLE = "sample"
FLAGS = "flags"
_PAIRS = ("xy", "xz", "yx", "yz", "zx", "zy")
GYRO_BIAS = tuple(f"gyro_bias_{a}_radps" for a in "xyz")
ACCEL_BIAS = tuple(f"accel_bias_{a}_mps2" for a in "xyz")
GYRO_SF = tuple(f"gyro_sf_{a}" for a in "xyz")
ACCEL_SF = tuple(f"accel_sf_{a}" for a in "xyz")
GYRO_CC = tuple(f"gyro_cc_{p}" for p in _PAIRS)
ACCEL_CC = tuple(f"accel_cc_{p}" for p in _PAIRS)
GNSS_BIAS = tuple(f"gnss_bias_{a}_m" for a in "enu")
ESTIMATES = {
    "bg": GYRO_BIAS, "ba": ACCEL_BIAS, "sg": GYRO_SF, "sa": ACCEL_SF, "cc": GYRO_CC,
    "ca": ACCEL_CC, "gnss_bias": GNSS_BIAS,
}  # fmt: skip
"""Estimated sensor-error states: block of :mod:`imugen.aid.filter.state` -> columns."""
SD = {
    "p": tuple(f"sd_p_{a}_m" for a in "enu"),
    "v": tuple(f"sd_v_{a}_mps" for a in "enu"),
    "att": tuple(f"sd_att_{a}_rad" for a in "enu"),
    **{k: tuple(f"sd_{c}" for c in cols) for k, cols in ESTIMATES.items()},
    "odo_sf": ("sd_odo_sf",),
    "baro_bias": ("sd_baro_bias_m",),
    "mount": ("sd_mount_pitch_rad", "sd_mount_yaw_rad"),
    "lever": tuple(f"sd_lever_{a}_m" for a in "xyz"),
    "odo_tick": ("sd_odo_tick_start_m", "sd_odo_tick_end_m"),
}
"""1-sigma columns: block of the error state -> columns (in the block's order)."""
NAV = (*POS, *VEL, *QUAT)
VALUES = tuple(c for cols in ESTIMATES.values() for c in cols)
SIGMAS = tuple(c for cols in SD.values() for c in cols)
CORRECTION = VALUES[: 2 * 3 + 2 * 3 + 2 * 6]
"""The estimates the filter corrects the increments with (biases, scale factors,
cross-coupling): those :func:`corrected_increments` takes."""
COLUMNS = (SEQUENCE, TIME, SAMPLE, FLAGS, *NAV, *VALUES, *SIGMAS)
UNITS = {
    SEQUENCE: "1",
    TIME: "s",
    SAMPLE: "1",
    FLAGS: "imugen.aid.filter.FLAGS bits",
    **dict.fromkeys(POS, "m"),
    **dict.fromkeys(VEL, "m/s"),
    **dict.fromkeys(QUAT, "1"),
}
for _c in (*VALUES, *SIGMAS):
    _u = _c.rsplit("_", 1)[-1]
    UNITS[_c] = {"radps": "rad/s", "mps2": "m/s^2", "m": "m", "mps": "m/s", "rad": "rad"}.get(
        _u, "1"
    )
WHAT = "filter-estimates table"


def _type(c: str) -> pa.DataType:
    if c in (SEQUENCE, SAMPLE):
        return pa.int64()
    if c == FLAGS:
        return pa.int16()
    return pa.float64() if c in (TIME, *NAV) else pa.float32()


def _schema(meta: dict) -> pa.Schema:
    md = {METADATA_KEY: json.dumps({**meta, "units": UNITS}).encode()}
    return pa.schema([pa.field(c, _type(c)) for c in COLUMNS], metadata=md)


@contextmanager
def writer(out, meta: dict | None = None) -> Iterator[SimpleNamespace]:
    """Stream the table to ``out`` atomically: yields ``w`` with ``w.put(cols)`` (a mapping of
    every column of :data:`COLUMNS`), one row group per call; ``w.meta`` settable until the
    first ``put``."""
    with block_writer(out, meta, _schema) as w:
        yield w


def write(cols, meta: dict, out) -> Path:
    """Write the rows ``cols`` (a DataFrame or a dict of columns) atomically."""
    with writer(out, meta) as w:
        w.put(cols)
    return Path(out)


def read(path, columns=None, filters=None):
    """Columns (default all) of a filter-estimates table, rows kept by ``filters``."""
    return read_table(path, columns, filters, WHAT).to_pandas()


def corrected_increments(dtheta, dv, est, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """The increments corrected with the filter's estimates, as the filter corrects them.

    ``dtheta_hat = (dtheta - b_g dt) / (1 + s_g)``, then minus the cross-coupling to first
    order (``dtheta_hat_a -= cc_ab dtheta_hat_b``, the pairs in the order of :data:`GYRO_CC`,
    each row from the values before), likewise ``dv`` with the accelerometer's; absent states
    (NaN) count as zero.

    Parameters
    ----------
    dtheta, dv : (..., 3)  the increments the filter was given [rad, m/s]
    est : (..., 24)  per row, the held estimates :data:`CORRECTION` (biases, scale factors,
        cross-coupling)
    dt : float  IMU interval [s]
    """
    e = np.nan_to_num(np.asarray(est, float))
    bg, ba, sg, sa, cg, ca = (e[..., i : i + n] for i, n in
                              ((0, 3), (3, 3), (6, 3), (9, 3), (12, 6), (18, 6)))  # fmt: skip
    return _cc((dtheta - bg * dt) / (1.0 + sg), cg), _cc((dv - ba * dt) / (1.0 + sa), ca)


def filter_aware_error(x, err, held, valid, dt) -> np.ndarray:
    """The **filter-aware target**: the effective error left after the filter's own correction,
    ``err - (x - x_hat)`` with ``x_hat`` the increments corrected as the filter does
    (:func:`corrected_increments`), NaN where no estimate is held.

    Parameters
    ----------
    x, err : (..., 6)  measured increments ``dtheta, dv`` and their effective error [rad, m/s]
    held : (..., 24)  the estimates :data:`CORRECTION` held at each row (those of the last
        filter epoch strictly before it)
    valid : (...) bool  rows holding an estimate
    dt : float or broadcastable  IMU interval [s]

    Returns
    -------
    (..., 6) float64
    """
    xx = np.asarray(x, np.float64)
    th, dv = corrected_increments(xx[..., :3], xx[..., 3:6], held, dt)
    out = np.asarray(err, np.float64) - (xx - np.concatenate([th, dv], -1))
    out[~np.asarray(valid, bool)] = np.nan
    return out


def _cc(u, c):
    x, y, z = u[..., 0], u[..., 1], u[..., 2]
    return np.stack(
        [x - c[..., 0] * y - c[..., 1] * z, y - c[..., 2] * x - c[..., 3] * z,
         z - c[..., 4] * x - c[..., 5] * y], -1,
    )  # fmt: skip
