"""Truth table: the output of ``imugen truth``; one row per IMU sample, float64.

Columns (:data:`COLUMNS`): ``time_s``; position ``p_n`` ``e_m, n_m, u_m`` (m); velocity
relative to the Earth ``v_e_mps, v_n_mps, v_u_mps``; attitude ``C_nb`` as a scalar-first
quaternion ``q_w .. q_z``. These are in the navigation coordinates of the truth's Earth model
(metadata ``earth``, ``nav_frame``): ENU of the route origin in ``flat`` and ``wgs84``; ECEF
(x, y, z; velocity resolved in ECEF; ``C_eb``) in ``geodetic``, whose truths also carry
:data:`GEODETIC` ``lat_deg, lon_deg, alt_m`` (WGS-84, ellipsoidal height) of every sample. In
every model ``OriginFrame.ecef_from_n`` gives ECEF and ``C_ln`` the local level; ``roll_rad, pitch_rad, yaw_rad`` relative to the local
level at the vehicle (unwrapped; ``C_lb = Rz(yaw) Ry(-pitch) Rx(roll)``, yaw 0 faces East);
instantaneous ``gyro_{x,y,z}_radps`` (``omega_ib_b``) and ``accel_{x,y,z}_mps2`` (``f_b``);
exact compensated increments ``dtheta_{x,y,z}_rad`` (rotation vector of the attitude change of
the interval) and ``dv_{x,y,z}_mps`` (velocity change in the body frame frozen at the interval
start, sculling included). Increments on row ``k`` belong to ``[t_{k-1}, t_k]``; row 0 is zero.
A multirotor's truth (``vehicle: multirotor``) also carries the companion signal
:data:`ROTORS`: ``rotor_{1..4}_rpm`` (X quadrotor: front-left, rear-left, rear-right,
front-right) and ``thrust_n`` (collective thrust, N), at every sample.

Metadata (JSON under ``b"imugen"``): ``origin`` {lat_deg, lon_deg, alt_m}, ``earth``
(``flat``/``wgs84``/``geodetic``), ``nav_frame`` (``"ENU of the origin"`` or ``"ECEF"``;
absent in older truths: ENU), ``rate_hz``, ``samples``, ``duration_s``, ``vehicle``, optionally
``route`` (the route name), fit and timing reports, ``units``.
"""

from __future__ import annotations

import hashlib
import json
from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from imugen.core.io import METADATA_KEY, write_parquet
from imugen.core.io import read_meta as read_meta
from imugen.tables import TIME
from imugen.tables._parquet import num_rows, open_file, read_table, require, to_numpy
from imugen.tables.enu import ALT, LAT, LON, E, N, U

if TYPE_CHECKING:
    import pandas as pd
    import pyarrow as pa

POS = (E, N, U)
VEL = ("v_e_mps", "v_n_mps", "v_u_mps")
QUAT = ("q_w", "q_x", "q_y", "q_z")
EULER = ("roll_rad", "pitch_rad", "yaw_rad")
GYRO = ("gyro_x_radps", "gyro_y_radps", "gyro_z_radps")
ACCEL = ("accel_x_mps2", "accel_y_mps2", "accel_z_mps2")
DTHETA = ("dtheta_x_rad", "dtheta_y_rad", "dtheta_z_rad")
DV = ("dv_x_mps", "dv_y_mps", "dv_z_mps")
COLUMNS = (TIME, *POS, *VEL, *QUAT, *EULER, *GYRO, *ACCEL, *DTHETA, *DV)
GEODETIC = (LAT, LON, ALT)
"""Optional columns (``geodetic`` truths): position of the vehicle in degrees and metres."""
ROTORS = ("rotor_1_rpm", "rotor_2_rpm", "rotor_3_rpm", "rotor_4_rpm", "thrust_n")
"""Optional columns (multirotor truths): rotor speeds [rpm] and collective thrust [N]."""
NAV_FRAMES = {"flat": "ENU of the origin", "wgs84": "ENU of the origin", "geodetic": "ECEF"}
"""The ``nav_frame`` of each Earth model: what the position, velocity and quaternion hold."""
UNITS = {
    LAT: "deg",
    LON: "deg",
    ALT: "m",
    TIME: "s",
    **dict.fromkeys(POS, "m"),
    **dict.fromkeys(VEL, "m/s"),
    **dict.fromkeys(QUAT, "1"),
    **dict.fromkeys(EULER, "rad"),
    **dict.fromkeys(GYRO, "rad/s"),
    **dict.fromkeys(ACCEL, "m/s^2"),
    **dict.fromkeys(DTHETA, "rad"),
    **dict.fromkeys(DV, "m/s"),
    **dict.fromkeys(ROTORS[:4], "rpm"),
    ROTORS[4]: "N",
}
WHAT = "truth table"


def write(df: pd.DataFrame, meta: dict, out) -> Path:
    """Write the truth table with its metadata atomically."""
    return write_parquet(df, meta, out)


def origin_frame(meta: dict):
    """The :class:`imugen.core.earth.OriginFrame` (origin and Earth model) a truth was built with."""
    from imugen.core.earth import OriginFrame

    o = meta["origin"]
    return OriginFrame.from_deg(o["lat_deg"], o["lon_deg"], o["alt_m"], model=meta["earth"])


def checksum(path) -> str:
    """SHA-256 (hex) of a truth file's bytes: names its content whatever the path spelling."""
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


@dataclass
class Truth:
    """A truth table in memory: columns (a DataFrame, or a pyarrow Table when read with
    ``arrow=True``), metadata, and its path if read.

    The array properties are float64 views/copies of the columns: ``time_s`` (K,), ``p_n``,
    ``v_n``, ``omega_ib_b``, ``f_b``, ``dtheta``, ``dv`` (K, 3), ``q_nb`` (K, 4).
    """

    frame: pd.DataFrame | pa.Table
    meta: dict = field(default_factory=dict)
    path: Path | None = None

    def _cols(self, names) -> np.ndarray:
        f = self.frame
        if hasattr(f, "column"):  # pyarrow.Table
            return np.column_stack([to_numpy(f.column(c)) for c in names]).astype(np.float64)
        return f[list(names)].to_numpy(dtype=np.float64)

    @property
    def K(self) -> int:
        return len(self.frame)

    @cached_property
    def time_s(self) -> np.ndarray:
        return self._cols([TIME])[:, 0]

    @property
    def rate_hz(self) -> float:
        """IMU rate: the metadata's ``rate_hz``, else from the time column."""
        r = self.meta.get("rate_hz")
        return float(r) if r else float(1.0 / np.median(np.diff(self.time_s)))

    @property
    def dt(self) -> float:
        return 1.0 / self.rate_hz

    @property
    def p_n(self) -> np.ndarray:
        return self._cols(POS)

    @property
    def v_n(self) -> np.ndarray:
        return self._cols(VEL)

    @property
    def q_nb(self) -> np.ndarray:
        return self._cols(QUAT)

    @property
    def omega_ib_b(self) -> np.ndarray:
        return self._cols(GYRO)

    @property
    def f_b(self) -> np.ndarray:
        return self._cols(ACCEL)

    @property
    def dtheta(self) -> np.ndarray:
        return self._cols(DTHETA)

    @property
    def dv(self) -> np.ndarray:
        return self._cols(DV)

    def origin_frame(self):
        """Navigation frame and Earth model (:func:`origin_frame`)."""
        return origin_frame(self.meta)

    def geodetic(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(lat_rad, lon_rad, h_m)`` of every sample, each (K,): the :data:`GEODETIC`
        columns when present, else converted from the navigation position."""
        f = self.frame
        names = f.column_names if hasattr(f, "column_names") else list(f.columns)
        if all(c in names for c in GEODETIC):
            g = self._cols(GEODETIC)
            return np.radians(g[:, 0]), np.radians(g[:, 1]), g[:, 2]
        return self.origin_frame().geodetic_from_n(self.p_n)


def read(path, columns=None, *, need_meta: bool = True, arrow: bool = False) -> Truth:
    """Read a truth file (``columns`` default all) and its metadata.

    ``need_meta=False`` accepts a table without imugen metadata (``meta = {}``): enough to
    simulate from, not to navigate (which needs the origin and Earth model). ``arrow=True``
    keeps the columns as a pyarrow Table (no pandas import: the stages that only need the
    arrays start faster).
    """
    df = read_table(path, columns=columns, what=WHAT)
    if not arrow:
        df = df.to_pandas()
    if need_meta:
        meta = read_meta(path)
    else:
        md = open_file(path, WHAT).schema_arrow.metadata or {}
        try:
            meta = json.loads(md[METADATA_KEY]) if METADATA_KEY in md else {}
        except ValueError:
            meta = {}
    return Truth(df, meta, Path(path))


def read_arrow(path, columns=None, filters=None):
    """Columns of a truth file as a :class:`pyarrow.Table` (no pandas conversion)."""
    return read_table(path, columns, filters, WHAT)


def samples(path) -> int:
    """Number of samples ``K`` of a truth file (footer only)."""
    return num_rows(path, WHAT)


def column_names(path) -> list[str]:
    """Columns present in a truth file (footer only)."""
    return list(open_file(path, WHAT).schema_arrow.names)


def iter_batches(path, columns, batch_size: int = 1 << 16):
    """Stream ``columns`` of a truth file as float64 ``(rows, len(columns))`` arrays."""
    pf = open_file(path, WHAT)
    require(path, pf.schema_arrow.names, list(columns), WHAT)
    for rb in pf.iter_batches(batch_size=batch_size, columns=list(columns)):
        yield np.column_stack([rb.column(c).to_numpy().astype(np.float64) for c in columns])
