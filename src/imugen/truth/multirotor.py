"""The multirotor carrier (``vehicle: multirotor``): attitude by differential flatness,
rotor speeds from thrust and the hover figures.

Differential flatness with linear rotor drag (Faessler, Franchi, Scaramuzza, RA-L 2018)
---------------------------------------------------------------------------------------
A multirotor's thrust is along body z; its rotors add a drag ``-C D C^T v`` with
``D = diag(dx, dy, 0)`` [1/s] (mass-normalized). With the specific force in n
``f = a + 2 Omega x v - g(p)`` and the heading reference ``y_c = (-sin psi, cos psi, 0)`` of
the yaw ``psi`` (from East towards North): ``alpha = f + dx v``, ``beta = f + dy v``,
``x_b = y_c x alpha / |.|``, ``y_b = beta x x_b / |.|``, ``z_b = x_b x y_b``, ``c = z_b . f``.
The accelerometer then reads ``f_b = (-dx v_bx, -dy v_by, c)``: along body z up to the drag
term. The body rate follows from the exact derivatives of the unit vectors
(``f' = j + 2 Omega x a - dg/dt``): ``omega_nb_b = (y_b' . z_b, z_b' . x_b, x_b' . y_b)``.
The yaw reference is taken in n (in ``wgs84`` the transport rate of the level is neglected:
tiny at a multirotor's range; attitude and rate stay exactly consistent).

Yaw: along the horizontal velocity where faster than ``yaw_speed_mps`` (held elsewhere),
smoothed by a P-spline at ``yaw_cutoff_hz`` (``yaw_path``), or the constant ``yaw_rad``.

Rotor speeds
------------
Thrust ``T = m c``, torques ``tau = J omega' + omega x J omega`` (``omega'`` by central
differences of the sampled rate); an X quadrotor's allocation with rotors at
``(+-l/sqrt2, +-l/sqrt2)`` (front-left, rear-left, rear-right, front-right; spin +, -, +, -)
and yaw torque ``+-k_m T_i``; ``Omega_i = sqrt(T_i / k_f)``, ``k_f = m g / (4
Omega_hover^2)``. The blade-pass frequency ``blades x rpm / 60`` is what the vibration model
locks its harmonics to (:mod:`imugen.sensors.vibration`).
"""

from __future__ import annotations

import math

import numpy as np

from imugen.core import rotations as rot
from imugen.truth.pose import USpline, _Design, lam_of_cutoff

G0 = 9.80665
ROTORS = 4


def _unit(w, wd):
    """Unit vector of ``w`` and its time derivative, from ``w`` and ``w'`` (m, 3)."""
    n = np.linalg.norm(w, axis=1, keepdims=True)
    u = w / n
    return u, (wd - u * np.sum(u * wd, axis=1, keepdims=True)) / n


def flat_attitude(p, v, a, j, psi, psi_d, E, drag=(0.0, 0.0)):
    """Attitude, body rate and thrust of a multirotor following ``p(t)``.

    Parameters
    ----------
    p, v, a, j : ndarray, shape (m, 3)
        Position, velocity, acceleration, jerk in n.
    psi, psi_d : ndarray, shape (m,)
        Yaw [rad] (from East towards North) and its rate [rad/s].
    E : imugen.truth.attitude.EarthField
    drag : (dx, dy)
        Rotor drag coefficients [1/s].

    Returns
    -------
    C_nb (m, 3, 3), omega_nb_b (m, 3), f_n (m, 3), thrust per unit mass c (m,) [m/s^2]
    """
    f = a + 2.0 * np.cross(E.Omega, v) - E.gravity(p)
    fd = j + 2.0 * np.cross(E.Omega, a) - E.gravity_rate(p, v)
    dx, dy = drag
    al, ald = f + dx * v, fd + dx * a
    be, bed = f + dy * v, fd + dy * a
    s, c = np.sin(psi), np.cos(psi)
    yc = np.column_stack([-s, c, np.zeros_like(s)])
    ycd = np.column_stack([-c, -s, np.zeros_like(s)]) * psi_d[:, None]
    xb, xbd = _unit(np.cross(yc, al), np.cross(ycd, al) + np.cross(yc, ald))
    yb, ybd = _unit(np.cross(be, xb), np.cross(bed, xb) + np.cross(be, xbd))
    zb = np.cross(xb, yb)
    zbd = np.cross(xbd, yb) + np.cross(xb, ybd)
    C = np.stack([xb, yb, zb], axis=-1)
    w = np.column_stack([np.sum(ybd * zb, 1), np.sum(zbd * xb, 1), np.sum(xbd * yb, 1)])
    return C, w, f, np.sum(zb * f, 1)


class Yaw:
    """The yaw of a multirotor flying ``motion``: ``t -> (psi, psi')`` (module docstring)."""

    def __init__(self, motion, vp, rate_hz: float = 50.0):
        self.const = None if vp.yaw_path else float(vp.yaw_rad)
        if self.const is not None:
            return
        n = max(8, math.floor((motion.t1 - motion.t0) * rate_hz) + 1)
        t = np.linspace(motion.t0, motion.t1, n)
        v = motion.velocity(t)
        ok = np.hypot(v[:, 0], v[:, 1]) > vp.yaw_speed_mps
        psi = np.arctan2(v[:, 1], v[:, 0])
        if ok.any():
            idx = np.maximum.accumulate(np.where(ok, np.arange(n), -1))
            idx[idx < 0] = np.argmax(ok)
            held = np.unwrap(psi[idx])
        else:
            held = np.zeros(n)
        w = np.where(ok, 1.0, 1e-3)
        dt = float(t[1] - t[0])
        d = _Design(t, t[0], t[-1], dt)
        c = d.solve(d.normal(w), d.rhs(w, held[:, None]), lam_of_cutoff(vp.yaw_cutoff_hz, dt))
        self.spline = USpline(t[0], d.h, c)

    def __call__(self, t):
        if self.const is not None:
            return np.full(len(t), self.const), np.zeros(len(t))
        return self.spline(t)[:, 0], self.spline(t, 1)[:, 0]


def thrust_pass(out, ci, motion, times, E, vp, chunk):
    """Kinematics and flatness attitude of every sample, written into ``out`` (as
    :func:`imugen.truth.attitude.attitude_pass`).

    Returns
    -------
    f_n : ndarray, shape (K, 3)
    stats : dict
        Acceleration and jerk figures, ``thrust_mps2`` (K,) thrust per unit mass,
        ``airborne`` (K,) all True.
    """
    K = len(times)
    yaw = Yaw(motion, vp)
    f_n_all = np.empty((K, 3))
    thrust = np.empty(K)
    acc_ss, acc_max, jerk_max = 0.0, 0.0, 0.0
    for k0 in range(0, K, chunk):
        k1 = min(K, k0 + chunk)
        p, v, a, j = motion.eval(times[k0:k1])
        an = np.linalg.norm(a, axis=1)
        acc_ss += float(np.sum(an * an))
        acc_max = max(acc_max, float(an.max()))
        jerk_max = max(jerk_max, float(np.linalg.norm(j, axis=1).max()))
        psi, psi_d = yaw(times[k0:k1])
        C, w, f, c = flat_attitude(p, v, a, j, psi, psi_d, E, (vp.drag_x_1ps, vp.drag_y_1ps))
        out[k0:k1, ci["pos"]] = p
        out[k0:k1, ci["vel"]] = v
        out[k0:k1, ci["quat"]] = rot.dcm_to_quat(C)
        out[k0:k1, ci["gyro"]] = w
        f_n_all[k0:k1] = f
        thrust[k0:k1] = c
    stats = {
        "accel_rms_mps2": float(np.sqrt(acc_ss / K)),
        "accel_max_mps2": acc_max,
        "jerk_max_mps3": jerk_max,
        "attitude": "differential flatness (thrust along body z)",
        "thrust_mps2": thrust,
        "airborne": np.ones(K, dtype=bool),
    }
    return f_n_all, stats


def k_f(vp) -> float:
    """Thrust coefficient [N / (rad/s)^2] of a rotor: the hover figures."""
    return vp.mass_kg * G0 / (ROTORS * (vp.hover_rpm * 2.0 * math.pi / 60.0) ** 2)


def rotor_speeds(t, omega_b, thrust_mps2, vp):
    """Rotor speeds [rpm] of an X quadrotor, shape (K, 4), and a report.

    Parameters
    ----------
    t : ndarray, shape (K,)
        Times [s].
    omega_b : ndarray, shape (K, 3)
        Body rate [rad/s].
    thrust_mps2 : ndarray, shape (K,)
        Thrust per unit mass [m/s^2].
    vp : imugen.truth.vehicles.VehicleParams

    Returns
    -------
    (ndarray (K, 4), dict)
        Speeds (front-left, rear-left, rear-right, front-right) and the report: rpm range,
        saturation counts (thrust below 0 or beyond ``max_thrust_to_weight``), blade-pass
        range [Hz].
    """
    dt = float(np.median(np.diff(t)))
    wd = np.gradient(omega_b, dt, axis=0)
    J = np.array([vp.inertia_x_kgm2, vp.inertia_y_kgm2, vp.inertia_z_kgm2])
    tau = wd * J + np.cross(omega_b, omega_b * J)
    T = vp.mass_kg * thrust_mps2
    r = vp.arm_m / math.sqrt(2.0)
    pos = np.array([[r, r], [-r, r], [-r, -r], [r, -r]])
    spin = np.array([1.0, -1.0, 1.0, -1.0])
    A = np.vstack([np.ones(4), pos[:, 1], -pos[:, 0], spin * vp.k_m_m])  # [T, tx, ty, tz]
    Ti = np.linalg.solve(A, np.column_stack([T, tau]).T).T
    T_max = vp.max_thrust_to_weight * vp.mass_kg * G0 / ROTORS
    rpm = np.sqrt(np.clip(Ti, 0.0, T_max) / k_f(vp)) * 60.0 / (2.0 * math.pi)
    return rpm, {
        "rotor_rpm_min": float(rpm.min()),
        "rotor_rpm_max": float(rpm.max()),
        "rotor_saturated_low": int(np.sum(Ti < 0.0)),
        "rotor_saturated_high": int(np.sum(Ti > T_max)),
        "blade_pass_hz": [float(rpm.min() * vp.blades / 60.0), float(rpm.max() * vp.blades / 60.0)],
    }


def plausibility(tilt_rad, omega_b, thrust_mps2, rotors: dict, vp) -> dict:
    """Small-multirotor limits: tilt, roll/pitch and yaw rates, thrust-to-weight, rotor
    saturation; figures and ``warnings``."""
    tw = thrust_mps2 / G0
    fig = {
        "max_tilt_rad": float(np.max(tilt_rad)),
        "max_rate_rp_radps": float(np.hypot(omega_b[:, 0], omega_b[:, 1]).max()),
        "max_rate_yaw_radps": float(np.abs(omega_b[:, 2]).max()),
        "thrust_to_weight_max": float(tw.max()),
        "thrust_to_weight_min": float(tw.min()),
    }
    lim = {
        "max_tilt_rad": vp.max_tilt_rad,
        "max_rate_rp_radps": vp.max_rate_rp_radps,
        "max_rate_yaw_radps": vp.max_rate_yaw_radps,
        "thrust_to_weight_max": vp.max_thrust_to_weight,
    }
    warn = [f"multirotor: {k} {fig[k]:.3g} beyond {v:.3g}" for k, v in lim.items() if fig[k] > v]
    if fig["thrust_to_weight_min"] < 0.0:
        warn.append("multirotor: negative thrust (the path falls faster than gravity)")
    sat = rotors["rotor_saturated_low"] + rotors["rotor_saturated_high"]
    if sat:
        warn.append(f"multirotor: {sat} rotor samples saturated (below 0 or above max thrust)")
    return {**fig, **rotors, "warnings": warn}
