"""The error state's propagation between two epochs: ``P <- Phi P Phi^T + Q``.

Error state (estimate minus truth; blocks of :mod:`imugen.aid.filter.state`): ``dp, dv`` [m,
m/s] in n; ``psi`` [rad] with ``C_hat = Exp(psi) C``; gyro and accelerometer bias errors;
optionally the GNSS receiver's Gauss-Markov position bias (E, N, U), gyro and accelerometer
scale-factor errors, the odometer scale factor and the barometer drift (companions), the IMU's
pitch and yaw misalignment from the vehicle and the NHC lever arm (constants, NHC only), the
gyro's six cross-coupling elements (constants, ``psi' = ... - C cc omega``) and the odometer's
tick residuals at the start and end of its window [m]. Continuous model

* ``dp' = dv``;
* ``dv' = -[f_n x] psi - C (db_a + diag(f) ds_a) - 2 Omega x dv + Gamma dp``;
* ``psi' = -Omega x psi - C (db_g + diag(omega) ds_g)``;
* biases random walks; scale factors random walks (``sf_q``); GNSS bias and barometer drift
  first-order Gauss-Markov (their nominal means decay with the same factor); the others
  constant.

The transition over one interval ``T`` uses the integrals accumulated by the strapdown
(:func:`imugen.aid.filter.propagate.strapdown`: ``int C dt``, ``int C f dt``, ``int C diag(f)
dt``, ``int C diag(omega) dt``), second order in ``T`` for the position rows; ``Gamma`` is
the gravity gradient ``g/R diag(-1, -1, 2)`` (``wgs84``; ``g/R (3 u u^T - I)`` with ``u`` the
geocentric vertical at the vehicle in ``geodetic``). The process noise is the tuning's
(:mod:`imugen.aid.filter.tuning`): white noise and random walks on the diagonal, the white
specific force's ``T^3/3``, ``T^2/2`` into position, and the motion-dependent noise
(:func:`motion_noise`).

``Phi`` is sparse: :func:`transition_pattern` lists the columns that may be non-zero in each
row once per kernel call, and ``Phi P Phi^T`` is two sparse-row products.
"""

from __future__ import annotations

import math

import numpy as np

from imugen.aid.filter.geometry import dcm, skew
from imugen.aid.filter.tuning import (
    T_BB_SD,
    T_BB_TAU,
    T_GB_SD,
    T_GB_TAU,
    T_MCA,
    T_MCG,
    T_MGS,
    T_MSA,
    T_MSG,
    T_MTAU,
    T_NA,
    T_NG,
    T_QBA,
    T_QBG,
    T_QS,
)  # fmt: skip
from imugen.core import earth
from imugen.core.jit import njit, njit_borrowing


@njit(cache=True, inline="always")
def _mark(cols, i0, size):
    for k in range(i0, i0 + size):
        cols[k] = True


@njit(cache=True)
def transition_pattern(ie, wgs, nnz, nzc):
    """Columns that may be non-zero in each row of ``Phi`` (ascending): ``nzc[i, :nnz[i]]``.

    Position and velocity rows: velocity, attitude, biases (and scale factors; velocity rows
    also position in a rotating Earth); attitude rows: attitude, gyro bias (gyro scale
    factor, cross-coupling); the other rows only their diagonal.
    """
    n = nnz.shape[0]
    sf_on = ie.sg >= 0
    for i in range(n):
        cols = np.zeros(n, np.bool_)
        cols[i] = True
        if ie.p <= i < ie.p + 3 or ie.v <= i < ie.v + 3:
            for b in (ie.v, ie.att, ie.bg, ie.ba):
                _mark(cols, b, 3)
            if wgs and ie.v <= i < ie.v + 3:
                _mark(cols, ie.p, 3)
            if sf_on:
                _mark(cols, ie.sg, 3)
                _mark(cols, ie.sa, 3)
            if ie.ca >= 0:
                _mark(cols, ie.ca, 6)
        elif ie.att <= i < ie.att + 3:
            _mark(cols, ie.att, 3)
            _mark(cols, ie.bg, 3)
            if sf_on:
                _mark(cols, ie.sg, 3)
            if ie.cc >= 0:
                _mark(cols, ie.cc, 6)
        m = 0
        for k in range(n):
            if cols[k]:
                nzc[i, m] = k
                m += 1
        nnz[i] = m


@njit_borrowing(cache=True, inline="always")
def _sparse_rows_times(Phi, nnz, nzc, P, T, n):
    """``T = Phi P`` using only the ``nnz[i]`` non-zero columns ``nzc[i, :]`` of each row of Phi."""
    for i in range(n):
        for j in range(n):
            T[i, j] = 0.0
        for m in range(nnz[i]):
            c = nzc[i, m]
            f = Phi[i, c]
            for j in range(n):
                T[i, j] += f * P[c, j]


@njit_borrowing(cache=True, inline="always")
def motion_axis(tn, i, ti, di, t2, d2, sf_on, cg_on, ca_on):
    """Gyro variance of body axis ``i`` along the rotation (times ``|t|^2``) and
    accelerometer variance of axis ``i`` over one interval (see :func:`motion_noise`)."""
    sg = 0.0 if sf_on else tn[T_MSG + i] ** 2
    sa = 0.0 if sf_on else tn[T_MSA + i] ** 2
    cg = 0.0 if cg_on else tn[T_MCG + i] ** 2
    vi = sg * ti * ti + cg * (t2 - ti * ti)
    ca = 0.0 if ca_on else tn[T_MCA + i] ** 2
    va = sa * di * di + ca * (d2 - di * di)
    return vi, va


@njit_borrowing(cache=True)
def motion_noise(P, ie, C, tx, ty, tz, ux, uy, uz, tn, T, sf_on, cg_on, ca_on=False):
    """Add the motion-dependent process noise of one interval of length ``T`` to ``P``
    (:mod:`imugen.aid.filter.tuning`).

    ``t`` (body) the corrected angle increment over the interval, ``u`` (n) the kinematic
    velocity change (specific force plus gravitation, integrated), ``d = C^T u``,
    ``c = max(1, tau / T)``, ``v_i = s_g,i^2 t_i^2 + cc_g,i^2 (|t|^2 - t_i^2)``. Gyro: along
    the rotation axis ``e = C t / |t|`` the variance ``c sum_i (t_i / |t|)^2 v_i`` (rank one),
    across it ``(sum_i v_i - v_par) / 2`` per axis, plus ``c sum_i G_i^2 |d|^2 / 3`` per axis
    (g-sensitivity). Accelerometer per body axis ``c (s_a,i^2 d_i^2 + cc_a,i^2 (|d|^2 -
    d_i^2))``, rotated to n, into velocity and (``T^2/3``, ``T/2``) position. Scale-factor
    (cross-coupling) terms are left out when they are states.
    """
    ip, iv, ia = ie.p, ie.v, ie.att
    dx = C[0, 0] * ux + C[1, 0] * uy + C[2, 0] * uz
    dy = C[0, 1] * ux + C[1, 1] * uy + C[2, 1] * uz
    dz = C[0, 2] * ux + C[1, 2] * uy + C[2, 2] * uz
    t2 = tx * tx + ty * ty + tz * tz
    d2 = dx * dx + dy * dy + dz * dz
    c = max(1.0, tn[T_MTAU] / T)
    vg0, va0 = motion_axis(tn, 0, tx, dx, t2, d2, sf_on, cg_on, ca_on)
    vg1, va1 = motion_axis(tn, 1, ty, dy, t2, d2, sf_on, cg_on, ca_on)
    vg2, va2 = motion_axis(tn, 2, tz, dz, t2, d2, sf_on, cg_on, ca_on)
    # along the rotation: c vpar e e^T with e = C t / |t|, i.e. c vpar / |t|^2 (C t)(C t)^T
    vpar = (tx * tx * vg0 + ty * ty * vg1 + tz * tz * vg2) / t2 if t2 > 0.0 else 0.0
    vperp = (vg0 + vg1 + vg2 - vpar) / 2.0  # per axis across the rotation, uncorrelated
    kpar = (c * vpar - vperp) / t2 if t2 > 0.0 else 0.0
    e0 = C[0, 0] * tx + C[0, 1] * ty + C[0, 2] * tz
    e1 = C[1, 0] * tx + C[1, 1] * ty + C[1, 2] * tz
    e2 = C[2, 0] * tx + C[2, 1] * ty + C[2, 2] * tz
    ev = (e0, e1, e2)
    viso = c * (tn[T_MGS] ** 2 + tn[T_MGS + 1] ** 2 + tn[T_MGS + 2] ** 2) * d2 / 3.0
    viso += vperp
    va0, va1, va2 = c * va0, c * va1, c * va2
    for a in range(3):
        for b in range(3):
            qa = C[a, 0] * C[b, 0] * va0 + C[a, 1] * C[b, 1] * va1 + C[a, 2] * C[b, 2] * va2
            P[ia + a, ia + b] += kpar * ev[a] * ev[b]
            P[iv + a, iv + b] += qa
            P[ip + a, iv + b] += 0.5 * T * qa
            P[iv + a, ip + b] += 0.5 * T * qa
            P[ip + a, ip + b] += T * T * qa / 3.0
        P[ia + a, ia + a] += viso


@njit_borrowing(cache=True)
def propagate_covariance(md, tn, wk, x, steps):
    """``P <- Phi P Phi^T + Q`` over ``steps`` IMU intervals just integrated by the strapdown
    (its integrals in ``wk``; ``x`` the nominal state at the interval's end), and the decay
    of the Gauss-Markov states' nominal means over the interval. ``tn`` (N_TUNE,): the
    sequence's tuning."""
    ie, dt = md.ie, md.dt
    P, Phi, T, qdiag, Xm = wk.P, wk.Phi, wk.T, wk.qdiag, wk.Xm
    Cint, Cf, Cw, Ccc, dvn = wk.Cint, wk.Cf, wk.Cw, wk.Ccc, wk.dvn
    n = P.shape[0]
    ip, iv, ia, ig, iba = ie.p, ie.v, ie.att, ie.bg, ie.ba
    i_sg, i_sa, i_cg = ie.sg, ie.sa, ie.cc
    sf_on = i_sg >= 0
    Tint = steps * dt
    for i in range(n):
        for j in range(n):
            Phi[i, j] = 0.0
        Phi[i, i] = 1.0
        qdiag[i] = 0.0
    skew(dvn[0], dvn[1], dvn[2], Xm)  # [dv_n x]
    for a in range(3):
        Phi[ip + a, iv + a] = Tint
        for b in range(3):
            # -[dv x] and -int C
            Phi[iv + a, ia + b] = -Xm[a, b]
            Phi[ip + a, ia + b] = -0.5 * Tint * Xm[a, b]
            Phi[iv + a, iba + b] = -Cint[a, b]
            Phi[ip + a, iba + b] = -0.5 * Tint * Cint[a, b]
            Phi[ia + a, ig + b] = -Cint[a, b]
            # psi driven by gyro bias, then velocity by psi: +1/2 [dv x] int C
            acc = Xm[a, 0] * Cint[0, b] + Xm[a, 1] * Cint[1, b] + Xm[a, 2] * Cint[2, b]
            Phi[iv + a, ig + b] = 0.5 * acc
            Phi[ip + a, ig + b] = Tint * acc / 6.0
            if sf_on:
                Phi[iv + a, i_sa + b] = -Cf[a, b]
                Phi[ip + a, i_sa + b] = -0.5 * Tint * Cf[a, b]
                Phi[ia + a, i_sg + b] = -Cw[a, b]
        if i_cg >= 0:
            for m in range(6):
                Phi[ia + a, i_cg + m] = -Ccc[a, m]
        if ie.ca >= 0:  # as the accelerometer bias: -int C cc f dt, half T into position
            for m in range(6):
                Phi[iv + a, ie.ca + m] = -wk.Cca[a, m]
                Phi[ip + a, ie.ca + m] = -0.5 * Tint * wk.Cca[a, m]
    if md.wgs:
        w0, w1, w2 = md.prm[earth.P_OMEGA], md.prm[earth.P_OMEGA + 1], md.prm[earth.P_OMEGA + 2]
        skew(w0, w1, w2, Xm)  # [Omega x]
        for a in range(3):
            for b in range(3):
                Phi[iv + a, iv + b] -= 2.0 * Xm[a, b] * Tint
                Phi[ia + a, ia + b] -= Xm[a, b] * Tint
        R_gamma = md.prm[earth.P_G0] / earth.R_MEAN
        if md.geo:  # gravity gradient g/R (3 u u^T - I), u = r / |r| in ECEF
            px, py, pz = x[md.ix.p], x[md.ix.p + 1], x[md.ix.p + 2]
            ir = 1.0 / math.sqrt(px * px + py * py + pz * pz)
            ur = (px * ir, py * ir, pz * ir)
            for a in range(3):
                for b in range(3):
                    d = 3.0 * ur[a] * ur[b] - (1.0 if a == b else 0.0)
                    Phi[iv + a, ip + b] = R_gamma * Tint * d
        else:  # gravity gradient at the origin, local ENU: g/R diag(-1, -1, 2)
            Phi[iv, ip] = -R_gamma * Tint
            Phi[iv + 1, ip + 1] = -R_gamma * Tint
            Phi[iv + 2, ip + 2] = 2.0 * R_gamma * Tint
    for a in range(3):
        qa = tn[T_NA + a] ** 2
        qdiag[iv + a] = qa * Tint
        qdiag[ia + a] = tn[T_NG + a] ** 2 * Tint
        qdiag[ig + a] = tn[T_QBG + a] * Tint
        qdiag[iba + a] = tn[T_QBA + a] * Tint
    if ie.gnss_bias >= 0:
        i_gb = ie.gnss_bias
        phig = math.exp(-Tint / tn[T_GB_TAU])
        for a in range(3):
            Phi[i_gb + a, i_gb + a] = phig
            qdiag[i_gb + a] = tn[T_GB_SD + a] ** 2 * (1.0 - phig * phig)
            x[md.ix.gnss_bias + a] *= phig  # the mean decays likewise
    if sf_on:
        for a in range(6):
            qdiag[i_sg + a] = tn[T_QS] * Tint
    if ie.baro_bias >= 0:
        i_bb = ie.baro_bias
        phib = math.exp(-Tint / tn[T_BB_TAU])
        Phi[i_bb, i_bb] = phib
        qdiag[i_bb] = tn[T_BB_SD] ** 2 * (1.0 - phib * phib)
        x[md.ix.baro_bias] *= phib
    # P <- Phi (Phi P)^T (= Phi P Phi^T for symmetric P): two sparse-row products
    # with contiguous inner loops, then the transpose in between
    _sparse_rows_times(Phi, wk.nnz, wk.nzc, P, T, n)
    for i in range(n):
        for j in range(n):
            P[i, j] = T[j, i]
    _sparse_rows_times(Phi, wk.nnz, wk.nzc, P, T, n)
    for i in range(n):
        for j in range(i, n):
            acc = 0.5 * (T[i, j] + T[j, i])
            P[i, j] = acc
            P[j, i] = acc
        P[i, i] += qdiag[i]
    # white VRW also integrates into position over the interval
    for a in range(3):
        qa = tn[T_NA + a] ** 2
        P[ip + a, ip + a] += qa * Tint**3 / 3.0
        P[ip + a, iv + a] += qa * Tint**2 / 2.0
        P[iv + a, ip + a] += qa * Tint**2 / 2.0
    # motion-dependent noise (scale factor, cross-coupling, g-sensitivity)
    C = wk.C
    ia4 = md.ix.att
    dcm(x[ia4], x[ia4 + 1], x[ia4 + 2], x[ia4 + 3], C)
    motion_noise(
        P, ie, C, wk.th[0], wk.th[1], wk.th[2], dvn[0] + wk.g_n[0] * Tint,
        dvn[1] + wk.g_n[1] * Tint, dvn[2] + wk.g_n[2] * Tint, tn, Tint, sf_on, i_cg >= 0,
        ie.ca >= 0,
    )  # fmt: skip
