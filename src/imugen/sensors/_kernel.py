"""Compiled kernels of the sensor error model (:mod:`imugen.sensors.model` is their face).

:func:`kernel` applies one triad's errors to a time chunk of ``S`` sequences, resuming from
the state arrays of :class:`imugen.sensors.model.SensorState`; :func:`kernel_increments` is
its one-pass special case (increments only), bit for bit the same. No I/O, no allocation
beyond the chunk's locals.
"""

from __future__ import annotations

import math

from imugen.core.jit import njit


@njit(cache=True, inline="always")
def quantize(res, y, q):
    """Quantize ``y`` to the step ``q`` with residual carry: ``(res + y - out, out)``."""
    res = res + y
    out = q * math.floor(res / q + 0.5)
    return res - out, out


@njit(cache=True)
def kernel(
    k0,
    dt,
    u,
    du,
    a,
    da,
    dT,
    use_t,
    zw,
    zr,
    zb,
    use_w,
    use_r,
    use_b,
    b_on,
    bi_sig,
    bi_phi,
    bi_drv,
    white,
    rrw,
    sf,
    cc,
    gs,
    use_g,
    tb,
    ts,
    lsb,
    full_scale,
    x,
    r,
    s_prev,
    q_rate,
    q_inc,
    slow,
    out_rate,
    out_inc,
    out_bias,
    out_sf,
    out_err_rate,
    out_err_inc,
):
    """Errors of one triad over samples ``k0 .. k0+L-1`` of ``S`` sequences (see
    :meth:`SensorModel.step`). Two passes per sequence: the slow bias of every sample, the
    three axes' recursions side by side with their states in registers (``slow``: an
    ``(L, 3)`` float64 scratch), then the measurements sample by sample with the sequence's error matrix in locals; the
    outputs are written once, in their storage dtype."""
    S = b_on.shape[0]
    L = u.shape[0]
    C = bi_sig.shape[2]
    sqdt = math.sqrt(dt)
    do_rate = out_rate.shape[0] > 0
    do_inc = out_inc.shape[0] > 0
    do_bias = out_bias.shape[0] > 0
    do_sf = out_sf.shape[0] > 0
    do_er = out_err_rate.shape[0] > 0
    do_ei = out_err_inc.shape[0] > 0
    lsb_i = lsb * dt
    fs_i = full_scale * dt
    for s in range(S):
        # pass 1: slow bias = turn-on + Gauss-Markov components + rate random walk + temperature
        # (the three axes side by side: three independent recursions in flight per sample)
        b0, b1, b2 = b_on[s, 0], b_on[s, 1], b_on[s, 2]
        for j in range(L):
            slow[j, 0] = b0
            slow[j, 1] = b1
            slow[j, 2] = b2
        if use_b:
            for c in range(C):
                phi = bi_phi[s, c]
                d0, d1, d2 = bi_drv[s, 0, c], bi_drv[s, 1, c], bi_drv[s, 2, c]
                x0, x1, x2 = x[s, 0, c], x[s, 1, c], x[s, 2, c]
                j0 = 0
                if k0 == 0 and L > 0:  # the process starts from its stationary law
                    x0 = bi_sig[s, 0, c] * zb[s, 0, c]
                    x1 = bi_sig[s, 1, c] * zb[s, 0, C + c]
                    x2 = bi_sig[s, 2, c] * zb[s, 0, 2 * C + c]
                    slow[0, 0] += x0
                    slow[0, 1] += x1
                    slow[0, 2] += x2
                    j0 = 1
                for j in range(j0, L):
                    x0 = phi * x0 + d0 * zb[s, j, c]
                    x1 = phi * x1 + d1 * zb[s, j, C + c]
                    x2 = phi * x2 + d2 * zb[s, j, 2 * C + c]
                    slow[j, 0] += x0
                    slow[j, 1] += x1
                    slow[j, 2] += x2
                x[s, 0, c], x[s, 1, c], x[s, 2, c] = x0, x1, x2
        if use_r:
            r0, r1, r2 = r[s, 0], r[s, 1], r[s, 2]
            k0r, k1r, k2r = rrw[s, 0] * sqdt, rrw[s, 1] * sqdt, rrw[s, 2] * sqdt
            for j in range(L):
                if k0 + j > 0:
                    r0 += k0r * zr[s, j, 0]
                    r1 += k1r * zr[s, j, 1]
                    r2 += k2r * zr[s, j, 2]
                slow[j, 0] += r0
                slow[j, 1] += r1
                slow[j, 2] += r2
            r[s, 0], r[s, 1], r[s, 2] = r0, r1, r2
        if use_t:
            t0, t1, t2 = tb[s, 0], tb[s, 1], tb[s, 2]
            for j in range(L):
                slow[j, 0] += t0 * dT[j + 1]
                slow[j, 1] += t1 * dT[j + 1]
                slow[j, 2] += t2 * dT[j + 1]
        # pass 2: measurements. Error matrix E = diag(sf) + cross-coupling, g-sensitivity G
        sf0, sf1, sf2 = sf[s, 0], sf[s, 1], sf[s, 2]
        ts0, ts1, ts2 = ts[s, 0], ts[s, 1], ts[s, 2]
        c01, c02, c10 = cc[s, 0, 1], cc[s, 0, 2], cc[s, 1, 0]
        c12, c20, c21 = cc[s, 1, 2], cc[s, 2, 0], cc[s, 2, 1]
        g00, g01, g02 = gs[s, 0, 0], gs[s, 0, 1], gs[s, 0, 2]
        g10, g11, g12 = gs[s, 1, 0], gs[s, 1, 1], gs[s, 1, 2]
        g20, g21, g22 = gs[s, 2, 0], gs[s, 2, 1], gs[s, 2, 2]
        wr0, wr1, wr2 = white[s, 0] / sqdt, white[s, 1] / sqdt, white[s, 2] / sqdt
        wi0, wi1, wi2 = white[s, 0] * sqdt, white[s, 1] * sqdt, white[s, 2] * sqdt
        p0, p1, p2 = s_prev[s, 0], s_prev[s, 1], s_prev[s, 2]
        qr0, qr1, qr2 = q_rate[s, 0], q_rate[s, 1], q_rate[s, 2]
        qi0, qi1, qi2 = q_inc[s, 0], q_inc[s, 1], q_inc[s, 2]
        for j in range(L):
            Tn = dT[j + 1] if use_t else 0.0
            sl0, sl1, sl2 = slow[j, 0], slow[j, 1], slow[j, 2]
            if do_bias:
                out_bias[s, j, 0] = sl0
                out_bias[s, j, 1] = sl1
                out_bias[s, j, 2] = sl2
            if do_sf:
                out_sf[s, j, 0] = sf0 + ts0 * Tn
                out_sf[s, j, 1] = sf1 + ts1 * Tn
                out_sf[s, j, 2] = sf2 + ts2 * Tn
            if do_rate:
                u0, u1, u2 = u[j, 0], u[j, 1], u[j, 2]
                e0 = (sf0 + ts0 * Tn) * u0 + c01 * u1 + c02 * u2
                e1 = (sf1 + ts1 * Tn) * u1 + c10 * u0 + c12 * u2
                e2 = (sf2 + ts2 * Tn) * u2 + c20 * u0 + c21 * u1
                if use_g:
                    a0, a1, a2 = a[j, 0], a[j, 1], a[j, 2]
                    e0 = e0 + g00 * a0 + g01 * a1 + g02 * a2
                    e1 = e1 + g10 * a0 + g11 * a1 + g12 * a2
                    e2 = e2 + g20 * a0 + g21 * a1 + g22 * a2
                y0 = u0 + e0 + sl0
                y1 = u1 + e1 + sl1
                y2 = u2 + e2 + sl2
                if use_w:
                    y0 += wr0 * zw[s, j, 0]
                    y1 += wr1 * zw[s, j, 1]
                    y2 += wr2 * zw[s, j, 2]
                c0 = min(max(y0, -full_scale), full_scale)
                c1 = min(max(y1, -full_scale), full_scale)
                c2 = min(max(y2, -full_scale), full_scale)
                if do_er:
                    out_err_rate[s, j, 0] = (e0 + sl0) + (c0 - y0)
                    out_err_rate[s, j, 1] = (e1 + sl1) + (c1 - y1)
                    out_err_rate[s, j, 2] = (e2 + sl2) + (c2 - y2)
                if lsb > 0.0:
                    qr0, c0 = quantize(qr0, c0, lsb)
                    qr1, c1 = quantize(qr1, c1, lsb)
                    qr2, c2 = quantize(qr2, c2, lsb)
                out_rate[s, j, 0] = c0
                out_rate[s, j, 1] = c1
                out_rate[s, j, 2] = c2
            if do_inc:
                if k0 + j == 0:
                    for i in range(3):
                        out_inc[s, j, i] = 0.0
                        if do_ei:
                            out_err_inc[s, j, i] = 0.0
                else:
                    Tm = 0.5 * (dT[j] + dT[j + 1]) if use_t else 0.0
                    v0, v1, v2 = du[j, 0], du[j, 1], du[j, 2]
                    e0 = (sf0 + ts0 * Tm) * v0 + c01 * v1 + c02 * v2
                    e1 = (sf1 + ts1 * Tm) * v1 + c10 * v0 + c12 * v2
                    e2 = (sf2 + ts2 * Tm) * v2 + c20 * v0 + c21 * v1
                    if use_g:
                        a0, a1, a2 = da[j, 0], da[j, 1], da[j, 2]
                        e0 = e0 + g00 * a0 + g01 * a1 + g02 * a2
                        e1 = e1 + g10 * a0 + g11 * a1 + g12 * a2
                        e2 = e2 + g20 * a0 + g21 * a1 + g22 * a2
                    e0 = e0 + 0.5 * (p0 + sl0) * dt
                    e1 = e1 + 0.5 * (p1 + sl1) * dt
                    e2 = e2 + 0.5 * (p2 + sl2) * dt
                    y0 = v0 + e0
                    y1 = v1 + e1
                    y2 = v2 + e2
                    if use_w:
                        y0 += wi0 * zw[s, j, 0]
                        y1 += wi1 * zw[s, j, 1]
                        y2 += wi2 * zw[s, j, 2]
                    c0 = min(max(y0, -fs_i), fs_i)
                    c1 = min(max(y1, -fs_i), fs_i)
                    c2 = min(max(y2, -fs_i), fs_i)
                    if do_ei:
                        out_err_inc[s, j, 0] = e0 + (c0 - y0)
                        out_err_inc[s, j, 1] = e1 + (c1 - y1)
                        out_err_inc[s, j, 2] = e2 + (c2 - y2)
                    if lsb_i > 0.0:
                        qi0, c0 = quantize(qi0, c0, lsb_i)
                        qi1, c1 = quantize(qi1, c1, lsb_i)
                        qi2, c2 = quantize(qi2, c2, lsb_i)
                    out_inc[s, j, 0] = c0
                    out_inc[s, j, 1] = c1
                    out_inc[s, j, 2] = c2
            p0, p1, p2 = sl0, sl1, sl2
        q_rate[s, 0], q_rate[s, 1], q_rate[s, 2] = qr0, qr1, qr2
        q_inc[s, 0], q_inc[s, 1], q_inc[s, 2] = qi0, qi1, qi2
        s_prev[s, 0], s_prev[s, 1], s_prev[s, 2] = p0, p1, p2


@njit(cache=True)
def kernel_increments(k0, dt, du, da, zw, zr, zb, use_w, use_r, use_b, b_on, bi_sig, bi_phi, bi_drv,
                      white, rrw, sf, cc, gs, use_g, ts, lsb, full_scale, x, r, s_prev, q_inc,
                      out_inc):  # fmt: skip
    """:func:`kernel` for the common case, increments only: no rate, series or temperature
    outputs, at most one Gauss-Markov component. One pass per sequence with the slow bias's
    recursions, the error matrix and the quantization residuals in registers; the same
    operations in the same order, hence the same bits as :func:`kernel`."""
    S = b_on.shape[0]
    L = du.shape[0]
    sqdt = math.sqrt(dt)
    lsb_i = lsb * dt
    fs_i = full_scale * dt
    for s in range(S):
        b0, b1, b2 = b_on[s, 0], b_on[s, 1], b_on[s, 2]
        phi, d0, d1, d2 = 0.0, 0.0, 0.0, 0.0
        x0, x1, x2 = 0.0, 0.0, 0.0
        if use_b:
            phi = bi_phi[s, 0]
            d0, d1, d2 = bi_drv[s, 0, 0], bi_drv[s, 1, 0], bi_drv[s, 2, 0]
            x0, x1, x2 = x[s, 0, 0], x[s, 1, 0], x[s, 2, 0]
        r0, r1, r2 = r[s, 0], r[s, 1], r[s, 2]
        k0r, k1r, k2r = rrw[s, 0] * sqdt, rrw[s, 1] * sqdt, rrw[s, 2] * sqdt
        # the general kernel's scale factor at zero temperature offset, signed zeros included
        sf0, sf1, sf2 = (
            sf[s, 0] + ts[s, 0] * 0.0,
            sf[s, 1] + ts[s, 1] * 0.0,
            sf[s, 2] + ts[s, 2] * 0.0,
        )
        c01, c02, c10 = cc[s, 0, 1], cc[s, 0, 2], cc[s, 1, 0]
        c12, c20, c21 = cc[s, 1, 2], cc[s, 2, 0], cc[s, 2, 1]
        g00, g01, g02 = gs[s, 0, 0], gs[s, 0, 1], gs[s, 0, 2]
        g10, g11, g12 = gs[s, 1, 0], gs[s, 1, 1], gs[s, 1, 2]
        g20, g21, g22 = gs[s, 2, 0], gs[s, 2, 1], gs[s, 2, 2]
        wi0, wi1, wi2 = white[s, 0] * sqdt, white[s, 1] * sqdt, white[s, 2] * sqdt
        p0, p1, p2 = s_prev[s, 0], s_prev[s, 1], s_prev[s, 2]
        qi0, qi1, qi2 = q_inc[s, 0], q_inc[s, 1], q_inc[s, 2]
        j0 = 0
        if k0 == 0 and L > 0:  # sample 0: the processes start, the increment row is zero
            p0, p1, p2 = b0, b1, b2
            if use_b:  # from the stationary law (bi_sig: its standard deviation)
                x0 = bi_sig[s, 0, 0] * zb[s, 0, 0]
                x1 = bi_sig[s, 1, 0] * zb[s, 0, 1]
                x2 = bi_sig[s, 2, 0] * zb[s, 0, 2]
                p0, p1, p2 = p0 + x0, p1 + x1, p2 + x2
            if use_r:
                p0, p1, p2 = p0 + r0, p1 + r1, p2 + r2
            out_inc[s, 0, 0] = 0.0
            out_inc[s, 0, 1] = 0.0
            out_inc[s, 0, 2] = 0.0
            j0 = 1
        for j in range(j0, L):
            sl0, sl1, sl2 = b0, b1, b2
            if use_b:
                x0 = phi * x0 + d0 * zb[s, j, 0]
                x1 = phi * x1 + d1 * zb[s, j, 1]
                x2 = phi * x2 + d2 * zb[s, j, 2]
                sl0, sl1, sl2 = sl0 + x0, sl1 + x1, sl2 + x2
            if use_r:
                r0 += k0r * zr[s, j, 0]
                r1 += k1r * zr[s, j, 1]
                r2 += k2r * zr[s, j, 2]
                sl0, sl1, sl2 = sl0 + r0, sl1 + r1, sl2 + r2
            v0, v1, v2 = du[j, 0], du[j, 1], du[j, 2]
            e0 = sf0 * v0 + c01 * v1 + c02 * v2
            e1 = sf1 * v1 + c10 * v0 + c12 * v2
            e2 = sf2 * v2 + c20 * v0 + c21 * v1
            if use_g:
                a0, a1, a2 = da[j, 0], da[j, 1], da[j, 2]
                e0 = e0 + g00 * a0 + g01 * a1 + g02 * a2
                e1 = e1 + g10 * a0 + g11 * a1 + g12 * a2
                e2 = e2 + g20 * a0 + g21 * a1 + g22 * a2
            e0 = e0 + 0.5 * (p0 + sl0) * dt
            e1 = e1 + 0.5 * (p1 + sl1) * dt
            e2 = e2 + 0.5 * (p2 + sl2) * dt
            y0 = v0 + e0
            y1 = v1 + e1
            y2 = v2 + e2
            if use_w:
                y0 += wi0 * zw[s, j, 0]
                y1 += wi1 * zw[s, j, 1]
                y2 += wi2 * zw[s, j, 2]
            c0 = min(max(y0, -fs_i), fs_i)
            c1 = min(max(y1, -fs_i), fs_i)
            c2 = min(max(y2, -fs_i), fs_i)
            if lsb_i > 0.0:
                qi0, c0 = quantize(qi0, c0, lsb_i)
                qi1, c1 = quantize(qi1, c1, lsb_i)
                qi2, c2 = quantize(qi2, c2, lsb_i)
            out_inc[s, j, 0] = c0
            out_inc[s, j, 1] = c1
            out_inc[s, j, 2] = c2
            p0, p1, p2 = sl0, sl1, sl2
        if use_b:
            x[s, 0, 0], x[s, 1, 0], x[s, 2, 0] = x0, x1, x2
        r[s, 0], r[s, 1], r[s, 2] = r0, r1, r2
        s_prev[s, 0], s_prev[s, 1], s_prev[s, 2] = p0, p1, p2
        q_inc[s, 0], q_inc[s, 1], q_inc[s, 2] = qi0, qi1, qi2


@njit(cache=True)
def quantize_series(y, q, rounding, res):
    """Quantize ``y`` ``(S, L, 3)`` in place to the step ``q`` (0: off): each sample rounded
    on its own (``rounding``) or with the residual ``res`` ``(S, 3)`` carried (:func:`quantize`)."""
    if q <= 0.0:
        return
    S, L = y.shape[0], y.shape[1]
    for s in range(S):
        for i in range(3):
            r = res[s, i]
            for j in range(L):
                if rounding:
                    y[s, j, i] = q * math.floor(y[s, j, i] / q + 0.5)
                else:
                    r, y[s, j, i] = quantize(r, y[s, j, i], q)
            res[s, i] = r
