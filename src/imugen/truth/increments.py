"""Ideal IMU and exact increments of the truth (pass 2).

``omega_ib_b = omega_nb_b + C_nb^T Omega_n``; ``f_b = C_nb^T (a_n + 2 Omega_n x v_n - g_n)``;
``dtheta_k = Log(C_nb(t_k)^T Exp(Omega_n dt) C_nb(t_k+1))``;
``dv_k = C_nb(t_k)^T [v_I(t_k+1) - v_I(t_k) - int A(tau) G_n(p_n) dtau]`` with the
gravitation integral by 4-node Gauss-Legendre quadrature on the continuous truth position
(exact in ``flat``: ``dv_k = C_nb(t_k)^T (v_k+1 - v_k - g_n dt)``). Increments of the
interval ``[t_k, t_k+1]`` are stored on row ``k + 1`` (row 0 zeros).
"""

from __future__ import annotations

import math

import numpy as np

from imugen.core import rotations as rot

N_GAUSS = 4  # Gauss-Legendre nodes of the gravitation integral


def _expm1_rot(phi):
    """Exp(phi) - I computed without cancellation, shape (3, 3)."""
    th = float(np.linalg.norm(phi))
    S = rot.skew(phi)
    if th < 1e-3:
        a = 1.0 - th**2 / 6.0 + th**4 / 120.0
        b = 0.5 - th**2 / 24.0 + th**4 / 720.0
    else:
        a = math.sin(th) / th
        b = (1.0 - math.cos(th)) / th**2
    return a * S + b * (S @ S)


def imu_pass(out, ci, f_n, E, motion, times, dt, chunk):
    """Ideal IMU, Euler angles and increments of the truth table ``out`` (in place).

    Parameters
    ----------
    out : ndarray, shape (K, columns)
        Truth table with position, velocity, ``q_nb`` and ``omega_nb_b`` filled (pass 1).
    ci : dict
        Column slices (``pos``, ``vel``, ``quat``, ``gyro``, ``accel``, ``euler``,
        ``dtheta``, ``dv``).
    f_n : ndarray, shape (K, 3)
        Specific force in n [m/s^2].
    E : imugen.truth.attitude.EarthField
    motion : TimedMotion or PathMotion
        Continuous position (gravitation quadrature).
    times : ndarray, shape (K,)
    dt : float
        Sample interval [s].
    chunk : int
        Samples per evaluation chunk.
    """
    K = len(times)
    sP, sV, sQ, sG = ci["pos"], ci["vel"], ci["quat"], ci["gyro"]
    frame = E.frame
    q_prev = None
    for k0 in range(0, K, chunk):
        k1 = min(K, k0 + chunk)
        q = rot.quat_normalize(rot.quat_continuous(out[k0:k1, sQ], q_prev))
        out[k0:k1, sQ] = q
        q_prev = q[-1].copy()
        C = rot.quat_to_dcm(q)
        CT = np.swapaxes(C, 1, 2)
        out[k0:k1, sG] += CT @ E.Omega
        out[k0:k1, ci["accel"]] = np.einsum("mij,mj->mi", CT, f_n[k0:k1])
        out[k0:k1, ci["euler"]] = rot.dcm_to_euler(frame.C_ln(out[k0:k1, sP]) @ C)
    xg, wg = np.polynomial.legendre.leggauss(N_GAUSS)
    tau = 0.5 * dt * (xg + 1.0)
    wq = 0.5 * dt * wg
    A_nodes = rot.exp_dcm(E.Omega[None, :] * tau[:, None])  # (N_GAUSS, 3, 3)
    A_dt_minus_I = _expm1_rot(E.Omega * dt)
    for k0 in range(0, K - 1, chunk):
        k1 = min(K - 1, k0 + chunk)
        qa = out[k0:k1, sQ]
        qb = out[k0 + 1 : k1 + 1, sQ]
        out[k0 + 1 : k1 + 1, ci["dtheta"]] = rot.relative_rotation_vector(qa, qb, E.Omega, dt)
        va = out[k0:k1, sV]
        vb = out[k0 + 1 : k1 + 1, sV]
        pa_ = out[k0:k1, sP]
        pb = out[k0 + 1 : k1 + 1, sP]
        if E.flat:
            dV = (vb - va) - dt * E.gravity(pa_[:1])[0]
        else:
            wb = vb + np.cross(E.Omega, frame.r0_n + pb)
            dV = (wb @ A_dt_minus_I.T) + (vb - va) + np.cross(E.Omega, pb - pa_)
            ta = times[k0:k1]
            for jn in range(N_GAUSS):
                Gn = E.gravitation(motion.position(ta + tau[jn]))
                dV -= wq[jn] * (Gn @ A_nodes[jn].T)
        out[k0 + 1 : k1 + 1, ci["dv"]] = np.einsum("mji,mj->mi", rot.quat_to_dcm(qa), dV)
    e = ci["euler"].start
    out[:, e] = np.unwrap(out[:, e])
    out[:, e + 2] = np.unwrap(out[:, e + 2])
