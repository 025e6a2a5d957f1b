"""Batched strapdown mechanization on exact angle/velocity increments (flat and wgs84).

The recursion (n = Earth-fixed ENU frame of the route origin, see :mod:`imugen.earth`;
``W = [Omega x]``, ``A(tau) = Exp(Omega tau)``, ``dt`` the sample interval):

attitude (exact for exact increments)
    ``C_{k+1} = Exp(-Omega dt) C_k Exp(dtheta_k)`` (quaternions, renormalized each step);
velocity (exact in ``flat``; in ``wgs84`` the gravitation integral is a 3-point rule)
    ``A(dt) (v_{k+1} + W r_{k+1}) = v_k + W r_k + C_k dv_k + J_k``,
    ``J_k = int_0^dt A(tau) G(p(t_k + tau)) dtau
    ~ dt/12 (5 A(dt) G_{k+1} + 8 G_k - A(-dt) G_{k-1})``;
    ``G_{k+1}`` is evaluated at a predicted ``p_{k+1}`` (one gravity evaluation per step);
    the implicit coupling through ``W r_{k+1}`` is solved exactly (3x3 closed form);
position
    ``p_{k+1} = p_k + dt/12 (5 v_{k+1} + 8 v_k - v_{k-1})`` (Adams-Moulton, 3 points); the
    first interval uses the same quadratic with one sample of look-ahead,
    ``dt/12 (5 v_0 + 8 v_1 - v_2)``, applied once ``v_2`` is known.

Positions and velocities are accumulated with compensated (Kahan) sums, so 1 kHz over an
hour loses nothing to float64 rounding. The time recursion is one numba kernel
(``cache=True``): sequences in the outer loop, time inside, state in registers, no
allocation per step; it resumes from a state array, so long runs can be fed in time chunks
and outputs can be decimated (every N-th sample) or restricted to positions.

numba caches the compiled kernel next to this file and keys the cache on this file only: after
editing :mod:`imugen.earth` during development, delete ``__pycache__/*.nbi``/``*.nbc`` so the
kernel picks up the change.

:func:`increments_from_rates` turns instantaneous rate samples into increments with the
standard second-order scheme (trapezoid + coning + sculling for linearly varying rates), and
:func:`mechanize_rates` feeds them to the same kernel.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from imugen import earth
from imugen.earth import OriginFrame
from imugen.jit import njit
from imugen.rotations import quat_mul

# --- state layout (one row per sequence) --------------------------------------------------------
S_P = 0  # position p_n (3)
S_PC = 3  # Kahan compensation of p (3)
S_V = 6  # velocity v_n (3)
S_VC = 9  # Kahan compensation of v (3)
S_Q = 12  # quaternion q_nb (4), scalar first
S_VP = 16  # v_{k-1} (3)
S_G = 19  # gravitation at p_k (3) (wgs84)
S_GP = 22  # gravitation at p_{k-1} (3) (wgs84)
S_K = 25  # steps done
S_QC = 26  # Kahan compensation of q (4)
N_STATE = 30

# --- kernel parameter vector: frame params (earth.N_PARAMS) then these ------------------------
K_DT = earth.N_PARAMS  # dt
K_A = K_DT + 1  # A(dt) = Exp(W dt), 9 row-major
K_D = K_A + 9  # D = A(dt)^T - I, 9 row-major (computed without cancellation)
K_M = K_D + 9  # M_am = (I + c W)^{-1}, c = 5 dt/12, 9
K_MT = K_M + 9  # M_tr = (I + c W)^{-1}, c = dt/2 (first step), 9
K_QW = K_MT + 9  # quaternion of Exp(-Omega dt) minus (1, 0, 0, 0), 4
N_KPARAMS = K_QW + 4


def _skew(w):
    return np.array([[0.0, -w[2], w[1]], [w[2], 0.0, -w[0]], [-w[1], w[0], 0.0]])


def _inv_i_plus_cw(w, c):
    """(I + c [w x])^-1 = (I - c W + c^2 w w^T) / (1 + c^2 |w|^2)."""
    W = _skew(w)
    return (np.eye(3) - c * W + c * c * np.outer(w, w)) / (1.0 + c * c * (w @ w))


def kernel_params(frame: OriginFrame, dt: float) -> np.ndarray:
    """Parameter vector of the kernel: earth parameters + dt + precomputed rotations."""
    prm = np.zeros(N_KPARAMS)
    prm[: earth.N_PARAMS] = frame.params()
    prm[K_DT] = dt
    w = earth.earth_rate_n(frame)
    wn = float(np.linalg.norm(w))
    W = _skew(w)
    if wn > 0.0:
        th = wn * dt
        s1 = math.sin(th) / wn
        s2 = 2.0 * math.sin(th / 2.0) ** 2 / wn**2  # (1 - cos) / |w|^2
        A = np.eye(3) + s1 * W + s2 * (W @ W)
        D = -s1 * W + s2 * (W @ W)  # A^T - I
        # quaternion of Exp(-Omega dt) minus identity
        qw = np.array([-2.0 * math.sin(th / 4.0) ** 2, *(-math.sin(th / 2.0) * w / wn)])
    else:
        A = np.eye(3)
        D = np.zeros((3, 3))
        qw = np.zeros(4)
    prm[K_A : K_A + 9] = A.ravel()
    prm[K_D : K_D + 9] = D.ravel()
    prm[K_M : K_M + 9] = _inv_i_plus_cw(w, 5.0 * dt / 12.0).ravel()
    prm[K_MT : K_MT + 9] = _inv_i_plus_cw(w, dt / 2.0).ravel()
    prm[K_QW : K_QW + 4] = qw
    return prm


def initial_state(p0_n, v0_n, q0_nb, frame: OriginFrame, S: int | None = None) -> np.ndarray:
    """State array (S, N_STATE) from initial position, velocity and attitude.

    Parameters
    ----------
    p0_n, v0_n : ndarray, shape (3,) or (S, 3)
        Initial position [m] and velocity [m/s] in n.
    q0_nb : ndarray, shape (4,) or (S, 4)
        Initial attitude quaternion (scalar first).
    frame : OriginFrame
    S : int, optional
        Number of sequences when all inputs are single vectors.
    """
    p0 = np.atleast_2d(np.asarray(p0_n, dtype=float))
    v0 = np.atleast_2d(np.asarray(v0_n, dtype=float))
    q0 = np.atleast_2d(np.asarray(q0_nb, dtype=float))
    n = max(len(p0), len(v0), len(q0), S or 1)
    st = np.zeros((n, N_STATE))
    st[:, S_P : S_P + 3] = p0
    st[:, S_V : S_V + 3] = v0
    st[:, S_VP : S_VP + 3] = v0
    q0 = q0 / np.linalg.norm(q0, axis=1, keepdims=True)
    st[:, S_Q : S_Q + 4] = q0
    G = earth.gravitation_n(np.broadcast_to(p0, (n, 3)), frame)
    st[:, S_G : S_G + 3] = G
    st[:, S_GP : S_GP + 3] = G
    return st


# --- numba kernel --------------------------------------------------------------------------------
@njit(cache=True, inline="always")
def _qexpm1(x, y, z):
    """Exp of a rotation vector as a quaternion minus identity: (cos(t/2) - 1, sin(t/2)/t v).

    Series for |t| < 0.1 (exact in float64), closed form otherwise; no cancellation in the
    scalar part.
    """
    t2 = x * x + y * y + z * z
    if t2 < 1e-2:
        a2 = 0.25 * t2
        cm1 = -a2 * (0.5 - a2 * (1.0 / 24.0 - a2 * (1.0 / 720.0 - a2 * (1.0 / 40320.0))))
        s = 0.5 * (
            1.0 - a2 * (1.0 / 6.0 - a2 * (1.0 / 120.0 - a2 * (1.0 / 5040.0 - a2 / 362880.0)))
        )
    else:
        t = math.sqrt(t2)
        sq = math.sin(0.25 * t)
        cm1 = -2.0 * sq * sq
        s = math.sin(0.5 * t) / t
    return cm1, s * x, s * y, s * z


@njit(cache=True, inline="always")
def _qmul(aw, ax, ay, az, bw, bx, by, bz):
    return (
        aw * bw - ax * bx - ay * by - az * bz,
        aw * bx + ax * bw + ay * bz - az * by,
        aw * by - ax * bz + ay * bw + az * bx,
        aw * bz + ax * by - ay * bx + az * bw,
    )


@njit(cache=True, inline="always")
def _qrot(qw, qx, qy, qz, vx, vy, vz):
    """Rotate v by q (C(q) v): v + w t + q_vec x t with t = 2 q_vec x v."""
    tx = 2.0 * (qy * vz - qz * vy)
    ty = 2.0 * (qz * vx - qx * vz)
    tz = 2.0 * (qx * vy - qy * vx)
    return (
        vx + qw * tx + (qy * tz - qz * ty),
        vy + qw * ty + (qz * tx - qx * tz),
        vz + qw * tz + (qx * ty - qy * tx),
    )


@njit(cache=True, inline="always")
def _mv(m, o, x, y, z):
    return (
        m[o] * x + m[o + 1] * y + m[o + 2] * z,
        m[o + 3] * x + m[o + 4] * y + m[o + 5] * z,
        m[o + 6] * x + m[o + 7] * y + m[o + 8] * z,
    )


@njit(cache=True, inline="always")
def _lookahead_shift(prm, wgs, v0x, v0y, v0z, v1x, v1y, v1z, v2x, v2y, v2z):
    """Shift of p1 (and p2) when the first interval gets dt/12 (5 v0 + 8 v1 - v2) instead of
    the trapezoid, and the matching change -W shift of v1, v2 (wgs84)."""
    c12 = prm[K_DT] / 12.0
    dx = c12 * (-v0x + 2.0 * v1x - v2x)
    dy = c12 * (-v0y + 2.0 * v1y - v2y)
    dz = c12 * (-v0z + 2.0 * v1z - v2z)
    if wgs:
        w0 = prm[earth.P_OMEGA]
        w1 = prm[earth.P_OMEGA + 1]
        w2 = prm[earth.P_OMEGA + 2]
        return dx, dy, dz, w1 * dz - w2 * dy, w2 * dx - w0 * dz, w0 * dy - w1 * dx
    return dx, dy, dz, 0.0, 0.0, 0.0


@njit(cache=True, inline="always")
def _write(out_p, out_v, out_q, s, slot, px, py, pz, vx, vy, vz, q0, q1, q2, q3, wq):
    if 0 <= slot < out_p.shape[1]:
        out_p[s, slot, 0] = px
        out_p[s, slot, 1] = py
        out_p[s, slot, 2] = pz
    if 0 <= slot < out_v.shape[1]:
        out_v[s, slot, 0] = vx
        out_v[s, slot, 1] = vy
        out_v[s, slot, 2] = vz
    if wq and 0 <= slot < out_q.shape[1]:
        out_q[s, slot, 0] = q0
        out_q[s, slot, 1] = q1
        out_q[s, slot, 2] = q2
        out_q[s, slot, 3] = q3


@njit(cache=True)
def _kernel(dth, dvb, st, prm, every, out_p, out_v, out_q, out_start):
    """Advance every sequence by ``dth.shape[1]`` steps (sequences outside, time inside).

    dth, dvb : (S, N, 3) increments; st : (S, N_STATE) state, updated in place;
    prm : kernel_params; out_* : (S, M, 3|4), M == 0 to skip; sample j (global index) is
    written to slot ``j // every - out_start`` when ``j % every == 0``.
    """
    S = dth.shape[0]
    N = dth.shape[1]
    wgs = prm[earth.P_MODEL] != 0.0
    dt = prm[K_DT]
    c12 = dt / 12.0
    for s in range(S):
        # fmt: off
        (px, py, pz, pcx, pcy, pcz, vx, vy, vz, vcx, vcy, vcz,
         q0, q1, q2, q3, vpx, vpy, vpz, Gx, Gy, Gz, Gpx, Gpy, Gpz) = st[s, :25]
        # fmt: on
        qc0, qc1, qc2, qc3 = st[s, S_QC], st[s, S_QC + 1], st[s, S_QC + 2], st[s, S_QC + 3]
        k = int(st[s, S_K])
        for i in range(N):
            if k == 1:
                v0x = vpx
                v0y = vpy
                v0z = vpz
                p1x = px
                p1y = py
                p1z = pz
            # specific-force increment resolved in n at t_k: a = C_k dv
            ax, ay, az = _qrot(q0, q1, q2, q3, dvb[s, i, 0], dvb[s, i, 1], dvb[s, i, 2])
            if wgs:
                w0 = prm[earth.P_OMEGA]
                w1 = prm[earth.P_OMEGA + 1]
                w2 = prm[earth.P_OMEGA + 2]
                rx = prm[earth.P_R0N] + px
                ry = prm[earth.P_R0N + 1] + py
                rz = prm[earth.P_R0N + 2] + pz
                wrx = w1 * rz - w2 * ry
                wry = w2 * rx - w0 * rz
                wrz = w0 * ry - w1 * rx
                # predictor of v_{k+1}, p_{k+1} (explicit Euler for gravity, Coriolis, centrifugal)
                wvx = w1 * vz - w2 * vy
                wvy = w2 * vx - w0 * vz
                wvz = w0 * vy - w1 * vx
                cfx = w1 * wrz - w2 * wry
                cfy = w2 * wrx - w0 * wrz
                cfz = w0 * wry - w1 * wrx
                sx = vx + ax + dt * (Gx - 2.0 * wvx - cfx)
                sy = vy + ay + dt * (Gy - 2.0 * wvy - cfy)
                sz = vz + az + dt * (Gz - 2.0 * wvz - cfz)
                if k == 0:
                    ppx = px + 0.5 * dt * (sx + vx)
                    ppy = py + 0.5 * dt * (sy + vy)
                    ppz = pz + 0.5 * dt * (sz + vz)
                else:
                    ppx = px + c12 * (5.0 * sx + 8.0 * vx - vpx)
                    ppy = py + c12 * (5.0 * sy + 8.0 * vy - vpy)
                    ppz = pz + c12 * (5.0 * sz + 8.0 * vz - vpz)
                Gnx, Gny, Gnz = earth.gravitation_nb(prm, ppx, ppy, ppz)
                AGx, AGy, AGz = _mv(prm, K_A, Gnx, Gny, Gnz)
                if k == 0:
                    Jx = 0.5 * dt * (AGx + Gx)
                    Jy = 0.5 * dt * (AGy + Gy)
                    Jz = 0.5 * dt * (AGz + Gz)
                else:
                    # A(-dt) G_{k-1} = A^T G_{k-1}
                    bx = prm[K_A] * Gpx + prm[K_A + 3] * Gpy + prm[K_A + 6] * Gpz
                    by = prm[K_A + 1] * Gpx + prm[K_A + 4] * Gpy + prm[K_A + 7] * Gpz
                    bz = prm[K_A + 2] * Gpx + prm[K_A + 5] * Gpy + prm[K_A + 8] * Gpz
                    Jx = c12 * (5.0 * AGx + 8.0 * Gx - bx)
                    Jy = c12 * (5.0 * AGy + 8.0 * Gy - by)
                    Jz = c12 * (5.0 * AGz + 8.0 * Gz - bz)
                # D s with s = v_k + W r_k + a + J and D = A^T - I
                dsx, dsy, dsz = _mv(
                    prm, K_D, vx + wrx + ax + Jx, vy + wry + ay + Jy, vz + wrz + az + Jz
                )
                # W (c v_k + e_p): AM3 -> dt/12 (13 v_k - v_{k-1}); trapezoid -> dt v_k
                if k == 0:
                    hx = dt * vx
                    hy = dt * vy
                    hz = dt * vz
                else:
                    hx = c12 * (13.0 * vx - vpx)
                    hy = c12 * (13.0 * vy - vpy)
                    hz = c12 * (13.0 * vz - vpz)
                ex = ax + Jx + dsx - (w1 * hz - w2 * hy)
                ey = ay + Jy + dsy - (w2 * hx - w0 * hz)
                ez = az + Jz + dsz - (w0 * hy - w1 * hx)
                if k == 0:
                    dvx, dvy, dvz = _mv(prm, K_MT, ex, ey, ez)
                else:
                    dvx, dvy, dvz = _mv(prm, K_M, ex, ey, ez)
                Gpx = Gx
                Gpy = Gy
                Gpz = Gz
                Gx = Gnx
                Gy = Gny
                Gz = Gnz
            else:
                dvx = ax
                dvy = ay
                dvz = az - prm[earth.P_G0] * dt
            # v_{k+1} = v_k + dv (Kahan)
            ovx = vx
            ovy = vy
            ovz = vz
            yx = dvx - vcx
            yy = dvy - vcy
            yz = dvz - vcz
            tx = vx + yx
            ty = vy + yy
            tz = vz + yz
            vcx = (tx - vx) - yx
            vcy = (ty - vy) - yy
            vcz = (tz - vz) - yz
            vx = tx
            vy = ty
            vz = tz
            # p_{k+1} = p_k + int v (Kahan)
            if k == 0:
                dpx = 0.5 * dt * (vx + ovx)
                dpy = 0.5 * dt * (vy + ovy)
                dpz = 0.5 * dt * (vz + ovz)
            else:
                dpx = c12 * (5.0 * vx + 8.0 * ovx - vpx)
                dpy = c12 * (5.0 * vy + 8.0 * ovy - vpy)
                dpz = c12 * (5.0 * vz + 8.0 * ovz - vpz)
            yx = dpx - pcx
            yy = dpy - pcy
            yz = dpz - pcz
            tx = px + yx
            ty = py + yy
            tz = pz + yz
            pcx = (tx - px) - yx
            pcy = (ty - py) - yy
            pcz = (tz - pz) - yz
            px = tx
            py = ty
            pz = tz
            # attitude: q <- q_W* (x) q (x) Exp(dtheta), as q + dq with dq computed from small
            # quantities and added with a compensated sum (no systematic rounding drift)
            em0, e1, e2, e3 = _qexpm1(dth[s, i, 0], dth[s, i, 1], dth[s, i, 2])
            d0, d1, d2, d3 = _qmul(q0, q1, q2, q3, em0, e1, e2, e3)
            if wgs:
                f0, f1, f2, f3 = _qmul(
                    prm[K_QW],
                    prm[K_QW + 1],
                    prm[K_QW + 2],
                    prm[K_QW + 3],
                    q0 + d0,
                    q1 + d1,
                    q2 + d2,
                    q3 + d3,
                )
                d0 += f0
                d1 += f1
                d2 += f2
                d3 += f3
            # first-order renormalization: scale by 1 - eps/2, eps = |q + dq|^2 - 1
            eps = (
                ((q0 * q0 + q1 * q1 + q2 * q2 + q3 * q3) - 1.0)
                + 2.0 * (q0 * d0 + q1 * d1 + q2 * d2 + q3 * d3)
                + (d0 * d0 + d1 * d1 + d2 * d2 + d3 * d3)
            )
            h = -0.5 * eps
            d0 += h * (q0 + d0)
            d1 += h * (q1 + d1)
            d2 += h * (q2 + d2)
            d3 += h * (q3 + d3)
            y0 = d0 - qc0
            y1 = d1 - qc1
            y2 = d2 - qc2
            y3 = d3 - qc3
            t0 = q0 + y0
            t1 = q1 + y1
            t2 = q2 + y2
            t3 = q3 + y3
            qc0 = (t0 - q0) - y0
            qc1 = (t1 - q1) - y1
            qc2 = (t2 - q2) - y2
            qc3 = (t3 - q3) - y3
            q0 = t0
            q1 = t1
            q2 = t2
            q3 = t3
            vpx = ovx
            vpy = ovy
            vpz = ovz
            if k == 1:
                dx, dy, dz, cx, cy, cz = _lookahead_shift(
                    prm, wgs, v0x, v0y, v0z, vpx, vpy, vpz, vx, vy, vz
                )
                px += dx
                py += dy
                pz += dz
                vpx -= cx
                vpy -= cy
                vpz -= cz
                vx -= cx
                vy -= cy
                vz -= cz
                if every == 1:
                    _write(
                        out_p,
                        out_v,
                        out_q,
                        s,
                        1 - out_start,
                        p1x + dx,
                        p1y + dy,
                        p1z + dz,
                        vpx,
                        vpy,
                        vpz,
                        0.0,
                        0.0,
                        0.0,
                        0.0,
                        False,
                    )
            k += 1
            if k % every == 0:
                _write(
                    out_p,
                    out_v,
                    out_q,
                    s,
                    k // every - out_start,
                    px,
                    py,
                    pz,
                    vx,
                    vy,
                    vz,
                    q0,
                    q1,
                    q2,
                    q3,
                    True,
                )
        # fmt: off
        st[s, :25] = (px, py, pz, pcx, pcy, pcz, vx, vy, vz, vcx, vcy, vcz,
                      q0, q1, q2, q3, vpx, vpy, vpz, Gx, Gy, Gz, Gpx, Gpy, Gpz)
        # fmt: on
        st[s, S_QC], st[s, S_QC + 1], st[s, S_QC + 2], st[s, S_QC + 3] = qc0, qc1, qc2, qc3
        st[s, S_K] = k


# --- Python drivers ------------------------------------------------------------------------------
@dataclass
class Navigation:
    """Result of a mechanization run.

    Attributes
    ----------
    index : ndarray, shape (M,)
        Sample indices of the stored outputs (``0, every, 2 every, ...``).
    p_n, v_n : ndarray, shape (S, M, 3) or None
        Position [m] and velocity [m/s] in n at those samples (None when not requested).
    q_nb : ndarray, shape (S, M, 4) or None
        Attitude quaternion (scalar first).
    p_end_n, v_end_n : ndarray, shape (S, 3)
        Final position and velocity (sample K-1), always returned.
    q_end_nb : ndarray, shape (S, 4)
        Final attitude.
    """

    index: np.ndarray
    p_n: np.ndarray | None
    v_n: np.ndarray | None
    q_nb: np.ndarray | None
    p_end_n: np.ndarray
    v_end_n: np.ndarray
    q_end_nb: np.ndarray

    def squeeze(self) -> Navigation:
        """Drop the sequence axis (single-sequence runs)."""

        def sq(a):
            return None if a is None else a[0]

        return Navigation(
            self.index,
            sq(self.p_n),
            sq(self.v_n),
            sq(self.q_nb),
            self.p_end_n[0],
            self.v_end_n[0],
            self.q_end_nb[0],
        )


class Mechanizer:
    """Stateful batched strapdown: feed increments in time chunks with :meth:`run`.

    Parameters
    ----------
    frame : OriginFrame
        Origin and Earth model (``frame.model`` is ``"flat"`` or ``"wgs84"``).
    dt : float
        Sample interval [s].
    p0_n, v0_n : ndarray, shape (3,) or (S, 3)
        Initial position [m] and velocity [m/s].
    q0_nb : ndarray, shape (4,) or (S, 4)
        Initial attitude (scalar first).
    S : int, optional
        Number of sequences when all initial values are single vectors.
    """

    def __init__(self, frame: OriginFrame, dt: float, p0_n, v0_n, q0_nb, S: int | None = None):
        self.frame = frame
        self.dt = float(dt)
        self.prm = kernel_params(frame, self.dt)
        self.state = initial_state(p0_n, v0_n, q0_nb, frame, S)

    @property
    def steps(self) -> int:
        """Number of increments integrated so far."""
        return int(self.state[0, S_K])

    @property
    def p_n(self) -> np.ndarray:
        return self.state[:, S_P : S_P + 3].copy()

    @property
    def v_n(self) -> np.ndarray:
        return self.state[:, S_V : S_V + 3].copy()

    @property
    def q_nb(self) -> np.ndarray:
        return self.state[:, S_Q : S_Q + 4].copy()

    def run(self, dtheta_b, dv_b, out_p=None, out_v=None, out_q=None, every=1, out_start=0):
        """Integrate a time chunk of increments for all sequences.

        Parameters
        ----------
        dtheta_b, dv_b : ndarray, shape (S, N, 3)
            Angle [rad] and velocity [m/s] increments of the next N intervals.
        out_p, out_v, out_q : ndarray, shape (S, M, 3|4), optional
            Preallocated outputs; sample ``j`` (global index) goes to slot
            ``j // every - out_start`` when ``j % every == 0``; None to skip.
        """
        dth = np.ascontiguousarray(dtheta_b, dtype=np.float64)
        dvb = np.ascontiguousarray(dv_b, dtype=np.float64)
        S = self.state.shape[0]
        if dth.shape != dvb.shape or dth.ndim != 3 or dth.shape[0] != S or dth.shape[2] != 3:
            raise ValueError(f"increments must be (S={S}, N, 3), got {dth.shape}, {dvb.shape}")
        empty3 = np.empty((S, 0, 3))
        empty4 = np.empty((S, 0, 4))
        _kernel(
            dth,
            dvb,
            self.state,
            self.prm,
            int(every),
            empty3 if out_p is None else out_p,
            empty3 if out_v is None else out_v,
            empty4 if out_q is None else out_q,
            int(out_start),
        )


def mechanize(
    dtheta_b,
    dv_b,
    dt,
    p0_n,
    v0_n,
    q0_nb,
    frame: OriginFrame,
    *,
    every=1,
    outputs=("p", "v", "q"),
    seq_chunk=256,
) -> Navigation:
    """Strapdown-integrate exact increments for a batch of sequences.

    Parameters
    ----------
    dtheta_b, dv_b : ndarray, shape (S, K-1, 3) or (K-1, 3)
        Angle [rad] and velocity [m/s] increments; row k is the interval [t_k, t_{k+1}].
    dt : float
        Sample interval [s].
    p0_n, v0_n : ndarray, shape (3,) or (S, 3)
        Initial position [m] and velocity [m/s] in n.
    q0_nb : ndarray, shape (4,) or (S, 4)
        Initial attitude quaternion (scalar first).
    frame : OriginFrame
        Origin and Earth model.
    every : int
        Store every N-th sample (``index = 0, every, ...``); the final state is always returned.
    outputs : iterable of {"p", "v", "q"}
        Which series to store (e.g. ``("p",)`` for positions only).
    seq_chunk : int
        Sequences per kernel call (bounds the working set; outputs are preallocated).

    Returns
    -------
    Navigation
        With a sequence axis, unless the increments were 2-D.
    """
    dth = np.asarray(dtheta_b, dtype=float)
    dvb = np.asarray(dv_b, dtype=float)
    single = dth.ndim == 2
    if single:
        dth = dth[None]
        dvb = dvb[None]
    S, N = dth.shape[:2]
    mech = Mechanizer(frame, dt, p0_n, v0_n, q0_nb, S)
    every = int(every)
    if every < 1:
        raise ValueError("every must be >= 1")
    index = np.arange(0, N + 1, every)
    M = len(index)
    outputs = set(outputs)
    out_p = np.empty((S, M, 3)) if "p" in outputs else None
    out_v = np.empty((S, M, 3)) if "v" in outputs else None
    out_q = np.empty((S, M, 4)) if "q" in outputs else None
    st = mech.state
    if out_p is not None:
        out_p[:, 0] = st[:, S_P : S_P + 3]
    if out_v is not None:
        out_v[:, 0] = st[:, S_V : S_V + 3]
    if out_q is not None:
        out_q[:, 0] = st[:, S_Q : S_Q + 4]
    empty3 = np.empty((0, 0, 3))
    empty4 = np.empty((0, 0, 4))
    for a in range(0, S, seq_chunk):
        b = min(S, a + seq_chunk)
        _kernel(
            np.ascontiguousarray(dth[a:b]),
            np.ascontiguousarray(dvb[a:b]),
            st[a:b],
            mech.prm,
            every,
            empty3 if out_p is None else out_p[a:b],
            empty3 if out_v is None else out_v[a:b],
            empty4 if out_q is None else out_q[a:b],
            0,
        )
    nav = Navigation(index, out_p, out_v, out_q, mech.p_n, mech.v_n, mech.q_nb)
    return nav.squeeze() if single else nav


# --- rate-sampled IMU ----------------------------------------------------------------------------
def increments_from_rates(omega_ib_b, f_b, dt):
    """Instantaneous rate samples -> increments (2nd-order: trapezoid + coning + sculling).

    With rates varying linearly over each interval, ``alpha(tau) = int_0^tau omega``:
    ``dtheta = dt/2 (w_k + w_{k+1}) + dt^2/12 w_k x w_{k+1}`` and
    ``dv = dt/2 (f_k + f_{k+1}) + int_0^dt alpha x f dtau``
    ``= ... + dt^2 (w_k x f_k / 2 + w_k x df / 3 + dw x f_k / 6 + dw x df / 8)``.

    Parameters
    ----------
    omega_ib_b : ndarray, shape (..., K, 3)
        Angular rate samples [rad/s] at t_k.
    f_b : ndarray, shape (..., K, 3)
        Specific force samples [m/s^2] at t_k.
    dt : float
        Sample interval [s].

    Returns
    -------
    dtheta_b, dv_b : ndarray, shape (..., K-1, 3)
    """
    w = np.asarray(omega_ib_b, dtype=float)
    f = np.asarray(f_b, dtype=float)
    w0, w1 = w[..., :-1, :], w[..., 1:, :]
    f0, f1 = f[..., :-1, :], f[..., 1:, :]
    dw = w1 - w0
    df = f1 - f0
    dtheta = 0.5 * dt * (w0 + w1) + dt * dt / 12.0 * np.cross(w0, w1)
    dv = 0.5 * dt * (f0 + f1) + dt * dt * (
        0.5 * np.cross(w0, f0)
        + np.cross(w0, df) / 3.0
        + np.cross(dw, f0) / 6.0
        + np.cross(dw, df) / 8.0
    )
    return dtheta, dv


def interval_integrals(x, dt):
    """Plain integrals of uniformly sampled signals over each sample interval (4-point rule).

    ``out[k] = int_{t_{k-1}}^{t_k} x dt`` for ``k >= 1`` (row 0 is zero), from the cubic through
    the four nearest samples: ``dt/24 (-x_{k-2} + 13 x_{k-1} + 13 x_k - x_{k+1})`` inside,
    ``dt/24 (9 x_0 + 19 x_1 - 5 x_2 + x_3)`` on the first interval and its mirror on the last.
    Exact for cubics; local error ``11/720 dt^5 x^(4)`` inside (``19/720`` at the ends), so
    the sum over a fixed span converges as ``dt^4``. Fewer than 4 samples: trapezoid.

    Parameters
    ----------
    x : ndarray, shape (K, 3)
        Samples at ``t_k = t_0 + k dt``.
    dt : float

    Returns
    -------
    ndarray, shape (K, 3)
    """
    x = np.asarray(x, dtype=float)
    K = x.shape[0]
    out = np.zeros_like(x)
    if K < 4:
        out[1:] = 0.5 * dt * (x[1:] + x[:-1])
        return out
    c = dt / 24.0
    out[2 : K - 1] = c * (-x[: K - 3] + 13.0 * x[1 : K - 2] + 13.0 * x[2 : K - 1] - x[3:])
    out[1] = c * (9.0 * x[0] + 19.0 * x[1] - 5.0 * x[2] + x[3])
    out[K - 1] = c * (9.0 * x[K - 1] + 19.0 * x[K - 2] - 5.0 * x[K - 3] + x[K - 4])
    return out


@njit(cache=True)
def _compensate(dth, dv):
    S, K = dth.shape[0], dth.shape[1]
    for s in range(S):
        pa0 = pa1 = pa2 = 0.0  # raw dtheta of the previous interval (zero before the first)
        pv0 = pv1 = pv2 = 0.0  # raw dv of the previous interval
        for k in range(K):
            a0, a1, a2 = dth[s, k, 0], dth[s, k, 1], dth[s, k, 2]
            v0, v1, v2 = dv[s, k, 0], dv[s, k, 1], dv[s, k, 2]
            # coning: (a_prev x a) / 12
            c0 = (pa1 * a2 - pa2 * a1) / 12.0
            c1 = (pa2 * a0 - pa0 * a2) / 12.0
            c2 = (pa0 * a1 - pa1 * a0) / 12.0
            # rotation a x v / 2 + a x (a x v) / 6 and sculling (a_prev x v + v_prev x a) / 12
            x0 = a1 * v2 - a2 * v1
            x1 = a2 * v0 - a0 * v2
            x2 = a0 * v1 - a1 * v0
            r0 = 0.5 * x0 + (a1 * x2 - a2 * x1) / 6.0
            r1 = 0.5 * x1 + (a2 * x0 - a0 * x2) / 6.0
            r2 = 0.5 * x2 + (a0 * x1 - a1 * x0) / 6.0
            s0 = (pa1 * v2 - pa2 * v1 + pv1 * a2 - pv2 * a1) / 12.0
            s1 = (pa2 * v0 - pa0 * v2 + pv2 * a0 - pv0 * a2) / 12.0
            s2 = (pa0 * v1 - pa1 * v0 + pv0 * a1 - pv1 * a0) / 12.0
            dth[s, k, 0] = a0 + c0
            dth[s, k, 1] = a1 + c1
            dth[s, k, 2] = a2 + c2
            dv[s, k, 0] = v0 + r0 + s0
            dv[s, k, 1] = v1 + r1 + s1
            dv[s, k, 2] = v2 + r2 + s2
            pa0, pa1, pa2 = a0, a1, a2
            pv0, pv1, pv2 = v0, v1, v2


def compensate_raw(dtheta_b, dv_b):
    """Raw increments (plain integrals) -> compensated increments, in place (two-sample rule).

    The standard two-sample coning and sculling corrections with the previous interval
    (Savage, Strapdown Analytics, 2000, sec. 7.1.1.1 and 7.2.2.2.2; exact for rates varying
    linearly across the two intervals):
    ``phi_k = a_k + (a_{k-1} x a_k) / 12`` and
    ``dv_k = v_k + (a_k x v_k) / 2 + (a_{k-1} x v_k + v_{k-1} x a_k) / 12``, with ``a``, ``v``
    the raw angle and velocity integrals; before the first interval the previous ones are
    taken as zero.

    Parameters
    ----------
    dtheta_b, dv_b : ndarray, shape (S, N, 3) or (N, 3), float64, C-contiguous
        Consecutive raw increments of each sequence (no zero row 0); overwritten and returned.
    """
    a = dtheta_b if dtheta_b.ndim == 3 else dtheta_b[None]
    b = dv_b if dv_b.ndim == 3 else dv_b[None]
    _compensate(a, b)
    return dtheta_b, dv_b


def mechanize_rates(omega_ib_b, f_b, dt, p0_n, v0_n, q0_nb, frame: OriginFrame, **kw):
    """Mechanize instantaneous rate samples: :func:`increments_from_rates` + :func:`mechanize`."""
    dtheta, dv = increments_from_rates(omega_ib_b, f_b, dt)
    return mechanize(dtheta, dv, dt, p0_n, v0_n, q0_nb, frame, **kw)


# --- pure NumPy reference (vectorized across sequences, Python loop over time) -----------------
def mechanize_numpy(dtheta_b, dv_b, dt, p0_n, v0_n, q0_nb, frame: OriginFrame, every=1):
    """The same recursion as the kernel in NumPy, for benchmarks and cross-checks.

    Vectorized across sequences, Python loop over time; no compensated sums (the kernel
    has them). Returns positions (S, M, 3), velocities (S, M, 3) and quaternions (S, M, 4)
    at samples ``0, every, 2 every, ...``.
    """
    dth = np.asarray(dtheta_b, dtype=float)
    dvb = np.asarray(dv_b, dtype=float)
    if dth.ndim == 2:
        dth = dth[None]
        dvb = dvb[None]
    S, N = dth.shape[:2]
    st = initial_state(p0_n, v0_n, q0_nb, frame, S)
    prm = kernel_params(frame, dt)
    wgs = frame.model == "wgs84"
    w = earth.earth_rate_n(frame)
    A = prm[K_A : K_A + 9].reshape(3, 3)
    Dm = prm[K_D : K_D + 9].reshape(3, 3)
    Mam = prm[K_M : K_M + 9].reshape(3, 3)
    Mtr = prm[K_MT : K_MT + 9].reshape(3, 3)
    qW = prm[K_QW : K_QW + 4]
    r0 = frame.r0_n
    g0 = frame.g0
    c12 = dt / 12.0
    p = st[:, S_P : S_P + 3].copy()
    v = st[:, S_V : S_V + 3].copy()
    vp = v.copy()
    q = st[:, S_Q : S_Q + 4].copy()
    G = st[:, S_G : S_G + 3].copy()
    Gp = G.copy()
    M_out = N // every + 1
    P = np.empty((S, M_out, 3))
    V = np.empty((S, M_out, 3))
    Q = np.empty((S, M_out, 4))
    P[:, 0], V[:, 0], Q[:, 0] = p, v, q
    for k in range(N):
        first = k == 0
        qv = q[:, 1:]
        t = 2.0 * np.cross(qv, dvb[:, k])
        a = dvb[:, k] + q[:, :1] * t + np.cross(qv, t)
        if wgs:
            r = r0 + p
            wr = np.cross(w, r)
            s_pred = v + a + dt * (G - 2.0 * np.cross(w, v) - np.cross(w, wr))
            if first:
                pp = p + 0.5 * dt * (s_pred + v)
            else:
                pp = p + c12 * (5.0 * s_pred + 8.0 * v - vp)
            Gn = earth.gravitation_n(pp, frame)
            AG = Gn @ A.T
            J = 0.5 * dt * (AG + G) if first else c12 * (5.0 * AG + 8.0 * G - Gp @ A)
            ds = (v + wr + a + J) @ Dm.T
            h = dt * v if first else c12 * (13.0 * v - vp)
            e = a + J + ds - np.cross(w, h)
            dvn = e @ (Mtr if first else Mam).T
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
            if wgs:
                c = np.cross(w, d)
                vk = vk - c
                v = v - c
            if every == 1:
                P[:, 1] = p
                V[:, 1] = vk
        p = p + dp
        vp = vk
        d = quat_mul(q, _qexpm1_np(dth[:, k]))
        if wgs:
            d = d + quat_mul(np.broadcast_to(qW, q.shape), q + d)
        eps = (
            (np.sum(q * q, axis=1, keepdims=True) - 1.0)
            + 2.0 * np.sum(q * d, axis=1, keepdims=True)
            + np.sum(d * d, axis=1, keepdims=True)
        )
        d = d - 0.5 * eps * (q + d)
        q = q + d
        if (k + 1) % every == 0:
            j = (k + 1) // every
            P[:, j], V[:, j], Q[:, j] = p, v, q
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
