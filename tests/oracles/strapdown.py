"""Strapdown oracles of the tests: the inverse of the mechanization and a NumPy twin of its kernel.

:func:`exact_increments` gives the exact angle and velocity increments of a continuous motion
(any Earth model), so an exact IMU can be generated for a known motion and integrated back;
:func:`mechanize_numpy` is the kernel's recursion written in NumPy (no compensated sums), the
cross-check of :mod:`imugen.navigate.mechanize`. Used only by the tests (and the benchmarks
that compare against them).
"""

from __future__ import annotations

import numpy as np

from imugen.core import earth
from imugen.core.earth import OriginFrame
from imugen.core.rotations import exp_dcm, quat_mul, quat_to_dcm, relative_rotation_vector
from imugen.navigate._kernel import IG2, K3, K_D4, K_MB, N_STATE, S_G, S_K, S_P, S_Q, S_V
from imugen.navigate.mechanize import initial_state, kernel_params, nav_from_state


def _skew(w):
    return np.array([[0.0, -w[2], w[1]], [w[2], 0.0, -w[0]], [-w[1], w[0], 0.0]])


def exact_increments(times, position, velocity, attitude, frame: OriginFrame, n_gauss=4):
    """Exact angle and velocity increments of a continuous motion in n (any Earth model).

    ``dtheta_k = Log(C_k^T Exp(Omega dt) C_k+1)`` and
    ``dv_k = C_k^T [(A(dt) - I) (v_k+1 + W r_k+1) + (v_k+1 - v_k) + W (p_k+1 - p_k)
    - int_0^dt A(tau) G_n(p(t_k + tau)) dtau]``, the gravitation integral by ``n_gauss``-node
    Gauss-Legendre quadrature on the continuous position (``A(tau) = Exp(W tau)``, ``W`` the
    Earth rate in n, ``r = r0_n + p``); in ``flat`` this is ``C_k^T (v_k+1 - v_k - g dt)``.
    For ``geodetic`` frames n is ECEF: pass ECEF position, Earth-relative velocity and the
    attitude body -> ECEF.

    Parameters
    ----------
    times : ndarray, shape (K,)
        Sample times [s], uniformly spaced (the kernel's ``dt`` must be their mean spacing).
    position, velocity : callable
        ``t (m,) -> (m, 3)``: position [m] and Earth-relative velocity [m/s] in n.
    attitude : callable
        ``t (m,) -> (m, 4)``: ``q_nb`` (scalar first, continuous in sign).
    frame : OriginFrame
    n_gauss : int
        Quadrature nodes per interval.

    Returns
    -------
    dtheta_b, dv_b : ndarray, shape (K-1, 3)
        Increments of the intervals ``[t_k, t_k+1]``.
    """
    t = np.asarray(times, dtype=float)
    K = len(t)
    # the mean spacing: t[1] - t[0] carries the rounding of t[0] (3.6e-12 relative at
    # t ~ 5,000 s, dt = 0.05 s), which would bias every gravitation integral
    dt = float(t[-1] - t[0]) / (K - 1)
    w = earth.earth_rate_n(frame)
    r0 = frame.r0_n
    xg, wg = np.polynomial.legendre.leggauss(n_gauss)
    tau = 0.5 * dt * (xg + 1.0)
    wq = 0.5 * dt * wg
    A_nodes = exp_dcm(w[None, :] * tau[:, None])  # (n_gauss, 3, 3)
    # A(dt) - I = a S + b S^2, S = [w dt x], without cancellation (|w dt| < 1e-3)
    S = _skew(w * dt)
    th2 = float(w @ w) * dt * dt
    A_m_I = (1.0 - th2 / 6.0 + th2 * th2 / 120.0) * S + (0.5 - th2 / 24.0 + th2 * th2 / 720.0) * (
        S @ S
    )
    dth = np.empty((K - 1, 3))
    dvb = np.empty((K - 1, 3))
    for a in range(0, K - 1, 1 << 16):
        b = min(K - 1, a + (1 << 16))
        ta, tb = t[a:b], t[a + 1 : b + 1]
        pa, pb = position(ta), position(tb)
        va, vb = velocity(ta), velocity(tb)
        qa, qb = attitude(ta), attitude(tb)
        dth[a:b] = relative_rotation_vector(qa, qb, w, dt)
        dV = (vb - va) + (vb + np.cross(w, r0 + pb)) @ A_m_I.T + np.cross(w, pb - pa)
        for j in range(n_gauss):
            dV -= wq[j] * (earth.gravitation_n(position(ta + tau[j]), frame) @ A_nodes[j].T)
        dvb[a:b] = np.einsum("mji,mj->mi", quat_to_dcm(qa), dV)
    return dth, dvb


def mechanize_numpy(dtheta_b, dv_b, dt, p0_n, v0_n, q0_nb, frame: OriginFrame, every=1):
    """The same recursion as the kernel in NumPy, for benchmarks and cross-checks.

    Vectorized across sequences, Python loop over time (gravitation blocks included); no
    compensated sums (the kernel has them). Returns positions (S, M, 3), velocities (S, M, 3)
    and quaternions (S, M, 4) in n at samples ``0, every, 2 every, ...``.
    """
    dth = np.asarray(dtheta_b, dtype=float)
    dvb = np.asarray(dv_b, dtype=float)
    if dth.ndim == 2:
        dth = dth[None]
        dvb = dvb[None]
    S, N = dth.shape[:2]
    st = initial_state(p0_n, v0_n, q0_nb, frame, S)
    prm = kernel_params(frame, dt)
    rot = frame.model != "flat"
    m = int(prm[K_MB]) if rot else 1
    d4lim = prm[K_D4]
    T = m * dt
    tau = np.arange(m + 1) / m
    W = np.stack([T * np.diff(tau**n) / n for n in (1, 2, 3, 4)], axis=1)  # (m, 4)
    g0 = frame.g0
    c12 = dt / 12.0
    p = st[:, S_P : S_P + 3].copy()
    v = st[:, S_V : S_V + 3].copy()
    vp = v.copy()
    q = st[:, S_Q : S_Q + 4].copy()
    G = st[:, S_G : S_G + 3].copy()
    Gp = G.copy()
    nodes = [G.copy(), G.copy(), G.copy(), G.copy()]  # newest first
    d4p = np.full((S, 3), np.inf)  # 4th difference at the previous node
    M_out = N // every + 1
    P = np.empty((S, M_out, 3))
    V = np.empty((S, M_out, 3))
    Q = np.empty((S, M_out, 4))
    out = np.zeros((S, N_STATE))

    def store(j, k, p_, v_, q_, rows=slice(None)):
        o = out[rows]
        o[:, S_P : S_P + 3] = p_
        o[:, S_V : S_V + 3] = v_
        o[:, S_Q : S_Q + 4] = q_
        o[:, S_K] = k
        P[rows, j], V[rows, j], Q[rows, j] = nav_from_state(o, prm)

    def resolve(q, dv):
        qv = q[:, 1:]
        t = 2.0 * np.cross(qv, dv)
        return dv + q[:, :1] * t + np.cross(qv, t)

    def att(q, dth_k):
        d = quat_mul(q, _qexpm1_np(dth_k))
        eps = (
            (np.sum(q * q, axis=1, keepdims=True) - 1.0)
            + 2.0 * np.sum(q * d, axis=1, keepdims=True)
            + np.sum(d * d, axis=1, keepdims=True)
        )
        return q + (d - 0.5 * eps * (q + d))

    store(0, 0, p, v, q)
    k = 0
    while k < N:
        if m > 1 and k >= 4 * m and k % m == 0 and k + m <= N:
            n0, n1, n2, n3 = nodes
            p_b, v_b, vp_b, G_b, Gp_b = p, v, vp, G, Gp
            a = np.empty((m, S, 3))
            qs = [q]
            for j in range(m):
                a[j] = resolve(q, dvb[:, k + j])
                q = att(q, dth[:, k + j])
                qs.append(q)
            e = np.einsum("j,jsi->si", (m - np.arange(m) - 0.5) * dt, a)
            pp = p + T * v + e + T * T / 6.0 * (4.0 * n0 - n1)
            ge = earth.gravitation_n(pp, frame)
            c2 = 0.5 * (ge + n1) - n0
            sv = 0.5 * (ge - n1)
            c3 = (n0 - n2 + 4.0 * c2 - 2.0 * sv) / 6.0
            c1 = sv - c3
            for j in range(m):
                J = W[j, 0] * n0 + W[j, 1] * c1 + W[j, 2] * c2 + W[j, 3] * c3
                vk = v
                v = v + (a[j] + J)
                p = p + c12 * (5.0 * v + 8.0 * vk - vp)
                vp = vk
                if (k + j + 1) % every == 0:
                    store((k + j + 1) // every, k + j + 1, p, v, qs[j + 1])
            d = p - pp
            gd = IG2 * np.sum(ge * d, axis=1, keepdims=True)
            ge = ge + K3 * (3.0 * gd * ge - d)
            x = 1.0 - 1.0 / m
            Gp = n0 + x * (c1 + x * (c2 + x * c3))
            G = ge
            d4 = ge - 4.0 * n0 + 6.0 * n1 - 4.0 * n2 + n3
            est = np.max(np.abs(np.stack([d4, d4p, 2.5 * d4 - 1.5 * d4p])), axis=(0, 2))
            bad = ~(est <= d4lim)
            d4p = d4
            if bad.any():  # the failed sequences' block again, exact gravitation every step
                p_b, v_b, vp_b, G_b, Gp_b = (x[bad] for x in (p_b, v_b, vp_b, G_b, Gp_b))
                for j in range(m):
                    a_j = a[j][bad]
                    s_pred = v_b + a_j + dt * G_b
                    Gn = earth.gravitation_n(p_b + c12 * (5.0 * s_pred + 8.0 * v_b - vp_b), frame)
                    vk = v_b
                    v_b = v_b + (a_j + c12 * (5.0 * Gn + 8.0 * G_b - Gp_b))
                    p_b = p_b + c12 * (5.0 * v_b + 8.0 * vk - vp_b)
                    vp_b = vk
                    Gp_b, G_b = G_b, Gn
                    if (k + j + 1) % every == 0:
                        store((k + j + 1) // every, k + j + 1, p_b, v_b, qs[j + 1][bad], bad)
                p, v, vp, G, Gp = (x.copy() for x in (p, v, vp, G, Gp))
                p[bad], v[bad], vp[bad], G[bad], Gp[bad] = p_b, v_b, vp_b, G_b, Gp_b
            nodes = [G, n0, n1, n2]
            k += m
            continue
        first = k == 0
        a = resolve(q, dvb[:, k])
        if rot:
            s_pred = v + a + dt * G
            pp = p + 0.5 * dt * (s_pred + v) if first else p + c12 * (5.0 * s_pred + 8.0 * v - vp)
            Gn = earth.gravitation_n(pp, frame)
            J = 0.5 * dt * (Gn + G) if first else c12 * (5.0 * Gn + 8.0 * G - Gp)
            dvn = a + J
            Gp, G = G, Gn
        else:
            dvn = a.copy()
            dvn[:, 2] -= g0 * dt
        vk = v
        v = v + dvn
        dp = 0.5 * dt * (v + vk) if first else c12 * (5.0 * v + 8.0 * vk - vp)
        if k == 1:
            d = c12 * (-vp + 2.0 * vk - v)
            p = p + d
            if every == 1:
                store(1, 1, p, vk, q)
        p = p + dp
        vp = vk
        q = att(q, dth[:, k])
        k += 1
        if rot and k % m == 0:
            if k >= 4 * m:
                d4p = G - 4.0 * nodes[0] + 6.0 * nodes[1] - 4.0 * nodes[2] + nodes[3]
            nodes = [G, nodes[0], nodes[1], nodes[2]]
        if k % every == 0:
            store(k // every, k, p, v, q)
    return P, V, Q


def _qexpm1_np(phi):
    t2 = np.sum(phi * phi, axis=-1, keepdims=True)
    t = np.sqrt(t2)
    small = t2 < 1e-2
    a2 = 0.25 * t2
    c_ser = -a2 * (0.5 - a2 * (1.0 / 24.0 - a2 * (1.0 / 720.0 - a2 * (1.0 / 40320.0))))
    s_ser = 0.5 * (
        1.0 - a2 * (1.0 / 6.0 - a2 * (1.0 / 120.0 - a2 * (1.0 / 5040.0 - a2 / 362880.0)))
    )
    with np.errstate(invalid="ignore", divide="ignore"):
        c = np.where(small, c_ser, -2.0 * np.sin(0.25 * t) ** 2)
        s = np.where(small, s_ser, np.sin(0.5 * t) / t)
    return np.concatenate([c, s * phi], axis=-1)
