"""IMU shard: the output of ``imugen simulate`` (and :func:`imugen.write_shard`).

A shard is one Parquet file plus a labels sidecar ``<stem>.labels.parquet``.

Shard rows are sorted by ``sequence`` then time, one per (sequence, IMU sample):

- ``sequence`` int64: global id ``route_id << 31 | index`` (:func:`sequence_ids`), where
  ``route_id`` is :func:`route_id` of the route name (32 bits) and ``index = shard *
  shard_size + j`` (< 2^31) counts the sequences of one route and grade. Ids are unique across
  routes within a grade, and the same ``(route, index)`` has the same id in every grade;
- ``time_s`` float64, stored only when it is not the truth's uniform clock: a shard of
  ``imugen simulate`` records its clock once, as metadata ``clock`` ``{"t0_s", "dt_s",
  "samples"}`` with ``time_s[k] = t0_s + k * dt_s`` (float64, :func:`clock_times`), and has no
  ``time_s`` column (8 of 32 bytes per row saved) unless written with ``explicit_time``. The
  readers of this module (:func:`read`, :func:`iter_sequences`, :func:`times`) rebuild the
  column bit for bit for callers that ask for it; shards with a ``time_s`` column (format 2,
  or ``explicit_time``) read the same way;
- measurements (float32 or float64): increments ``dtheta_{x,y,z}_rad``, ``dv_{x,y,z}_mps``
  (row ``k`` holds the interval ``[t_{k-1}, t_k]``, row 0 of each sequence is zero) and/or
  rates ``gyro_{x,y,z}_radps``, ``accel_{x,y,z}_mps2`` sampled at ``t_k``;
- optional series (``series=True``), each per axis: the true slow bias
  ``{gyro,accel}_bias_*`` (turn-on + in-run + RRW + temperature, at ``t_k``), the scale-factor
  error ``{gyro,accel}_sf_*``, and the effective error ``err_dtheta_*_rad``, ``err_dv_*_mps``
  (increments) / ``err_gyro_*_radps``, ``err_accel_*_mps2`` (rates): everything the sensor adds
  except white noise and quantization, in the units of the measurement, so that
  ``measured = true + err + white noise + quantization`` exactly (up to the storage rounding).

Increment semantics (metadata ``increments``): ``"compensated"`` (default; the truth's exact
increments: rotation vector of the interval's attitude change, velocity change in the body
frame frozen at the interval start, coning and sculling included) or ``"raw"`` (plain
integrals of ``omega_ib_b`` and ``f_b`` over the interval, what an integrating IMU outputs;
navigation applies the two-sample coning/sculling correction). A file without the key is
compensated.

The labels sidecar holds one row per sequence: ``sequence``, ``route_id``, ``shard``,
``index`` (the sequence's index in its route, ``shard * shard_size + j``: the low 31 bits of
``sequence``, the ``index`` of :func:`sequence_ids`; ``j``, the position in the shard, is
``index - first_index`` of the metadata), ``seed``, ``grade_id`` and every drawn parameter
(SI unit in each name), among them,
when the shard was simulated with a mounting (metadata ``mounting``, :mod:`imugen.sensors.mounting`),
the IMU's misalignment from the vehicle ``mount_roll_rad``, ``mount_pitch_rad``,
``mount_yaw_rad`` (``C_vb = Rz(yaw) Ry(-pitch) Rx(roll)``, IMU axes ``b`` from vehicle axes
``v``) and its lever arm from the vehicle reference point ``lever_arm_{x,y,z}_m`` (vehicle
axes): the IMU measures at that point in those axes, and its truth is the vehicle's moved there
(:func:`imugen.sensors.mounting.imu_states`; :func:`mounting` reads them back), and the
static terms a user would fit, named apart (:func:`static_labels`): the additive bias
``{gyro,accel}_turn_on_bias_{x,y,z}_{radps,mps2}`` (for a grade calibrated at rest, the
calibration's residual minus the static gravity error it absorbed), the gyro g-sensitivity on
gravity ``gyro_g_sensitivity_gravity_{x,y,z}_radps`` (``G (0, 0, g0)``), the accelerometer
scale factor and cross-coupling on gravity ``accel_scale_factor_gravity_{x,y,z}_mps2``
(``E (0, 0, g0)``), and their sum, what the still, level sensor reads beyond the truth at
turn-on: ``{gyro,accel}_bias_at_rest_{x,y,z}_{radps,mps2}``. Both
files carry the shard metadata (JSON under ``b"imugen"``; :data:`FORMAT`); a shard written
from corrected data by :func:`imugen.write_shard` has ``derived`` set.
"""

from __future__ import annotations

import hashlib
import json
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from imugen.core.errors import InputError
from imugen.core.io import METADATA_KEY, atomic_output, with_meta
from imugen.core.io import read_meta as read_meta
from imugen.tables import SEQUENCE, TIME
from imugen.tables._parquet import (
    from_numpy,
    names,
    num_rows,
    open_file,
    read_table,
    to_numpy,
)
from imugen.tables.truth import ACCEL, DTHETA, DV, GYRO

if TYPE_CHECKING:
    import pandas as pd

FORMAT = "imugen-shard"
LABELS_FORMAT = "imugen-shard-labels"
FORMAT_VERSION = 3
"""3: ``time_s`` may be implicit (metadata ``clock``); 2: always a column."""
WHAT = "IMU shard"

INCREMENTS = (*DTHETA, *DV)
RATES = (*GYRO, *ACCEL)
BIAS_SERIES = {
    "gyro": tuple(f"gyro_bias_{a}_radps" for a in "xyz"),
    "accel": tuple(f"accel_bias_{a}_mps2" for a in "xyz"),
}
SF_SERIES = {
    "gyro": tuple(f"gyro_sf_{a}" for a in "xyz"),
    "accel": tuple(f"accel_sf_{a}" for a in "xyz"),
}
ERR_DTHETA = tuple(f"err_dtheta_{a}_rad" for a in "xyz")
ERR_DV = tuple(f"err_dv_{a}_mps" for a in "xyz")
ERR_GYRO = tuple(f"err_gyro_{a}_radps" for a in "xyz")
ERR_ACCEL = tuple(f"err_accel_{a}_mps2" for a in "xyz")
BIAS = (*BIAS_SERIES["gyro"], *BIAS_SERIES["accel"])
"""Six true slow-bias columns, gyro then accel."""
EFFECTIVE_ERROR = {"increments": (*ERR_DTHETA, *ERR_DV), "rates": (*ERR_GYRO, *ERR_ACCEL)}
"""Six effective-error columns per measurement kind, gyro then accel."""

GROUPS = {
    "dtheta": (DTHETA, "rad"),
    "dv": (DV, "m/s"),
    "gyro": (GYRO, "rad/s"),
    "accel": (ACCEL, "m/s^2"),
    "gyro_bias": (BIAS_SERIES["gyro"], "rad/s"),
    "gyro_sf": (SF_SERIES["gyro"], "1"),
    "accel_bias": (BIAS_SERIES["accel"], "m/s^2"),
    "accel_sf": (SF_SERIES["accel"], "1"),
    "err_dtheta": (ERR_DTHETA, "rad"),
    "err_dv": (ERR_DV, "m/s"),
    "err_gyro": (ERR_GYRO, "rad/s"),
    "err_accel": (ERR_ACCEL, "m/s^2"),
}
"""Column groups of three (x, y, z): name -> (columns, unit)."""

MOUNT_ANGLES = ("mount_roll_rad", "mount_pitch_rad", "mount_yaw_rad")
LEVER_ARM = ("lever_arm_x_m", "lever_arm_y_m", "lever_arm_z_m")
MOUNTING = (*MOUNT_ANGLES, *LEVER_ARM)
"""Label columns of the IMU mounting (absent: the IMU is the vehicle frame at its point)."""

OUTPUTS = ("increments", "rates", "both")
INCREMENT_KINDS = ("compensated", "raw")
ROUTE_SHIFT = 31
"""Sequence id = ``route_id << ROUTE_SHIFT | index``; index < 2^31, route_id < 2^32."""


# --- ids ---------------------------------------------------------------------------------
def route_id(name: str) -> int:
    """Stable id of a route: the first 4 bytes of SHA-256 of its UTF-8 name, big-endian.

    In ``[0, 2^32)``; it names the route in every spawn key and in the sequence ids.
    """
    return int.from_bytes(hashlib.sha256(str(name).encode("utf-8")).digest()[:4], "big")


def sequence_ids(rid: int, index) -> np.ndarray:
    """Global sequence ids (int64) of indices ``index`` (< 2^31) of route id ``rid``."""
    index = np.asarray(index, dtype=np.int64)
    if np.any(index < 0) or np.any(index >= 1 << ROUTE_SHIFT):
        raise InputError("--shard", "sequence index (shard * shard_size + j) must be < 2^31")
    return (np.int64(rid) << np.int64(ROUTE_SHIFT)) | index


def split_ids(ids) -> tuple[np.ndarray, np.ndarray]:
    """``(route_id, index)`` int64 arrays of global sequence ids."""
    ids = np.asarray(ids, dtype=np.int64)
    return ids >> ROUTE_SHIFT, ids & ((1 << ROUTE_SHIFT) - 1)


# --- layout ------------------------------------------------------------------------------
def groups(outputs: str, series: bool) -> list[str]:
    """Column groups written for ``outputs`` (increments/rates/both) and ``series``."""
    inc = outputs in ("increments", "both")
    rate = outputs in ("rates", "both")
    out = (["dtheta", "dv"] if inc else []) + (["gyro", "accel"] if rate else [])
    if series:
        out += ["gyro_bias", "gyro_sf", "accel_bias", "accel_sf"]
        out += (["err_dtheta", "err_dv"] if inc else []) + (
            ["err_gyro", "err_accel"] if rate else []
        )
    return out


def units(group_names) -> dict:
    """Units of the shard's columns."""
    u = {SEQUENCE: "1", TIME: "s"}
    for g in group_names:
        cols, unit = GROUPS[g]
        u.update(dict.fromkeys(cols, unit))
    return u


def schema(group_names, dtype, meta: dict, time_column: bool = True) -> pa.Schema:
    """Arrow schema of a shard: ``sequence`` int64, ``time_s`` float64 (unless the clock is
    implicit), groups in ``dtype``. Every column is required (no nulls): Parquet then stores no
    definition levels, which halves the encoder's CPU (42 -> 21 ns per row of six float32
    columns, ``benchmarks/README.md``)."""
    ftype = pa.from_numpy_dtype(np.dtype(dtype))
    fields = [pa.field(SEQUENCE, pa.int64(), nullable=False)]
    if time_column:
        fields.append(pa.field(TIME, pa.float64(), nullable=False))
    for g in group_names:
        fields += [pa.field(c, ftype, nullable=False) for c in GROUPS[g][0]]
    return pa.schema(fields, metadata={METADATA_KEY: json.dumps(meta).encode()})


def labels_path(path) -> Path:
    """Sidecar path of a shard: ``dir/stem.labels.parquet``."""
    p = Path(path)
    stem = p.name[: -len(".parquet")] if p.name.endswith(".parquet") else p.name
    return p.with_name(stem + ".labels.parquet")


# --- clock -------------------------------------------------------------------------------
def clock_times(clock: dict) -> np.ndarray:
    """``time_s`` (float64, ``(samples,)``) of an implicit clock: ``t0_s + k * dt_s``."""
    k = np.arange(int(clock["samples"]), dtype=np.float64)
    return float(clock["t0_s"]) + k * float(clock["dt_s"])


def uniform_clock(time_s, dt=None) -> dict | None:
    """The implicit clock ``{"t0_s", "dt_s", "samples"}`` that :func:`clock_times` turns back
    into ``time_s`` bit for bit, or None when no uniform clock reproduces it exactly.

    Tried steps: ``dt`` (e.g. ``1 / rate_hz``, how the truth builds its grid), the mean step
    and its neighbours within 4 ulp, and the first step."""
    t = np.ascontiguousarray(time_s, dtype=np.float64)
    n = len(t)
    if n < 2 or not np.all(np.isfinite(t)):
        return None
    est = (t[-1] - t[0]) / (n - 1)
    steps = [] if dt is None else [float(dt)]
    up = down = est
    steps.append(est)
    for _ in range(4):
        up, down = np.nextafter(up, np.inf), np.nextafter(down, -np.inf)
        steps += [up, down]
    steps.append(t[1] - t[0])
    for step in steps:
        clock = {"t0_s": float(t[0]), "dt_s": float(step), "samples": n}
        if np.array_equal(clock_times(clock).view(np.int64), t.view(np.int64)):
            return clock
    return None


def implicit_clock(meta: dict) -> dict | None:
    """The shard's implicit clock (metadata ``clock``), or None when ``time_s`` is a column."""
    return meta.get("clock")


# --- writing -----------------------------------------------------------------------------
ROW_GROUP = 1 << 20
"""Rows per Parquet row group."""
WRITE_BATCH = 1 << 16
"""Rows the Parquet encoder takes per step (pyarrow's default: 1,024). A page is closed after
the step that fills it, so pages hold up to ~1.25 MiB instead of 1 MiB; the values written
are the same and the encoder's CPU falls by ~2.5 ns per row (benchmarks/README.md)."""


class Writer:
    """Column buffers of one row group (plus one chunk of slack), written as they fill.

    Producers either hand rows over (:meth:`put`, a copy) or write them in place: :meth:`reserve`
    gives ``(L, 3)`` views of each group's three column buffers at the next free rows, and
    :meth:`commit` appends them under a sequence id. Each group is one ``(3, capacity)``
    array, so a column is a contiguous row of it and goes to Parquet without a copy; when
    ``rows`` rows are filled they are written as one row group and the slack (fewer than one
    chunk of rows) moves to the front.
    """

    def __init__(self, pw: pq.ParquetWriter, schema_: pa.Schema, group_names, dtype, rows):
        self.w = pw
        self.schema = schema_
        self.groups = {g: GROUPS[g][0] for g in group_names}
        self.rows = rows
        self.cap = rows
        self.n = 0
        self.labels: pd.DataFrame | dict | None = None
        self.time = TIME in schema_.names  # False: implicit clock, ``t`` is not stored
        self.dtype = np.dtype(dtype)
        self._alloc(rows)

    def _alloc(self, cap: int) -> None:
        old = getattr(self, "gbuf", None)
        gbuf = {g: np.empty((3, cap), self.dtype) for g in self.groups}
        seq = np.empty(cap, np.int64)
        tim = np.empty(cap) if self.time else None
        if old is not None:
            for g in self.groups:
                gbuf[g][:, : self.n] = old[g][:, : self.n]
            seq[: self.n] = self.seq[: self.n]
            if self.time:
                tim[: self.n] = self.tim[: self.n]
        self.gbuf, self.seq, self.tim, self.cap = gbuf, seq, tim, cap

    def reserve(self, L: int) -> dict:
        """``{group: (L, 3) view}`` of the next ``L`` free rows (valid until :meth:`commit`)."""
        if self.n + L > self.cap:
            self._alloc(self.n + max(L, self.rows // 8))
        a, b = self.n, self.n + L
        return {g: buf[:, a:b].T for g, buf in self.gbuf.items()}

    def commit(self, seq_id: int, t: np.ndarray) -> None:
        """Append the ``len(t)`` reserved rows (filled) as samples of sequence ``seq_id``."""
        L = len(t)
        a, b = self.n, self.n + L
        self.seq[a:b] = seq_id
        if self.time:
            self.tim[a:b] = t
        self.n = b
        while self.n >= self.rows:
            self._write(self.rows)

    def put(self, seq_id: int, t: np.ndarray, outs: dict) -> None:
        """Append ``len(t)`` rows of sequence ``seq_id``; ``outs``: group -> (L, 3)."""
        views = self.reserve(len(t))
        for g, v in views.items():
            v[...] = outs[g]
        self.commit(seq_id, t)

    def _write(self, m: int) -> None:
        """Write the first ``m`` buffered rows as a row group; move the rest to the front."""
        cols = {SEQUENCE: self.seq[:m]}
        if self.time:
            cols[TIME] = self.tim[:m]
        for g, names_ in self.groups.items():
            for i, c in enumerate(names_):
                cols[c] = self.gbuf[g][i, :m]
        arrays = [from_numpy(cols[f.name]) for f in self.schema]
        self.w.write_table(pa.Table.from_arrays(arrays, schema=self.schema), row_group_size=m)
        rest = self.n - m
        if rest:
            for buf in self.gbuf.values():
                buf[:, :rest] = buf[:, m : self.n]
            self.seq[:rest] = self.seq[m : self.n]
            if self.time:
                self.tim[:rest] = self.tim[m : self.n]
        self.n = rest

    def flush(self) -> None:
        if self.n:
            self._write(self.n)


@contextmanager
def writer(
    out,
    meta: dict,
    group_names,
    dtype="float32",
    *,
    compression="none",
    row_group=None,
    time_s=None,
    dt=None,
    explicit_time=False,
) -> Iterator[Writer]:
    """Write a shard atomically: yields a :class:`Writer`; set ``w.labels`` (a DataFrame, or a
    dict of equal-length columns) before the end.

    ``time_s`` (the ``(K,)`` clock every sequence shares): when :func:`uniform_clock` (step
    hint ``dt``) reproduces it exactly and ``explicit_time`` is false, it is recorded once in the metadata
    (``clock``) and the rows carry no ``time_s`` column; otherwise (or without ``time_s``) the
    ``t`` handed to :meth:`Writer.put` is stored in every row.

    The shard and its labels each go to a temporary name; both are renamed only when both
    are complete, the shard last: a shard at its path always has its labels beside it.
    Dictionary encoding only for ``sequence``; float columns PLAIN; statistics on
    ``sequence`` and ``time_s``.
    """
    out = Path(out)
    lab_path = labels_path(out)
    meta = {**meta, "format": FORMAT, "format_version": FORMAT_VERSION}
    meta["labels_file"] = lab_path.name
    meta["units"] = units(group_names)
    clock = None if explicit_time or time_s is None else uniform_clock(time_s, dt)
    meta["clock"] = clock
    sch = schema(group_names, dtype, meta, time_column=clock is None)
    with atomic_output(out) as tmp:
        with pq.ParquetWriter(
            tmp,
            sch,
            compression=compression,
            use_dictionary=[SEQUENCE],
            write_statistics=[SEQUENCE] if clock else [SEQUENCE, TIME],
            write_batch_size=WRITE_BATCH,
        ) as pw:
            w = Writer(pw, sch, group_names, np.dtype(dtype), row_group or ROW_GROUP)
            yield w
            w.flush()
        if w.labels is None:
            raise RuntimeError("shard writer closed without labels")
        lmeta = {**meta, "format": LABELS_FORMAT, "shard_file": out.name}
        with atomic_output(lab_path) as tmp_lab:
            pq.write_table(with_meta(_labels_table(w.labels), lmeta), tmp_lab)


def _labels_table(labels) -> pa.Table:
    """Arrow table of the labels: a dict of columns (no pandas needed) or a DataFrame."""
    if isinstance(labels, dict):
        return pa.table({k: from_numpy(np.asarray(v)) for k, v in labels.items()})
    return pa.Table.from_pandas(labels, preserve_index=False)


def write(
    out,
    time_s,
    data: dict,
    ids,
    labels: pd.DataFrame,
    meta: dict,
    dtype="float32",
    explicit_time=False,
) -> Path:
    """Write in-memory sequences as a shard: ``data`` group -> (M, K, 3), ``ids`` (M,);
    ``time_s`` (K,) as an implicit clock when it is uniform (see :func:`writer`)."""
    time_s = np.asarray(time_s, np.float64)
    ids = np.asarray(ids, np.int64)
    gnames = [g for g in GROUPS if g in data]
    K = len(time_s)
    for g in gnames:
        if np.shape(data[g]) != (len(ids), K, 3):
            raise InputError(out, f"{g} must be ({len(ids)}, {K}, 3), got {np.shape(data[g])}")
    with writer(out, meta, gnames, dtype, time_s=time_s, explicit_time=explicit_time) as w:
        for j, sid in enumerate(ids):
            w.put(int(sid), time_s, {g: data[g][j] for g in gnames})
        w.labels = labels
    return Path(out)


# --- reading -----------------------------------------------------------------------------
def read(path, columns=None, filters=None) -> pa.Table:
    """Columns (default all, ``time_s`` included) of a shard, rows kept by ``filters`` (pyarrow
    syntax: a list of ``(column, op, value)``; filters on ``time_s`` are applied after reading
    when the clock is implicit). An implicit ``time_s`` is rebuilt from the metadata's clock."""
    stored = column_names(path)
    if TIME in stored or (columns is not None and TIME not in columns and not _on_time(filters)):
        return read_table(path, columns, filters, WHAT)
    clock = implicit_clock(read_meta(path))
    if clock is None:
        raise InputError(path, "has neither a time_s column nor a clock in its metadata")
    want = stored if columns is None else list(columns)
    if columns is None:  # the documented order: sequence, time_s, measurements
        want = [SEQUENCE, TIME, *[c for c in stored if c != SEQUENCE]]
    time_filters = [f for f in filters or () if f[0] == TIME]
    other = [f for f in filters or () if f[0] != TIME] or None
    if other and not all(isinstance(f, tuple | list) and len(f) == 3 for f in other):
        raise InputError(path, "filters must be a list of (column, op, value)")
    base = [c for c in want if c != TIME]
    if SEQUENCE not in base:
        base.append(SEQUENCE)
    tbl = read_table(path, base, other, WHAT)
    K = int(clock["samples"])
    if tbl.num_rows % K:
        raise InputError(path, f"holds {tbl.num_rows} rows: not whole sequences of {K} samples")
    t = np.tile(clock_times(clock), tbl.num_rows // K)
    tbl = tbl.append_column(pa.field(TIME, pa.float64(), nullable=False), from_numpy(t))
    if time_filters:
        keep = np.ones(len(t), bool)
        for _, op, v in time_filters:
            keep &= _compare(t, op, v, path)
        tbl = tbl.filter(from_numpy(keep.view(np.uint8)).cast(pa.bool_()))
    return tbl.select(want)


def _on_time(filters) -> bool:
    return any(isinstance(f, tuple | list) and f and f[0] == TIME for f in filters or ())


def _compare(t: np.ndarray, op: str, v, path) -> np.ndarray:
    ops = {
        "==": np.equal,
        "=": np.equal,
        "!=": np.not_equal,
        "<": np.less,
        "<=": np.less_equal,
        ">": np.greater,
        ">=": np.greater_equal,
    }
    if op in ("in", "not in"):
        m = np.isin(t, np.asarray(list(v), float))
        return m if op == "in" else ~m
    if op not in ops:
        raise InputError(path, f"unsupported filter operator {op!r} on {TIME}")
    return ops[op](t, float(v))


def times(path, meta: dict | None = None) -> np.ndarray:
    """The ``(K,)`` clock every sequence of shard ``path`` shares (float64): the implicit
    clock of the metadata, else the ``time_s`` of its first sequence."""
    meta = read_meta(path) if meta is None else meta
    clock = implicit_clock(meta)
    if clock is not None:
        return clock_times(clock)
    K = int(meta.get("samples_per_sequence") or 0)
    tbl = read(path, [SEQUENCE, TIME])
    if K <= 0 or tbl.num_rows % K:
        raise InputError(path, f"holds {tbl.num_rows} rows: not whole sequences of {K} samples")
    return tbl.column(TIME).to_numpy()[:K].astype(np.float64)


def column_names(path) -> list[str]:
    """Columns present in a shard (footer only)."""
    return names(path, WHAT)


def schema_of(path) -> pa.Schema:
    """Arrow schema of a shard (footer only)."""
    return open_file(path, WHAT).schema_arrow


def rows(path) -> int:
    """Rows of a shard (footer only)."""
    return num_rows(path, WHAT)


def read_labels(path, meta: dict | None = None) -> pd.DataFrame:
    """The labels sidecar of shard ``path`` (InputError if missing)."""
    path = Path(path)
    name = (meta or {}).get("labels_file") or labels_path(path).name
    lp = path.with_name(name)
    if not lp.exists():
        raise InputError(lp, "labels sidecar missing (incomplete shard?)")
    return read_table(lp, what="shard labels table").to_pandas()


G0 = 9.80665
"""Standard gravity [m/s^2] of the static labels (:data:`imugen.core.units.G0`)."""


def static_labels(sensor: str, b_on, E, G=None) -> dict:
    """The static terms of one triad, named apart (see the module docstring).

    Parameters
    ----------
    sensor : {"gyro", "accel"}
    b_on : (S, 3)
        Additive turn-on bias [rad/s | m/s^2].
    E : (S, 3, 3)
        Scale factor (diagonal) and cross-coupling.
    G : (S, 3, 3), optional
        Gyro g-sensitivity [rad/s per m/s^2].
    """
    unit = "radps" if sensor == "gyro" else "mps2"
    b = np.asarray(b_on, float)
    out = {}
    if sensor == "gyro":
        grav = np.asarray(G, float)[:, :, 2] * G0
        name = "gyro_g_sensitivity_gravity"
    else:
        grav = np.asarray(E, float)[:, :, 2] * G0
        name = "accel_scale_factor_gravity"
    for i, a in enumerate("xyz"):
        out[f"{name}_{a}_{unit}"] = grav[:, i]
    for i, a in enumerate("xyz"):
        out[f"{sensor}_bias_at_rest_{a}_{unit}"] = b[:, i] + grav[:, i]
    return out


def mounting_labels(angles, lever) -> dict:
    """Label columns :data:`MOUNTING` of ``angles``, ``lever`` (S, 3) [rad, m]."""
    a, lv = np.asarray(angles, float), np.asarray(lever, float)
    out = {c: a[:, i] for i, c in enumerate(MOUNT_ANGLES)}
    out.update({c: lv[:, i] for i, c in enumerate(LEVER_ARM)})
    return out


def mounting(labels, ids=None):
    """``(angles (S, 3) rad, lever (S, 3) m)`` of the sequences ``ids`` (default all, in the
    labels' order) from a labels table (DataFrame or dict of columns); None without mounting."""
    if labels is None or any(c not in labels for c in MOUNTING):
        return None
    col = {c: np.asarray(labels[c], dtype=np.float64) for c in MOUNTING}
    if ids is not None:
        seq = np.asarray(labels[SEQUENCE], dtype=np.int64)
        order = np.argsort(seq)
        pos = order[np.searchsorted(seq, np.asarray(ids, np.int64), sorter=order)]
        col = {c: v[pos] for c, v in col.items()}
    angles = np.column_stack([col[c] for c in MOUNT_ANGLES])
    return angles, np.column_stack([col[c] for c in LEVER_ARM])


def increment_kind(meta: dict) -> str:
    """``"compensated"`` or ``"raw"``: the increment semantics recorded in a shard's metadata."""
    kind = meta.get("increments", "compensated")
    if kind not in INCREMENT_KINDS:
        raise InputError("shard metadata", f"unknown increment semantics {kind!r}")
    return kind


def measurement(path) -> tuple[list[str], str]:
    """``(columns, kind)`` of a shard's measurements: increments if present, else rates."""
    have = set(column_names(path))
    if set(INCREMENTS) <= have:
        return list(INCREMENTS), "increments"
    if set(RATES) <= have:
        return list(RATES), "rates"
    raise InputError(path, "holds neither increment nor rate columns of an IMU shard")


def stored_ids(path, rows_per_sequence: int, meta: dict | None = None) -> np.ndarray:
    """Sequence ids of a shard in row order (int64): the metadata's contiguous ``sequence_ids``
    range when it matches the row count, else the ``sequence`` column's runs."""
    n = rows(path)
    if n % rows_per_sequence:
        raise InputError(
            path, f"holds {n} rows: not whole sequences of {rows_per_sequence} samples"
        )
    ids = (meta or {}).get("sequence_ids")
    if ids and ids[1] - ids[0] + 1 == n // rows_per_sequence:
        return np.arange(ids[0], ids[1] + 1, dtype=np.int64)
    seq = read(path, [SEQUENCE]).column(SEQUENCE).to_numpy()
    return seq[::rows_per_sequence].astype(np.int64)


def iter_sequences(path, columns, rows_per_sequence: int, dtype):
    """Yield ``(sequence id, block (len(columns), rows))`` for each sequence, in file order.

    Reads one row group at a time; ``block`` is a reused buffer (consume it before the next
    step). Raises InputError unless the rows come in runs of exactly ``rows_per_sequence``
    per sequence with increasing ids.
    """
    pf = open_file(path, WHAT)
    buf = np.empty((len(columns), rows_per_sequence), dtype)
    columns = list(columns)
    if TIME in columns and TIME not in pf.schema_arrow.names:
        clock = implicit_clock(read_meta(path))
        if clock is None or int(clock["samples"]) != rows_per_sequence:
            raise InputError(path, "has neither a time_s column nor a matching clock")
        buf[columns.index(TIME)] = clock_times(clock)  # filled once, never overwritten
        stored = [c for c in columns if c != TIME]
        rows_of = [i for i, c in enumerate(columns) if c != TIME]
    else:
        stored, rows_of = columns, list(range(len(columns)))
    fill, cur, last = 0, None, None
    bad = (
        f"rows are not grouped by sequence with {rows_per_sequence} rows each "
        "(sorted by sequence, time)"
    )
    for g in range(pf.num_row_groups):
        t = pf.read_row_group(g, columns=[SEQUENCE, *stored])
        seq = to_numpy(t.column(SEQUENCE))
        cols = [to_numpy(t.column(c)) for c in stored]
        n, pos = len(seq), 0
        while pos < n:
            m = min(rows_per_sequence - fill, n - pos)
            ids = seq[pos : pos + m]
            if fill == 0:
                cur = int(ids[0])
                if last is not None and cur <= last:
                    raise InputError(path, bad)
            if not (ids == cur).all():
                raise InputError(path, bad)
            for i, c in zip(rows_of, cols, strict=True):
                buf[i, fill : fill + m] = c[pos : pos + m]
            fill += m
            pos += m
            if fill == rows_per_sequence:
                yield cur, buf
                fill, last = 0, cur
    if fill:
        raise InputError(path, bad)


READ_ROWS = 1 << 16
"""Rows per Parquet record batch read by :func:`iter_blocks` (results do not depend on it)."""


def iter_blocks(path, columns, samples: int, batch: int, skip: int = 0):
    """Yield ``(ids (b,), a (b, samples-skip, 3), c (b, samples-skip, 3))`` per batch of sequences.

    ``a`` holds ``columns[:3]`` and ``c`` ``columns[3:6]`` as float64, the first ``skip`` rows
    of each sequence dropped (the zero increment of ``t_0``). The arrays are views into two
    buffers reused from batch to batch, filled straight from the Parquet record batches:
    memory stays at ``2 * batch * samples * 24`` bytes plus one record batch, whatever the
    shard holds. Each view is valid until the next iteration.
    """
    # buffered reads, no pre-buffering of whole row groups, no reader threads: a 250-sequence
    # shard then streams through ~30 MB instead of ~180 MB, with a fifth of the system time
    pf = open_file(path, WHAT, pre_buffer=False, buffer_size=1 << 20)
    K = int(samples)
    width = K - skip
    bufs = (np.empty((batch, width, 3)), np.empty((batch, width, 3)))
    ids = np.empty(batch, np.int64)
    n = 0  # complete sequences in the buffers
    k = 0  # rows received of the current sequence
    cur = 0
    for rb in pf.iter_batches(
        batch_size=READ_ROWS, columns=[SEQUENCE, *columns], use_threads=False
    ):
        seq = to_numpy(rb.column(0))
        data = [to_numpy(rb.column(i + 1)) for i in range(len(columns))]
        r, R = 0, len(seq)
        while r < R:
            m = min(R - r, K - k)
            if k == 0:
                cur = seq[r]
                ids[n] = cur
            if not (seq[r : r + m] == cur).all():
                raise InputError(path, "rows are not grouped by sequence with one row per sample")
            lo = max(k, skip)  # first sample of this run that is stored
            if lo < k + m:
                for i, src in enumerate(data):
                    bufs[i // 3][n, lo - skip : k + m - skip, i % 3] = src[r + lo - k : r + m]
            k += m
            r += m
            if k == K:
                n, k = n + 1, 0
                if n == batch:
                    yield ids[:n], bufs[0][:n], bufs[1][:n]
                    n = 0
    if k:
        raise InputError(path, f"holds {k} stray rows: not whole sequences of {K}")
    if n:
        yield ids[:n], bufs[0][:n], bufs[1][:n]


# --- derived shards ------------------------------------------------------------------------
def _groups_of(data, K: int, S: int, source) -> dict:
    """``{group: (S, K, 3) float64}`` from (dtheta, dv), a dict of groups or an (S, K, 6) array."""
    if isinstance(data, dict):
        items = dict(data)
    elif isinstance(data, tuple | list) and len(data) == 2:
        items = {"dtheta": data[0], "dv": data[1]}
    else:
        a = np.asarray(data, dtype=np.float64)
        if a.shape[-1] != 6:
            raise InputError(source, f"expected (S, K, 6) or (dtheta, dv), got {a.shape}")
        items = {"dtheta": a[..., :3], "dv": a[..., 3:]}
    unknown = [g for g in items if g not in GROUPS]
    if unknown:
        raise InputError(source, f"unknown column group(s) {', '.join(unknown)}")
    out = {}
    for g, x in items.items():
        x = np.asarray(x, dtype=np.float64)
        if x.ndim == 2:
            x = x[None]
        if x.ndim != 3 or x.shape[0] != S or x.shape[2] != 3 or x.shape[1] not in (K, K - 1):
            raise InputError(
                source, f"{g} must be ({S}, {K}, 3) or ({S}, {K - 1}, 3), got {x.shape}"
            )
        if x.shape[1] == K - 1:  # no row for t_0: the empty interval is zero
            x = np.concatenate([np.zeros((S, 1, 3)), x], axis=1)
        if not np.all(np.isfinite(x)):
            raise InputError(source, f"{g} holds non-finite values")
        out[g] = x
    if not ({"dtheta", "dv"} <= set(out) or {"gyro", "accel"} <= set(out)):
        raise InputError(source, "give both dtheta and dv (or both gyro and accel)")
    return out


def write_like(path, data, like, *, semantics: str | None = None, dtype="float32", note=None):
    """Write corrected measurements as a valid shard, metadata derived from shard ``like``.

    Parameters
    ----------
    path : path
        Output shard (its labels sidecar is written beside it).
    data : (dtheta, dv), dict or ndarray
        The new measurements of every sequence of ``like``, in its order: ``(dtheta, dv)``
        each ``(S, K, 3)`` (rows aligned with the shard; or ``(S, K-1, 3)`` without the empty
        row of ``t_0``), a dict of column groups (``"dtheta"``, ``"dv"``, ``"gyro"``,
        ``"accel"``, ...; see :data:`GROUPS`) or an ``(S, K, 6)`` array (dtheta then dv).
    like : path
        The shard the data were derived from: ids, times, labels and metadata are taken from
        it; the metadata's ``derived`` records the origin (file name, SHA-256) and ``note``.
    semantics : {"compensated", "raw"}, optional
        Increment semantics of ``data`` (default that of ``like``).
    dtype : {"float32", "float64"}

    Returns
    -------
    Path
    """
    from imugen.tables.truth import checksum

    like = Path(like)
    meta = read_meta(like)
    K = int(meta.get("samples_per_sequence") or 0)
    n = rows(like)
    if K <= 0 or n % K:
        raise InputError(like, f"holds {n} rows: not whole sequences of {K} samples")
    S = n // K
    ids = stored_ids(like, K, meta)
    clock = times(like, meta)
    groups_ = _groups_of(data, K, S, "data")
    semantics = semantics or increment_kind(meta)
    if semantics not in INCREMENT_KINDS:
        raise InputError("semantics", f"must be compensated or raw, got {semantics!r}")
    if dtype not in ("float32", "float64"):
        raise InputError("dtype", f"must be float32 or float64, got {dtype!r}")
    inc = "dtheta" in groups_
    rate = "gyro" in groups_
    new = {
        **meta,
        "outputs": "both" if inc and rate else ("increments" if inc else "rates"),
        "increments": semantics,
        "series": any(g not in ("dtheta", "dv", "gyro", "accel") for g in groups_),
        "dtype": np.dtype(dtype).name,
        "derived": {
            "from": like.name,
            "from_sha256": checksum(like),
            "groups": sorted(groups_),
            "note": note,
        },
    }
    labels = read_labels(like, meta)
    return write(path, clock, groups_, ids, labels, new, dtype)
