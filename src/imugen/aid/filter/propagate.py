"""Propagation of the nominal state between two epochs: the filter's own strapdown.

Frames, conventions and the strapdown are those of :mod:`imugen.navigate.mechanize` (n =
Earth-fixed ENU of the route origin in ``flat`` and ``wgs84``, ECEF in ``geodetic``: the same
rotating-frame step with ``Omega = (0, 0, Omega)`` and no transport rate); one step per IMU
interval: ``C_{k+1} = Exp(-Omega dt) C_k Exp(dtheta)``,
``A(dt) (v_{k+1} + W r_{k+1}) = v_k + W r_k + C_k dv + dt/2 (A G_{k+1} + G_k)`` (solved with
``(I + dt/2 W)^-1``; in ``flat`` exactly ``v_{k+1} = v_k + C_k dv + g dt``) and the trapezoid
for position. Increments are corrected with the estimated biases, scale factors and (when
states) the gyro cross-coupling, ``dtheta_hat = (dtheta - b_g dt) / (1 + s_g)`` (likewise
``dv``), ``- cc dtheta_hat`` to first order.

Over the interval the step accumulates what the error model's transition needs
(:mod:`imugen.aid.filter.error_model`: ``int C dt``, ``int C dv``, ``int C diag(dv)``, ``int C
diag(dtheta)``, the cross-coupling integrals, the corrected angle), tests the ZUPT
thresholds on every sample, and calls the windowed measurements' per-sample accumulators
(:func:`imugen.aid.filter.measurements.on_sample`).
"""

from __future__ import annotations

import math

import numpy as np

from imugen.aid.filter import measurements
from imugen.aid.filter.geometry import dcm, mv
from imugen.core import earth
from imugen.core.jit import njit_borrowing
from imugen.core.rotations_nb import qexpm1, qmul

# --- parameters of the strapdown step: the Earth model's (earth.N_PARAMS), then these slots ----
A_DT = earth.N_PARAMS  # dt
A_A = A_DT + 1  # A(dt) = Exp(W dt), 9 row-major
A_D = A_A + 9  # D = A(dt)^T - I, 9 (computed without cancellation)
A_MT = A_D + 9  # (I + dt/2 W)^{-1}, 9
A_QW = A_MT + 9  # quaternion of Exp(-Omega dt) minus (1, 0, 0, 0), 4
N_STEP_PARAMS = A_QW + 4


def step_params(frame, dt: float) -> np.ndarray:
    """Parameters of the filter's strapdown step: the Earth model's and precomputed rotations."""
    prm = np.zeros(N_STEP_PARAMS)
    prm[: earth.N_PARAMS] = frame.params()
    prm[A_DT] = dt
    w = np.asarray(earth.earth_rate_n(frame), float).reshape(3)
    wn = float(np.linalg.norm(w))
    W = np.array([[0.0, -w[2], w[1]], [w[2], 0.0, -w[0]], [-w[1], w[0], 0.0]])
    if wn > 0.0:
        th = wn * dt
        s1 = math.sin(th) / wn
        s2 = 2.0 * math.sin(th / 2.0) ** 2 / wn**2  # (1 - cos) / |w|^2
        A = np.eye(3) + s1 * W + s2 * (W @ W)
        D = -s1 * W + s2 * (W @ W)
        qw = np.array([-2.0 * math.sin(th / 4.0) ** 2, *(-math.sin(th / 2.0) * w / wn)])
    else:
        A, D, qw = np.eye(3), np.zeros((3, 3)), np.zeros(4)
    c = dt / 2.0
    MT = (np.eye(3) - c * W + c * c * np.outer(w, w)) / (1.0 + c * c * (w @ w))
    prm[A_A : A_A + 9] = A.ravel()
    prm[A_D : A_D + 9] = D.ravel()
    prm[A_MT : A_MT + 9] = MT.ravel()
    prm[A_QW : A_QW + 4] = qw
    return prm


@njit_borrowing(cache=True)
def gravitation(md, x):
    """Gravitation at the nominal position ``x`` (``(0, 0, -g0)`` in ``flat``) [m/s^2]."""
    if md.wgs:
        return earth.gravitation_nb(md.prm, x[md.ix.p], x[md.ix.p + 1], x[md.ix.p + 2])
    return 0.0, 0.0, -md.g0


@njit_borrowing(cache=True)
def strapdown(md, inp, s, k, ke, x, wk, win, fc):
    """Propagate the nominal state ``x`` of sequence ``s`` from sample ``k`` to ``ke``.

    ``fc`` (K, 6) or (0, 6): where the correction applied to each sample is stored (raw minus
    corrected increments), when not empty.

    Accumulates the interval's integrals in ``wk`` (``dvn``, ``Cint``, ``Cf``, ``Cw``, ``Ccc``,
    ``th``), the acceleration of its last IMU interval (``wk.acc``, the GNSS latency's) and
    carries the gravitation ``wk.g_n``; calls the windowed measurements' accumulators on every
    sample. Returns whether every sample passed the ZUPT thresholds (``False`` when
    ``ke == k``).
    """
    ix, ie, opt, prm = md.ix, md.ie, md.opt, md.prm
    dth, dvb = inp.dth, inp.dvb
    dt, g0, wgs = md.dt, md.g0, md.wgs
    sf_on = ie.sg >= 0
    cg_on = ie.cc >= 0
    ca_on = ie.ca >= 0
    w0, w1, w2 = prm[earth.P_OMEGA], prm[earth.P_OMEGA + 1], prm[earth.P_OMEGA + 2]
    dvn, Cint, Cf, Cw, Ccc, C = wk.dvn, wk.Cint, wk.Cf, wk.Cw, wk.Ccc, wk.C
    px, py, pz = x[ix.p], x[ix.p + 1], x[ix.p + 2]
    vx, vy, vz = x[ix.v], x[ix.v + 1], x[ix.v + 2]
    q0, q1, q2, q3 = x[ix.att], x[ix.att + 1], x[ix.att + 2], x[ix.att + 3]
    Gx, Gy, Gz = wk.g_n[0], wk.g_n[1], wk.g_n[2]
    for a in range(3):
        dvn[a] = 0.0
        for b in range(3):
            Cint[a, b] = 0.0
            Cf[a, b] = 0.0
            Cw[a, b] = 0.0
    still = ke > k
    thx, thy, thz = 0.0, 0.0, 0.0  # corrected angle over the interval (motion noise)
    if cg_on or ca_on:
        for a in range(3):
            for m in range(6):
                Ccc[a, m] = 0.0
                wk.Cca[a, m] = 0.0
    bgx, bgy, bgz = x[ix.bg], x[ix.bg + 1], x[ix.bg + 2]
    bax, bay, baz = x[ix.ba], x[ix.ba + 1], x[ix.ba + 2]
    sgx, sgy, sgz = x[ix.sg], x[ix.sg + 1], x[ix.sg + 2]
    sax, say, saz = x[ix.sa], x[ix.sa + 1], x[ix.sa + 2]
    ovx, ovy, ovz = vx, vy, vz
    measurements.begin_interval(win, md, inp, s, k, ke, x, wk)
    for i in range(k + 1, ke + 1):
        tx = (dth[s, i, 0] - bgx * dt) / (1.0 + sgx)
        ty = (dth[s, i, 1] - bgy * dt) / (1.0 + sgy)
        tz = (dth[s, i, 2] - bgz * dt) / (1.0 + sgz)
        ux = (dvb[s, i, 0] - bax * dt) / (1.0 + sax)
        uy = (dvb[s, i, 1] - bay * dt) / (1.0 + say)
        uz = (dvb[s, i, 2] - baz * dt) / (1.0 + saz)
        if cg_on:  # minus the estimated cross-coupling (first order)
            c = ix.cc
            ttx = tx - x[c] * ty - x[c + 1] * tz
            tty = ty - x[c + 2] * tx - x[c + 3] * tz
            tz = tz - x[c + 4] * tx - x[c + 5] * ty
            tx, ty = ttx, tty
        if ca_on:  # the accelerometer's likewise
            c = ix.ca
            uux = ux - x[c] * uy - x[c + 1] * uz
            uuy = uy - x[c + 2] * ux - x[c + 3] * uz
            uz = uz - x[c + 4] * ux - x[c + 5] * uy
            ux, uy = uux, uuy
        if fc.shape[0] > 0:
            fc[i, 0] = dth[s, i, 0] - tx
            fc[i, 1] = dth[s, i, 1] - ty
            fc[i, 2] = dth[s, i, 2] - tz
            fc[i, 3] = dvb[s, i, 0] - ux
            fc[i, 4] = dvb[s, i, 1] - uy
            fc[i, 5] = dvb[s, i, 2] - uz
        thx += tx
        thy += ty
        thz += tz
        if still:
            wn = math.sqrt(tx * tx + ty * ty + tz * tz) / dt
            fn = math.sqrt(ux * ux + uy * uy + uz * uz) / dt
            if wn > opt.zupt_gyro or abs(fn - g0) > opt.zupt_accel:
                still = False
        dcm(q0, q1, q2, q3, C)
        ax = C[0, 0] * ux + C[0, 1] * uy + C[0, 2] * uz
        ay = C[1, 0] * ux + C[1, 1] * uy + C[1, 2] * uz
        az = C[2, 0] * ux + C[2, 1] * uy + C[2, 2] * uz
        dvn[0] += ax
        dvn[1] += ay
        dvn[2] += az
        for a in range(3):
            Cint[a, 0] += C[a, 0] * dt
            Cint[a, 1] += C[a, 1] * dt
            Cint[a, 2] += C[a, 2] * dt
        if sf_on:
            for a in range(3):
                Cf[a, 0] += C[a, 0] * ux
                Cf[a, 1] += C[a, 1] * uy
                Cf[a, 2] += C[a, 2] * uz
                Cw[a, 0] += C[a, 0] * tx
                Cw[a, 1] += C[a, 1] * ty
                Cw[a, 2] += C[a, 2] * tz
        if cg_on:  # pairs (0,1) (0,2) (1,0) (1,2) (2,0) (2,1): C[:, row] t_col
            for a in range(3):
                Ccc[a, 0] += C[a, 0] * ty
                Ccc[a, 1] += C[a, 0] * tz
                Ccc[a, 2] += C[a, 1] * tx
                Ccc[a, 3] += C[a, 1] * tz
                Ccc[a, 4] += C[a, 2] * tx
                Ccc[a, 5] += C[a, 2] * ty
        if ca_on:  # the same pairs on the specific-force increment
            Cca = wk.Cca
            for a in range(3):
                Cca[a, 0] += C[a, 0] * uy
                Cca[a, 1] += C[a, 0] * uz
                Cca[a, 2] += C[a, 1] * ux
                Cca[a, 3] += C[a, 1] * uz
                Cca[a, 4] += C[a, 2] * ux
                Cca[a, 5] += C[a, 2] * uy
        ovx, ovy, ovz = vx, vy, vz
        if wgs:
            rx = prm[earth.P_R0N] + px
            ry = prm[earth.P_R0N + 1] + py
            rz = prm[earth.P_R0N + 2] + pz
            wrx = w1 * rz - w2 * ry
            wry = w2 * rx - w0 * rz
            wrz = w0 * ry - w1 * rx
            wvx = w1 * vz - w2 * vy
            wvy = w2 * vx - w0 * vz
            wvz = w0 * vy - w1 * vx
            cfx = w1 * wrz - w2 * wry
            cfy = w2 * wrx - w0 * wrz
            cfz = w0 * wry - w1 * wrx
            sx = vx + ax + dt * (Gx - 2.0 * wvx - cfx)
            sy = vy + ay + dt * (Gy - 2.0 * wvy - cfy)
            sz = vz + az + dt * (Gz - 2.0 * wvz - cfz)
            Gnx, Gny, Gnz = earth.gravitation_nb(
                prm, px + 0.5 * dt * (sx + vx), py + 0.5 * dt * (sy + vy),
                pz + 0.5 * dt * (sz + vz),
            )  # fmt: skip
            AGx, AGy, AGz = mv(prm, A_A, Gnx, Gny, Gnz)
            Jx = 0.5 * dt * (AGx + Gx)
            Jy = 0.5 * dt * (AGy + Gy)
            Jz = 0.5 * dt * (AGz + Gz)
            dsx, dsy, dsz = mv(prm, A_D, vx + wrx + ax + Jx, vy + wry + ay + Jy, vz + wrz + az + Jz)
            ex = ax + Jx + dsx - dt * wvx
            ey = ay + Jy + dsy - dt * wvy
            ez = az + Jz + dsz - dt * wvz
            ddx, ddy, ddz = mv(prm, A_MT, ex, ey, ez)
            vx += ddx
            vy += ddy
            vz += ddz
            Gx, Gy, Gz = Gnx, Gny, Gnz
        else:
            vx += ax
            vy += ay
            vz += az - g0 * dt
        px += 0.5 * dt * (vx + ovx)
        py += 0.5 * dt * (vy + ovy)
        pz += 0.5 * dt * (vz + ovz)
        e0, e1, e2, e3 = qexpm1(tx, ty, tz)
        e0 += 1.0
        q0, q1, q2, q3 = qmul(q0, q1, q2, q3, e0, e1, e2, e3)
        if wgs:
            q0, q1, q2, q3 = qmul(
                1.0 + prm[A_QW], prm[A_QW + 1], prm[A_QW + 2], prm[A_QW + 3], q0, q1, q2, q3
            )
        nq = 1.0 / math.sqrt(q0 * q0 + q1 * q1 + q2 * q2 + q3 * q3)
        q0 *= nq
        q1 *= nq
        q2 *= nq
        q3 *= nq
        measurements.on_sample(win, md, wk, q0, q1, q2, q3, vx, vy, vz, tx, ty, tz)
    if ke > k:  # acceleration of the last IMU interval (latency of the fix)
        wk.acc[0] = (vx - ovx) / dt
        wk.acc[1] = (vy - ovy) / dt
        wk.acc[2] = (vz - ovz) / dt
    else:
        wk.acc[0], wk.acc[1], wk.acc[2] = 0.0, 0.0, 0.0
    wk.th[0], wk.th[1], wk.th[2] = thx, thy, thz
    wk.g_n[0], wk.g_n[1], wk.g_n[2] = Gx, Gy, Gz
    x[ix.p], x[ix.p + 1], x[ix.p + 2] = px, py, pz
    x[ix.v], x[ix.v + 1], x[ix.v + 2] = vx, vy, vz
    x[ix.att], x[ix.att + 1], x[ix.att + 2], x[ix.att + 3] = q0, q1, q2, q3
    return still


@njit_borrowing(cache=True)
def rate_at(md, inp, s, ke, x):
    """Corrected angular rate at ``t_ke`` (body) [rad/s], extrapolated from the mean rates of
    the last two intervals (second order; the lever arms' velocity)."""
    dth, dt, bg, sg = inp.dth, md.dt, md.ix.bg, md.ix.sg
    if ke > 1:
        wbx = ((1.5 * dth[s, ke, 0] - 0.5 * dth[s, ke - 1, 0]) / dt - x[bg]) / (1.0 + x[sg])
        wby = ((1.5 * dth[s, ke, 1] - 0.5 * dth[s, ke - 1, 1]) / dt - x[bg + 1]) / (1.0 + x[sg + 1])
        wbz = ((1.5 * dth[s, ke, 2] - 0.5 * dth[s, ke - 1, 2]) / dt - x[bg + 2]) / (1.0 + x[sg + 2])
    elif ke > 0:
        wbx = (dth[s, ke, 0] / dt - x[bg]) / (1.0 + x[sg])
        wby = (dth[s, ke, 1] / dt - x[bg + 1]) / (1.0 + x[sg + 1])
        wbz = (dth[s, ke, 2] / dt - x[bg + 2]) / (1.0 + x[sg + 2])
    else:
        wbx, wby, wbz = 0.0, 0.0, 0.0
    return wbx, wby, wbz
