"""Body roll and pitch of a car on its suspension: a damped second-order response to the
lateral and longitudinal acceleration.

Model (per angle): ``x'' = omega_n^2 (K a(t) - x) - 2 zeta omega_n x'`` with the gradient ``K``
[rad per m/s^2], natural frequency ``omega_n = 2 pi f_n`` and damping ratio ``zeta``; in a
steady turn or steady braking the angle settles at ``K a``, a step of acceleration overshoots
by ``exp(-pi zeta / sqrt(1 - zeta^2))`` and rings at ``f_n sqrt(1 - zeta^2)``.

* roll ``phi_s = K_roll a_lat``, ``a_lat = v_h^2 Psi'(s)`` (the centripetal acceleration of the
  path, +y left): turning left the body rolls outwards, right side down (roll > 0 in the
  package's convention, ``C_lb = Rz(yaw) Ry(-pitch) Rx(roll)``);
* pitch ``theta_s = K_pitch a_lon``, ``a_lon = dv_h/dt``: braking dips the nose (pitch < 0),
  accelerating squats (nose up).
* the input is capped at the tyres' limit: ``|(a_lat, a_lon)|`` is bounded smoothly below the
  vehicle's ``max_accel_mps2`` (0.8 g for a car: the friction circle of road tyres; exact up
  to 3/4 of it, then saturating, C^2: :func:`imugen.truth.attitude.soft_bound`) and both are
  scaled alike, since no body is pushed harder than its tyres grip (a GNSS glitch of 16 m/s^2
  in a real track would otherwise roll a car 7.7 deg; capped, 4.4 deg).

Defaults (:data:`imugen.truth.vehicles.VEHICLES` ``car``; sources in
:data:`imugen.truth.vehicles.SUSPENSION_SOURCES`) are mid-range passenger-car figures: roll
gradient 5 deg/g (published typical values 4.0 sports, 5.0 small and 7.0 large passenger cars),
pitch gradient 2 deg/g (brake dive and squat; no published typical figure found, a worked
textbook exercise gives about 4 deg/g without anti-dive geometry), body natural frequencies
1.5 Hz in roll and 1.2 Hz in pitch (passenger-car body modes 1-1.5 Hz) and damping ratios 0.5
and 0.4 (0.2-0.6 of critical).

The input is sampled on a fine time grid (``dt <= 1 / (25 f_n)``, at most 0.02 s), carried
between the nodes by its C^2 cubic spline, and the response to that spline is solved exactly
and evaluated in closed form (:class:`Response`: a cubic particular solution per interval plus
the free response): the angle is C^4 in time and the truth's angular rate is its exact
derivative. Smoothness matters to raw increments (a 4-point quadrature of the rates): a
first-order hold with a quintic Hermite interpolant (C^2: the angular acceleration kinked every
0.02 s) made the raw closure's convergence order erratic (3.0, 5.9, 4.1 at 50-400 Hz) and
dependent on the grid; now 3.74, 3.91, 4.00 for any grid
(``tests/oracles/test_increments.py``).
"""

from __future__ import annotations

import math

import numpy as np
from scipy.interpolate import CubicSpline

from imugen.core.jit import njit

NODES_PER_PERIOD = 25  # nodes of the time grid per natural period (at least; dt <= 0.02 s)
MAX_DT_S = 0.02
REST_RAD = 1e-12  # an input angle this small is rest (a stopped vehicle's is 0)
CHUNK = 1 << 16


def _homogeneous(tau, f_n, zeta):
    """``exp(-sigma tau)``, ``C(tau)``, ``S(tau)`` of the free response of
    ``x'' + 2 sigma x' + w^2 x = 0`` (``w = 2 pi f_n``, ``sigma = zeta w``): from ``x(0) = dx``,
    ``x'(0) = dv``, ``x = e (C dx + S (sigma dx + dv))`` and ``x' = e (C dv - S (w^2 dx +
    sigma dv))``, for any damping (``C = cos(w_d tau)``, ``S = sin(w_d tau) / w_d`` below
    critical; ``1``, ``tau`` at it; ``cosh``, ``sinh`` above)."""
    w = 2.0 * math.pi * f_n
    sigma = zeta * w
    e = np.exp(-sigma * tau)
    if zeta < 1.0:
        wd = w * math.sqrt(1.0 - zeta * zeta)
        return e, np.cos(wd * tau), np.sin(wd * tau) / wd
    if zeta == 1.0:
        return e, np.ones_like(tau), tau
    wd = w * math.sqrt(zeta * zeta - 1.0)
    return e, np.cosh(wd * tau), np.sinh(wd * tau) / wd


def _particular(c, f_n, zeta):
    """Cubic ``P`` with ``P'' + 2 sigma P' + w^2 P = w^2 u`` for the cubic input ``u`` of
    coefficients ``c`` (4, m) (highest power first, :class:`scipy.interpolate.PPoly`'s order):
    its coefficients (4, m), same order."""
    w2 = (2.0 * math.pi * f_n) ** 2
    s2 = 2.0 * zeta * 2.0 * math.pi * f_n  # 2 sigma
    p3 = c[0]
    p2 = c[1] - 3.0 * s2 * p3 / w2
    p1 = c[2] - (2.0 * s2 * p2 + 6.0 * p3) / w2
    p0 = c[3] - (s2 * p1 + 2.0 * p2) / w2
    return np.stack([p3, p2, p1, p0])


@njit(cache=True)
def _node_states(P, h, e, C, S, w2, sigma, x0, xd0):
    """States ``x``, ``x'`` at the nodes of the exact response, interval ``k``'s particular
    cubic ``P[:, k]`` plus the free response of the state's departure from it (one step
    ``h`` apart: ``e``, ``C``, ``S`` of :func:`_homogeneous` at ``h``)."""
    n = P.shape[1] + 1
    x = np.empty(n)
    xd = np.empty(n)
    x[0], xd[0] = x0, xd0
    for k in range(n - 1):
        p3, p2, p1, p0 = P[0, k], P[1, k], P[2, k], P[3, k]
        dx, dv = x[k] - p0, xd[k] - p1
        x[k + 1] = ((p3 * h + p2) * h + p1) * h + p0 + e * (C * dx + S * (sigma * dx + dv))
        xd[k + 1] = (3.0 * p3 * h + 2.0 * p2) * h + p1 + e * (C * dv - S * (w2 * dx + sigma * dv))
    return x, xd


def _input_spline(t, u):
    """Coefficients (4, n - 1) of the input's piecewise cubic (highest power first): identically
    the input's value over every interval whose two nodes are at rest (``|u| <= REST_RAD``: a
    stopped vehicle), and the C^2 cubic spline through the nodes of each stretch between them.
    One spline through a stop would reach into it ((2 - sqrt 3)^k at the k-th node): the body
    would stir up to a second before the vehicle pulls away (1.3e-6 rad/s 0.02 s before)."""
    n = len(t)
    c = np.zeros((4, n - 1))
    c[3] = u[:-1]
    rest = np.abs(u) <= REST_RAD
    moving = ~(rest[:-1] & rest[1:])  # intervals (n - 1,)
    edges = np.flatnonzero(np.diff(np.concatenate(([0], moving.astype(np.int8), [0]))))
    for i, j in zip(edges[::2], edges[1::2], strict=True):  # intervals i..j-1 move: nodes i..j
        if j - i == 1:  # two nodes: the linear input
            c[2, i] = (u[j] - u[i]) / (t[j] - t[i])
        else:
            c[:, i:j] = CubicSpline(t[i : j + 1], u[i : j + 1]).c
    return c


class Response:
    """Exact response of ``x'' = w^2 (u - x) - 2 zeta w x'`` to the C^2 cubic spline ``u``
    through input values on a uniform grid, from rest at ``u[0]``: C^4 in time (its fifth
    derivative steps with the spline's third), evaluated in closed form at any time. Over
    intervals at rest the input is held at rest and the spline restarts after them (a stop's
    edges are C^2 in the body's angle: the pull-away's step of jerk), so a body at rest stays
    exactly at rest until its vehicle moves.

    Parameters
    ----------
    t : ndarray, shape (n,)
        Uniform times [s], ``n >= 2``.
    u : ndarray, shape (n,)
        Input (steady-state angle) at ``t`` [rad].
    f_n, zeta : float
        Natural frequency [Hz] and damping ratio (> 0).
    """

    def __init__(self, t, u, f_n, zeta):
        self.t0, self.h, self.n = float(t[0]), float(t[1] - t[0]), len(t)
        self.f_n, self.zeta = f_n, zeta
        self.w2 = (2.0 * math.pi * f_n) ** 2
        self.sigma = zeta * 2.0 * math.pi * f_n
        u = np.asarray(u, float)
        c = _input_spline(np.asarray(t, float), u)
        self.P = np.ascontiguousarray(_particular(c, f_n, zeta))
        e, C, S = _homogeneous(np.array(self.h), f_n, zeta)
        self.x, self.xd = _node_states(
            self.P, self.h, float(e), float(C), float(S), self.w2, self.sigma, float(u[0]), 0.0
        )

    def __call__(self, t):
        """Angle and its rate at times ``t`` (m,) [rad, rad/s] (beyond the grid, the end
        intervals' solutions continued)."""
        t = np.asarray(t, float)
        k = np.clip(((t - self.t0) // self.h).astype(np.int64), 0, self.n - 2)
        tau = t - (self.t0 + k * self.h)
        p3, p2, p1, p0 = self.P[:, k]
        dx, dv = self.x[k] - p0, self.xd[k] - p1
        e, C, S = _homogeneous(tau, self.f_n, self.zeta)
        x = ((p3 * tau + p2) * tau + p1) * tau + p0 + e * (C * dx + S * (self.sigma * dx + dv))
        xd = (
            (3.0 * p3 * tau + 2.0 * p2) * tau
            + p1
            + e * (C * dv - S * (self.w2 * dx + self.sigma * dv))
        )
        return x, xd


class Suspension:
    """Roll and pitch of the body on its suspension over a motion (module docstring).

    Parameters
    ----------
    t0, t1 : float
        Time span of the motion [s].
    inputs : callable
        ``inputs(t) -> (a_lat, a_lon)``, each (m,) [m/s^2], at times ``t`` (m,).
    vp : VehicleParams
        ``roll_gradient_radpmps2``, ``pitch_gradient_radpmps2``, ``roll_hz``, ``pitch_hz``,
        ``roll_damping``, ``pitch_damping``.
    """

    def __init__(self, t0, t1, inputs, vp):
        f_max = max(vp.roll_hz, vp.pitch_hz)
        dt = min(MAX_DT_S, 1.0 / (NODES_PER_PERIOD * f_max))
        n = max(2, math.ceil((t1 - t0) / dt) + 1)
        t = np.linspace(t0, t1, n)
        a_lat, a_lon = np.empty(n), np.empty(n)
        for k0 in range(0, n, CHUNK):
            a_lat[k0 : k0 + CHUNK], a_lon[k0 : k0 + CHUNK] = inputs(t[k0 : k0 + CHUNK])
        from imugen.truth.attitude import soft_bound  # (attitude imports this module)

        a_raw = np.hypot(a_lat, a_lon)
        a_max = vp.max_accel_mps2  # the tyres' limit: no body is pushed harder than they grip
        # smoothly (C^2, exact below 3/4 of the limit): a hard cap's kink is a step of jerk
        scale = np.where(a_raw > 0.0, soft_bound(a_raw, a_max)[0] / np.maximum(a_raw, 1e-300), 1.0)
        a_lat, a_lon = a_lat * scale, a_lon * scale
        self.angles = []
        for K, f, z, a in (
            (vp.roll_gradient_radpmps2, vp.roll_hz, vp.roll_damping, a_lat),
            (vp.pitch_gradient_radpmps2, vp.pitch_hz, vp.pitch_damping, a_lon),
        ):
            self.angles.append(Response(t, K * a, f, z))
        self.report = {
            "model": "damped second order",
            "grid_dt_s": float(t[1] - t[0]),
            "max_abs_lateral_accel_mps2": float(np.abs(a_lat).max()),
            "max_abs_longitudinal_accel_mps2": float(np.abs(a_lon).max()),
            "input_cap_mps2": float(a_max),
            "max_input_accel_uncapped_mps2": float(a_raw.max()),
            "capped_fraction": float(np.mean(scale < 1.0)),
        }

    def __call__(self, t):
        """``(roll, roll rate, pitch, pitch rate)`` at times ``t`` (m,) [rad, rad/s]."""
        (r, r_d), (p, p_d) = (angle(t) for angle in self.angles)
        return r, r_d, p, p_d
