"""Generation of IMU windows without disk: a whole sequence exactly, or windows on their own.

Two ways to make the measured window of a key ``(route, grade, shard, j, k0)``:

exact (:func:`exact_sequence`)
    The sequence is generated from its turn-on (sample 0) to the window's end with the draws of
    the simulate stage: parameters from stream ``params``, noise from the streams ``*_white``,
    ``*_rrw``, ``*_bi`` (and ``*_slow`` for a grade's ``slow_bias``) of spawn key
    ``(route_id, grade_id, shard, j, stream)``, the same kernel
    (:class:`imugen.sensors.model.SensorModel`). The numbers are those of the shard, bit for bit
    (the shard stores them as float32: the same rounding). Its cost grows with ``k0``.
window (:func:`window_batch`)
    Only the window's rows are generated. Parameters are the sequence's, from stream
    ``params`` (its labels are the shard path's bit for bit). The slow states at the sample
    before the window (``m = k0 - 1``) are drawn from their exact law there: each Gauss-Markov
    component ``N(0, x0^2 phi^(2m) + sigma^2 (1 - phi^(2m)))`` (``x0`` its start deviation,
    the stationary ``sigma`` unless the grade starts it at zero), the rate random walk
    ``N(0, K^2 m dt)``, the quantization residuals uniform on ``[-q/2, q/2)``; the window's
    noise follows. These draws come from the sequence's stream :data:`~imugen.stream.keys.WINDOW_STREAM`,
    consumed window after window in increasing ``k0``; per window and sensor (gyro, then
    accel): ``3 C`` GM states (axis-major; ``C`` counts a ``slow_bias`` as the last
    component), 3 random-walk states, 3 + 3 normals turned into the rate and increment
    quantization residuals (``Phi(z)``), then the window's white
    ``(W, 3)``, random-walk ``(W, 3)`` and GM ``(W, 3 C)`` normals, each only when the
    sequence has the term. The stream's bit generator is SFC64 (not the shard path's PCG64;
    the same SeedSequence and spawn key): the normals are those of
    ``Generator(SFC64(SeedSequence(seed, spawn_key=(route_id, grade_id, shard, j, 11))))
    .standard_normal()``, drawn inside the kernel where they are used (:mod:`imugen.core.sfc64`). The joint law of a window's values is the shard path's; windows
    of one sequence are drawn independently of each other (their slow states are not the
    same realization), so use the exact mode where the cross-window correlation matters.

Output bandwidth and rounding quantization (a grade's ``bandwidth``, ``quantization.mode:
round``): exact mode runs the shard path's :class:`~imugen.sensors.model.SensorModel` (its
filter streams, stream ``*_band``). Window mode (:func:`output_stage`) runs the kernel from
:func:`warmup_rows` rows before the window (the impulse response's length on the output grid,
plus two; from row 1 when the window starts closer to the route's start) without white noise
and quantization, then the output filter on the motion (started in steady state on the first
warm-up row, so the window's rows carry the filter's true history up to an IIR's truncated
tail), the filtered internal-rate white noise at the window's reads from its exact
stationary law (jointly Gaussian, covariance ``N^2 f_i c(j_k - j_l)``), saturation, and quantization (rounded per sample, or carried
from a uniform residual), these draws from the sequence's stream ``window_band`` in blocks over
its windows; the filters run over all the windows in one compiled call per sensor
(:func:`imugen.sensors.bandwidth.filter_windows`, :func:`~imugen.sensors.bandwidth.noise_windows`).

Vibration and mounting (the shard options ``vibration``, ``mounting``) are applied to the truth
chunks in exact mode as the shard loop applies them (streams ``vibration``, ``mounting``). They
have no state (a sequence's draw gives every sample in closed form), so window mode applies the
same draws to each window's rows (:func:`moved_windows`): the same motion sample for sample. Raw increments (``increments="raw"``) are not streamed: a stream is the
sensor on the truth's compensated increments and rates.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from imugen.core import sfc64
from imugen.core.jit import njit, njit_borrowing
from imugen.core.seeding import sensor_key, sensor_rng
from imugen.core.seedseq import generate_state, pcg64_state
from imugen.sensors._kernel import kernel, quantize_series
from imugen.sensors.ideal import CHUNK
from imugen.sensors.model import (
    N_NORMAL,
    N_SLOW_UNIFORM,
    N_UNIFORM,
    SensorModel,
    SensorParams,
    draw_sensor,
    draw_sensors,
)
from imugen.stream.keys import WINDOW_STREAM

_EMPTY3 = np.zeros((0, 0, 3))
_kernel = njit_borrowing(cache=True)(kernel.py_func)
"""The shard path's kernel without reference counting (:func:`imugen.core.jit.njit_borrowing`):
the window loop calls it per window and sensor with some 40 arrays."""


@dataclass
class Draw:
    """A sequence's drawn parameters (gyro, accel) and its keys."""

    gyro: SensorParams
    accel: SensorParams


def draw_params(seed, rid, grade, enabled, nominal, shard, j) -> Draw:
    """Parameters of sequence ``j`` of ``shard`` (stream ``params``; the shard path's draw)."""
    rng = sensor_rng(seed, rid, grade.id, shard, j, "params")
    gp = draw_sensor(grade.gyro, rng, enabled["gyro"], nominal)
    ap = draw_sensor(grade.accel, rng, enabled["accel"], nominal)
    return Draw(gp, ap)


def draw_params_many(seed, keys, grades, enabled, nominal) -> list[Draw]:
    """:func:`draw_params` of many sequences: ``keys`` ``[(route_id, grade index, shard, j)]``
    (``grades``, ``enabled``: the stream's lists). Each sequence's variates come from its own
    stream ``params`` as :func:`draw_params` draws them; the parameters are computed for all
    sequences of a grade at once (:func:`imugen.sensors.model.draw_sensors`, the same numbers)."""
    n = len(keys)
    ug, zg = np.empty((n, N_UNIFORM)), np.empty((n, N_NORMAL))
    ua, za = np.empty((n, N_UNIFORM)), np.empty((n, N_NORMAL))
    gi = np.empty(n, np.int64)
    words = generate_state(
        seed, [sensor_key(rid, grades[g].id, shard, j, "params") for rid, g, shard, j in keys], 4
    )
    usg, usa = np.zeros((n, N_SLOW_UNIFORM)), np.zeros((n, N_SLOW_UNIFORM))
    rng = np.random.Generator(np.random.PCG64(0))
    for i, (_rid, g, _shard, _j) in enumerate(keys):
        rng.bit_generator.state = pcg64_state(words[i])  # = sensor_rng(..., "params")
        ug[i], zg[i] = rng.random(N_UNIFORM), rng.standard_normal(N_NORMAL)
        if grades[g].gyro.slow_bias is not None:  # draw_sensor's order
            usg[i] = rng.random(N_SLOW_UNIFORM)
        ua[i], za[i] = rng.random(N_UNIFORM), rng.standard_normal(N_NORMAL)
        if grades[g].accel.slow_bias is not None:
            usa[i] = rng.random(N_SLOW_UNIFORM)
        gi[i] = g
    out: list = [None] * n
    for g in np.unique(gi):
        rows = np.flatnonzero(gi == g)
        gp = draw_sensors(grades[g].gyro, ug[rows], zg[rows], enabled[g]["gyro"], nominal,
                          usg[rows])  # fmt: skip
        ap = draw_sensors(grades[g].accel, ua[rows], za[rows], enabled[g]["accel"], nominal,
                          usa[rows])  # fmt: skip
        for r, i in enumerate(rows):
            out[i] = Draw(gp.rows(r), ap.rows(r))
    return out


def exact_sequence(truth, draw: Draw, seed, rid, gid, shard, j, kmax, temp, want, *,
                   bands=(None, None), vib=None, mounting=None, mount=None) -> dict:  # fmt: skip
    """Samples ``0 .. kmax - 1`` of one sequence exactly as the simulate stage makes them.

    The same chunks (:data:`imugen.sensors.ideal.CHUNK`), streams and models as the shard
    loop (:func:`imugen.simulate.stage._loop`): mounting, then vibration of the truth chunk,
    then each sensor (with its output bandwidth, stream ``*_band``, and its quantization mode).

    Parameters
    ----------
    truth : TruthSource
    draw : Draw
        From :func:`draw_params` with the same key.
    temp : callable or None
        Temperature profile (:func:`imugen.simulate.plan.temperature_profile`).
    want : iterable of str
        Groups of :data:`imugen.tables.shard.GROUPS` to return (``dtheta``, ``err_dv``, ...).
    bands : (OutputFilter or None, OutputFilter or None)
        Output bandwidth of the gyro and the accelerometer read at ``1 / dt``.
    vib : imugen.sensors.vibration.SequenceVibration, optional
        The sequence's drawn vibration (stream ``vibration``).
    mounting, mount : imugen.sensors.mounting.Mounting and the sequence's ``(angles, lever)``
        (stream ``mounting``), optional.

    Returns
    -------
    dict name -> (kmax, 3) float64
    """
    dt = truth.dt
    want = set(want)
    out = {n: np.empty((kmax, 3)) for n in want}
    models, rngs = {}, {}
    for s, p, band in (("gyro", draw.gyro, bands[0]), ("accel", draw.accel, bands[1])):
        extra = () if band is None else (band, [sensor_rng(seed, rid, gid, shard, j, f"{s}_band")])
        m = models[s] = SensorModel(p, dt, *extra)
        for name, use, width in (
            ("white", m.use_w, 3),
            ("rrw", m.use_r, 3),
            ("bi", m.use_bf, 3 * p.fast_components),
            ("slow", m.use_s, 3),
        ):
            if use:
                rngs[f"{s}_{name}"] = (sensor_rng(seed, rid, gid, shard, j, f"{s}_{name}"), width)
    for k0 in range(0, kmax, CHUNK):
        L = min(CHUNK, kmax - k0)
        _, w_b, f_b, dth, dv = truth.chunk(k0, L)
        if mounting is not None:
            sh = mounting.shared(k0, L, False)
            w_b, f_b, dth, dv = mounting.apply(k0, sh, *mount, dth, dv, False)
        if vib is not None:
            w_b, f_b, dth, dv = vib.apply(k0, w_b, f_b, dth, dv, raw=False)
        dT = None
        if temp is not None:
            tt = np.maximum(np.arange(k0 - 1, k0 + L), 0) * dt
            dT = np.ascontiguousarray(temp(tt), dtype=np.float64)
        z = {k: rng.standard_normal((L, w))[None] for k, (rng, w) in rngs.items()}
        for s, m in models.items():
            inc, rate = ("dtheta", "gyro") if s == "gyro" else ("dv", "accel")
            args = (w_b, dth, f_b, dv) if s == "gyro" else (f_b, dv, None, None)

            def o(name, k0=k0, L=L):
                return out[name][None, k0 : k0 + L] if name in want else None

            m.step(
                k0, *args, dT, z.get(f"{s}_white"), z.get(f"{s}_rrw"), z.get(f"{s}_bi"),
                o(rate), o(inc), o(f"{s}_bias"), o(f"{s}_sf"), o(f"err_{rate}"), o(f"err_{inc}"),
                zs=z.get(f"{s}_slow"),
            )  # fmt: skip
    return out


# --- window mode -------------------------------------------------------------------------------
def normals_per_window(p: SensorParams, W: int) -> int:
    """Normals of one window and one sensor in window mode (module docstring)."""
    C = p.components
    use_w, use_r, use_b = (bool(np.any(v > 0)) for v in (p.white, p.rrw, p.bi_sigma))
    return 3 * C + 9 + 3 * W * (use_w + use_r + C * use_b)


def _per_window(flags: np.ndarray, C: int, W: int) -> np.ndarray:
    """:func:`normals_per_window` of each sequence from :func:`_pack`'s flags, ``(S,)`` int64."""
    f = flags.astype(np.int64)
    return 3 * C + 9 + 3 * W * (f[:, 0] + f[:, 1] + C * f[:, 2])


def _pack(p: SensorParams, dt: float) -> tuple:
    """The kernel's per-sequence arrays of a stacked parameter set, and the terms' flags."""
    phi = np.exp(-dt / p.bi_tau)
    drv = p.bi_sigma * np.sqrt(-np.expm1(-2.0 * dt / p.bi_tau))[:, None, :]
    flags = np.column_stack(
        [
            np.any(p.white > 0, axis=1),
            np.any(p.rrw > 0, axis=1),
            np.any(p.bi_sigma > 0, axis=(1, 2)),
            np.any(p.gs != 0, axis=(1, 2)),
        ]
    ).astype(np.bool_)
    f64 = np.ascontiguousarray
    return (
        f64(p.b_on), f64(p.bi_x0), f64(p.bi_sigma), f64(phi), f64(drv), f64(p.white),
        f64(p.rrw), f64(p.sf), f64(p.cc), f64(p.gs), f64(p.tb), f64(p.ts),
    ), flags  # fmt: skip


def window_batch(tr, draws, seqs, states, k0, W, temp_rows, want, outs):
    """Window-mode generation of one grade's windows (the module docstring's law).

    Parameters
    ----------
    tr : tuple (w, f, dth, dv, dT, dt)
        Concatenated truths of the stream's routes, float64 rows ``(sum K, 3)``; ``dT``
        ``(sum K,)`` the temperature offset at each sample (empty without a profile); ``dt``
        the common sample interval [s].
    draws : list of Draw
        One per sequence of this call.
    seqs : (B,) int
        Sequence (index into ``draws``) of each window; windows of a sequence are contiguous
        and in increasing ``k0``.
    states : (S, 4) uint64
        The window stream of each sequence (:func:`window_states`), advanced in place.
    k0 : (B,) int
        First row of each window (``>= 1``).
    W : int
    temp_rows : (B,) int
        Row of each window's ``k0`` in the concatenated truth.
    want : dict
        ``{"rate", "inc", "bias", "sf", "err_rate", "err_inc"}`` -> bool.
    outs : dict
        ``name -> (B, W, 6)`` output buffers (gyro columns, then accel), float64 or float32
        (the kernel computes in float64 and rounds once on writing, as the shard path).
    """
    dt = tr[5]
    gp = SensorParams.stack([d.gyro for d in draws])
    ap = SensorParams.stack([d.accel for d in draws])
    Pg, fg = _pack(gp, dt)
    Pa, fa = _pack(ap, dt)
    per = _per_window(fg, gp.components, W) + _per_window(fa, ap.components, W)
    st = states
    empty = np.zeros((0, W, 6), next(iter(outs.values())).dtype if outs else np.float64)
    o = {
        n: (outs[n] if want.get(n) else empty)
        for n in ("rate", "inc", "bias", "sf", "err_rate", "err_inc")
    }
    use_t = len(tr[4]) > 0
    _windows(
        np.asarray(k0, np.int64), np.asarray(temp_rows, np.int64), dt, W, st, per,
        np.asarray(seqs, np.int64), fg, fa, gp.lsb, gp.full_scale, ap.lsb, ap.full_scale,
        Pg, Pa, tr[0], tr[1], tr[2], tr[3], tr[4] if use_t else np.zeros(1), use_t,
        o["rate"], o["inc"], o["bias"], o["sf"], o["err_rate"], o["err_inc"],
        sfc64.KI, sfc64.WI, sfc64.FI,
    )  # fmt: skip


class Scratch:
    """Flat float64 buffers reused from call to call, by name (grown when too small)."""

    def __init__(self):
        self._a = {}

    def get(self, name: str, *shape, dtype=np.float64) -> np.ndarray:
        n = int(np.prod(shape))
        key = (name, np.dtype(dtype))
        a = self._a.get(key)
        if a is None or len(a) < n:
            a = self._a[key] = np.empty(max(n, 2 * len(a) if a is not None else n), dtype)
        return a[:n].reshape(shape)


def window_states(seed, keys) -> np.ndarray:
    """The window-mode streams of sequences ``keys`` ``[(rid, gid, shard, j)]``
    (:data:`~imugen.stream.keys.WINDOW_STREAM`): the states ``(S, 4)`` of
    ``SFC64(SeedSequence(seed, spawn_key=(rid, gid, shard, j, WINDOW_STREAM)))``
    (:mod:`imugen.core.sfc64`)."""
    return sfc64.states(seed, [(*k, WINDOW_STREAM) for k in keys])


@njit(cache=True)
def _states(k0, dt, z, o, s, P, flags, lsb, x, r, sp, qr, qi, dT0, use_t):
    """Slow states and quantization residuals at sample ``k0 - 1`` from their exact law."""
    b_on, bi_x0, bi_sig, phi, _drv, _white, rrw, _sf, _cc, _gs, tb, _ts = P
    C = bi_sig.shape[2]
    m = k0 - 1
    for i in range(3):
        sl = b_on[s, i]
        for c in range(C):
            f2 = phi[s, c] ** (2 * m)
            sd = math.sqrt(bi_x0[s, i, c] ** 2 * f2 + bi_sig[s, i, c] ** 2 * (1.0 - f2))
            x[0, i, c] = sd * z[o + i * C + c] if flags[s, 2] else 0.0
            sl += x[0, i, c]
        r[0, i] = rrw[s, i] * math.sqrt(dt * m) * z[o + 3 * C + i] if flags[s, 1] else 0.0
        sl += r[0, i]
        if use_t:
            sl += tb[s, i] * dT0
        sp[0, i] = sl
        u_r = 0.5 * math.erfc(-z[o + 3 * C + 3 + i] / math.sqrt(2.0)) - 0.5
        u_i = 0.5 * math.erfc(-z[o + 3 * C + 6 + i] / math.sqrt(2.0)) - 0.5
        qr[0, i] = u_r * lsb
        qi[0, i] = u_i * lsb * dt
    return o + 3 * C + 9


@njit(cache=True)
def _windows(k0, rows, dt, W, st, per, seqs, fg, fa, lsb_g, fs_g, lsb_a, fs_a, Pg, Pa,
             tw, tf, tdth, tdv, tdT, use_t, o_rate, o_inc, o_bias, o_sf, o_er, o_ei,
             ki, wi, fi):  # fmt: skip
    """Every window: its normals from its sequence's state ``st[s]`` (``per[s]`` of them),
    slow states from their law, then the shard path's kernel on its rows."""
    Cg = Pg[2].shape[2]
    Ca = Pa[2].shape[2]
    xg = np.zeros((1, 3, Cg))
    xa = np.zeros((1, 3, Ca))
    r = np.zeros((1, 3))
    sp = np.zeros((1, 3))
    qr = np.zeros((1, 3))
    qi = np.zeros((1, 3))
    slow = np.empty((W, 3))
    z = np.empty(per.max() if len(per) else 0)
    for b in range(len(k0)):
        s = seqs[b]
        g = rows[b]
        sfc64.normals(st[s], z[: per[s]], ki, wi, fi)
        u_w, u_f = tw[g : g + W], tf[g : g + W]
        d_th, d_v = tdth[g : g + W], tdv[g : g + W]
        dT = tdT[g - 1 : g + W] if use_t else tdT[0:0]
        o = 0
        for sensor in range(2):
            P = Pg if sensor == 0 else Pa
            fl = fg if sensor == 0 else fa
            C = Cg if sensor == 0 else Ca
            x = xg if sensor == 0 else xa
            lsb = lsb_g if sensor == 0 else lsb_a
            fs = fs_g if sensor == 0 else fs_a
            dT0 = dT[0] if use_t else 0.0
            o = _states(k0[b], dt, z, o, s, P, fl, lsb, x, r, sp, qr, qi, dT0, use_t)
            use_w, use_r, use_b = fl[s, 0], fl[s, 1], fl[s, 2]
            zw = z[o : o + 3 * W].reshape((1, W, 3)) if use_w else z[0:0].reshape((1, 0, 3))
            o += 3 * W if use_w else 0
            zr = z[o : o + 3 * W].reshape((1, W, 3)) if use_r else z[0:0].reshape((1, 0, 3))
            o += 3 * W if use_r else 0
            n = 3 * C * W
            zb = z[o : o + n].reshape((1, W, 3 * C)) if use_b else z[0:0].reshape((1, 0, 3 * C))
            o += n if use_b else 0
            c0 = 3 * sensor
            ss = slice(s, s + 1)
            use_g = fl[s, 3] and sensor == 0
            u = u_w if sensor == 0 else u_f
            du = d_th if sensor == 0 else d_v
            a = u_f if use_g else u_f[0:0]
            da = d_v if use_g else d_v[0:0]
            out_r = o_rate[b : b + 1, :, c0 : c0 + 3]
            out_i = o_inc[b : b + 1, :, c0 : c0 + 3]
            out_b = o_bias[b : b + 1, :, c0 : c0 + 3]
            out_s = o_sf[b : b + 1, :, c0 : c0 + 3]
            out_er = o_er[b : b + 1, :, c0 : c0 + 3]
            out_ei = o_ei[b : b + 1, :, c0 : c0 + 3]
            _kernel(k0[b], dt, u, du, a, da, dT, use_t, zw, zr, zb, use_w, use_r, use_b,
                   P[0][ss], P[1][ss], P[3][ss], P[4][ss], P[5][ss], P[6][ss], P[7][ss],
                   P[8][ss], P[9][ss], use_g, P[10][ss], P[11][ss], lsb, fs, x, r, sp, qr, qi,
                   slow, out_r, out_i, out_b, out_s, out_er, out_ei)  # fmt: skip


# --- window mode of a sensor with an output bandwidth or rounding quantization ----------------
def warmup_rows(bands, dt) -> int:
    """Output rows generated before a window so that its output filters forget their start:
    the impulse response's length on the output grid, plus two (0 without a bandwidth)."""
    n = 0
    for f in bands:
        if f is not None:
            n = max(n, math.ceil(len(f.impulse()) / f.ratio) + 2)
    return n


def window_band_rng(seed, rid, gid, shard, j):
    """The window-mode stream of a sequence's internal-rate noise, read phases and carry
    residuals (stream ``window_band``, :data:`imugen.core.seeding.SENSOR_STREAMS`)."""
    return sensor_rng(seed, rid, gid, shard, j, "window_band")


def without_output_stage(d: Draw, bands) -> Draw:
    """The draw the window kernel runs for a grade with an output stage: no quantization
    (applied after the filter), no white noise where a bandwidth generates it internally."""
    out = []
    for p, band in ((d.gyro, bands[0]), (d.accel, bands[1])):
        kw = {"lsb": 0.0}
        if band is not None:
            kw["white"] = np.zeros_like(p.white)
        out.append(replace(p, **kw))
    return Draw(*out)


def output_stage(draws, seqs, band_rngs, bands, truth_rate, truth_inc, dt, lead, W, outs, want):
    """Bandwidth and quantization of window-mode rows, as :meth:`SensorModel.step` does them,
    vectorized over the windows (:func:`imugen.sensors.bandwidth.filter_windows`,
    :func:`~imugen.sensors.bandwidth.noise_windows`: one filter call per block of windows).

    The kernel's rows ``(B, lead_max + W, 6)`` in ``outs`` (no white noise where a bandwidth
    generates it, no quantization) start ``lead[b]`` rows before each window: the output
    filter's motion state starts in steady state on the first of them (a warm-up of
    :func:`warmup_rows`), the filtered internal-rate white noise is drawn at the window's
    reads from its exact (stationary) law (:func:`~imugen.sensors.bandwidth.noise_windows`),
    the asynchronous read phase is uniform, the carry residual uniform on ``[-q/2, q/2)``.
    These draws come from each sequence's ``window_band`` stream (``band_rngs``, one per
    sequence of ``draws``; its windows are contiguous in ``seqs``), per sensor (gyro, then
    accelerometer) in blocks over the sequence's windows: the read phases ``(n,)``
    (asynchronous read), the noise's normals ``(n, W, 3)``, then the carry residuals
    ``(n, 3)`` of the rate and of the increments (those served). Returns ``name -> (B, W, 6)`` for ``rate``, ``inc``,
    ``err_rate``, ``err_inc``, ``bias``: the window's rows.
    """
    from imugen.sensors.bandwidth import filter_windows, noise_windows

    seqs = np.asarray(seqs, np.int64)
    B = len(seqs)
    nwin = np.bincount(seqs, minlength=len(draws))
    first = np.concatenate([[0], np.cumsum(nwin)[:-1]])
    take = np.asarray(lead)[:, None] + np.arange(W)  # (B, W)
    bi = np.arange(B)[:, None]
    res = {n: np.empty((B, W, 6)) for n in ("rate", "inc", "err_rate", "err_inc", "bias")
           if want.get(n)}  # fmt: skip
    if "bias" in res:
        res["bias"][...] = outs["bias"][bi, take]
    kinds = [k for k in ("rate", "inc") if k in outs]

    def per_seq(fn):
        """``fn(rng, n)`` of each sequence's stream, its windows' rows stacked."""
        return np.concatenate([fn(band_rngs[s], int(nwin[s])) for s in range(len(draws))])

    for s, name in enumerate(("gyro", "accel")):
        c = slice(3 * s, 3 * s + 3)
        p0 = getattr(draws[0], name)
        band = bands[s]
        if band is not None:
            phase = np.zeros(B)
            if not band.synchronous:
                phase = per_seq(lambda g, n: g.random(n))
            z = np.empty((B, W, 3))
            for q in range(len(draws)):
                band_rngs[q].standard_normal(out=z[first[q] : first[q] + nwin[q]])
            white = np.concatenate([getattr(d, name).white for d in draws])[seqs]
            noise = noise_windows(band, z, white * math.sqrt(band.internal_rate_hz), phase)
            del z
            y2 = np.concatenate([outs[k][..., c] for k in kinds], axis=2)
            if "inc" in kinds:
                y2[..., -3:] /= dt
            yf = filter_windows(band, y2, phase)[bi, take]
        for i, kind in enumerate(kinds):
            q = p0.lsb if kind == "rate" else p0.lsb * dt
            fs = p0.full_scale if kind == "rate" else p0.full_scale * dt
            truth = truth_rate if kind == "rate" else truth_inc
            if band is not None:
                y = yf[..., 3 * i : 3 * i + 3] * (1.0 if kind == "rate" else dt)
                if f"err_{kind}" in res:
                    res[f"err_{kind}"][..., c] = y - truth[..., c]
                if kind in res:
                    y = np.clip(y + (noise if kind == "rate" else noise * dt), -fs, fs)
            else:
                if f"err_{kind}" in res:
                    res[f"err_{kind}"][..., c] = outs[f"err_{kind}"][bi, take, c]
                y = outs[kind][bi, take, c]
            if kind not in res:  # served for its error only: no noise or quantization needed
                continue
            y = np.ascontiguousarray(y)
            r0 = np.zeros((B, 3))
            if q > 0 and not p0.q_round:  # carry from a uniform residual at the window start
                r0 = (per_seq(lambda g, n: g.random((n, 3))) - 0.5) * q
            quantize_series(y, q, p0.q_round, r0)
            res[kind][..., c] = y
    return res


# --- window mode with mounting and vibration ----------------------------------------------------
def moved_windows(tr, starts, rows, L, moves):
    """Each window's truth rows as the mounted, vibrating case senses them.

    Mounting and vibration have no state: a sequence's draw (streams ``mounting`` and
    ``vibration``, the shard path's) and the truth give every sample in closed form
    (:meth:`imugen.sensors.mounting.Mounting.apply`, the rate's derivative from the truth's
    neighbouring rows; :meth:`imugen.sensors.vibration.SequenceVibration.apply`, the phases at
    the sample's time), so a window's rows are the whole sequence's rows, applied as the shard
    loop applies them (mounting, then vibration).

    Parameters
    ----------
    tr : tuple (w, f, dth, dv, dT, dt)
        Concatenated truths (:func:`window_batch`).
    starts : (B,) int
        Sample of each window's first row (``>= 1``) in its route.
    rows : (B,) int
        Row of ``starts`` in the concatenated truth.
    L : int
        Rows per window.
    moves : list of (Mounting or None, (angles, lever) or None, SequenceVibration or None)
        One per window.

    Returns
    -------
    tr_w : tuple
        The windows' rows, ``L + 1`` per window (a leading row for the temperature at the
        sample before), in :func:`window_batch`'s form.
    rows_w : (B,) int
        Row of each window's first sample in ``tr_w``.
    """
    w, f, dth, dv, dT, dt = tr
    B, n = len(starts), L + 1
    out = [np.zeros((B * n, 3)) for _ in range(4)]
    for b in range(B):
        k, g = int(starts[b]), int(rows[b])
        a = tuple(x[g : g + L] for x in (w, f, dth, dv))
        mounting, mount, vib = moves[b]
        if mounting is not None:
            a = mounting.apply(k, mounting.shared(k, L, False), *mount, a[2], a[3], False)
        if vib is not None:
            a = vib.apply(k, *a, raw=False)
        for o, x in zip(out, a, strict=True):
            o[b * n + 1 : (b + 1) * n] = x
    rows = np.asarray(rows, np.int64)
    dTw = dT[(rows[:, None] - 1 + np.arange(n)).ravel()] if len(dT) else dT
    return (*out, dTw, dt), np.arange(B, dtype=np.int64) * n + 1
