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
    sequence has the term. The joint law of a window's values is the shard path's; windows
    of one sequence are drawn independently of each other (their slow states are not the
    same realization), so use the exact mode where the cross-window correlation matters.

Output bandwidth and rounding quantization (a grade's ``bandwidth``, ``quantization.mode:
round``): exact mode runs the shard path's :class:`~imugen.sensors.model.SensorModel` (its
filter streams, stream ``*_band``). Window mode (:func:`output_stage`) runs the kernel from
:func:`warmup_rows` rows before the window (the impulse response's length on the output grid,
plus two; from row 1 when the window starts closer to the route's start) without white noise
and quantization, then the output filter on the motion (started in steady state on the first
warm-up row, so the window's rows carry the filter's true history up to an IIR's truncated
tail), the internal-rate white noise after a warm-up of the impulse response's length
(steady state: its exact law), saturation, and quantization (rounded per sample, or carried
from a uniform residual), these draws from the sequence's stream ``window_band``.

Vibration and mounting (the shard options ``vibration``, ``mounting``) are applied to the truth
chunks in exact mode as the shard loop applies them (streams ``vibration``, ``mounting``); window
mode has neither. Raw increments (``increments="raw"``) are not streamed: a stream is the
sensor on the truth's compensated increments and rates.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from imugen.core.jit import njit
from imugen.core.seeding import generator, sensor_rng
from imugen.sensors._kernel import kernel, quantize_series
from imugen.sensors.ideal import CHUNK
from imugen.sensors.model import SensorModel, SensorParams, draw_sensor
from imugen.stream.keys import WINDOW_STREAM

_EMPTY3 = np.zeros((0, 0, 3))


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


def window_batch(tr, draws, seqs, rngs, k0, W, temp_rows, want, outs, scratch=None):
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
    rngs : list of numpy Generator
        The window stream of each sequence.
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
    scratch : Scratch, optional
        Reused memory for the normals (fresh pages cost more than the draws).
    """
    B = len(k0)
    dt = tr[5]
    gp = SensorParams.stack([d.gyro for d in draws])
    ap = SensorParams.stack([d.accel for d in draws])
    Pg, fg = _pack(gp, dt)
    Pa, fa = _pack(ap, dt)
    per = _per_window(fg, gp.components, W) + _per_window(fa, ap.components, W)
    nwin = np.bincount(seqs, minlength=len(draws))
    counts = per * nwin
    z = np.empty(int(counts.sum())) if scratch is None else scratch.get("z", int(counts.sum()))
    starts = np.concatenate([[0], np.cumsum(counts)])
    for s, rng in enumerate(rngs):
        rng.standard_normal(out=z[starts[s] : starts[s + 1]])
    first = np.concatenate([[0], np.cumsum(nwin)[:-1]])
    zoff = starts[seqs] + (np.arange(B) - first[seqs]) * per[seqs]
    empty = np.zeros((0, W, 6), next(iter(outs.values())).dtype if outs else np.float64)
    o = {
        n: (outs[n] if want.get(n) else empty)
        for n in ("rate", "inc", "bias", "sf", "err_rate", "err_inc")
    }
    use_t = len(tr[4]) > 0
    _windows(
        np.asarray(k0, np.int64), np.asarray(temp_rows, np.int64), dt, W, z, zoff,
        np.asarray(seqs, np.int64), fg, fa, gp.lsb, gp.full_scale, ap.lsb, ap.full_scale,
        Pg, Pa, tr[0], tr[1], tr[2], tr[3], tr[4] if use_t else np.zeros(1), use_t,
        o["rate"], o["inc"], o["bias"], o["sf"], o["err_rate"], o["err_inc"],
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


def window_rngs(seed, rid, gid, shard, j):
    """The window-mode stream of a sequence (:data:`~imugen.stream.keys.WINDOW_STREAM`)."""
    return generator(seed, (rid, gid, shard, j, WINDOW_STREAM))


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
def _windows(k0, rows, dt, W, z, zoff, seqs, fg, fa, lsb_g, fs_g, lsb_a, fs_a, Pg, Pa,
             tw, tf, tdth, tdv, tdT, use_t, o_rate, o_inc, o_bias, o_sf, o_er, o_ei):  # fmt: skip
    """Every window: slow states from their law, then the shard path's kernel on its rows."""
    Cg = Pg[2].shape[2]
    Ca = Pa[2].shape[2]
    xg = np.zeros((1, 3, Cg))
    xa = np.zeros((1, 3, Ca))
    r = np.zeros((1, 3))
    sp = np.zeros((1, 3))
    qr = np.zeros((1, 3))
    qi = np.zeros((1, 3))
    slow = np.empty((W, 3))
    for b in range(len(k0)):
        s = seqs[b]
        g = rows[b]
        u_w, u_f = tw[g : g + W], tf[g : g + W]
        d_th, d_v = tdth[g : g + W], tdv[g : g + W]
        dT = tdT[g - 1 : g + W] if use_t else tdT[0:0]
        o = zoff[b]
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
            kernel(k0[b], dt, u, du, a, da, dT, use_t, zw, zr, zb, use_w, use_r, use_b,
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
    """Bandwidth and quantization of window-mode rows, as :meth:`SensorModel.step` does them.

    The kernel's rows ``(B, lead_max + W, 6)`` in ``outs`` (no white noise where a bandwidth
    generates it, no quantization) start ``lead[b]`` rows before each window: the output
    filter's motion state starts in steady state on the first of them (a warm-up of
    :func:`warmup_rows`), its internal-rate white noise in steady state after a warm-up of
    the impulse response's length (exact law), the asynchronous read phase is uniform, the
    carry residual uniform on ``[-q/2, q/2)``, all from each sequence's ``window_band``
    stream (``band_rngs``, one per window: the sequence's, consumed window after window, gyro
    then accelerometer). Returns ``name -> (B, W, 6)`` for ``rate``, ``inc``, ``err_rate``,
    ``err_inc``, ``bias``: the window's rows.
    """
    from imugen.sensors.bandwidth import Stream as BandStream

    B = len(seqs)
    take = np.asarray(lead)[:, None] + np.arange(W)  # (B, W)
    bi = np.arange(B)[:, None]
    res = {n: np.empty((B, W, 6)) for n in ("rate", "inc", "err_rate", "err_inc", "bias")
           if want.get(n)}  # fmt: skip
    if "bias" in res:
        res["bias"][...] = outs["bias"][bi, take]
    for s, name in enumerate(("gyro", "accel")):
        c = slice(3 * s, 3 * s + 3)
        p = SensorParams.stack([getattr(draws[q], name) for q in seqs])
        band = bands[s]
        st = None
        if band is not None:
            st = BandStream(band, p.white, band_rngs)
            noise = st.noise(1, outs["rate" if "rate" in outs else "inc"].shape[1])
        for kind, q, fs, truth in (
            ("rate", p.lsb, p.full_scale, truth_rate),
            ("inc", p.lsb * dt, p.full_scale * dt, truth_inc),
        ):
            if kind not in outs:
                continue
            y = np.ascontiguousarray(outs[kind][..., c])
            if band is not None:
                y = st.motion(kind, 1, y / dt if kind == "inc" else y)
                if kind == "inc":
                    y *= dt
                if f"err_{kind}" in res:
                    res[f"err_{kind}"][..., c] = y[bi, take] - truth[..., c]
                np.clip(y + (noise if kind == "rate" else noise * dt), -fs, fs, out=y)
            elif f"err_{kind}" in res:
                res[f"err_{kind}"][..., c] = outs[f"err_{kind}"][bi, take, c]
            y = np.ascontiguousarray(y[bi, take])
            r0 = np.zeros((B, 3))
            if q > 0 and not p.q_round:  # carry from a uniform residual at the window start
                r0 = np.stack([(g.random(3) - 0.5) * q for g in band_rngs])
            quantize_series(y, q, p.q_round, r0)
            if kind in res:
                res[kind][..., c] = y
    return res
