"""MATLAB export: one ``.mat`` file per route and grade (truth, IMU sequences, labels, nav errors).

:func:`export_mat` streams the Parquet shards of one grade into a MAT file that MATLAB
loads. MAT v5 (MATLAB's ``-v6``/``-v7`` format, written uncompressed) is written when every
variable is below MATLAB's 2 GiB per-variable limit; beyond it, MAT v7.3 (HDF5 with the 512-byte
MATLAB header, written with the optional dependency ``h5py``). Neither path holds the IMU data
in memory: the shards are read row group by row group and each sequence is written in place
(v5: at its offset in the file; v7.3: into a chunked dataset). The file is written under a
temporary name and renamed when complete, and it is byte-reproducible (no creation date in the
header, no HDF5 timestamps).

Layout
------
``K`` samples (the truth's IMU rate), ``S`` sequences (ascending ``sequence_id``), ``E``
navigation evaluation epochs. Per-sequence arrays are ``K x 3 x S`` (sample, axis, sequence):
``imu_dv_mps(:, :, s)`` is the ``K x 3`` series of sequence ``s``, aligned row by row with
``truth_dv_mps``, so ``imu_dv_mps(:, :, s) - truth_dv_mps`` is its total error. Sequence is the
last (slowest) dimension because it is the order of the shards: the export is a pure stream,
and one sequence is contiguous in the file. NumPy sees the same shapes through
``scipy.io.loadmat`` (``(K, 3, S)``, element ``[k, i, s]`` = MATLAB ``(k+1, i+1, s+1)``); in a
v7.3 file read with ``h5py`` every dataset has the reversed shape (``(S, 3, K)``, ``(3, K)``,
...) since HDF5 is row-major and MATLAB column-major.

====================== =========  =======  ======  ===============================================
variable               size       class    unit    meaning
====================== =========  =======  ======  ===============================================
truth_time_s           K x 1      double   s       sample times from the route start
truth_pos_enu_m        K x 3      double   m       position p_n (East, North, Up of the origin)
truth_vel_enu_mps      K x 3      double   m/s     velocity v_n relative to the Earth
truth_quat_nb          K x 4      double   1       attitude C_nb as a quaternion (w, x, y, z)
truth_rpy_rad          K x 3      double   rad     roll, pitch, yaw (unwrapped; yaw 0 = East)
truth_gyro_radps       K x 3      double   rad/s   true angular rate omega_ib_b
truth_accel_mps2       K x 3      double   m/s^2   true specific force f_b
truth_dtheta_rad       K x 3      double   rad     exact angle increment of (t(k-1), t(k)]
truth_dv_mps           K x 3      double   m/s     exact velocity increment of (t(k-1), t(k)]
imu_dtheta_rad         K x 3 x S  single*  rad     measured angle increments (row 1 zero)
imu_dv_mps             K x 3 x S  single*  m/s     measured velocity increments (row 1 zero)
imu_gyro_radps         K x 3 x S  single*  rad/s   measured angular rate (if simulated)
imu_accel_mps2         K x 3 x S  single*  m/s^2   measured specific force (if simulated)
true_gyro_bias_radps   K x 3 x S  single*  rad/s   true slow gyro bias (if ``series``)
true_gyro_sf           K x 3 x S  single*  1       true gyro scale-factor error (if ``series``)
true_accel_bias_mps2   K x 3 x S  single*  m/s^2   true slow accel bias (if ``series``)
true_accel_sf          K x 3 x S  single*  1       true accel scale-factor error (if ``series``)
err_dtheta_rad         K x 3 x S  single*  rad     effective error of imu_dtheta_rad (if ``series``)
err_dv_mps             K x 3 x S  single*  m/s     effective error of imu_dv_mps (if ``series``)
err_gyro_radps         K x 3 x S  single*  rad/s   effective error of imu_gyro_radps (if ``series``)
err_accel_mps2         K x 3 x S  single*  m/s^2   effective error of imu_accel_mps2 (if ``series``)
sequence_id            S x 1      int64    1       global sequence id (``route_id << 31 | index``)
labels                 struct              SI      one S x 1 field per labels column (drawn
                                                   parameters; the unit is in the field name)
nav_time_s             E x 1      double   s       navigation evaluation epochs (with ``nav``)
nav_err_enu_m          E x 3 x S  double   m       navigated minus true position, ENU at the
                                                   true position (imugen.tables.nav)
nav_err_att_rad        E x S      double   rad     attitude error angle
info                   struct                      metadata, below
====================== =========  =======  ======  ===============================================

``*`` as stored in the shards (single by default, double for shards written with
``dtype="float64"``). Increments on row ``k`` belong to the interval ending at ``t(k)``; row 1
(MATLAB indexing) of every increment series is zero. The effective error is everything the
sensor adds except white noise and quantization (``imu = true + err + white + quantization``).
``info.increment_semantics`` is ``compensated`` (the truth's increments: ``imu_dv_mps -
truth_dv_mps`` is the total error) or ``raw`` (plain integrals of rate and specific force).

``info`` fields: ``format`` ("imugen-mat"), ``format_version``, ``imugen_version``, ``route``,
``grade``, ``grade_id``, ``grade_description``, ``seed``, ``origin`` (struct ``lat_deg``,
``lon_deg``, ``alt_m``: WGS-84 geodetic origin of the ENU frame), ``earth`` ("flat" or
"wgs84"), ``rate_hz``, ``dt_s``, ``samples`` (K), ``sequences`` (S), ``epochs`` (E, 0 without
navigation), ``mat_version`` ("5" or "7.3"), ``layout``, ``frames``, ``increments`` (text),
``increment_semantics``, and
``units`` (struct: variable name -> unit string).

Frames: ``n`` is local East-North-Up with the axes of the topocentric frame at the route
origin; body ``b`` is x forward, y left, z up (a level still IMU reads ``f_b = (0, 0, +g)``);
``C_nb`` rotates body to navigation vectors (``v_n = C_nb * v_b``); quaternions are scalar first.

MATLAB::

    d = load('results/route/mat/consumer.mat');
    s = 1;
    err = double(d.imu_dv_mps(:, :, s)) - d.truth_dv_mps;   % K x 3 increment error
    plot(d.nav_time_s, d.nav_err_enu_m(:, 1, s));           % East error of sequence 1
"""

from __future__ import annotations

import os
import re
from pathlib import Path

import numpy as np
import pandas as pd

from imugen import __version__
from imugen.core.errors import InputError
from imugen.core.io import atomic_output, read_meta
from imugen.export.options import ExportMatOptions
from imugen.tables import SEQUENCE
from imugen.tables import nav as tnav
from imugen.tables import shard as tshard
from imugen.tables import truth as col

V5_MAX_BYTES = 2**31
"""MATLAB's per-variable limit of MAT v5/v7 files (bytes); larger variables need v7.3."""

TRUTH_VARS = {
    "truth_time_s": ((col.TIME,), "s"),
    "truth_pos_enu_m": (col.POS, "m"),
    "truth_vel_enu_mps": (col.VEL, "m/s"),
    "truth_quat_nb": (col.QUAT, "1"),
    "truth_rpy_rad": (col.EULER, "rad"),
    "truth_gyro_radps": (col.GYRO, "rad/s"),
    "truth_accel_mps2": (col.ACCEL, "m/s^2"),
    "truth_dtheta_rad": (col.DTHETA, "rad"),
    "truth_dv_mps": (col.DV, "m/s"),
}
"""Truth variables: MATLAB name -> (truth columns, unit)."""

IMU_VARS = {
    "imu_dtheta_rad": (col.DTHETA, "rad"),
    "imu_dv_mps": (col.DV, "m/s"),
    "imu_gyro_radps": (col.GYRO, "rad/s"),
    "imu_accel_mps2": (col.ACCEL, "m/s^2"),
    "true_gyro_bias_radps": (tshard.BIAS_SERIES["gyro"], "rad/s"),
    "true_gyro_sf": (tshard.SF_SERIES["gyro"], "1"),
    "true_accel_bias_mps2": (tshard.BIAS_SERIES["accel"], "m/s^2"),
    "true_accel_sf": (tshard.SF_SERIES["accel"], "1"),
    "err_dtheta_rad": (tshard.ERR_DTHETA, "rad"),
    "err_dv_mps": (tshard.ERR_DV, "m/s"),
    "err_gyro_radps": (tshard.ERR_GYRO, "rad/s"),
    "err_accel_mps2": (tshard.ERR_ACCEL, "m/s^2"),
}
"""Per-sequence shard variables (exported when the shards have the columns)."""

LAYOUT = (
    "per-sequence arrays are K x 3 x S (sample, axis, sequence): imu_dv_mps(:,:,s) is the "
    "K x 3 series of sequence s, aligned row by row with truth_dv_mps; nav_err_enu_m is E x 3 x S"
)
FRAMES = (
    "n: local East-North-Up, axes of the topocentric frame at the route origin; b: body x "
    "forward, y left, z up (level still IMU reads f_b = (0,0,+g)); C_nb rotates b to n "
    "(v_n = C_nb*v_b); quaternions scalar first (w,x,y,z); rpy: C_lb = Rz(yaw)*Ry(-pitch)*Rx(roll), "
    "yaw 0 faces East"
)
INCREMENTS = (
    "row k of *_dtheta_rad and *_dv_mps is the increment over (t(k-1), t(k)]; row 1 is zero"
)


# --- shard and navigation files -------------------------------------------------------------
def _labels_table(shard_paths, ids) -> pd.DataFrame:
    parts = [tshard.read_labels(p) for p in shard_paths]
    lab = pd.concat(parts, ignore_index=True).sort_values(SEQUENCE, kind="stable")
    if not np.array_equal(lab[SEQUENCE].to_numpy(np.int64), ids):
        raise InputError(
            tshard.labels_path(shard_paths[-1]),
            "labels sequences do not match the shards' sequences",
        )
    return lab


def _field_name(name: str) -> str:
    """A valid MATLAB field name (letters, digits, underscores; a letter first; <= 63)."""
    s = re.sub(r"\W", "_", name, flags=re.ASCII)
    if not s or not s[0].isalpha():
        s = "x" + s
    return s[:63]


# --- MAT v5 ------------------------------------------------------------------------------------
_MI_INT8, _MI_INT32, _MI_UINT32, _MI_SINGLE, _MI_DOUBLE, _MI_MATRIX = 1, 5, 6, 7, 9, 14
_V5_CLASS = {"float32": (7, _MI_SINGLE), "float64": (6, _MI_DOUBLE)}  # (mxCLASS, miTYPE)


def _pad8(n: int) -> int:
    return (-n) % 8


def _v5_header() -> bytes:
    text = f"MATLAB 5.0 MAT-file, Platform: posix, Created by: imugen {__version__}"
    return text.encode("ascii").ljust(116, b" ") + bytes(8) + np.uint16(0x0100).tobytes() + b"IM"


def _v5_tag(mdtype: int, nbytes: int) -> bytes:
    return np.array([mdtype, nbytes], "<u4").tobytes()


def _v5_matrix_prefix(name: str, dims, dtype) -> tuple[bytes, int, int]:
    """Bytes of a numeric miMATRIX element up to its data; the data size and trailing pad."""
    mclass, mdtype = _V5_CLASS[np.dtype(dtype).name]
    nbytes = int(np.prod(dims)) * np.dtype(dtype).itemsize
    flags = _v5_tag(_MI_UINT32, 8) + np.array([mclass, 0], "<u4").tobytes()
    d = np.asarray(dims, "<i4").tobytes()
    dims_el = _v5_tag(_MI_INT32, len(d)) + d + bytes(_pad8(len(d)))
    nm = name.encode("ascii")
    if len(nm) <= 4:
        name_el = np.uint32((len(nm) << 16) | _MI_INT8).astype("<u4").tobytes() + nm.ljust(4, b"\0")
    else:
        name_el = _v5_tag(_MI_INT8, len(nm)) + nm + bytes(_pad8(len(nm)))
    pad = _pad8(nbytes)
    body = flags + dims_el + name_el + _v5_tag(mdtype, nbytes)
    total = len(body) + nbytes + pad
    if total >= 2**32:
        raise ValueError(f"{name}: {total} bytes do not fit a MAT v5 element")
    return _v5_tag(_MI_MATRIX, total) + body, nbytes, pad


class _V5Writer:
    """MAT v5: small variables through scipy, per-sequence arrays written at their offsets."""

    version = "5"

    def __init__(self, path):
        from scipy.io.matlab._mio5 import MatFile5Writer

        self.f = open(path, "wb")
        self.f.write(_v5_header())
        self.w = MatFile5Writer(
            self.f,
            do_compression=False,
            unicode_strings=True,
            long_field_names=True,
            oned_as="column",
        )
        self.streams = {}

    def put(self, name, value):
        self.f.seek(0, os.SEEK_END)
        self.w.put_variables({name: value}, write_header=False)

    def reserve(self, name, rows, width, S, dtype):
        """Reserve ``rows x width x S`` (``rows x S`` if width is None) of ``dtype``."""
        dims = (rows, S) if width is None else (rows, width, S)
        prefix, nbytes, pad = _v5_matrix_prefix(name, dims, dtype)
        self.f.seek(0, os.SEEK_END)
        self.f.write(prefix)
        off = self.f.tell()
        self.f.truncate(off + nbytes + pad)  # zeros; the data is written in place later
        self.streams[name] = (off, rows * (width or 1) * np.dtype(dtype).itemsize, np.dtype(dtype))

    def write(self, name, s, block):
        """Sequence ``s`` of ``name``: ``block`` (width, rows), C order = MATLAB (rows, width)."""
        off, step, dtype = self.streams[name]
        self.f.seek(off + s * step)
        self.f.write(np.ascontiguousarray(block, dtype).tobytes())

    def close(self):
        self.f.close()


# --- MAT v7.3 (HDF5) ----------------------------------------------------------------------------
_H5_CLASS = {
    "float64": "double",
    "float32": "single",
    "int8": "int8",
    "uint8": "uint8",
    "int16": "int16",
    "uint16": "uint16",
    "int32": "int32",
    "uint32": "uint32",
    "int64": "int64",
    "uint64": "uint64",
}


def _v73_header() -> bytes:
    text = f"MATLAB 7.3 MAT-file, Platform: imugen {__version__}, HDF5 schema 1.00 ."
    return text.encode("ascii").ljust(116, b" ") + bytes(8) + np.uint16(0x0200).tobytes() + b"IM"


def _import_h5py(out_path):
    try:
        import h5py
    except ImportError:
        raise InputError(
            out_path,
            "a variable exceeds the 2 GiB MAT v5 limit per variable; install h5py "
            "(pip install h5py) for MAT v7.3, or use the Parquet shards",
        ) from None
    return h5py


class _H5Writer:
    """MAT v7.3: HDF5 with MATLAB attributes; dimensions reversed (MATLAB is column-major)."""

    version = "7.3"
    CHUNK = 1 << 16
    """Samples per chunk along time (one sequence's axis block; no compression)."""

    def __init__(self, path, h5py):
        self.h5py = h5py
        self.path = path
        self.f = h5py.File(path, "w", userblock_size=512, libver="earliest")
        self.streams = {}

    def _cls(self, obj, name):
        """``MATLAB_class``: a fixed-length ASCII string (as hdf5storage writes it)."""
        obj.attrs.create("MATLAB_class", np.bytes_(name))

    def _put(self, grp, name, value):
        if isinstance(value, dict):
            g = grp.create_group(name, track_order=False)
            self._cls(g, "struct")
            vlen = self.h5py.vlen_dtype(np.dtype("S1"))
            fields = np.empty(len(value), dtype=vlen)
            for i, k in enumerate(value):
                fields[i] = np.array([c.encode("ascii") for c in k], dtype="S1")
            g.attrs.create("MATLAB_fields", fields, dtype=vlen)
            for k, v in value.items():
                self._put(g, k, v)
            return
        if isinstance(value, str):
            codes = np.frombuffer(value.encode("utf-16-le"), "<u2")
            if codes.size == 0:
                d = grp.create_dataset(name, data=np.zeros(2, np.uint64), track_times=False)
                d.attrs.create("MATLAB_empty", np.uint8(1))
            else:
                d = grp.create_dataset(name, data=codes.reshape(-1, 1), track_times=False)
            self._cls(d, "char")
            d.attrs.create("MATLAB_int_decode", np.int32(2))
            return
        arr = np.asarray(value)
        if arr.dtype == bool:
            arr = arr.astype(np.uint8)
        if arr.ndim == 0:
            arr = arr.reshape(1, 1)
        elif arr.ndim == 1:
            arr = arr.reshape(-1, 1)  # column, as oned_as="column" in v5
        d = grp.create_dataset(name, data=np.ascontiguousarray(arr.T), track_times=False)
        self._cls(d, _H5_CLASS[arr.dtype.name])

    def put(self, name, value):
        self._put(self.f, name, value)

    def reserve(self, name, rows, width, S, dtype):
        shape = (S, rows) if width is None else (S, width, rows)
        chunk = (1, min(rows, self.CHUNK)) if width is None else (1, width, min(rows, self.CHUNK))
        d = self.f.create_dataset(
            name, shape=shape, dtype=np.dtype(dtype), chunks=chunk, track_times=False
        )
        self._cls(d, _H5_CLASS[np.dtype(dtype).name])
        self.streams[name] = d

    def write(self, name, s, block):
        d = self.streams[name]
        d[s] = block if d.ndim == 3 else block[0]

    def close(self):
        self.f.close()
        with open(self.path, "r+b") as f:
            f.write(_v73_header())


# --- export ---------------------------------------------------------------------------------
def _sorted_by_first_id(paths, rows, metas):
    ids = [tshard.stored_ids(p, rows, m) for p, m in zip(paths, metas, strict=True)]
    order = sorted(range(len(paths)), key=lambda i: int(ids[i][0]) if len(ids[i]) else -1)
    return [paths[i] for i in order], [ids[i] for i in order], [metas[i] for i in order]


def export_mat(
    truth_path,
    shard_paths: list,
    out_path,
    *,
    grade: str,
    nav_paths=None,
    version: str = "auto",
    route: str | None = None,
) -> dict:
    """Write one grade's truth, IMU shards, labels (and navigation errors) as a ``.mat`` file.

    Parameters
    ----------
    truth_path : path
        ``truth.parquet`` of the route.
    shard_paths : list of path
        The grade's IMU shards (any order; sequences are written by ascending id), each with
        its ``.labels.parquet`` sidecar.
    out_path : path
        The ``.mat`` file (written atomically).
    grade : str
        Grade name; every shard's metadata must name it.
    nav_paths : list of path, optional
        The grade's navigation error tables (one per shard), exported as ``nav_*``.
    version : {"auto", "5", "7.3"}
        MAT version; ``"auto"`` is v5 when every variable is below :data:`V5_MAX_BYTES`.
    route : str, optional
        Route name for ``info.route`` (default: the name of the truth file's folder).

    Returns
    -------
    dict
        ``{"version", "sequences", "samples", "epochs", "variables"}`` of the file written.
    """
    truth_path, out_path = Path(truth_path), Path(out_path)
    if version not in ("auto", "5", "7.3"):
        raise InputError("--mat-version", f"must be auto, 5 or 7.3, got {version!r}")
    if not shard_paths:
        raise InputError(out_path, "no IMU shards to export")
    tmeta = read_meta(truth_path)
    K = col.samples(truth_path)
    truth_cols = set(col.column_names(truth_path))

    # shards: metadata, order, sequence ids, variables present
    shard_paths = [Path(p) for p in shard_paths]
    metas = [read_meta(p) for p in shard_paths]
    for p, m in zip(shard_paths, metas, strict=True):
        name = (m.get("grade") or {}).get("name")
        if name != grade:
            raise InputError(p, f"is a shard of grade {name!r}, not {grade!r}")
        samples = m.get("samples_per_sequence", m.get("samples"))
        if samples is not None and samples != K:
            raise InputError(p, f"has {samples} samples per sequence; the truth has {K}")
    shard_paths, shard_ids, metas = _sorted_by_first_id(shard_paths, K, metas)
    ids = np.concatenate(shard_ids)
    if np.any(np.diff(ids) <= 0):
        raise InputError(shard_paths[0], "shards hold overlapping sequence ids")
    S = len(ids)
    schema = tshard.schema_of(shard_paths[0])
    names0 = set(schema.names)
    imu_vars = {v: c for v, c in IMU_VARS.items() if set(c[0]) <= names0}
    if not imu_vars:
        raise InputError(shard_paths[0], "holds no IMU measurement columns")
    imu_cols = [c for cols, _ in imu_vars.values() for c in cols]
    dtype = np.result_type(*(schema.field(c).type.to_pandas_dtype() for c in imu_cols))
    for p in shard_paths[1:]:
        sch = tshard.schema_of(p)
        if not set(imu_cols) <= set(sch.names) or any(
            sch.field(c).type != schema.field(c).type for c in imu_cols
        ):
            raise InputError(p, f"columns or types differ from {shard_paths[0].name}")
    labels = _labels_table(shard_paths, ids)

    # navigation errors
    nav = None
    if nav_paths:
        nav_paths = [Path(p) for p in nav_paths]
        first = tnav.read(nav_paths[0], columns=[SEQUENCE, col.TIME])
        if first.empty:
            raise InputError(nav_paths[0], "is empty")
        nav_time = first.loc[first[SEQUENCE] == first[SEQUENCE].iloc[0], col.TIME].to_numpy()
        E = len(nav_time)
        nav_paths, nav_ids, _ = _sorted_by_first_id(nav_paths, E, [None] * len(nav_paths))
        if not np.array_equal(np.concatenate(nav_ids), ids):
            raise InputError(nav_paths[0], "navigation sequences do not match the IMU shards")
        nav = (nav_paths, nav_time)
    E = 0 if nav is None else len(nav[1])

    # version
    isz = np.dtype(dtype).itemsize
    sizes = {v: K * 3 * S * isz for v in imu_vars}
    if nav is not None:
        sizes["nav_err_enu_m"] = E * 3 * S * 8
    sizes["truth_quat_nb"] = K * 4 * 8
    big = max(sizes.values())
    if version == "auto":
        version = "5" if big < V5_MAX_BYTES else "7.3"
    if version == "5" and big >= V5_MAX_BYTES:
        raise InputError(out_path, f"a variable holds {big} bytes, beyond the MAT v5 limit (2 GiB)")
    h5py = _import_h5py(out_path) if version == "7.3" else None

    first_meta = metas[0]
    gmeta = first_meta.get("grade") or {}
    origin = tmeta.get("origin") or {}
    rate = float(tmeta.get("rate_hz") or first_meta.get("rate_hz") or np.nan)
    units = {v: u for v, (_, u) in TRUTH_VARS.items()}
    units.update({v: u for v, (_, u) in imu_vars.items()})
    units["sequence_id"] = "1"
    if nav is not None:
        units.update(nav_time_s="s", nav_err_enu_m="m", nav_err_att_rad="rad")
    info = {
        "format": "imugen-mat",
        "format_version": 1,
        "imugen_version": __version__,
        "route": route if route is not None else truth_path.parent.name,
        "grade": grade,
        "grade_id": int(gmeta.get("id", -1)),
        "grade_description": str(gmeta.get("description") or ""),
        "seed": int(first_meta.get("seed", -1)),
        "origin": {k: float(origin.get(k, np.nan)) for k in ("lat_deg", "lon_deg", "alt_m")},
        "earth": str(tmeta.get("earth", "")),
        "rate_hz": rate,
        "dt_s": 1.0 / rate,
        "samples": K,
        "sequences": S,
        "epochs": E,
        "mat_version": version,
        "layout": LAYOUT,
        "frames": FRAMES,
        "increments": INCREMENTS,
        "increment_semantics": str(first_meta.get("increments", "compensated")),
        "units": units,
    }

    with atomic_output(out_path) as tmp:
        w = _V5Writer(tmp) if version == "5" else _H5Writer(tmp, h5py)
        try:
            w.put("info", info)
            for v, (cols, _) in TRUTH_VARS.items():
                if not set(cols) <= truth_cols:
                    raise InputError(truth_path, f"lacks the columns {', '.join(cols)}")
                t = col.read_arrow(truth_path, columns=list(cols))
                w.put(v, np.column_stack([t.column(c).to_numpy() for c in cols]))
            w.put("sequence_id", ids.astype(np.int64))
            w.put(
                "labels",
                {_field_name(c): labels[c].to_numpy() for c in labels.columns if c != SEQUENCE},
            )
            if nav is not None:
                w.put("nav_time_s", nav[1])
            for v in imu_vars:
                w.reserve(v, K, 3, S, dtype)
            if nav is not None:
                w.reserve("nav_err_enu_m", E, 3, S, np.float64)
                w.reserve("nav_err_att_rad", E, None, S, np.float64)
            s = 0
            for p in shard_paths:
                for sid, block in tshard.iter_sequences(p, imu_cols, K, dtype):
                    if sid != ids[s]:
                        raise InputError(p, f"sequence {sid} where {ids[s]} was expected")
                    for i, v in enumerate(imu_vars):
                        w.write(v, s, block[3 * i : 3 * i + 3])
                    s += 1
            if nav is not None:
                s = 0
                for p in nav[0]:
                    cols = [col.TIME, *tnav.ERR_POS, tnav.ERR_ATT]
                    for _, block in tshard.iter_sequences(p, cols, E, np.float64):
                        if not np.array_equal(block[0], nav[1]):
                            raise InputError(p, "sequences have different evaluation epochs")
                        w.write("nav_err_enu_m", s, block[1:4])
                        w.write("nav_err_att_rad", s, block[4:5])
                        s += 1
        finally:
            w.close()
    variables = ["info", *TRUTH_VARS, "sequence_id", "labels", *imu_vars]
    if nav is not None:
        variables += ["nav_time_s", "nav_err_enu_m", "nav_err_att_rad"]
    return {"version": version, "sequences": S, "samples": K, "epochs": E, "variables": variables}


def main(options: ExportMatOptions, truth, shards, nav, output) -> None:
    """``imugen export-mat``."""
    o = options
    export_mat(
        truth, shards, output, grade=o.grade, nav_paths=nav, version=o.mat_version, route=o.route
    )
