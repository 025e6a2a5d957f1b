"""Odometer distance over a window (a windowed measurement).

At marked epochs (:class:`~imugen.aid.companions.CompanionEpochs`) the distance counted over
the window since the previous mark, ``z = (1 + k) d + w + e_b - e_a``:

* ``d`` the forward distance of the odometer point along the vehicle's x, predicted as the
  trapezoid of ``r . (C^T v) + omega . a`` over the window's IMU samples (:func:`on_sample`),
  ``r = R^T e_x`` the vehicle's forward axis in IMU axes through the estimated mounting,
  ``a = (l_o - l) x r`` with ``l_o`` the odometer point from the vehicle reference point and
  ``l`` the IMU's, nominal plus its states (:func:`axes`); sensitivities to the velocity and
  attitude errors ``int C r dt``, ``int (C r) x v dt`` (errors taken constant over the
  window), to the gyro bias ``-a T_w`` and to the lever-arm states ``-(r x theta_w)``,
  ``theta_w`` the window's angle, gated as NHC's (:func:`window_sensitivities`); the rate's
  white noise adds ``N_g^2 T_w a^2``; the mounting angles' effect is second order, ``u theta
  dtheta``, and left out (with large misalignments, 3, 3, 5 deg, and a 1 m lever arm, NEES
  9.3, 192 with the wheel along the IMU's x at the IMU);
* ``k`` the scale factor (a state, or its prior added to the variance);
* ``w`` the white speed noise integrated over the window (variance ``n (s_w T_o)^2``);
* ``e = (1/2 - r) c`` the residual of the tick count at each end (``c`` the tick length,
  ``r`` the fraction of a tick counted late, uniform: variance ``c^2 / 12``). The residual at
  a window's end is the next window's start, so it is not white noise: both ends are states
  (start, end), the end's drawn fresh at each mark and then becoming the next window's start
  (the start's marginalized). Taken as white noise of ``c^2 / 6`` per window instead, the
  telescoping of the residuals is lost: the scale factor's NEES is 0.09 (10 times
  conservative) and the velocity's too (per-component 0.85 along-track).

The window's prediction is corrected by every epoch's feedback (:func:`after_feedback`). The
hooks :func:`begin_interval`, :func:`on_sample`, :func:`update` and :func:`after_feedback`
are the windowed-measurement protocol of :mod:`imugen.aid.filter.measurements`.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from imugen.aid.companions import C_ODO, C_ODO_VAR
from imugen.aid.filter.geometry import dcm
from imugen.aid.filter.kalman import F_REJECT, clear, fresh_state, put, scalar_update
from imugen.aid.filter.tuning import T_NG, T_OQ_SD, T_OSF_SD
from imugen.core.jit import njit

F_ODO = 64
"""Epoch flag: odometer update applied."""

W_DIST, W_T, W_U0, W_ARMED = 0, 1, 2, 3
"""Slots of :attr:`Window.sc`."""


class Window(NamedTuple):
    """The odometer's window since its last mark (one sequence at a time).

    Attributes
    ----------
    sc : (4,)  predicted distance ``d`` [m], duration ``T_w`` [s], forward speed at the
        current sample [m/s], armed (a window is open: 1.0)
    hv, hpsi : (3,)  sensitivities of ``d`` to the velocity and attitude errors (n) [s, m]
    tw : (3,)  corrected angle over the window, body [rad]
    ra : (6,)  the geometry of the current interval: ``r`` then ``a`` (:func:`axes`)
    hbg, hla : (3,)  sensitivities to the gyro bias [m s/rad] and to the lever arm [m/m]
        (:func:`window_sensitivities`)
    """

    sc: np.ndarray
    hv: np.ndarray
    hpsi: np.ndarray
    tw: np.ndarray
    ra: np.ndarray
    hbg: np.ndarray
    hla: np.ndarray


@njit(cache=True)
def new_window():
    """A zeroed :class:`Window`."""
    z = np.zeros(3)
    return Window(np.zeros(4), z, z.copy(), z.copy(), np.zeros(6), z.copy(), z.copy())


@njit(cache=True)
def start(win):
    """No window open (a sequence's start)."""
    win.sc[W_ARMED] = 0.0
    reset(win)


@njit(cache=True)
def reset(win):
    """Close the window: zero distance, duration and sensitivities (``armed`` unchanged)."""
    win.sc[W_DIST] = 0.0
    win.sc[W_T] = 0.0
    for a in range(3):
        win.hv[a] = 0.0
        win.hpsi[a] = 0.0
        win.tw[a] = 0.0


@njit(cache=True)
def axes(md, x, l_odo, ra):
    """The odometer's geometry in IMU axes: ``ra[:3]`` the vehicle's forward axis ``r``
    (``R^T e_x`` with the estimated mounting ``R = Rz(yaw) Ry(-pitch)``, else ``e_x``),
    ``ra[3:]`` ``a = (l_odo - l_imu) x r`` (``l_imu`` the NHC lever arm, nominal plus its
    estimate; ``l_odo`` (3,) vehicle axes [m]): the wheel's forward speed is ``r . (C^T v) +
    omega . a``."""
    ix = md.ix
    if md.ie.mount >= 0:
        mcp, msp = math.cos(x[ix.mount]), math.sin(x[ix.mount])
        mcy, msy = math.cos(x[ix.mount + 1]), math.sin(x[ix.mount + 1])
        ra[0], ra[1], ra[2] = mcy * mcp, -msy, -mcy * msp
    else:
        ra[0], ra[1], ra[2] = 1.0, 0.0, 0.0
    lever = md.opt.nhc_lever_m
    d0 = l_odo[0] - lever[0]
    d1 = l_odo[1] - lever[1]
    d2 = l_odo[2] - lever[2]
    if md.ie.lever >= 0:
        d0 -= x[ix.lever]
        d1 -= x[ix.lever + 1]
        d2 -= x[ix.lever + 2]
    ra[3] = d1 * ra[2] - d2 * ra[1]
    ra[4] = d2 * ra[0] - d0 * ra[2]
    ra[5] = d0 * ra[1] - d1 * ra[0]


@njit(cache=True)
def window_sensitivities(win, tn, dt):
    """Sensitivities of the window's distance to the gyro bias (``win.hbg = -a T_w``) and to
    the IMU lever arm (``win.hla = -(r x theta_w)``, ``theta_w`` the window's corrected angle,
    only its components well above their noise ``N_g^2 T_w``: see
    :mod:`imugen.aid.filter.nhc`)."""
    tw, ra, Tw = win.tw, win.ra, win.sc[W_T]
    g0 = tw[0] if tw[0] * tw[0] > 250.0 * tn[T_NG] ** 2 * Tw else 0.0
    g1 = tw[1] if tw[1] * tw[1] > 250.0 * tn[T_NG + 1] ** 2 * Tw else 0.0
    g2 = tw[2] if tw[2] * tw[2] > 250.0 * tn[T_NG + 2] ** 2 * Tw else 0.0
    for a in range(3):
        win.hbg[a] = -ra[3 + a] * Tw
    win.hla[0] = -(ra[1] * g2 - ra[2] * g1)
    win.hla[1] = -(ra[2] * g0 - ra[0] * g2)
    win.hla[2] = -(ra[0] * g1 - ra[1] * g0)


@njit(cache=True, inline="always")
def begin_interval(win, md, inp, s, k, ke, x, wk):
    """At the start of an interval (nominal state ``x`` at sample ``k``): the geometry and
    the forward speed at ``t_k`` (lever-arm term: the first interval's rate)."""
    if not md.opt.odometer:
        return
    ra, ix, dt = win.ra, md.ix, md.dt
    axes(md, x, inp.clever[s], ra)
    C = wk.C
    dcm(x[ix.att], x[ix.att + 1], x[ix.att + 2], x[ix.att + 3], C)
    vx, vy, vz = x[ix.v], x[ix.v + 1], x[ix.v + 2]
    cr0 = C[0, 0] * ra[0] + C[0, 1] * ra[1] + C[0, 2] * ra[2]
    cr1 = C[1, 0] * ra[0] + C[1, 1] * ra[1] + C[1, 2] * ra[2]
    cr2 = C[2, 0] * ra[0] + C[2, 1] * ra[1] + C[2, 2] * ra[2]
    u0 = cr0 * vx + cr1 * vy + cr2 * vz
    if ke > k:
        dth = inp.dth
        u0 += (
            (dth[s, k + 1, 0] - x[ix.bg] * dt) * ra[3]
            + (dth[s, k + 1, 1] - x[ix.bg + 1] * dt) * ra[4]
            + (dth[s, k + 1, 2] - x[ix.bg + 2] * dt) * ra[5]
        ) / dt
    win.sc[W_U0] = u0


@njit(cache=True, inline="always")
def on_sample(win, md, wk, q0, q1, q2, q3, vx, vy, vz, tx, ty, tz):
    """After one strapdown step (``wk.C`` before it, quaternion ``q`` and velocity ``v``
    after it, ``t`` the corrected angle increment): the trapezoid of the forward speed, as
    the odometer's truth, and of the sensitivities."""
    if not md.opt.odometer:
        return
    ra, C, Cn, dt = win.ra, wk.C, wk.Cn, md.dt
    dcm(q0, q1, q2, q3, Cn)  # C r before (C) and after (Cn) the step
    cx = Cn[0, 0] * ra[0] + Cn[0, 1] * ra[1] + Cn[0, 2] * ra[2]
    cy = Cn[1, 0] * ra[0] + Cn[1, 1] * ra[1] + Cn[1, 2] * ra[2]
    cz_ = Cn[2, 0] * ra[0] + Cn[2, 1] * ra[1] + Cn[2, 2] * ra[2]
    cr0 = C[0, 0] * ra[0] + C[0, 1] * ra[1] + C[0, 2] * ra[2]
    cr1 = C[1, 0] * ra[0] + C[1, 1] * ra[1] + C[1, 2] * ra[2]
    cr2 = C[2, 0] * ra[0] + C[2, 1] * ra[1] + C[2, 2] * ra[2]
    u1 = cx * vx + cy * vy + cz_ * vz + (tx * ra[3] + ty * ra[4] + tz * ra[5]) / dt
    win.sc[W_DIST] += 0.5 * dt * (win.sc[W_U0] + u1)
    win.sc[W_U0] = u1
    win.tw[0] += tx
    win.tw[1] += ty
    win.tw[2] += tz
    win.sc[W_T] += dt
    win.hv[0] += 0.5 * dt * (cr0 + cx)
    win.hv[1] += 0.5 * dt * (cr1 + cy)
    win.hv[2] += 0.5 * dt * (cr2 + cz_)
    win.hpsi[0] += dt * (cy * vz - cz_ * vy)
    win.hpsi[1] += dt * (cz_ * vx - cx * vz)
    win.hpsi[2] += dt * (cx * vy - cy * vx)


@njit(cache=True)
def distance_row(md, x, wk, win, z):
    """The row of the distance ``z`` [m] over the window: ``z_pred = (1 + k) d - e_a`` with
    ``e_a`` the estimated tick residual at the window's start (the end's has prior mean 0);
    fills ``wk.h`` (after :func:`window_sensitivities`); returns ``(m, r)``."""
    ie, ix = md.ie, md.ix
    d_hat = win.sc[W_DIST]
    g = 1.0 + x[ix.odo_sf]
    m = clear(wk)
    for a in range(3):
        m = put(wk, m, ie.v + a, g * win.hv[a])
    for a in range(3):
        m = put(wk, m, ie.att + a, g * win.hpsi[a])
    for a in range(3):
        m = put(wk, m, ie.bg + a, g * win.hbg[a])
    m = put(wk, m, ie.odo_tick, -1.0)
    m = put(wk, m, ie.odo_tick + 1, 1.0)
    if ie.lever >= 0:
        for a in range(3):
            m = put(wk, m, ie.lever + a, g * win.hla[a])
    if ie.odo_sf >= 0:
        m = put(wk, m, ie.odo_sf, d_hat)
    return m, g * d_hat - x[ix.odo_tick] - z


@njit(cache=True)
def update(e, md, inp, wk, x, tn, wins):
    """At a marked epoch: the distance update (when a window is open and the count is
    finite), then the end's tick residual becomes the next window's start and a new window
    opens (``wins.odometer``). Returns the flag bits."""
    if not (md.opt.odometer and inp.cmark[e.j] != 0):
        return 0
    win = wins.odometer
    P, dx, ie, dt = wk.P, wk.dx, md.ie, md.dt
    i_oq = ie.odo_tick
    n = P.shape[0]
    flag = 0
    zo = inp.cz[e.s, e.j, C_ODO]
    # the residual of the count at this epoch ends this window and starts the next
    fresh_state(P, dx, i_oq + 1, tn[T_OQ_SD])
    if win.sc[W_ARMED] != 0.0 and e.started and math.isfinite(zo):
        vo = inp.cz[e.s, e.j, C_ODO_VAR]
        if ie.odo_sf < 0:
            vo += (tn[T_OSF_SD] * zo) ** 2
        window_sensitivities(win, tn, dt)
        # the rate's white noise in omega . a over the window: N_g^2 T_w a^2
        for a in range(3):
            vo += (tn[T_NG + a] * win.ra[3 + a]) ** 2 * win.sc[W_T]
        m, r = distance_row(md, x, wk, win, zo)
        flag = F_ODO if scalar_update(wk, m, r, vo, md.opt.gate) else F_REJECT
    # the end's residual becomes the next window's start (the start's marginalized)
    for i in range(n):
        P[i_oq, i] = P[i_oq + 1, i]
    for i in range(n):
        P[i, i_oq] = P[i, i_oq + 1]
    P[i_oq, i_oq] = P[i_oq + 1, i_oq + 1]
    dx[i_oq] = dx[i_oq + 1]
    x[md.ix.odo_tick] = 0.0
    fresh_state(P, dx, i_oq + 1, 0.0)
    win.sc[W_ARMED] = 1.0
    reset(win)
    return flag


@njit(cache=True, inline="always")
def after_feedback(win, md, wk, tn):
    """An open window's distance so far, corrected by the epoch's feedback ``wk.dx``."""
    if not (md.opt.odometer and win.sc[W_ARMED] != 0.0):
        return
    ie, dx = md.ie, wk.dx
    window_sensitivities(win, tn, md.dt)
    for a in range(3):
        win.sc[W_DIST] -= (
            win.hv[a] * dx[ie.v + a] + win.hpsi[a] * dx[ie.att + a] + win.hbg[a] * dx[ie.bg + a]
        )
        if ie.lever >= 0:
            win.sc[W_DIST] -= win.hla[a] * dx[ie.lever + a]
