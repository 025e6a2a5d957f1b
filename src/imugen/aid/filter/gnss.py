"""GNSS position and velocity updates (loosely coupled), with the antenna's lever arm.

The fix is the antenna's position ``p + C l_b (+ b_gnss)`` and velocity ``v + C (omega x
l_b)`` (``omega`` the body rate relative to n: ``C (omega_ib x l) - Omega x (C l)``) taken back
to the fix's time of validity (``- v L + a L^2 / 2`` and ``- a L``, ``a`` the acceleration of
the last IMU interval, ``L`` the latency when ``Options.latency``). One scalar update per axis,
position then velocity (``Options.use_velocity``); sensitivities ``dp - [(C l) x] psi - L dv
(+ db_gnss)`` and ``dv - [(C (omega x l)) x] psi + C [l x] db_g``. With GNSS bias states the
reported sigma is split between the white part (``R``) and the modelled bias in the tuning's
proportions; without them ``R`` is the reported variance.

In ``geodetic`` (n = ECEF) the receiver's errors are independent along East, North, Up at the
antenna, not along ECEF axes: each scalar update is one local axis (rows of ``C_le`` at the
predicted antenna applied to the residual and the sensitivities), which is the update with the
full ECEF covariance ``C_el diag(s^2) C_le``; the GNSS bias states are along the local axes.
"""

from __future__ import annotations

from imugen.aid.filter.geometry import local_level_nb, skew
from imugen.aid.filter.kalman import F_REJECT, clear, put, scalar_update
from imugen.aid.filter.tuning import T_GB_SD, T_GW
from imugen.core import earth
from imugen.core.jit import njit

F_GNSS_P, F_GNSS_V = 1, 2
"""Epoch flags: GNSS position, velocity updates applied."""


@njit(cache=True)
def antenna(e, md, inp, x, wk):
    """The fix's prediction at epoch ``e``: antenna position ``pred`` and velocity ``predv``
    at the time of validity (n, m and m/s), ``C l``, ``C (omega x l)`` (relative to n) and the
    latency ``L`` [s]; tuples of 3 floats but ``L``."""
    C, s, ix, prm = wk.C, e.s, md.ix, md.prm
    w0, w1, w2 = prm[earth.P_OMEGA], prm[earth.P_OMEGA + 1], prm[earth.P_OMEGA + 2]
    wbx, wby, wbz = e.w_b
    lx, ly, lz = inp.lever[s, 0], inp.lever[s, 1], inp.lever[s, 2]
    # C l and C (w x l)
    cl0 = C[0, 0] * lx + C[0, 1] * ly + C[0, 2] * lz
    cl1 = C[1, 0] * lx + C[1, 1] * ly + C[1, 2] * lz
    cl2 = C[2, 0] * lx + C[2, 1] * ly + C[2, 2] * lz
    cwx = wby * lz - wbz * ly
    cwy = wbz * lx - wbx * lz
    cwz = wbx * ly - wby * lx
    # C ((w_ib - C^T Omega) x l) = C (w_ib x l) - Omega x (C l)
    cw0 = C[0, 0] * cwx + C[0, 1] * cwy + C[0, 2] * cwz - (w1 * cl2 - w2 * cl1)
    cw1 = C[1, 0] * cwx + C[1, 1] * cwy + C[1, 2] * cwz - (w2 * cl0 - w0 * cl2)
    cw2 = C[2, 0] * cwx + C[2, 1] * cwy + C[2, 2] * cwz - (w0 * cl1 - w1 * cl0)
    L = inp.lat[s] if md.opt.latency else 0.0
    px, py, pz = x[ix.p], x[ix.p + 1], x[ix.p + 2]
    vx, vy, vz = x[ix.v], x[ix.v + 1], x[ix.v + 2]
    acx, acy, acz = wk.acc[0], wk.acc[1], wk.acc[2]
    # antenna at t - L, second order: p - L v + L^2/2 a
    hL = 0.5 * L * L
    pred = (
        px + cl0 - L * (vx + cw0) + hL * acx,
        py + cl1 - L * (vy + cw1) + hL * acy,
        pz + cl2 - L * (vz + cw2) + hL * acz,
    )
    predv = (vx + cw0 - L * acx, vy + cw1 - L * acy, vz + cw2 - L * acz)
    return pred, predv, (cl0, cl1, cl2), (cw0, cw1, cw2), L


@njit(cache=True, inline="always")
def _split_variance(var, tn, a):
    """The white part of the reported variance of axis ``a`` (with bias states)."""
    wsd = tn[T_GW + a]
    tot = wsd * wsd + tn[T_GB_SD + a] ** 2
    return var * (wsd * wsd / tot) if tot > 0.0 else var


@njit(cache=True)
def position_row(e, md, inp, x, wk, tn, a, pred, cl, L):
    """Row of axis ``a`` (n) of the position fix: fills ``wk.h``; returns ``(m, r, var)``."""
    ie = md.ie
    m = clear(wk)
    # dp - [(C l) x] psi (+ gnss bias); row a of -[c x]: (a, b1) = c[b2], (a, b2) = -c[b1]
    b1 = (a + 1) % 3
    b2 = (a + 2) % 3
    m = put(wk, m, ie.p + a, 1.0)
    m = put(wk, m, ie.att + b1, cl[b2])
    m = put(wk, m, ie.att + b2, -cl[b1])
    if L > 0.0:  # the fix is p(t - L) = p - L v: velocity error enters too
        m = put(wk, m, ie.v + a, -L)
    var = inp.sp[e.s, e.j, a] ** 2
    r = pred[a] - inp.zp[e.s, e.j, a]
    if ie.gnss_bias >= 0:
        m = put(wk, m, ie.gnss_bias + a, 1.0)
        r += x[md.ix.gnss_bias + a]
        var = _split_variance(var, tn, a)
    return m, r, max(var, 1e-12)


@njit(cache=True)
def velocity_row(e, md, inp, x, wk, a, predv, cw):
    """Row of axis ``a`` (n) of the velocity fix: fills ``wk.h``; returns ``(m, r, var)``."""
    ie, C, s = md.ie, wk.C, e.s
    lx, ly, lz = inp.lever[s, 0], inp.lever[s, 1], inp.lever[s, 2]
    m = clear(wk)
    b1 = (a + 1) % 3
    b2 = (a + 2) % 3
    m = put(wk, m, ie.v + a, 1.0)
    m = put(wk, m, ie.att + b1, cw[b2])
    m = put(wk, m, ie.att + b2, -cw[b1])
    # d(C (w x l))/d dbg = C [l x] (w_hat = w - dbg): columns C (l x e_b)
    for b in range(3):
        eb0 = 1.0 if b == 0 else 0.0
        eb1 = 1.0 if b == 1 else 0.0
        eb2 = 1.0 if b == 2 else 0.0
        lxe0 = ly * eb2 - lz * eb1
        lxe1 = lz * eb0 - lx * eb2
        lxe2 = lx * eb1 - ly * eb0
        m = put(wk, m, ie.bg + b, C[a, 0] * lxe0 + C[a, 1] * lxe1 + C[a, 2] * lxe2)
    var = max(inp.sv[s, e.j, a] ** 2, 1e-12)
    return m, predv[a] - inp.zv[s, e.j, a], var


@njit(cache=True)
def position_row_local(e, md, inp, x, wk, tn, a, pred, cl, L):
    """Row of local axis ``a`` (E, N, U at the antenna, rows of ``wk.Lm``) of the position fix
    in ``geodetic``: fills ``wk.h``; returns ``(m, r, var)``."""
    ie, Lm, Xc = md.ie, wk.Lm, wk.Xc
    skew(cl[0], cl[1], cl[2], Xc)
    m = clear(wk)
    r = 0.0
    for c in range(3):
        r += Lm[a, c] * (pred[c] - inp.zp[e.s, e.j, c])
    for c in range(3):
        wk.h[ie.p + c] = Lm[a, c]
        wk.hz[c] = ie.p + c
        # dp - [(C l) x] psi - Lat dv
        acc = 0.0
        for f in range(3):
            acc -= Lm[a, f] * Xc[f, c]
        wk.h[ie.att + c] = acc
        wk.hz[3 + c] = ie.att + c
    m = 6
    if L > 0.0:
        for c in range(3):
            m = put(wk, m, ie.v + c, -L * Lm[a, c])
    var = inp.sp[e.s, e.j, a] ** 2
    if ie.gnss_bias >= 0:
        m = put(wk, m, ie.gnss_bias + a, 1.0)
        r += x[md.ix.gnss_bias + a]
        var = _split_variance(var, tn, a)
    return m, r, max(var, 1e-12)


@njit(cache=True)
def velocity_row_local(e, md, inp, x, wk, a, predv, cw):
    """Row of local axis ``a`` of the velocity fix in ``geodetic``: fills ``wk.h``; returns
    ``(m, r, var)``."""
    ie, Lm, Xc, C = md.ie, wk.Lm, wk.Xc, wk.C
    lx, ly, lz = inp.lever[e.s, 0], inp.lever[e.s, 1], inp.lever[e.s, 2]
    skew(cw[0], cw[1], cw[2], Xc)
    clear(wk)
    r = 0.0
    for c in range(3):
        r += Lm[a, c] * (predv[c] - inp.zv[e.s, e.j, c])
    for c in range(3):
        wk.h[ie.v + c] = Lm[a, c]
        wk.hz[c] = ie.v + c
        acc = 0.0
        for f in range(3):
            acc -= Lm[a, f] * Xc[f, c]
        wk.h[ie.att + c] = acc
        wk.hz[3 + c] = ie.att + c
        # d(C (w x l))/d dbg = C [l x] (w_hat = w - dbg)
        eb0 = 1.0 if c == 0 else 0.0
        eb1 = 1.0 if c == 1 else 0.0
        eb2 = 1.0 if c == 2 else 0.0
        lxe0 = ly * eb2 - lz * eb1
        lxe1 = lz * eb0 - lx * eb2
        lxe2 = lx * eb1 - ly * eb0
        acc = 0.0
        for f in range(3):
            acc += Lm[a, f] * (C[f, 0] * lxe0 + C[f, 1] * lxe1 + C[f, 2] * lxe2)
        wk.h[ie.bg + c] = acc
        wk.hz[6 + c] = ie.bg + c
    return 9, r, max(inp.sv[e.s, e.j, a] ** 2, 1e-12)


@njit(cache=True)
def update(e, md, inp, wk, x, tn, win):
    """GNSS updates at epoch ``e`` when its fix is usable; returns the flag bits."""
    if not inp.ok[e.s, e.j]:
        return 0
    pred, predv, cl, cw, L = antenna(e, md, inp, x, wk)
    gate = md.opt.gate
    flag = 0
    if md.geo:
        local_level_nb(pred[0], pred[1], pred[2], wk.Lm)
    for a in range(3):
        if md.geo:
            m, r, var = position_row_local(e, md, inp, x, wk, tn, a, pred, cl, L)
        else:
            m, r, var = position_row(e, md, inp, x, wk, tn, a, pred, cl, L)
        flag |= F_GNSS_P if scalar_update(wk, m, r, var, gate) else F_REJECT
    if not md.opt.use_velocity:
        return flag
    for a in range(3):
        if md.geo:
            m, r, var = velocity_row_local(e, md, inp, x, wk, a, predv, cw)
        else:
            m, r, var = velocity_row(e, md, inp, x, wk, a, predv, cw)
        flag |= F_GNSS_V if scalar_update(wk, m, r, var, gate) else F_REJECT
    return flag
