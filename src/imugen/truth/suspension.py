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
* the input is capped at the tyres' limit: where ``|(a_lat, a_lon)|`` exceeds the vehicle's
  ``max_accel_mps2`` (0.8 g for a car: the friction circle of road tyres) both are scaled down
  to it, since no body is pushed harder than its tyres grip (a GNSS glitch of 16 m/s^2 in a
  real track would otherwise roll a car 7.7 deg; capped, 4.4 deg).

Defaults (:data:`imugen.truth.vehicles.VEHICLES` ``car``) are mid-range passenger-car figures:
roll gradient 5 deg/g (passenger cars 3-7 deg/g, Gillespie, *Fundamentals of Vehicle
Dynamics*, SAE 1992, ch. 9; Milliken & Milliken, *Race Car Vehicle Dynamics*, SAE 1995, ch. 18),
pitch gradient 2 deg/g (brake dive and squat of passenger cars, about 1-3 deg/g, same sources),
body natural frequencies 1.5 Hz in roll and 1.2 Hz in pitch (ride and roll modes of passenger
cars 1-2 Hz, Gillespie ch. 5) and damping ratios 0.5 and 0.4 (passenger-car dampers give
0.2-0.5 of critical, Gillespie ch. 5).

The response is solved exactly for an input linear between the nodes of a fine time grid
(``dt <= 1 / (25 f_n)``, first-order hold) and represented by the quintic Hermite interpolant
of the angle and its first two derivatives at the nodes: C^2 in time, so the truth's angular
rate is the exact derivative of its attitude and the synthesized IMU stays exact.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.interpolate import PPoly
from scipy.linalg import expm

from imugen.core.jit import njit

NODES_PER_PERIOD = 25  # nodes of the time grid per natural period (at least; dt <= 0.02 s)
MAX_DT_S = 0.02
CHUNK = 1 << 16


@njit(cache=True)
def _second_order(u, Phi, G0, G1, h, x0, xd0):
    """Exact step of ``x'' = w^2 (u - x) - 2 z w x'`` for ``u`` linear between nodes."""
    n = u.shape[0]
    x = np.empty(n)
    xd = np.empty(n)
    x[0], xd[0] = x0, xd0
    for k in range(n - 1):
        r = (u[k + 1] - u[k]) / h
        a, b = x[k], xd[k]
        x[k + 1] = Phi[0, 0] * a + Phi[0, 1] * b + G0[0] * u[k] + G1[0] * r
        xd[k + 1] = Phi[1, 0] * a + Phi[1, 1] * b + G0[1] * u[k] + G1[1] * r
    return x, xd


def response(t, u, f_n, zeta):
    """Damped second-order response to ``u`` (the target angle ``K a``) on a uniform grid.

    Parameters
    ----------
    t : ndarray, shape (n,)
        Uniform times [s].
    u : ndarray, shape (n,)
        Input (steady-state angle) at ``t`` [rad], linear in between.
    f_n, zeta : float
        Natural frequency [Hz] and damping ratio.

    Returns
    -------
    x, xd, xdd : ndarray, shape (n,) each
        Angle [rad] and its first two derivatives at ``t``, from rest at ``u[0]``.
    """
    w = 2.0 * math.pi * f_n
    h = float(t[1] - t[0])
    M = np.zeros((4, 4))
    M[0, 1] = 1.0
    M[1, 0], M[1, 1], M[1, 2] = -w * w, -2.0 * zeta * w, w * w
    M[2, 3] = 1.0
    E = expm(M * h)
    x, xd = _second_order(
        np.ascontiguousarray(u, float), E[:2, :2].copy(), E[:2, 2].copy(), E[:2, 3].copy(),
        h, float(u[0]), 0.0,
    )  # fmt: skip
    xdd = w * w * (u - x) - 2.0 * zeta * w * xd
    return x, xd, xdd


def hermite(t, x, xd, xdd) -> PPoly:
    """Quintic Hermite interpolant (C^2) of values and two derivatives at the nodes ``t``."""
    h = np.diff(t)
    p0, p1 = x[:-1], x[1:]
    d10, d11 = h * xd[:-1], h * xd[1:]
    d20, d21 = h * h * xdd[:-1], h * h * xdd[1:]
    A = p1 - p0 - d10 - 0.5 * d20
    B = d11 - d10 - d20
    C = d21 - d20
    c = np.stack(
        [
            (6.0 * A - 3.0 * B + 0.5 * C) / h**5,
            (-15.0 * A + 7.0 * B - C) / h**4,
            (10.0 * A - 4.0 * B + 0.5 * C) / h**3,
            0.5 * d20 / h**2,
            d10 / h,
            p0,
        ]
    )
    return PPoly(c, t, extrapolate=True)


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
        a_raw = np.hypot(a_lat, a_lon)
        a_max = vp.max_accel_mps2  # the tyres' limit: no body is pushed harder than they grip
        scale = np.minimum(1.0, a_max / np.maximum(a_raw, 1e-300))
        a_lat, a_lon = a_lat * scale, a_lon * scale
        self.angles = []
        for K, f, z, a in (
            (vp.roll_gradient_radpmps2, vp.roll_hz, vp.roll_damping, a_lat),
            (vp.pitch_gradient_radpmps2, vp.pitch_hz, vp.pitch_damping, a_lon),
        ):
            self.angles.append(hermite(t, *response(t, K * a, f, z)))
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
        r, p = self.angles
        return r(t), r(t, 1), p(t), p(t, 1)
