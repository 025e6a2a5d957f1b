"""Monte-Carlo shards: a truth table (or a still IMU) -> M erroneous IMU sequences of a grade.

Randomness
----------
A route is named by its id ``route_id = int.from_bytes(sha256(name.encode("utf-8"))[:4],
"big")`` (:func:`imugen.tables.shard.route_id`; the name is ``--route``, else the truth
metadata's ``route``, else the truth file's folder name, see :func:`imugen.simulate.sources.route_name`). A shard's
root is ``SeedSequence(seed, spawn_key=(route_id, grade_id, shard))``. Sequence ``j`` of the
shard (``0 <= j < M``) uses the children ``SeedSequence(seed, spawn_key=(route_id, grade_id,
shard, j, stream))`` -- exactly what ``root.spawn`` would give, but addressed by index -- one
per stream (:data:`imugen.core.seeding.SENSOR_STREAMS`): its parameter draw and, for each sensor, its white noise, rate
random walk and bias-instability normals (and those of a grade's ``slow_bias``). So no two (route, grade, sequence) share a draw (up
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
and specific force, :meth:`imugen.sensors.ideal.TruthSource.raw_chunk`), recorded as ``increments`` in the metadata.
Row groups are written as time chunks are produced (bounded buffer, never the whole shard).
"""

from __future__ import annotations

import math
import sys
from contextlib import ExitStack
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from imugen.core.errors import InputError
from imugen.core.seeding import sensor_rng
from imugen.sensors.ideal import CHUNK, TruthSource
from imugen.sensors.model import SensorModel, SensorParams
from imugen.simulate.options import SimulateOptions
from imugen.simulate.plan import Plan, plan_shard
from imugen.simulate.sinks import MemorySink, WriterSink, navigation_sink
from imugen.tables import shard as tshard


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


def _band(spec, sensor, dt, rng):
    """``(filter, [rng])`` of a sensor with an output bandwidth read every ``dt``, else ``()``."""
    if spec.bandwidth is None:
        return ()
    return spec.bandwidth.output_filter(sensor, 1.0 / dt), [rng]


def _loop(plan: Plan, sink, progress=None):
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
        models = {
            s: SensorModel(
                par,
                dt,
                *_band(
                    grade.sensor(s), s, dt, sensor_rng(seed, rid, grade.id, shard, j, f"{s}_band")
                ),
            )
            for s, par in (("gyro", gp[j]), ("accel", ap[j]))
        }
        rngs = {}
        for s, m in models.items():
            normals += m.normals_per_sample
            if m.use_w:
                rngs[f"{s}_white"] = (sensor_rng(seed, rid, grade.id, shard, j, f"{s}_white"), 3)
            if m.use_r:
                rngs[f"{s}_rrw"] = (sensor_rng(seed, rid, grade.id, shard, j, f"{s}_rrw"), 3)
            if m.use_bf:
                rngs[f"{s}_bi"] = (
                    sensor_rng(seed, rid, grade.id, shard, j, f"{s}_bi"),
                    3 * m.p.fast_components,
                )
            if m.use_s:
                rngs[f"{s}_slow"] = (sensor_rng(seed, rid, grade.id, shard, j, f"{s}_slow"), 3)
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
                    zs=z.get(f"{s}_slow"),
                )
            sink.put(j, k0, L, t, outs)
        if progress is not None:
            progress.update(j + 1)
    return normals / M if M else 0


FILE_ONLY = (
    "dtype",
    "explicit_time",
    "eval_rate_hz",
    "vertical",
    "vertical_order",
    "vertical_time_constant_s",
    "vertical_reference",
)
"""Fields of :class:`SimulateOptions` that concern the written shard only, not :func:`simulate`."""


def simulate(truth, grade, sequences=1, seed=0, shard=0, **options) -> Shard:
    """Generate a shard in memory (float64 arrays ``(M, K, 3)``); same numbers as :func:`run`.

    Parameters
    ----------
    truth : path, DataFrame, dict, TruthSource or None
        Truth table (Parquet path or DataFrame with the columns of :mod:`imugen.tables.truth`),
        a dict with ``time_s``, ``omega_ib_b``, ``f_b``, ``dtheta``, ``dv`` arrays, or None
        with ``static_s``.
    grade : str or Grade
        Preset name, ``file.yaml:name``, or a :class:`~imugen.sensors.grades.Grade`.
    sequences, seed, shard : int
        ``M`` sequences; root seed; shard index.
    **options
        Further fields of :class:`~imugen.simulate.options.SimulateOptions` (defaults there),
        except those of the written file (:data:`FILE_ONLY`): ``outputs`` ({"increments",
        "rates", "both"}), ``draw`` (levels drawn in the grade's ranges, or ``"nominal"`` for
        every sequence), ``terms`` (apply only these: :func:`imugen.simulate.plan.enabled_terms`),
        ``temperature`` (:func:`imugen.simulate.plan.temperature_profile`), ``series`` (also
        the true slow-bias, scale-factor and effective-error series), ``static_s``,
        ``rate_hz``, ``static_earth`` (a still IMU instead of a truth table), ``grades_file``,
        ``shard_size`` (sequences per shard of the experiment, ``>= sequences``: indices are
        ``shard * shard_size + j``), ``route`` (its :func:`~imugen.tables.shard.route_id`
        enters every spawn key and the sequence ids; default
        :func:`imugen.simulate.sources.route_name`), ``increments`` ({"compensated", "raw"}:
        the truth's compensated increments, or plain integrals of rate and specific force),
        ``vibration`` ({"off", "car", "aircraft", "vehicle"}: :mod:`imugen.sensors.vibration`),
        ``mounting`` (IMU misalignment and lever arm drawn per sequence,
        :meth:`~imugen.sensors.mounting.MountingSpec.from_option`; None: the IMU is the vehicle
        frame at its reference point).
    """
    unknown = set(options) & set(FILE_ONLY)
    if unknown:
        raise TypeError(f"simulate() got options of the written file only: {sorted(unknown)}")
    opts = SimulateOptions(grade=grade, sequences=sequences, seed=seed, shard=shard, **options)
    plan = plan_shard(truth, opts, dtype=np.float64)
    tr = plan.truth
    sink = MemorySink(plan.M, tr.K, plan.names)
    _loop(plan, sink)
    time_s = tr.times()
    meta = {**plan.meta, "units": tshard.units(plan.names)}
    gpar, apar = SensorParams.stack(plan.gp), SensorParams.stack(plan.ap)
    return Shard(time_s, sink.data, plan.labels(), gpar, apar, meta)


def run(truth, out, options: SimulateOptions, *, navigate=None) -> dict:
    """Generate one shard and write it (Parquet + labels sidecar) atomically; optionally
    navigate it in the same pass.

    Parameters
    ----------
    truth
        As :func:`simulate` takes it.
    out : path or None
        The shard; its labels sidecar is :func:`~imugen.tables.shard.labels_path`.
    options : SimulateOptions
        ``dtype`` is the storage type of the measurement columns; ``rate_hz`` and
        ``static_earth`` only apply to ``static_s`` (a truth table has its own rate). The
        truth's uniform clock is stored once in the shard metadata (``clock``), not in every
        row, unless ``explicit_time`` (:func:`imugen.tables.shard.writer`).
    navigate : path, optional
        Also write the navigation error table of the shard (:mod:`imugen.tables.nav`),
        computed from the sequences as they are generated -- the shard is never re-read --
        at ``options.eval_rate_hz`` epochs per second: the same table, bit for bit, as
        :func:`imugen.navigate.stage.run` on the written shard. ``out=None`` with
        ``navigate`` writes the errors only (no IMU shard). Needs a truth file.

    Returns
    -------
    dict
        The shard's metadata (as written when ``out`` is given).
    """
    o = options
    if out is None and navigate is None:
        raise InputError("-o", "give an output shard (-o) and/or --navigate NAV.parquet")
    if navigate is not None:
        if not isinstance(truth, str | Path):
            raise InputError("--navigate", "needs a truth file (not --static or arrays)")
        if not (isinstance(o.eval_rate_hz, int | float) and 0 < o.eval_rate_hz < math.inf):
            raise InputError("--eval-rate-hz", f"must be > 0, got {o.eval_rate_hz!r}")
    if o.dtype not in ("float32", "float64"):
        raise InputError("--dtype", f"must be float32 or float64, got {o.dtype!r}")
    plan = plan_shard(truth, o)
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
                    o.dtype,
                    time_s=plan.truth.times(),
                    dt=_nominal_dt(plan.truth),
                    explicit_time=o.explicit_time,
                )
            )
            sink = WriterSink(w, plan.ids)
        if navigate is not None:
            from imugen.navigate.vertical import VerticalSpec

            sink = navigation_sink(stack, sink, plan, truth, out, navigate, o.eval_rate_hz,
                                   o.dtype, VerticalSpec.of(o))  # fmt: skip
        _loop(plan, sink, progress)
        if navigate is not None:
            sink.flush()
        if w is not None:
            w.labels = plan.label_columns()
    return tshard.read_meta(out) if out is not None else plan.meta


def main(options: SimulateOptions, truth, output, navigate) -> None:
    """``imugen simulate``: :func:`run`, then a summary line on stderr."""
    if truth is None and options.static_s is None:
        raise InputError("imugen simulate", "give a TRUTH.parquet or --static SECONDS")
    if truth is not None and options.static_s is not None:
        raise InputError("imugen simulate", "give either a TRUTH.parquet or --static, not both")
    meta = run(truth, output, options, navigate=navigate)
    written = " + ".join(p for p in (output, navigate) if p is not None)
    print(
        f"{written}: grade {meta['grade']['name']!r}, {options.sequences} sequences, "
        f"shard {options.shard}, seed {options.seed}",
        file=sys.stderr,
    )


def _nominal_dt(truth: TruthSource) -> float | None:
    """``1 / rate_hz`` of the truth's metadata (the step its time grid was built with)."""
    rate = truth.meta.get("rate_hz")
    return 1.0 / float(rate) if isinstance(rate, int | float) and rate > 0 else None
