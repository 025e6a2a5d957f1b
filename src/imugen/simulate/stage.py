"""Monte-Carlo shards: a truth table (or a still IMU) -> M erroneous IMU sequences of a grade.

Randomness
----------
A route is named by its id ``route_id = int.from_bytes(sha256(name.encode("utf-8"))[:4],
"big")`` (:func:`imugen.tables.shard.route_id`; the name is ``--route``, else the truth
metadata's ``route``, else the truth file's folder name, see :func:`route_name`). A shard's
root is ``SeedSequence(seed, spawn_key=(route_id, grade_id, shard))``. Sequence ``j`` of the
shard (``0 <= j < M``) uses the children ``SeedSequence(seed, spawn_key=(route_id, grade_id,
shard, j, stream))`` -- exactly what ``root.spawn`` would give, but addressed by index -- one
per stream (:data:`STREAMS`): its parameter draw and, for each sensor, its white noise, rate
random walk and bias-instability normals. So no two (route, grade, sequence) share a draw (up
to a collision of 32-bit route ids: probability ``n^2 / 2^33`` for ``n`` routes); a shard's
data never depends on how many shards or routes exist or on the order they run; raising N
only adds shards; sequence ``j`` of a shard does not depend on ``M`` (a larger shard only
appends sequences); switching a term off leaves the other terms' realizations unchanged; and
the chunking of time cannot change the numbers (NumPy fills normals sequentially).
Bit-identity across machines holds for the same NumPy bit-generator algorithms (PCG64,
``standard_normal``) -- the NumPy version is recorded in the metadata. The shard's bytes do
not depend on how the truth path was spelled: the metadata names the truth by file name and
SHA-256.

Per-sequence parameters (see :func:`imugen.sensors.model.draw_sensor`)
-----------------------------------------------------------------
Levels log-uniform in the grade's ranges (``draw="ranges"``, default) or nominal
(``draw="nominal"``); turn-on biases, scale factors, cross-couplings, g-sensitivities,
temperature coefficients ``N(0, level^2)``; the GM bias starts from its stationary law.
With ``mounting``, the IMU's misalignment and lever arm (stream ``mounting``,
:mod:`imugen.sensors.mounting`) turn the truth's ideal signals into the mounted IMU's before the case
vibration and the sensor errors are applied.

Output (one shard = one Parquet file + a labels sidecar)
--------------------------------------------------------
The layout, ids and columns are those of :mod:`imugen.tables.shard` (``sequence`` int64
``route_id << 31 | (shard * shard_size + j)``, ``time_s``, increments and/or rates, with
``series=True`` the true bias, scale-factor and effective-error series). Measurements are
float32 by default: their rounding (relative 6e-8, e.g. 6e-10 rad on a 0.01 rad increment) is
a white error below 1 % of the navigation-grade noise floor (ARW 0.002 deg/sqrt(h) gives
6e-8 rad per 100 Hz increment), and it halves the bytes written; ``dtype="float64"`` is
available. Increments are ``compensated`` (the truth's) or ``raw`` (plain integrals of rate
and specific force, :meth:`Truth.raw_chunk`), recorded as ``increments`` in the metadata.
Row groups are written as time chunks are produced (bounded buffer, never the whole shard).
"""

from __future__ import annotations

import hashlib
import json
import math
import sys
from abc import ABC, abstractmethod
from contextlib import ExitStack
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from imugen import __version__
from imugen.core.errors import InputError
from imugen.sensors.grades import TERMS, Grade, get_grade, preset_text
from imugen.sensors.model import SensorModel, SensorParams, draw_sensor
from imugen.sensors.mounting import MountingSpec
from imugen.sensors.mounting import setup as setup_mounting
from imugen.sensors.vibration import setup_vibration
from imugen.tables import nav as tnav
from imugen.tables import shard as tshard
from imugen.tables import truth as ttruth
from imugen.tables.shard import SEQUENCE
from imugen.tables.truth import ACCEL, DTHETA, DV, GYRO, TIME, VEL

CHUNK = 8192
"""Samples per sequence processed per step (a constant; results do not depend on it)."""
STREAMS = {
    "params": 0,
    "gyro_white": 1,
    "accel_white": 2,
    "gyro_rrw": 3,
    "accel_rrw": 4,
    "gyro_bi": 5,
    "accel_bi": 6,
    "vibration": 7,
    "mounting": 8,
}
"""Per-sequence random streams: last element of the spawn key."""
OUTPUTS = tshard.OUTPUTS
DRAWS = ("ranges", "nominal")
DEFAULT_STATIC_ORIGIN = (45.0, 0.0, 0.0)
"""Origin (lat_deg, lon_deg, alt_m) of a still IMU built with ``--static``."""


# --- truth sources ------------------------------------------------------------------------------
class Truth(ABC):
    """Ideal IMU signals on a uniform time grid, served in chunks (abstract base).

    Attributes
    ----------
    K : int
        Number of samples.
    dt : float
        Sample interval [s].
    meta : dict
        Provenance for the shard metadata.
    """

    K: int
    dt: float
    meta: dict

    @abstractmethod
    def chunk(self, k0: int, L: int):
        """``(time_s (L,), omega_ib_b (L,3), f_b (L,3), dtheta (L,3), dv (L,3))``, float64."""

    def times(self) -> np.ndarray:
        """``time_s`` of every sample (K,), float64: the chunks' times, joined."""
        return np.concatenate(
            [self.chunk(k, min(CHUNK, self.K - k))[0] for k in range(0, self.K, CHUNK)]
        )

    @abstractmethod
    def raw_chunk(self, k0: int, L: int):
        """Raw increments ``(int omega_ib_b dt (L,3), int f_b dt (L,3))`` of the intervals
        ending at samples ``k0 .. k0+L-1`` (row 0 zero), float64."""


class ArrayTruth(Truth):
    """Truth held as arrays (rows ``k``: sample at ``t_k``; increments of the interval ending there).

    Parameters
    ----------
    time_s : (K,)
    omega_ib_b, f_b, dtheta, dv : (K, 3)
    meta : dict, optional
    """

    def __init__(self, time_s, omega_ib_b, f_b, dtheta, dv, meta=None, source="<arrays>"):
        self.time = np.ascontiguousarray(time_s, dtype=np.float64)
        self.w = np.ascontiguousarray(omega_ib_b, dtype=np.float64)
        self.f = np.ascontiguousarray(f_b, dtype=np.float64)
        self.dth = np.ascontiguousarray(dtheta, dtype=np.float64)
        self.dv = np.ascontiguousarray(dv, dtype=np.float64)
        self.K = len(self.time)
        if self.K < 2:
            raise InputError(source, "truth needs at least 2 samples")
        for a in (self.w, self.f, self.dth, self.dv):
            if a.shape != (self.K, 3):
                raise InputError(source, f"truth arrays must be ({self.K}, 3), got {a.shape}")
        d = np.diff(self.time)
        self.dt = float((self.time[-1] - self.time[0]) / (self.K - 1))
        if not np.all(np.isfinite(self.time)) or np.max(np.abs(d - self.dt)) > 1e-9 * max(
            1.0, self.dt
        ) + 1e-12 * abs(self.time[-1]):
            raise InputError(source, "time_s is not a uniform grid")
        self.meta = dict(meta or {})
        self._raw = None
        self.speed_mps = None  # vehicle speed per sample when known (vibration model)

    def chunk(self, k0, L):
        s = slice(k0, k0 + L)
        return self.time[s], self.w[s], self.f[s], self.dth[s], self.dv[s]

    def times(self):
        return self.time

    def raw_chunk(self, k0, L):
        """4-point quadrature of the rate samples (:func:`imugen.navigate.mechanize.interval_integrals`:
        exact for cubics, local error ``O(dt^5)``), computed once for the whole truth."""
        if self._raw is None:
            from imugen.navigate.mechanize import interval_integrals

            self._raw = (interval_integrals(self.w, self.dt), interval_integrals(self.f, self.dt))
        s = slice(k0, k0 + L)
        return self._raw[0][s], self._raw[1][s]

    @classmethod
    def from_frame(cls, df, meta=None, source="<frame>") -> ArrayTruth:
        need = (TIME, *GYRO, *ACCEL, *DTHETA, *DV)
        miss = [c for c in need if c not in df.columns]
        if miss:
            raise InputError(source, f"not a truth table: missing column(s) {', '.join(miss)}")
        out = cls(
            df[TIME].to_numpy(),
            df[list(GYRO)].to_numpy(),
            df[list(ACCEL)].to_numpy(),
            df[list(DTHETA)].to_numpy(),
            df[list(DV)].to_numpy(),
            meta,
            source,
        )
        if set(VEL) <= set(df.columns):
            out.speed_mps = np.linalg.norm(df[list(VEL)].to_numpy(), axis=1)
        return out

    @classmethod
    def read(cls, path) -> ArrayTruth:
        """Read a truth file; the provenance kept names it by file name and checksum only."""
        has_vel = set(VEL) <= set(ttruth.column_names(path))
        cols = [TIME, *GYRO, *ACCEL, *DTHETA, *DV, *(VEL if has_vel else ())]
        tr = ttruth.read(path, columns=cols, need_meta=False, arrow=True)
        keep = {
            k: tr.meta[k]
            for k in ("origin", "earth", "rate_hz", "vehicle", "route")
            if k in tr.meta
        }
        # no path strings (the truth's own ``source`` is one): a shard's bytes must not depend
        # on how paths were spelled; the checksum names the truth and its provenance
        keep["file"] = Path(path).name
        keep["sha256"] = ttruth.checksum(path)
        out = cls(tr.time_s, tr.omega_ib_b, tr.f_b, tr.dtheta, tr.dv, keep, str(path))
        if has_vel:
            out.speed_mps = np.linalg.norm(tr.v_n, axis=1)
        return out


class StaticTruth(Truth):
    """A still, level IMU (body axes = ENU axes of the origin), built chunk by chunk.

    ``flat``: ``f_b = (0, 0, g0)``, ``omega_ib_b = 0``. ``wgs84``: the body turns with the Earth,
    ``omega_ib_b = Omega (0, cos lat, sin lat)``, and the exact increments are
    ``dtheta = omega dt`` and ``dv = int_0^dt Exp([omega x] tau) f_b dtau`` (closed form).

    Parameters
    ----------
    duration_s : float
        Length [s]; samples at ``k dt`` for ``k = 0 .. floor(duration/dt)``.
    rate_hz : float
    earth : {"flat", "wgs84"}
    origin : (lat_deg, lon_deg, alt_m)
    """

    def __init__(self, duration_s, rate_hz=100.0, earth="flat", origin=DEFAULT_STATIC_ORIGIN):
        from imugen.core.earth import OriginFrame, earth_rate_n, gravity_n

        if not (duration_s > 0 and math.isfinite(duration_s)):
            raise InputError("--static", f"duration must be > 0 s, got {duration_s!r}")
        if not (rate_hz > 0 and math.isfinite(rate_hz)):
            raise InputError("--rate-hz", f"rate must be > 0 Hz, got {rate_hz!r}")
        if earth not in ("flat", "wgs84"):
            raise InputError("--earth", f"static earth model must be flat or wgs84, got {earth!r}")
        self.dt = 1.0 / float(rate_hz)
        self.K = math.floor(duration_s * rate_hz + 1e-9) + 1
        frame = OriginFrame.from_deg(*origin, model=earth)
        if earth == "flat":
            g = np.array([0.0, 0.0, -frame.g0])
        else:
            g = np.asarray(gravity_n(np.zeros((1, 3)), frame), float).reshape(3)
        self.omega = np.asarray(earth_rate_n(frame), float).reshape(3)
        self.f_b = -g
        self.dth_c = self.omega * self.dt
        W = np.array(
            [
                [0.0, -self.omega[2], self.omega[1]],
                [self.omega[2], 0.0, -self.omega[0]],
                [-self.omega[1], self.omega[0], 0.0],
            ]
        )
        wn = float(np.linalg.norm(self.omega))
        if wn > 0:
            th = wn * self.dt
            # (th - sin th) / wn^3 by its series when th is small (cancellation)
            c3 = (
                (th - math.sin(th)) / wn**3
                if th > 1e-2
                else self.dt**3 / 6.0 * (1.0 - th**2 / 20.0 + th**4 / 840.0)
            )
            A = self.dt * np.eye(3) + (2.0 * math.sin(th / 2) ** 2 / wn**2) * W + c3 * (W @ W)
        else:
            A = self.dt * np.eye(3)
        self.dv_c = A @ self.f_b
        self._cache = None
        self.meta = {
            "static": {
                "duration_s": float(duration_s),
                "earth": earth,
                "origin": {"lat_deg": origin[0], "lon_deg": origin[1], "alt_m": origin[2]},
                "f_b_mps2": self.f_b.tolist(),
                "omega_ib_b_radps": self.omega.tolist(),
            },
            "rate_hz": float(rate_hz),
            "earth": earth,
        }

    def chunk(self, k0, L):
        if self._cache is None or len(self._cache[0]) < L:
            n = max(L, CHUNK)
            self._cache = (
                np.tile(self.omega, (n, 1)),
                np.tile(self.f_b, (n, 1)),
                np.tile(self.dth_c, (n, 1)),
                np.tile(self.dv_c, (n, 1)),
            )
        w, f, dth, dv = (c[:L] for c in self._cache)
        if k0 == 0:
            dth = dth.copy()
            dv = dv.copy()
            dth[0] = 0.0
            dv[0] = 0.0
        t = np.arange(k0, k0 + L, dtype=np.float64) * self.dt
        return t, w, f, dth, dv

    def raw_chunk(self, k0, L):
        """Constant rates: the plain integrals are exactly ``omega dt`` and ``f_b dt``."""
        a = np.tile(self.omega * self.dt, (L, 1))
        b = np.tile(self.f_b * self.dt, (L, 1))
        if k0 == 0:
            a[0] = 0.0
            b[0] = 0.0
        return a, b


# --- temperature profiles ---------------------------------------------------------------------------
def temperature_profile(spec):
    """A callable ``t [s] -> temperature offset [K]`` from a profile specification.

    ``None`` (off); ``{"kind": "warmup", "delta_K": d, "tau_s": T}`` for
    ``d (1 - exp(-t / T))`` (self-heating after turn-on; the turn-on bias holds the value at
    turn-on); ``{"kind": "linear", "rate_K_per_s": r}``; ``{"kind": "table", "time_s": [...],
    "delta_K": [...]}`` (linear interpolation, held constant outside). A JSON string is accepted.
    """
    if spec is None:
        return None
    if isinstance(spec, str):
        try:
            spec = json.loads(spec)
        except ValueError:
            raise InputError("--temperature", "expected a JSON object") from None
    if not isinstance(spec, dict) or "kind" not in spec:
        raise InputError("--temperature", 'expected {"kind": warmup|linear|table, ...}')
    k = spec["kind"]
    try:
        if k == "warmup":
            d, T = float(spec["delta_K"]), float(spec["tau_s"])
            if not T > 0:
                raise ValueError("tau_s must be > 0")
            return lambda t: -d * np.expm1(-np.asarray(t) / T)
        if k == "linear":
            r = float(spec["rate_K_per_s"])
            return lambda t: r * np.asarray(t)
        if k == "table":
            tt = np.asarray(spec["time_s"], float)
            dd = np.asarray(spec["delta_K"], float)
            if tt.ndim != 1 or tt.shape != dd.shape or len(tt) < 1 or np.any(np.diff(tt) <= 0):
                raise ValueError("time_s and delta_K must be equal-length, time increasing")
            return lambda t: np.interp(t, tt, dd)
    except (KeyError, TypeError, ValueError) as exc:
        raise InputError("--temperature", f"bad {k} profile: {exc}") from None
    raise InputError("--temperature", f"unknown profile kind {k!r}")


# --- term selection ----------------------------------------------------------------------------------
def enabled_terms(grade: Grade, terms=None) -> dict[str, frozenset]:
    """Which terms to apply per sensor.

    ``terms=None``: everything the grade configures. Otherwise an iterable of ``"gyro"``,
    ``"accel"``, a term name (both sensors; ``"temperature"`` = both temperature terms) or
    ``"gyro.<term>"`` / ``"accel.<term>"``.
    """
    out = {"gyro": set(), "accel": set()}
    if terms is None:
        for s in out:
            out[s] = set(grade.sensor(s).configured())
        return {k: frozenset(v) for k, v in out.items()}
    if isinstance(terms, str):
        terms = [t for t in terms.replace(",", " ").split() if t]
    alias = {
        "temperature": ("temperature_bias", "temperature_scale_factor"),
        "saturation": ("range",),
        "misalignment": ("cross_coupling",),
    }
    for item in terms:
        sensors, _, name = item.rpartition(".")
        sens = [sensors] if sensors else ["gyro", "accel"]
        if not sensors and name in out:
            sens, name = [name], ""
        if any(s not in out for s in sens):
            raise InputError("--terms", f"unknown sensor in {item!r} (gyro or accel)")
        names = TERMS if not name else alias.get(name, (name,))
        for n in names:
            if n not in TERMS:
                raise InputError("--terms", f"unknown term {item!r}; terms: {', '.join(TERMS)}")
            for s in sens:
                if n in grade.sensor(s).configured():
                    out[s].add(n)
    return {k: frozenset(v) for k, v in out.items()}


# --- sinks ----------------------------------------------------------------------------------------------
class _MemorySink:
    """Sequences kept in memory, float64 ``(M, K, 3)`` per group; the kernels write in place."""

    def __init__(self, M, K, names):
        self.data = {n: np.empty((M, K, 3)) for n in names}

    def reserve(self, j, k0, L):
        return {n: a[j, k0 : k0 + L] for n, a in self.data.items()}

    def put(self, j, k0, L, t, outs):
        pass


class _WriterSink:
    """Lets the kernels write each chunk in place into a :class:`imugen.tables.shard.Writer`'s
    column buffers (strided ``(L, 3)`` views), committed under the sequence's global id.

    Measured (``benchmarks/README.md``, issue 14): 219 against 230 CPU-ns per sample-sequence
    of generation + Parquet write for the former contiguous chunk buffers copied into the
    column buffers (the copy wrote every row group's 24 MiB a second time, out of cache)."""

    def __init__(self, writer, ids):
        self.w = writer
        self.ids = ids

    def reserve(self, j, k0, L):
        return self.w.reserve(L)

    def put(self, j, k0, L, t, outs):
        self.w.commit(int(self.ids[j]), t)


class _NavSink:
    """Navigates the sequences as they are produced, passing every chunk on to ``inner``.

    Keeps one batch of measurements (float64 buffers holding the values as stored, i.e.
    rounded to the shard's ``dtype``), mechanizes the batch when its last sequence is
    complete and streams its errors to ``nav_writer``: the same numbers as ``imugen navigate``
    on the written shard (same batches, same arithmetic), without re-reading it.
    """

    def __init__(self, inner, navigator, plan: _Plan, dtype, nav_writer, batch):
        self.inner = inner
        self.nav = navigator
        self.kind = "increments" if plan.outputs in ("increments", "both") else "rates"
        self.groups = ("dtheta", "dv") if self.kind == "increments" else ("gyro", "accel")
        self.raw = plan.raw and self.kind == "increments"
        self.skip = 1 if self.kind == "increments" else 0
        self.K = plan.truth.K
        self.dtype = np.dtype(dtype)
        self.ids = plan.ids
        self.mount = plan.mount
        self.w = nav_writer
        self.batch = int(batch)
        width = self.K - self.skip
        self.bufs = tuple(np.empty((self.batch, width, 3)) for _ in self.groups)
        self.first = 0  # sequence index of the batch's first row
        self.n = 0  # complete sequences in the buffers
        self.own = {n: np.empty((CHUNK, 3), self.dtype) for n in plan.names}

    def reserve(self, j, k0, L):
        if hasattr(self.inner, "reserve"):
            return self.inner.reserve(j, k0, L)
        return {n: a[:L] for n, a in self.own.items()}

    def put(self, j, k0, L, t, outs):
        lo = max(k0, self.skip)
        if lo < k0 + L:
            for buf, g in zip(self.bufs, self.groups, strict=True):
                # the stored rounding (float32 by default), widened exactly to float64; axis
                # by axis: each is a contiguous row of the writer's column buffers
                dst = buf[self.n, lo - self.skip : k0 + L - self.skip]
                for i in range(3):
                    dst[:, i] = outs[g][lo - k0 :, i]
        if self.inner is not None:
            self.inner.put(j, k0, L, t, outs)
        if k0 + L == self.K:
            self.n += 1
            if self.n == self.batch:
                self.flush()

    def flush(self):
        if self.n:
            a, b = (buf[: self.n] for buf in self.bufs)
            ids = self.ids[self.first : self.first + self.n]
            mount = None
            if self.mount is not None:
                sel = self.mount[self.first : self.first + self.n]
                mount = tuple(np.array(x) for x in zip(*sel, strict=True))
            self.w.put(self.nav.columns(ids, *self.nav.measured(self.kind, self.raw, a, b), mount))
            self.first += self.n
            self.n = 0


# --- the generator ---------------------------------------------------------------------------------------
@dataclass
class Shard:
    """In-memory result of :func:`simulate`.

    Attributes
    ----------
    time_s : (K,)
    data : dict of name -> (M, K, 3) float64
        ``"dtheta"``, ``"dv"`` (increments) and/or ``"gyro"``, ``"accel"`` (rates), plus
        ``"gyro_bias"``, ``"gyro_sf"``, ``"accel_bias"``, ``"accel_sf"`` with ``series``.
    labels : pandas.DataFrame
        One row per sequence, every drawn parameter.
    gyro, accel : SensorParams
        Drawn parameters (arrays with leading axis M).
    meta : dict
    """

    time_s: np.ndarray
    data: dict
    labels: object
    gyro: SensorParams
    accel: SensorParams
    meta: dict


def _seed_seq(seed, rid, gid, shard, j, stream):
    return np.random.SeedSequence(seed, spawn_key=(rid, gid, shard, j, STREAMS[stream]))


def _rng(seed, rid, gid, shard, j, stream):
    return np.random.Generator(np.random.PCG64(_seed_seq(seed, rid, gid, shard, j, stream)))


def route_name(truth, tr: Truth, route=None) -> str:
    """The route a shard belongs to: ``route``; else the truth metadata's ``route``; else the
    truth file's folder name (``results/<route>/truth.parquet``); else ``"static"`` for a
    still IMU and ``""`` for in-memory arrays."""
    if route is not None:
        if not isinstance(route, str):
            raise InputError("--route", f"must be a string, got {route!r}")
        return route
    if tr.meta.get("route"):
        return str(tr.meta["route"])
    if isinstance(tr, StaticTruth):
        return "static"
    if isinstance(truth, str | Path):
        return Path(truth).resolve().parent.name
    return ""


def _check_int(name, v, lo=0):
    if isinstance(v, bool) or not isinstance(v, int | np.integer) or v < lo:
        raise InputError(name, f"must be an integer >= {lo}, got {v!r}")
    return int(v)


def _resolve_truth(truth, static_s, rate_hz, static_earth, static_origin) -> Truth:
    if isinstance(truth, Truth):
        return truth
    if truth is None:
        if static_s is None:
            raise InputError("simulate", "give a truth table or --static SECONDS")
        return StaticTruth(float(static_s), rate_hz, static_earth, static_origin)
    if static_s is not None:
        raise InputError("--static", "give either a truth table or --static, not both")
    pd = sys.modules.get("pandas")  # a DataFrame can only exist once pandas is imported
    if pd is not None and isinstance(truth, pd.DataFrame):
        return ArrayTruth.from_frame(truth)
    if isinstance(truth, dict):
        return ArrayTruth(
            truth[TIME],
            truth["omega_ib_b"],
            truth["f_b"],
            truth["dtheta"],
            truth["dv"],
            truth.get("meta"),
        )
    return ArrayTruth.read(truth)


def _first_id(shard: int, M: int, shard_size) -> int:
    """Index of the shard's first sequence: ``shard * shard_size`` (default ``M``).

    A shard holds at most ``shard_size`` sequences; only the last shard of an experiment whose
    N is not a multiple of the shard size is shorter, and it must be given the experiment's
    shard size, or its ids would repeat those of an earlier shard.
    """
    size = M if shard_size is None else _check_int("--shard-size", shard_size, 1)
    if M > size:
        raise InputError("--shard-size", f"is {size}, fewer than the {M} sequences of this shard")
    if shard * size + M - 1 >= 2**tshard.ROUTE_SHIFT:
        raise InputError("--shard", "sequence index shard * shard_size + j must be < 2^31")
    return shard * size


@dataclass
class _Plan:
    """Everything one shard's generation needs, validated once (shared by simulate and run)."""

    truth: Truth
    grade: Grade
    M: int
    seed: int
    shard: int
    rid: int
    ids: np.ndarray
    enabled: dict
    temp: object
    gp: list
    ap: list
    outputs: str
    series: bool
    raw: bool
    names: list
    meta: dict
    vib: list | None = None  # one imugen.sensors.vibration.SequenceVibration per sequence
    mounting: object = None  # imugen.sensors.mounting.Mounting (None: the IMU is the vehicle)
    mount: list | None = None  # per sequence (angles (3,) rad, lever arm (3,) m)

    def labels(self):
        """One row per sequence: ids, provenance and every drawn parameter (a DataFrame)."""
        import pandas as pd

        return pd.DataFrame(self.label_columns())

    def label_columns(self) -> dict:
        """:meth:`labels` as a dict of columns (no pandas)."""
        M = self.M
        d = {
            SEQUENCE: self.ids,
            "route_id": np.full(M, self.rid, np.int64),
            "shard": np.full(M, self.shard, np.int32),
            "index": np.arange(M, dtype=np.int32),
            "seed": np.full(M, self.seed, np.int64),
            "grade_id": np.full(M, self.grade.id, np.int32),
        }
        d.update(SensorParams.stack(self.gp).labels("gyro", "radps"))
        d.update(SensorParams.stack(self.ap).labels("accel", "mps2"))
        if self.mount is not None:
            d.update(tshard.mounting_labels(*(np.array(x) for x in zip(*self.mount, strict=True))))
        if self.vib is not None:
            for name in self.vib[0].labels():
                d[name] = np.array([v.labels()[name] for v in self.vib])
        return d


def _loop(plan: _Plan, sink, progress=None):
    """Generate every sequence in time chunks and hand each chunk to ``sink.put``.

    With ``plan.raw`` the sensor integrates the plain integrals of rate and specific force
    (raw increments) instead of the truth's compensated increments."""
    truth, M, seed, shard, rid = plan.truth, plan.M, plan.seed, plan.shard, plan.rid
    grade, temp, gp, ap, outputs, series = (
        plan.grade, plan.temp, plan.gp, plan.ap, plan.outputs, plan.series,
    )  # fmt: skip
    raw = plan.raw
    K, dt = truth.K, truth.dt
    want_inc = outputs in ("increments", "both")
    want_rate = outputs in ("rates", "both")
    # outputs in the storage dtype, written by the kernels in place: into the sink's own
    # buffers (the shard writer's column buffers) when it offers them, else into these
    odt = np.dtype(plan.meta["dtype"])
    reserve = getattr(sink, "reserve", None)
    own = {n: np.empty((CHUNK, 3), odt) for n in plan.names}
    nz = {}
    normals = 0
    for j in range(M):
        models = {"gyro": SensorModel(gp[j], dt), "accel": SensorModel(ap[j], dt)}
        rngs = {}
        for s, m in models.items():
            normals += m.normals_per_sample
            if m.use_w:
                rngs[f"{s}_white"] = (_rng(seed, rid, grade.id, shard, j, f"{s}_white"), 3)
            if m.use_r:
                rngs[f"{s}_rrw"] = (_rng(seed, rid, grade.id, shard, j, f"{s}_rrw"), 3)
            if m.use_b:
                rngs[f"{s}_bi"] = (
                    _rng(seed, rid, grade.id, shard, j, f"{s}_bi"),
                    3 * m.p.components,
                )
        for key, (_, w) in rngs.items():
            if key not in nz or nz[key].shape[1] != w:
                nz[key] = np.empty((CHUNK, w))
        for k0 in range(0, K, CHUNK):
            L = min(CHUNK, K - k0)
            t, w_b, f_b, dth, dv = truth.chunk(k0, L)
            if raw:
                dth, dv = truth.raw_chunk(k0, L)
            if plan.mounting is not None:
                sh = plan.mounting.shared(k0, L, raw)
                w_b, f_b, dth, dv = plan.mounting.apply(k0, sh, *plan.mount[j], dth, dv, raw)
            if plan.vib is not None:
                w_b, f_b, dth, dv = plan.vib[j].apply(k0, w_b, f_b, dth, dv, raw=raw)
            dT = None
            if temp is not None:
                # time since turn-on of the sample before the chunk and of each sample
                tt = np.maximum(np.arange(k0 - 1, k0 + L), 0) * dt
                dT = np.ascontiguousarray(temp(tt), dtype=np.float64)
            z = {}
            for key, (rng, _) in rngs.items():
                buf = nz[key][:L]
                rng.standard_normal(out=buf)
                z[key] = buf[None]
            outs = reserve(j, k0, L) if reserve is not None else {n: a[:L] for n, a in own.items()}
            for s, m in models.items():
                inc, rate = ("dtheta", "gyro") if s == "gyro" else ("dv", "accel")
                o_inc = outs[inc][None] if want_inc else None
                o_rate = outs[rate][None] if want_rate else None
                o_bias = outs[f"{s}_bias"][None] if series else None
                o_sf = outs[f"{s}_sf"][None] if series else None
                o_er = outs[f"err_{rate}"][None] if series and want_rate else None
                o_ei = outs[f"err_{inc}"][None] if series and want_inc else None
                if s == "gyro":
                    args = (w_b, dth, f_b, dv)
                else:
                    args = (f_b, dv, None, None)
                m.step(
                    k0,
                    *args,
                    dT,
                    z.get(f"{s}_white"),
                    z.get(f"{s}_rrw"),
                    z.get(f"{s}_bi"),
                    o_rate,
                    o_inc,
                    o_bias,
                    o_sf,
                    o_er,
                    o_ei,
                )
            sink.put(j, k0, L, t, outs)
        if progress is not None:
            progress.update(j + 1)
    return normals / M if M else 0


def _plan(
    truth,
    grade,
    sequences,
    seed,
    shard,
    *,
    outputs="increments",
    draw="ranges",
    terms=None,
    temperature=None,
    series=False,
    static_s=None,
    rate_hz=100.0,
    static_earth="flat",
    static_origin=DEFAULT_STATIC_ORIGIN,
    grades_file=None,
    shard_size=None,
    route=None,
    increments="compensated",
    dtype="float32",
    vibration=None,
    mounting=None,
) -> _Plan:
    tr = _resolve_truth(truth, static_s, rate_hz, static_earth, static_origin)
    route = route_name(truth, tr, route)
    rid = tshard.route_id(route)
    grade = get_grade(grade, grades_file)
    M = _check_int("--sequences", sequences, 1)
    seed = _check_int("--seed", seed, 0)
    shard = _check_int("--shard", shard, 0)
    if outputs not in OUTPUTS:
        raise InputError("--outputs", f"must be one of {', '.join(OUTPUTS)}, got {outputs!r}")
    if draw not in DRAWS:
        raise InputError("--draw", f"must be one of {', '.join(DRAWS)}, got {draw!r}")
    if increments not in tshard.INCREMENT_KINDS:
        kinds = ", ".join(tshard.INCREMENT_KINDS)
        raise InputError("--increments", f"must be one of {kinds}, got {increments!r}")
    first = _first_id(shard, M, shard_size)
    enabled = enabled_terms(grade, terms)
    temp = temperature_profile(temperature)
    nominal = draw == "nominal"
    gp, ap = [], []
    for j in range(M):
        rng = _rng(seed, rid, grade.id, shard, j, "params")
        gp.append(draw_sensor(grade.gyro, rng, enabled["gyro"], nominal))
        ap.append(draw_sensor(grade.accel, rng, enabled["accel"], nominal))
    ids = tshard.sequence_ids(rid, first + np.arange(M))
    meta = {
        "format": tshard.FORMAT,
        "format_version": tshard.FORMAT_VERSION,
        "code_version": __version__,
        "numpy_version": np.__version__,
        "grade": {
            "name": grade.name,
            "id": grade.id,
            "origin": grade.origin,
            "description": grade.description,
            "source": grade.source,
            "reading": grade.reading,
            "config": grade.config,
        },
        "preset_source": grade.origin,
        # checksum of the shipped presets file when the grade is a preset (None: custom grade)
        "preset_sha": hashlib.sha256(preset_text().encode()).hexdigest()
        if grade.origin.startswith("imugen/data/")
        else None,
        "route": route,
        "route_id": rid,
        "seed": seed,
        "shard": shard,
        "sequences": M,
        "first_index": first,
        "sequence_ids": [int(ids[0]), int(ids[-1])],
        "sequence_id": "route_id << 31 | index, index = shard * shard_size + j",
        "spawn_key": [rid, grade.id, shard],
        "sequence_spawn_key": "(route_id, grade_id, shard, index_in_shard, stream)",
        "streams": STREAMS,
        "bit_generator": "PCG64",
        "draw": draw,
        "terms": {k: sorted(v) for k, v in enabled.items()},
        "outputs": outputs,
        "increments": increments,
        "series": bool(series),
        "dtype": np.dtype(dtype).name,
        "chunk": CHUNK,
        "rate_hz": 1.0 / tr.dt,
        "dt_s": tr.dt,
        "samples_per_sequence": tr.K,
        "truth": tr.meta,
        "temperature": temperature,
        "vibration": None,
        "rows": "sorted by sequence then time; increments on row k are the interval ending at "
        "t_k; row 0 of each sequence is zero",
        "derived": None,
    }
    names = tshard.groups(outputs, series)
    vib, meta["vibration"] = _vibrations(tr, vibration, seed, rid, grade, shard, M)
    spec = MountingSpec.from_option(mounting, "--mounting")
    meta["mounting"] = None if spec is None else spec.as_dict()
    mount = None
    if spec is not None:
        mount = [spec.draw(_rng(seed, rid, grade.id, shard, j, "mounting")) for j in range(M)]
    source = truth if isinstance(truth, str | Path) else None
    return _Plan(
        tr, grade, M, seed, shard, rid, ids, enabled, temp, gp, ap, outputs, bool(series),
        increments == "raw", names, meta, vib, setup_mounting(tr, spec, source), mount,
    )  # fmt: skip


def _vibrations(truth, option, seed, rid, grade, shard, M):
    """Per-sequence vibrations (stream ``vibration``) and their metadata, or (None, meta)."""
    v = setup_vibration(truth, option)
    meta = None if option in (None, "off") else {"option": option, "profile": None}
    if v is None:
        return None, meta
    meta["profile"] = v.profile.as_dict()
    return [v.draw(_rng(seed, rid, grade.id, shard, j, "vibration")) for j in range(M)], meta


def simulate(
    truth,
    grade,
    sequences=1,
    seed=0,
    shard=0,
    *,
    outputs="increments",
    draw="ranges",
    terms=None,
    temperature=None,
    series=False,
    static_s=None,
    rate_hz=100.0,
    static_earth="flat",
    static_origin=DEFAULT_STATIC_ORIGIN,
    grades_file=None,
    shard_size=None,
    route=None,
    increments="compensated",
    vibration=None,
    mounting=None,
) -> Shard:
    """Generate a shard in memory (float64 arrays ``(M, K, 3)``); same numbers as :func:`run`.

    Parameters
    ----------
    truth : path, DataFrame, dict, Truth or None
        Truth table (Parquet path or DataFrame with the columns of :mod:`imugen.tables.truth`),
        a dict with ``time_s``, ``omega_ib_b``, ``f_b``, ``dtheta``, ``dv`` arrays, or None
        with ``static_s``.
    grade : str or Grade
        Preset name, ``file.yaml:name``, or a :class:`~imugen.sensors.grades.Grade`.
    sequences, seed, shard : int
        ``M`` sequences; root seed; shard index.
    outputs : {"increments", "rates", "both"}
    draw : {"ranges", "nominal"}
        Draw levels in the grade's ranges, or use the nominal values for every sequence.
    terms : iterable of str, optional
        Apply only these terms (see :func:`enabled_terms`).
    temperature : dict or str, optional
        Temperature profile (:func:`temperature_profile`).
    series : bool
        Also return the true slow-bias, scale-factor and effective-error series.
    static_s, rate_hz, static_earth, static_origin
        Still IMU instead of a truth table.
    shard_size : int, optional
        Sequences per shard of the experiment (``>= sequences``): indices are
        ``shard * shard_size + j``. Default ``sequences``; give it for a short last shard.
    route : str, optional
        Route name; its :func:`~imugen.tables.shard.route_id` enters every spawn key and the
        sequence ids. Default :func:`route_name`.
    increments : {"compensated", "raw"}
        Increment semantics (:mod:`imugen.tables.shard`): the truth's compensated increments,
        or plain integrals of rate and specific force (``Truth.raw_chunk``).
    vibration : {"off", "car", "aircraft", "vehicle"}, optional
        Vibration of the IMU case (:mod:`imugen.sensors.vibration`; ``vehicle``: the truth's class).
    mounting : dict, optional
        IMU misalignment and lever arm drawn per sequence (:mod:`imugen.sensors.mounting`; keys of
        :meth:`~imugen.sensors.mounting.MountingSpec.from_option`); None: the IMU is the vehicle frame
        at its reference point.
    """
    plan = _plan(
        truth, grade, sequences, seed, shard, outputs=outputs, draw=draw, terms=terms,
        temperature=temperature, series=series, static_s=static_s, rate_hz=rate_hz,
        static_earth=static_earth, static_origin=static_origin, grades_file=grades_file,
        shard_size=shard_size, route=route, increments=increments, dtype=np.float64,
        vibration=vibration, mounting=mounting,
    )  # fmt: skip
    tr = plan.truth
    sink = _MemorySink(plan.M, tr.K, plan.names)
    _loop(plan, sink)
    time_s = tr.times()
    meta = {**plan.meta, "units": tshard.units(plan.names)}
    gpar, apar = SensorParams.stack(plan.gp), SensorParams.stack(plan.ap)
    return Shard(time_s, sink.data, plan.labels(), gpar, apar, meta)


def run(
    truth=None,
    out=None,
    grade="consumer",
    sequences=1,
    seed=0,
    shard=0,
    static_s=None,
    rate_hz=100.0,
    *,
    outputs="increments",
    draw="ranges",
    terms=None,
    temperature=None,
    series=False,
    dtype="float32",
    compression="none",
    explicit_time=False,
    grades_file=None,
    static_earth="flat",
    static_origin=DEFAULT_STATIC_ORIGIN,
    shard_size=None,
    route=None,
    increments="compensated",
    vibration=None,
    mounting=None,
    navigate=None,
    eval_rate_hz=1.0,
) -> dict:
    """Generate one shard and write it (Parquet + labels sidecar) atomically; optionally
    navigate it in the same pass.

    Parameters are those of :func:`simulate`, plus ``out`` (the shard path; the sidecar is
    :func:`~imugen.tables.shard.labels_path`), ``dtype`` of the measurement columns
    (``"float32"`` or ``"float64"``) and the Parquet ``compression`` (``"none"`` default:
    noise-like floats do not compress, see benchmarks/README.md). ``rate_hz`` and ``static_*``
    only apply to ``static_s`` (a truth table has its own rate). The truth's uniform clock is
    stored once in the shard metadata (``clock``), not in every row, unless ``explicit_time``
    (:func:`imugen.tables.shard.writer`).

    ``navigate`` (a path) also writes the navigation error table of the shard
    (:mod:`imugen.tables.nav`), computed from the sequences as they are generated -- the
    shard is never re-read -- at ``eval_rate_hz`` epochs per second: the same table, bit for
    bit, as :func:`imugen.navigate.stage.run` on the written shard. ``out=None`` with ``navigate``
    writes the errors only (no IMU shard). Needs a truth file.

    Returns
    -------
    dict
        The shard's metadata (as written when ``out`` is given).
    """
    if out is None and navigate is None:
        raise InputError("-o", "give an output shard (-o) and/or --navigate NAV.parquet")
    if navigate is not None:
        if not isinstance(truth, str | Path):
            raise InputError("--navigate", "needs a truth file (not --static or arrays)")
        if not (isinstance(eval_rate_hz, int | float) and 0 < eval_rate_hz < math.inf):
            raise InputError("--eval-rate-hz", f"must be > 0, got {eval_rate_hz!r}")
    if dtype not in ("float32", "float64"):
        raise InputError("--dtype", f"must be float32 or float64, got {dtype!r}")
    plan = _plan(
        truth, grade, sequences, seed, shard, outputs=outputs, draw=draw, terms=terms,
        temperature=temperature, series=series, static_s=static_s, rate_hz=rate_hz,
        static_earth=static_earth, static_origin=static_origin, grades_file=grades_file,
        shard_size=shard_size, route=route, increments=increments, dtype=dtype,
        vibration=vibration, mounting=mounting,
    )  # fmt: skip
    from imugen.core.progress import Progress

    label = f"simulate {Path(out).parent.name}/{Path(out).name}" if out else "simulate"
    progress = Progress(label, plan.M)
    with ExitStack() as stack:
        sink = w = None
        if out is not None:
            w = stack.enter_context(
                tshard.writer(
                    out,
                    plan.meta,
                    plan.names,
                    dtype,
                    compression=compression,
                    time_s=plan.truth.times(),
                    dt=_nominal_dt(plan.truth),
                    explicit_time=explicit_time,
                )
            )
            sink = _WriterSink(w, plan.ids)
        if navigate is not None:
            sink = _nav_sink(stack, sink, plan, truth, out, navigate, eval_rate_hz, dtype)
        _loop(plan, sink, progress)
        if navigate is not None:
            sink.flush()
        if w is not None:
            w.labels = plan.label_columns()
    return tshard.read_meta(out) if out is not None else plan.meta


def _nominal_dt(truth: Truth) -> float | None:
    """``1 / rate_hz`` of the truth's metadata (the step its time grid was built with)."""
    rate = truth.meta.get("rate_hz")
    return 1.0 / float(rate) if isinstance(rate, int | float) and rate > 0 else None


def _nav_sink(stack, inner, plan, truth, out, nav_out, eval_rate_hz, dtype) -> _NavSink:
    """A :class:`_NavSink` writing to ``nav_out`` (entered on ``stack``), with the metadata
    ``imugen navigate`` would record for the written shard."""
    from imugen.navigate import stage as nv

    nav = nv.Navigator(ttruth.read(truth, columns=nv.NAV_TRUTH_COLUMNS, arrow=True), eval_rate_hz)
    if nav.K != plan.truth.K:
        raise InputError(truth, "changed while being read")
    meta = nv.table_meta(
        plan.truth.meta["file"],
        plan.truth.meta["sha256"],
        None if out is None else Path(out).name,
        json.loads(json.dumps(plan.meta)),
        eval_rate_hz,
    )
    nw = stack.enter_context(tnav.writer(nav_out, meta))
    return _NavSink(inner, nav, plan, dtype, nw, nv.batch_size(nav.K))
