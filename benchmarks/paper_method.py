"""The paper's IMU synthesis and mechanization (forward differences + Euler angles), ported.

Used only by ``bench_accuracy.py`` as the "paper's way" baseline. Faithful to the structure
of the published MATLAB (see ``shared/notes/seed-code-review.md`` sections 2 and 4):

* ``v_k = (p_{k+1} - p_k) / dt``, ``a_k = (v_{k+1} - v_k) / dt`` (forward differences);
* attitude as Euler angles derived from ``v_k``; gyro = Euler-angle forward differences mapped
  to body rates through the Euler-rate matrix; ``f_b = C_bn (a_k - g_n)``;
* mechanization: forward (explicit) Euler on Euler angles, velocity and position, i.e. the
  exact discrete inverse of the synthesis.

Corrected where the paper's code was wrong (each would only make this baseline worse):

1. yaw from the horizontal velocity, pitch from the climb angle, roll 0 (the paper took pitch
   from the East velocity alone and "roll" from the North-Up climb angle); angles unwrapped;
   yaw held when the horizontal speed drops below ``hold_speed`` (the paper had no guard);
2. no wrap-around pad (``v(K) = v(1)``): the series are simply one/two samples shorter;
3. the attitude loop is closed (bug B1): the mechanization rotates ``f_b`` with its own
   integrated angles, not the reference ones;
4. one consistent convention: n = ENU, b = x forward / y left / z up,
   ``C_nb = Rz(yaw) Ry(-pitch) Rx(roll)`` (as :func:`imugen.core.rotations.euler_to_dcm`);
5. flat Earth (n inertial, constant gravity ``g_n = (0, 0, -g0)``), as the comparison scene.

Sample conventions (both consequences of forward differences): ``v_k`` is the mean velocity
over ``[t_k, t_{k+1}]`` (exact at ``t_k + dt/2`` for constant acceleration) and ``a_k`` is a
second difference centred on ``t_{k+1}`` (exact at ``t_{k+1}`` for constant jerk), yet both
are declared as samples at ``t_k``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit


def attitude_from_velocity(v_n, hold_speed=0.2):
    """Euler angles (roll, pitch, yaw) [rad], shape (K, 3), from velocities v_n (K, 3) [m/s].

    Yaw 0 faces East (ENU convention), unwrapped; pitch is the climb angle; roll is 0.
    Below ``hold_speed`` (horizontal, m/s) the previous yaw and pitch are held.
    """
    v = np.asarray(v_n, dtype=float)
    vh = np.hypot(v[:, 0], v[:, 1])
    yaw = np.arctan2(v[:, 1], v[:, 0])
    pitch = np.arctan2(v[:, 2], vh)
    slow = vh < hold_speed
    if np.any(slow):
        idx = np.where(~slow, np.arange(len(v)), 0)
        np.maximum.accumulate(idx, out=idx)  # last fast sample (sample 0 if none yet)
        yaw, pitch = yaw[idx], pitch[idx]
    e = np.zeros((len(v), 3))
    e[:, 1] = pitch
    e[:, 2] = np.unwrap(yaw)
    return e


def body_rate_from_euler_rate(e, e_dot):
    """omega_nb_b = W(e) e_dot for ``C_nb = Rz(yaw) Ry(-pitch) Rx(roll)``; (..., 3) arrays."""
    sr, cr = np.sin(e[..., 0]), np.cos(e[..., 0])
    sp, cp = np.sin(e[..., 1]), np.cos(e[..., 1])
    rd, pd, yd = e_dot[..., 0], e_dot[..., 1], e_dot[..., 2]
    return np.stack([rd + sp * yd, -cr * pd + cp * sr * yd, sr * pd + cp * cr * yd], axis=-1)


def dcm_from_euler(e):
    """``C_nb = Rz(yaw) Ry(-pitch) Rx(roll)`` from (..., 3) Euler angles -> (..., 3, 3)."""
    from imugen.core.rotations import euler_to_dcm

    return euler_to_dcm(e[..., 0], e[..., 1], e[..., 2])


@dataclass
class PaperIMU:
    """Output of :func:`synthesize` (K positions in).

    v_n : (K-1, 3) forward-difference velocities; euler : (K-1, 3) attitude from them;
    gyro_b : (K-2, 3) omega_ib_b [rad/s]; accel_b : (K-2, 3) f_b [m/s^2]; all declared at t_k.
    """

    v_n: np.ndarray
    euler: np.ndarray
    gyro_b: np.ndarray
    accel_b: np.ndarray


def synthesize(p_n, dt, g0, hold_speed=0.2) -> PaperIMU:
    """Forward-difference IMU synthesis from positions p_n (K, 3) [m] sampled every dt [s]."""
    p = np.asarray(p_n, dtype=float)
    v = np.diff(p, axis=0) / dt
    a = np.diff(v, axis=0) / dt
    e = attitude_from_velocity(v, hold_speed)
    e_dot = np.diff(e, axis=0) / dt
    w = body_rate_from_euler_rate(e[:-1], e_dot)
    f_n = a.copy()
    f_n[:, 2] += g0  # f_n = a_n - g_n, g_n = (0, 0, -g0)
    C_nb = dcm_from_euler(e[:-1])
    f_b = np.einsum("kji,kj->ki", C_nb, f_n)  # C_bn f_n
    return PaperIMU(v, e, w, f_b)


@njit  # no cache: the module is also loaded by path from tests
def _forward_euler(gyro, accel, dt, g0, p0, v0, e0, P, V, Ea):
    P[0] = p0
    V[0] = v0
    Ea[0] = e0
    for k in range(gyro.shape[0]):
        r, pt, y = Ea[k, 0], Ea[k, 1], Ea[k, 2]
        sr, cr, sp, cp = np.sin(r), np.cos(r), np.sin(pt), np.cos(pt)
        sy, cy = np.sin(y), np.cos(y)
        wx, wy, wz = gyro[k, 0], gyro[k, 1], gyro[k, 2]
        # Euler rates: inverse of body_rate_from_euler_rate (singular at cos(pitch) = 0)
        yd = (sr * wy + cr * wz) / cp
        pd = -cr * wy + sr * wz
        rd = wx - sp * yd
        # C_nb f_b with C_nb = Rz(y) Ry(-pt) Rx(r)
        fx, fy, fz = accel[k, 0], accel[k, 1], accel[k, 2]
        ax = cy * cp * fx + (-sy * cr - cy * sp * sr) * fy + (sy * sr - cy * sp * cr) * fz
        ay = sy * cp * fx + (cy * cr - sy * sp * sr) * fy + (-cy * sr - sy * sp * cr) * fz
        az = sp * fx + cp * sr * fy + cp * cr * fz - g0
        P[k + 1, 0] = P[k, 0] + V[k, 0] * dt
        P[k + 1, 1] = P[k, 1] + V[k, 1] * dt
        P[k + 1, 2] = P[k, 2] + V[k, 2] * dt
        V[k + 1, 0] = V[k, 0] + ax * dt
        V[k + 1, 1] = V[k, 1] + ay * dt
        V[k + 1, 2] = V[k, 2] + az * dt
        Ea[k + 1, 0] = r + rd * dt
        Ea[k + 1, 1] = pt + pd * dt
        Ea[k + 1, 2] = y + yd * dt


def mechanize(gyro_b, accel_b, dt, g0, p0_n, v0_n, euler0):
    """Forward-Euler mechanization (the paper's INS loop, flat Earth, attitude loop closed).

    gyro_b, accel_b : (N, 3) samples; p0_n, v0_n, euler0 : (3,) initial state.
    Returns positions, velocities, Euler angles, each (N+1, 3).
    """
    gyro = np.ascontiguousarray(gyro_b, dtype=float)
    accel = np.ascontiguousarray(accel_b, dtype=float)
    N = gyro.shape[0]
    P, V, Ea = np.empty((N + 1, 3)), np.empty((N + 1, 3)), np.empty((N + 1, 3))
    _forward_euler(
        gyro,
        accel,
        float(dt),
        float(g0),
        np.asarray(p0_n, float),
        np.asarray(v0_n, float),
        np.asarray(euler0, float),
        P,
        V,
        Ea,
    )
    return P, V, Ea
