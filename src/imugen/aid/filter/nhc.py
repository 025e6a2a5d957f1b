"""Non-holonomic constraint (cars): lateral and vertical velocity of the vehicle reference point zero in the
vehicle frame ``v``: ``(R (C^T v - omega x l))_{y,z} = 0`` (the whole body vector
rotated: its x part, ``-(omega x l)_x``, enters the y row through the mounting yaw),
``l`` the IMU's lever arm from that point (body axes): the nominal
``nhc_lever_arm_m`` (the filter does not know the drawn one, :mod:`imugen.sensors.mounting`)
plus, with ``nhc_lever_arm_sd_m`` set, three random-constant states (prior that sigma
plus the misalignment's rotation of the nominal, ``[l x] theta``). A constant lever-arm
error is no white noise: taken as ``(omega x sd_l)^2`` it averaged down over each turn
(mounting NEES 20, pitch z^2 166 against 60). The states' Jacobian ``-(r x omega)``
(``r`` the vehicle row in body axes) keeps only the rate components above 15.8 times
their noise: at the noisy rate it correlates with the innovation's own noise and pulls
the lever arm to zero (errors in variables: 0.5 m -> 0.1 m in 25 s of straight road).
The rate's error enters ``r . (dw x l) = dw . (l x r)``: the gyro-bias error as a
sensitivity, the extrapolated rate's white noise (``2.5 N_g^2 / dt`` per axis: the two
intervals' means weighted 1.5 and -0.5) as variance; the Earth rate's part, ``7e-5
|l|`` m/s, is left out. The variance is what is uncertain in that zero, per component:
the vehicle's own residual slip ``nhc_sd_mps`` (lateral, vertical; none for the
simulator's vehicles, whose body velocity has no y, z component: 4e-9 m/s RMS, the
truth's plausibility report), the rate's noise above, plus the constraint's second-order
error, state-dependent: with ``psi``, ``dv`` in vehicle axes, ``v_b,hat - v_b = ... -
psi x dv + u/2 psi psi_x``, so row y has ``var(u/2 psi_y psi_x - psi_z dv_x + psi_x
dv_z)`` from ``P`` (Gaussian products, ``var(a b) = s_a^2 s_b^2 + s_ab^2``), likewise
row z; 1e-3 m/s after a moving alignment (tilt 1 deg, 14 m/s), 1e-5 m/s converged.
Without that term an exact constraint is overconfident after the alignment (NEES 130-200
at the first epoch, at 3e-5 m/s); a constant noise instead (the former 0.1 m/s, or even
1e-3 m/s) over-covers the two attitude directions NHC fixes (NEES 0.3 per direction
where 1 is due, measured in P's eigenbasis, car rectangle of tests/aid/test_companions.py).
A car's body pitches on its suspension (:mod:`imugen.truth.suspension`): its vertical body
speed is ``-u sin(theta_s)``, the dive and squat, which the vertical row takes as noise of
``(u nhc_pitch_sd)^2`` at the estimated forward speed ``u`` (``Options.nhc_pitch_sd_rad``;
without it a car on its suspension drove the companion scene's NEES to 1e7); the roll on the
suspension moves no velocity into the lateral row.
The slip is the truth's RMS (:func:`imugen.aid.stage.truth_slip_sd`; the vertical one under the
body's pitch on the suspension, which is the term above) and its bursts, where a
path is implausible, are left to NHC's own innovation gate (``Options.nhc_gate_sigma``; the
largest slip as white noise left heading NEES/dof 0.13-0.17, tilt 2.3). The rows linearize at
the estimated velocity: NHC waits while ``|v|^2 <= ratio^2 tr(P_vv)``
(``Options.nhc_speed_ratio``; at a stop inside an outage they turned the heading towards the
velocity error, NEES up to 1e6 in single runs).
``R`` is the nominal mounting (identity), or, with ``nhc_misalignment_sd_rad`` set,
``Rz(yaw) Ry(-pitch)`` of two more error states, the IMU's pitch and yaw from the vehicle
(random constants with that prior sigma): a misaligned IMU driving straight at ``u`` sees
``v_b = u (1, -yaw, -pitch)``, a bias no white NHC noise can cover (measured: NEES 80-280
against a bound of 11 on a car scene with the noise inflated by ``u sd``). NHC observes
the direction of the vehicle's forward axis in IMU axes only, so the two states converge
to its angles (:func:`imugen.sensors.mounting.forward_axis_angles`), not to the roll-dependent
Euler pitch and yaw of the labels (they differ by ``roll x yaw``).
Odometer (marked epochs, :class:`CompanionEpochs`): the distance counted over the window
since the previous mark, ``z = (1 + k) d + w + e_b - e_a``: ``d`` the forward distance
"""

from __future__ import annotations

import math

from imugen.aid.filter.geometry import skew
from imugen.aid.filter.kalman import F_REJECT, clear, put, scalar_update
from imugen.aid.filter.tuning import T_NG
from imugen.core.jit import njit_borrowing

F_NHC = 8
"""Epoch flag: non-holonomic constraint applied."""


@njit_borrowing(cache=True, inline="always")
def body_cov(P, i0, Cv, i, j):
    """``Cv[:, i]^T P_blk Cv[:, j]``: covariance of components ``i``, ``j`` (vehicle axes) of
    the 3x3 block of ``P`` starting at ``i0``."""
    acc = 0.0
    for a in range(3):
        for b in range(3):
            acc += Cv[a, i] * P[i0 + a, i0 + b] * Cv[b, j]
    return acc


@njit_borrowing(cache=True)
def second_order_var(P, ie, Cv, u, row):
    """Variance of the NHC prediction's second-order error (module docstring): with ``psi``, ``dv`` in vehicle axes, ``v_b,hat - v_b = -(psi x dv) +
    u/2 psi (psi_x) + ...``, so row y carries ``u/2 psi_y psi_x - psi_z dv_x + psi_x dv_z``
    and row z ``u/2 psi_z psi_x - psi_x dv_y + psi_y dv_x``; products of zero-mean Gaussian
    components, ``var(a b) = s_a^2 s_b^2 + s_ab^2`` (the products taken uncorrelated)."""
    sxx = body_cov(P, ie.att, Cv, 0, 0)
    o = 1 if row == 1 else 2  # the row's own axis, and the remaining one
    r = 2 if row == 1 else 1
    soo = body_cov(P, ie.att, Cv, o, o)
    sxo = body_cov(P, ie.att, Cv, 0, o)
    srr = body_cov(P, ie.att, Cv, r, r)
    vxx = body_cov(P, ie.v, Cv, 0, 0)
    vrr = body_cov(P, ie.v, Cv, r, r)
    return 0.25 * u * u * (sxx * soo + sxo * sxo) + srr * vxx + sxx * vrr


@njit_borrowing(cache=True)
def vehicle_velocity(e, md, x, wk):
    """The reference point's velocity in vehicle axes, ``R (C^T v - omega x l)`` [m/s]
    (``(u, v_y, v_z)``), and the lever arm ``l`` (nominal plus its estimate, body [m]); fills
    ``wk.Cv`` (``C R^T``: n -> vehicle rows) and ``wk.Xm`` (``[v x]``)."""
    ix, C, Cv = md.ix, wk.C, wk.Cv
    vx, vy, vz = x[ix.v], x[ix.v + 1], x[ix.v + 2]
    wbx, wby, wbz = e.w_b
    # v_b = C^T v - w x l; rows y, z: dv_b = C^T dv + C^T [v x] psi
    skew(vx, vy, vz, wk.Xm)
    nlx, nly, nlz = md.opt.nhc_lever_m
    if md.ie.lever >= 0:  # the estimated lever arm
        nlx += x[ix.lever]
        nly += x[ix.lever + 1]
        nlz += x[ix.lever + 2]
    # the reference point's whole body velocity C^T v - omega x l (its x part matters once
    # rotated by the mounting: yaw x (omega x l)_x, 0.02 m/s in a turn at 5 deg and 0.5 m)
    ub = C[0, 0] * vx + C[1, 0] * vy + C[2, 0] * vz - (wby * nlz - wbz * nly)
    vby = C[0, 1] * vx + C[1, 1] * vy + C[2, 1] * vz - (wbz * nlx - wbx * nlz)
    vbz = C[0, 2] * vx + C[1, 2] * vy + C[2, 2] * vz - (wbx * nly - wby * nlx)
    for a in range(3):
        for b in range(3):
            Cv[a, b] = C[a, b]
    if md.ie.mount >= 0:
        # vehicle axes v = R b, R = Rz(yaw) Ry(-pitch) (estimated angles; roll is not
        # observable by NHC): d(v_v,y)/d yaw = d(v_v,z)/d pitch = u to first order; the
        # velocity and attitude rows use C R^T
        mcp, msp = math.cos(x[ix.mount]), math.sin(x[ix.mount])
        mcy, msy = math.cos(x[ix.mount + 1]), math.sin(x[ix.mount + 1])
        ax = mcp * ub - msp * vbz
        vbz = msp * ub + mcp * vbz
        vby_ = msy * ax + mcy * vby
        ub = mcy * ax - msy * vby
        vby = vby_
        for a in range(3):
            c0, c1, c2 = C[a, 0], C[a, 1], C[a, 2]
            Cv[a, 1] = msy * (mcp * c0 - msp * c2) + mcy * c1
            Cv[a, 2] = msp * c0 + mcp * c2
    return (ub, vby, vbz), (nlx, nly, nlz)


@njit_borrowing(cache=True)
def row(e, md, x, wk, tn, r_, vel, lever, slip_var):
    """Row ``r_`` (1: lateral, 2: vertical) of the constraint, after
    :func:`vehicle_velocity`, with the slip's variance ``slip_var``: fills ``wk.h``; returns
    ``(m, r, var)``."""
    ie, C, Cv, Xm, P, dt = md.ie, wk.C, wk.Cv, wk.Xm, wk.P, md.dt
    ub = vel[0]
    nlx, nly, nlz = lever
    wbx, wby, wbz = e.w_b
    # the lever arm is observed through the rate components well above their noise (the
    # extrapolated rate's, 2.5 N_g^2 / dt): a Jacobian taken at a noisy rate, correlated with
    # the innovation's own noise, pulls the lever arm towards zero (errors in variables;
    # 0.5 m -> 0.1 m in 25 s of straight road)
    wgx = wbx if wbx * wbx > 250.0 * tn[T_NG] ** 2 / dt else 0.0
    wgy = wby if wby * wby > 250.0 * tn[T_NG + 1] ** 2 / dt else 0.0
    wgz = wbz if wbz * wbz > 250.0 * tn[T_NG + 2] ** 2 / dt else 0.0
    m = clear(wk)
    var = slip_var + second_order_var(P, ie, Cv, ub, r_)
    # the vehicle row r (body) and l x r: the rate's error enters as r . (dw x l) = dw . (l x
    # r); its white noise (the rate extrapolated from two intervals' means, 1.5 and -0.5:
    # 2.5 N_g^2 / dt per axis) as noise, the gyro bias error as a sensitivity (dw = -dbg)
    r0 = C[0, 0] * Cv[0, r_] + C[1, 0] * Cv[1, r_] + C[2, 0] * Cv[2, r_]
    r1 = C[0, 1] * Cv[0, r_] + C[1, 1] * Cv[1, r_] + C[2, 1] * Cv[2, r_]
    r2 = C[0, 2] * Cv[0, r_] + C[1, 2] * Cv[1, r_] + C[2, 2] * Cv[2, r_]
    lr0 = nly * r2 - nlz * r1
    lr1 = nlz * r0 - nlx * r2
    lr2 = nlx * r1 - nly * r0
    var += (2.5 / dt) * (
        (tn[T_NG] * lr0) ** 2 + (tn[T_NG + 1] * lr1) ** 2 + (tn[T_NG + 2] * lr2) ** 2
    )
    for a in range(3):
        m = put(wk, m, ie.v + a, Cv[a, r_])
    # (Cv^T [v x])[row, b]
    for b in range(3):
        m = put(
            wk, m, ie.att + b, Cv[0, r_] * Xm[0, b] + Cv[1, r_] * Xm[1, b] + Cv[2, r_] * Xm[2, b]
        )
    m = put(wk, m, ie.bg, lr0)
    m = put(wk, m, ie.bg + 1, lr1)
    m = put(wk, m, ie.bg + 2, lr2)
    if ie.mount >= 0:  # row y: the yaw, row z: the pitch
        m = put(wk, m, ie.mount + (1 if r_ == 1 else 0), ub)
    if ie.lever >= 0:  # d(-omega x l)/dl: -(r x omega)
        m = put(wk, m, ie.lever, -(r1 * wgz - r2 * wgy))
        m = put(wk, m, ie.lever + 1, -(r2 * wgx - r0 * wgz))
        m = put(wk, m, ie.lever + 2, -(r0 * wgy - r1 * wgx))
    return m, vel[r_], var


@njit_borrowing(cache=True)
def update(e, md, inp, wk, x, tn, win):
    """NHC at epoch ``e`` when switched on (lateral, then vertical); returns the flag bits."""
    if not md.opt.nhc:
        return 0
    ratio = md.opt.nhc_speed_ratio
    if ratio > 0.0:  # the attitude rows need the velocity's direction (module docstring)
        iv, ie, P = md.ix.v, md.ie.v, wk.P
        v2 = x[iv] * x[iv] + x[iv + 1] * x[iv + 1] + x[iv + 2] * x[iv + 2]
        if not v2 > ratio * ratio * (P[ie, ie] + P[ie + 1, ie + 1] + P[ie + 2, ie + 2]):
            return 0
    vel, lever = vehicle_velocity(e, md, x, wk)
    flag = F_NHC
    learned = inp.nvar.shape[1] > 0
    for r_ in (1, 2):
        slip = md.opt.nhc_sd_lat if r_ == 1 else md.opt.nhc_sd_vert
        slip_var = slip * slip
        if r_ == 2:  # the dive and squat on the suspension: -u sin(theta_s), theta_s ~ sd
            slip_var += (vel[0] * md.opt.nhc_pitch_sd) ** 2
        if learned and math.isfinite(inp.nvar[e.s, e.j, r_ - 1]):  # a learner's (AI-IMU)
            slip_var = inp.nvar[e.s, e.j, r_ - 1]
        m, r, var = row(e, md, x, wk, tn, r_, vel, lever, slip_var)
        if not scalar_update(wk, m, r, var, md.opt.nhc_gate):
            flag |= F_REJECT
    return flag
