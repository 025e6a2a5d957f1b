"""Batched strapdown mechanization on exact angle/velocity increments (flat, wgs84, geodetic).

``flat``: the navigation frame n (ENU of the route origin) is inertial, gravity constant.

``wgs84`` and ``geodetic``: n is Earth-fixed (ENU axes of the origin, or ECEF in
``geodetic``) and turns at ``Omega`` (``W = [Omega x]``, ``A(t) = Exp(W t)``). The kernel
integrates in the inertial frame ``I`` that coincides with n at the start of the run
(``t = 0``, sample ``k = 0``): ``r_I = A(t) r_n``, ``v_I = A(t) (v_n + W r_n)``,
``C_Ib = A(t) C_nb``. The normal gravitation field is symmetric about the Earth's axis, so in
``I`` it is the same static function of position as in n (:mod:`imugen.core.earth`), and the
recursion is the flat one plus gravitation:

attitude (exact for exact increments)
    ``C_Ib,k+1 = C_Ib,k Exp(dtheta_k)`` (quaternions, renormalized each step);
velocity
    ``v_k+1 = v_k + C_Ib,k dv_k + J_k``, ``J_k = int G_I dt ~ dt/12 (5 G_k+1 + 8 G_k - G_k-1)``
    (exact in ``flat``, where ``J = g dt``); ``G_k+1`` is evaluated at a predicted ``r_k+1``
    (one gravitation evaluation per step);
position
    ``r_k+1 = r_k + dt/12 (5 v_k+1 + 8 v_k - v_k-1)`` (Adams-Moulton, 3 points); the first
    interval uses the same quadratic with one sample of look-ahead,
    ``dt/12 (5 v_0 + 8 v_1 - v_2)``, applied once ``v_2`` is known.

Gravitation nodes: the exact gravitation is evaluated once per block of ``m = round(T / dt)``
steps (``T = GRAVITY_NODE_S``), at the block's predicted end; in between, the cubic in time
through it and the three previous nodes (``tau = -2, -1, 0, 1`` in units of ``T``). Its error
is ``T^4/24 |w(tau)| |G^(4)|``, ``|w| = |(tau+2)(tau+1)tau(tau-1)| <= 0.98`` on the block,
``G^(4) = d^4 G / dt^4 ~ Gamma snap`` (``|Gamma| <= GAMMA_MAX = 3.1e-6 s^-2``; the field's own
curvature adds ``~ 120 g v^4 / R^4``, 1e-13 m/s^6 at 700 m/s). A block is accepted only when the
estimate ``max(|D_j|, |D_j-1|, |2.5 D_j - 1.5 D_j-1|) / 24`` is within ``GRAVITY_TOL_MPS2 /
GRAVITY_CHECK_MARGIN``, ``D_j`` the 4th difference of the five newest nodes (``T^4 G^(4)`` at
the middle one; ``D_j-1`` the previous, the extrapolation reaches the block): the estimate is
within 2 % above the error for motion of periods >= 4 T, within the margin down to ``pi T``.
Otherwise the block takes the exact gravitation every step (bit for bit the per-step rule).
Motion faster than ``pi T`` (vibration) is invisible to nodes: its error is at most
``4 Gamma A`` (Lebesgue constant of the cubic + 1 < 4), ``A`` its position amplitude.

Outputs are converted back to n at the stored samples only (``p_n = A^T r_I - r0_n``,
``v_n = A^T v_I - W r_n``, ``q_nb = q(A^T) q_Ib``, with ``A(t_k)`` from ``Omega k dt``), so
the Earth's rotation costs nothing per step. The kernel state holds ``r_I - r0_n`` (the
displacement from where the origin was at ``t = 0``), so positions keep float64 precision
relative to the origin.

Positions and velocities are accumulated with compensated (Kahan) sums, so 1 kHz over an
hour loses nothing to float64 rounding. The time recursion is one numba kernel
(``cache=True``): sequences in the outer loop, time inside, state in registers, no
allocation per step; it resumes from a state array, so long runs can be fed in time chunks
and outputs can be decimated (every N-th sample) or restricted to positions.

:func:`increments_from_rates` turns instantaneous rate samples into increments with the
standard second-order scheme (trapezoid + coning + sculling for linearly varying rates), and
:func:`mechanize_rates` feeds them to the same kernel. :func:`exact_increments` is the inverse
of the mechanization: the exact increments of a continuous motion given in n (any model).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from llvmlite import ir
from numba.core import cgutils, types
from numba.extending import intrinsic

from imugen.core import earth
from imugen.core.earth import OriginFrame
from imugen.core.jit import njit
from imugen.core.rotations import exp_dcm, quat_mul, quat_to_dcm, relative_rotation_vector

# --- state layout (one row per sequence) --------------------------------------------------------
# flat: n-frame quantities; wgs84/geodetic: inertial ones (module docstring)
S_P = 0  # position p_n, or r_I - r0_n (3)
S_PC = 3  # Kahan compensation of p (3)
S_V = 6  # velocity v_n, or v_I (3)
S_VC = 9  # Kahan compensation of v (3)
S_Q = 12  # quaternion q_nb, or q_Ib (4), scalar first
S_VP = 16  # velocity at the previous sample (3)
S_G = 19  # gravitation at sample k (3)
S_GP = 22  # gravitation at sample k-1 (3)
S_K = 25  # steps done
S_QC = 26  # Kahan compensation of q (4)
S_N = 30  # gravitation at the last four nodes k = j m, (j-1) m .. (j-3) m (12), newest first
S_FB = 42  # blocks integrated with the exact gravitation every step (error check failed)
S_D4 = 43  # 4th difference of the nodes at the previous node (3; inf until 5 nodes exist)
N_STATE = 46

# --- kernel parameter vector: frame params (earth.N_PARAMS) then these ------------------------
K_DT = earth.N_PARAMS  # dt
K_MB = K_DT + 1  # steps per gravitation node interval m (1: exact gravitation every step)
K_D4 = K_MB + 1  # limit on |4th difference of the nodes| (24 x the error allowed, / margin)
N_KPARAMS = K_D4 + 1

GRAVITY_TOL_MPS2 = 1e-8
"""Allowed error of the interpolated gravitation [m/s^2]: 1 ng, 1/15,000 of the smallest
accelerometer bias the grades model (``navigation_calibrated``, 15 ug); module docstring."""
GRAVITY_NODE_S = 0.4
"""Spacing of the exact gravitation evaluations in the rotating-Earth kernels [s]: the cubic's
error ``T^4/24 |Gamma| snap`` stays within :data:`GRAVITY_TOL_MPS2` up to a snap of
``24 tol / (GAMMA_MAX T^4)`` = 3.0 m/s^4; blocks beyond the check's limit take the exact
gravitation every step (module docstring)."""
GRAVITY_CHECK_MARGIN = 2.0
"""Safety factor of the a-posteriori check: a block is accepted when its estimated error
is within ``GRAVITY_TOL_MPS2 / GRAVITY_CHECK_MARGIN``."""
GAMMA_MAX = 2.0 * earth.GM_WGS84 / (earth.B_WGS84 - 1000.0) ** 3
"""Largest gravity-gradient eigenvalue anywhere on the routes (2 GM / r^3, r >= b - 1 km)
[1/s^2], 3.1e-6."""
_K3 = earth.GM_WGS84 / earth.R_MEAN**3  # point-mass gravity gradient scale [1/s^2]
_IG2 = (earth.R_MEAN**2 / earth.GM_WGS84) ** 2  # 1 / |G|^2 at the mean radius


def _skew(w):
    return np.array([[0.0, -w[2], w[1]], [w[2], 0.0, -w[0]], [-w[1], w[0], 0.0]])


def kernel_params(
    frame: OriginFrame,
    dt: float,
    node_s: float = GRAVITY_NODE_S,
    tol_mps2: float = GRAVITY_TOL_MPS2,
) -> np.ndarray:
    """Parameter vector of the kernel: earth parameters, dt, gravitation node interval, check.

    The exact gravitation is evaluated every ``m = round(node_s / dt)`` steps (``m >= 1``)
    and interpolated in between (module docstring); ``node_s = 0`` gives ``m = 1``. A block
    whose estimated interpolation error ``|Delta^4 G| / 24`` exceeds
    ``tol_mps2 / GRAVITY_CHECK_MARGIN`` is integrated with the exact gravitation every step;
    ``tol_mps2 = inf`` turns the check off.
    """
    prm = np.zeros(N_KPARAMS)
    prm[: earth.N_PARAMS] = frame.params()
    prm[K_DT] = dt
    prm[K_MB] = max(1, round(node_s / dt))
    prm[K_D4] = 24.0 * tol_mps2 / GRAVITY_CHECK_MARGIN
    return prm


def _rot_about_axis(x, axis, c, s, omc):
    """Rotate vectors x (..., 3) by the angle with cosine c, sine s, 1 - c = omc about axis."""
    ax = np.cross(axis, x)
    return x * c[..., None] + ax * s[..., None] + axis * (x @ axis)[..., None] * omc[..., None]


def _to_inertial(p_n, v_n, q_nb, frame: OriginFrame):
    """n-frame (p, v, q) at t = 0 -> kernel state quantities (displacement, v_I, q_Ib)."""
    if frame.model == "flat":
        return p_n, v_n, q_nb
    w = earth.earth_rate_n(frame)
    return p_n, v_n + np.cross(w, frame.r0_n + p_n), q_nb


def nav_from_state(st: np.ndarray, prm: np.ndarray):
    """Kernel state rows -> (p_n, v_n, q_nb) at the state's sample ``k`` (NumPy).

    Parameters
    ----------
    st : ndarray, shape (S, N_STATE)
    prm : ndarray, kernel parameters

    Returns
    -------
    p_n, v_n : ndarray, shape (S, 3); q_nb : ndarray, shape (S, 4)
    """
    p = st[:, S_P : S_P + 3] - st[:, S_PC : S_PC + 3]
    v = st[:, S_V : S_V + 3] - st[:, S_VC : S_VC + 3]
    q = st[:, S_Q : S_Q + 4] - st[:, S_QC : S_QC + 4]
    if prm[earth.P_MODEL] == 0.0:
        return p, v, q
    zax = prm[earth.P_OMEGA : earth.P_OMEGA + 3] / earth.OMEGA_IE
    r0 = prm[earth.P_R0N : earth.P_R0N + 3]
    th = -earth.OMEGA_IE * prm[K_DT] * st[:, S_K]  # rotation by A^T
    h, ch = np.sin(0.5 * th), np.cos(0.5 * th)  # half angle (the kernel's _write alike)
    omc = 2.0 * h * h
    c, s = 1.0 - omc, 2.0 * h * ch
    # p_n = A^T d + (A^T - I) r0_n
    r0 = np.broadcast_to(r0, p.shape)
    p_n = _rot_about_axis(p, zax, c, s, omc) + (
        _rot_about_axis(r0, zax, 0.0 * c, s, omc) - r0 * omc[:, None]
    )
    v_n = _rot_about_axis(v, zax, c, s, omc) - np.cross(earth.OMEGA_IE * zax, r0 + p_n)
    qa = np.concatenate([ch[:, None], h[:, None] * zax], axis=1)
    return p_n, v_n, quat_mul(qa, q)


def initial_state(p0_n, v0_n, q0_nb, frame: OriginFrame, S: int | None = None) -> np.ndarray:
    """State array (S, N_STATE) from initial position, velocity and attitude (sample k = 0).

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
    p0 = np.broadcast_to(p0, (n, 3))
    q0 = q0 / np.linalg.norm(q0, axis=1, keepdims=True)
    p, v, q = _to_inertial(p0, np.broadcast_to(v0, (n, 3)), q0, frame)
    st = np.zeros((n, N_STATE))
    st[:, S_P : S_P + 3] = p
    st[:, S_V : S_V + 3] = v
    st[:, S_VP : S_VP + 3] = v
    st[:, S_Q : S_Q + 4] = q
    G = earth.gravitation_n(p0, frame)
    st[:, S_G : S_G + 3] = G
    st[:, S_GP : S_GP + 3] = G
    for j in range(4):
        st[:, S_N + 3 * j : S_N + 3 * j + 3] = G
    st[:, S_D4 : S_D4 + 3] = np.inf
    return st


# --- numba kernel --------------------------------------------------------------------------------
@intrinsic
def _fma(typingctx, a, b, c):
    """``a * b + c`` rounded once (the CPU's fused multiply-add; float64 only).

    Explicit, so results do not depend on where a compiler chooses to contract (numba's
    ``fastmath`` would also reach every callee, e.g. the shared gravitation).
    """
    if not all(isinstance(x, types.Float) for x in (a, b, c)):
        return None
    sig = types.float64(types.float64, types.float64, types.float64)

    def codegen(context, builder, signature, args):
        d = ir.DoubleType()
        fn = cgutils.get_or_insert_function(
            builder.module, ir.FunctionType(d, [d, d, d]), "llvm.fma.f64"
        )
        return builder.call(
            fn,
            [
                context.cast(builder, v, t, types.float64)
                for v, t in zip(args, signature.args, strict=True)
            ],
        )

    return sig, codegen


@njit(cache=True, inline="always")
def _qexpm1(x, y, z):
    """Exp of a rotation vector as a quaternion minus identity: (cos(t/2) - 1, sin(t/2)/t v).

    Series for |t| < 0.1 (exact in float64), closed form otherwise; no cancellation in the
    scalar part.
    """
    t2 = _fma(x, x, _fma(y, y, z * z))
    if t2 < 1e-2:
        a2 = 0.25 * t2
        c = _fma(a2, -1.0 / 40320.0, 1.0 / 720.0)
        c = _fma(a2, -c, 1.0 / 24.0)
        c = _fma(a2, -c, 0.5)
        cm1 = -a2 * c
        s = _fma(a2, -1.0 / 362880.0, 1.0 / 5040.0)
        s = _fma(a2, -s, 1.0 / 120.0)
        s = _fma(a2, -s, 1.0 / 6.0)
        s = _fma(-0.5 * a2, s, 0.5)
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
def _qmul_f(aw, ax, ay, az, bw, bx, by, bz):
    """``_qmul`` with fused multiply-adds, in two balanced halves (short dependency chain)."""
    return (
        _fma(aw, bw, -ax * bx) - _fma(ay, by, az * bz),
        _fma(aw, bx, ax * bw) + _fma(ay, bz, -az * by),
        _fma(aw, by, -ax * bz) + _fma(ay, bw, az * bx),
        _fma(aw, bz, ax * by) + _fma(-ay, bx, az * bw),
    )


@njit(cache=True, inline="always")
def _qrot(qw, qx, qy, qz, vx, vy, vz):
    """Rotate v by q (C(q) v): v + w t + q_vec x t with t = 2 q_vec x v."""
    tx = 2.0 * _fma(qy, vz, -qz * vy)
    ty = 2.0 * _fma(qz, vx, -qx * vz)
    tz = 2.0 * _fma(qx, vy, -qy * vx)
    return (
        _fma(qw, tx, vx) + _fma(qy, tz, -qz * ty),
        _fma(qw, ty, vy) + _fma(qz, tx, -qx * tz),
        _fma(qw, tz, vz) + _fma(qx, ty, -qy * tx),
    )


@njit(cache=True)
def _rot_axis(zx, zy, zz, c, s, omc, x, y, z):
    """Rotate (x, y, z) about the unit axis zax by the angle (cos c, sin s, 1 - cos omc)."""
    d = omc * (zx * x + zy * y + zz * z)
    return (
        c * x + s * (zy * z - zz * y) + d * zx,
        c * y + s * (zz * x - zx * z) + d * zy,
        c * z + s * (zx * y - zy * x) + d * zz,
    )


@njit(cache=True)
def _write(out_p, out_v, out_q, s, slot, prm, k, px, py, pz, vx, vy, vz, q0, q1, q2, q3, wq):
    """Store sample ``k`` (kernel quantities, compensations already applied) in n."""
    if prm[earth.P_MODEL] != 0.0:
        iw = 1.0 / earth.OMEGA_IE
        zx = prm[earth.P_OMEGA] * iw
        zy = prm[earth.P_OMEGA + 1] * iw
        zz = prm[earth.P_OMEGA + 2] * iw
        th = -earth.OMEGA_IE * prm[K_DT] * k  # A(t_k)^T, from its half angle
        h = math.sin(0.5 * th)
        ch = math.cos(0.5 * th)
        omc = 2.0 * h * h
        c = 1.0 - omc
        sn = 2.0 * h * ch
        r0x = prm[earth.P_R0N]
        r0y = prm[earth.P_R0N + 1]
        r0z = prm[earth.P_R0N + 2]
        # p_n = A^T d + (A^T - I) r0_n (no cancellation against r0_n)
        ax, ay, az = _rot_axis(zx, zy, zz, c, sn, omc, px, py, pz)
        bx, by, bz = _rot_axis(zx, zy, zz, 0.0, sn, omc, r0x, r0y, r0z)
        px = ax + (bx - omc * r0x)
        py = ay + (by - omc * r0y)
        pz = az + (bz - omc * r0z)
        # v_n = A^T v_I - Omega x r_n
        ax, ay, az = _rot_axis(zx, zy, zz, c, sn, omc, vx, vy, vz)
        rx = r0x + px
        ry = r0y + py
        rz = r0z + pz
        w = earth.OMEGA_IE
        vx = ax - w * (zy * rz - zz * ry)
        vy = ay - w * (zz * rx - zx * rz)
        vz = az - w * (zx * ry - zy * rx)
        if wq:
            q0, q1, q2, q3 = _qmul(ch, h * zx, h * zy, h * zz, q0, q1, q2, q3)
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
    rot = prm[earth.P_MODEL] != 0.0
    dt = prm[K_DT]
    m = int(prm[K_MB]) if rot else 1
    d4lim = prm[K_D4]
    wq = out_q.shape[1] > 0  # attitude stored (else not converted)
    c12 = dt / 12.0
    hdt = 0.5 * dt
    iw = 1.0 / earth.OMEGA_IE
    zx = prm[earth.P_OMEGA] * iw
    zy = prm[earth.P_OMEGA + 1] * iw
    zz = prm[earth.P_OMEGA + 2] * iw
    r0x = prm[earth.P_R0N]
    r0y = prm[earth.P_R0N + 1]
    r0z = prm[earth.P_R0N + 2]
    g0dt = prm[earth.P_G0] * dt
    # block tables for a cubic gravitation g(tau) = sum_n c_n tau^n, tau = (t - t_k0) / T:
    # WC[j, n] = int_0^(j dt) tau^n dt = T (j/m)^(n+1) / (n+1), its velocity change after j
    # steps; QC[j, n], the matching position change by the 3-point rule (module docstring)
    T = m * dt
    WC = np.zeros((m + 1, 4))
    QC = np.zeros((m + 1, 4))
    for j in range(1, m + 1):
        x = j / m
        for n in range(4):
            WC[j, n] = T * x ** (n + 1) / (n + 1)
            wm = WC[j - 2, n] if j >= 2 else 0.0
            QC[j, n] = QC[j - 1, n] + c12 * (5.0 * WC[j, n] + 8.0 * WC[j - 1, n] - wm)
    abuf = np.empty((m + 1, 3))  # A_j: sums of the resolved specific-force increments
    pbuf = np.empty((m + 1, 3))  # QA_j: their position effect
    qbuf = np.empty((m + 1, 4))
    fbuf = np.empty((m, 3))  # a_j = C_Ib dv_j of the block's steps
    abuf[0] = 0.0
    pbuf[0] = 0.0
    for s in range(S):
        # fmt: off
        (px, py, pz, pcx, pcy, pcz, vx, vy, vz, vcx, vcy, vcz,
         q0, q1, q2, q3, vpx, vpy, vpz, Gx, Gy, Gz, Gpx, Gpy, Gpz) = st[s, :25]
        (n0x, n0y, n0z, n1x, n1y, n1z, n2x, n2y, n2z,
         n3x, n3y, n3z) = st[s, S_N:S_N + 12]
        # fmt: on
        nfb = st[s, S_FB]
        dpx, dpy, dpz = st[s, S_D4], st[s, S_D4 + 1], st[s, S_D4 + 2]
        qc0, qc1, qc2, qc3 = st[s, S_QC], st[s, S_QC + 1], st[s, S_QC + 2], st[s, S_QC + 3]
        k = int(st[s, S_K])
        km = k % m  # phases of k (no integer division per step)
        kw = k % every
        i = 0
        while i < N:
            if km == 0 and m > 1 and k >= 4 * m and i + m <= N:
                # ---- a block of m steps: attitude first (it does not depend on gravity),
                # then the exact gravitation once at the block's predicted end, a cubic in
                # time through it and the three previous nodes, and velocity/position
                # specific force: running sums A_j and their 3-point position effect QA_j
                # (relative to the block start; v_k-1 - v_k enters the first step)
                inner = every - kw < m  # samples to store inside the block (buffers needed)
                # two short loops (few live values each, no register spills): attitude and
                # resolved increments a_j, then A_j and the 3-point position effect
                # QA_J = dt/12 (12 sum_(j<J) A_j + 5 A_J + A_(J-1) - A_(-1)), A_0 = 0
                for j in range(m):
                    ax, ay, az = _qrot(
                        q0, q1, q2, q3, dvb[s, i + j, 0], dvb[s, i + j, 1], dvb[s, i + j, 2]
                    )
                    fbuf[j, 0] = ax
                    fbuf[j, 1] = ay
                    fbuf[j, 2] = az
                    q0, q1, q2, q3, qc0, qc1, qc2, qc3 = _att_step(
                        q0, q1, q2, q3, qc0, qc1, qc2, qc3,
                        dth[s, i + j, 0], dth[s, i + j, 1], dth[s, i + j, 2],
                    )  # fmt: skip
                    if inner and wq:
                        qbuf[j + 1, 0] = q0 - qc0
                        qbuf[j + 1, 1] = q1 - qc1
                        qbuf[j + 1, 2] = q2 - qc2
                        qbuf[j + 1, 3] = q3 - qc3
                b0x = vpx - vx  # A_(-1) = v_(k-1) - v_k
                b0y = vpy - vy
                b0z = vpz - vz
                bx = b0x  # A_(j-1)
                by = b0y
                bz = b0z
                Ax = 0.0
                Ay = 0.0
                Az = 0.0
                Sx = 0.0  # sum_(j' < j) A_j'
                Sy = 0.0
                Sz = 0.0
                for j in range(m):
                    Sx += Ax
                    Sy += Ay
                    Sz += Az
                    bx = Ax
                    by = Ay
                    bz = Az
                    Ax += fbuf[j, 0]
                    Ay += fbuf[j, 1]
                    Az += fbuf[j, 2]
                    if inner:
                        abuf[j + 1, 0] = Ax
                        abuf[j + 1, 1] = Ay
                        abuf[j + 1, 2] = Az
                        pbuf[j + 1, 0] = c12 * (_fma(12.0, Sx, _fma(5.0, Ax, bx)) - b0x)
                        pbuf[j + 1, 1] = c12 * (_fma(12.0, Sy, _fma(5.0, Ay, by)) - b0y)
                        pbuf[j + 1, 2] = c12 * (_fma(12.0, Sz, _fma(5.0, Az, bz)) - b0z)
                Px = c12 * (_fma(12.0, Sx, _fma(5.0, Ax, bx)) - b0x)
                Py = c12 * (_fma(12.0, Sy, _fma(5.0, Ay, by)) - b0y)
                Pz = c12 * (_fma(12.0, Sz, _fma(5.0, Az, bz)) - b0z)
                # predicted end position: gravitation extrapolated linearly from the nodes
                e0 = QC[m, 0] + QC[m, 1]
                e1 = QC[m, 1]
                ppx = px + T * vx + Px + e0 * n0x - e1 * n1x
                ppy = py + T * vy + Py + e0 * n0y - e1 * n1y
                ppz = pz + T * vz + Pz + e0 * n0z - e1 * n1z
                gex, gey, gez = earth._gravitation_nb(r0x + ppx, r0y + ppy, r0z + ppz, zx, zy, zz)
                # error check (module docstring): 4th differences of the nodes, this one and
                # the previous one, and their extrapolation to the block; beyond the limit the
                # block takes the exact gravitation every step (the per-step rule, bit for bit)
                d4x = gex - 4.0 * n0x + 6.0 * n1x - 4.0 * n2x + n3x
                d4y = gey - 4.0 * n0y + 6.0 * n1y - 4.0 * n2y + n3y
                d4z = gez - 4.0 * n0z + 6.0 * n1z - 4.0 * n2z + n3z
                est = max(
                    max(abs(d4x), abs(d4y), abs(d4z)),
                    max(abs(dpx), abs(dpy), abs(dpz)),
                    max(abs(2.5 * d4x - 1.5 * dpx), abs(2.5 * d4y - 1.5 * dpy),
                        abs(2.5 * d4z - 1.5 * dpz)),
                )  # fmt: skip
                dpx = d4x
                dpy = d4y
                dpz = d4z
                if not est <= d4lim:
                    nfb += 1.0
                    for j in range(m):
                        ax = fbuf[j, 0]
                        ay = fbuf[j, 1]
                        az = fbuf[j, 2]
                        sx = vx + ax + dt * Gx
                        sy = vy + ay + dt * Gy
                        sz = vz + az + dt * Gz
                        ppx = px + c12 * (5.0 * sx + 8.0 * vx - vpx)
                        ppy = py + c12 * (5.0 * sy + 8.0 * vy - vpy)
                        ppz = pz + c12 * (5.0 * sz + 8.0 * vz - vpz)
                        Gnx, Gny, Gnz = earth._gravitation_nb(
                            r0x + ppx, r0y + ppy, r0z + ppz, zx, zy, zz
                        )
                        dvx = ax + c12 * (5.0 * Gnx + 8.0 * Gx - Gpx)
                        dvy = ay + c12 * (5.0 * Gny + 8.0 * Gy - Gpy)
                        dvz = az + c12 * (5.0 * Gnz + 8.0 * Gz - Gpz)
                        Gpx = Gx
                        Gpy = Gy
                        Gpz = Gz
                        Gx = Gnx
                        Gy = Gny
                        Gz = Gnz
                        ovx = vx
                        ovy = vy
                        ovz = vz
                        vx, vcx = _kahan(vx, vcx, dvx)
                        vy, vcy = _kahan(vy, vcy, dvy)
                        vz, vcz = _kahan(vz, vcz, dvz)
                        px, pcx = _kahan(px, pcx, c12 * _fma(5.0, vx, _fma(8.0, ovx, -vpx)))
                        py, pcy = _kahan(py, pcy, c12 * _fma(5.0, vy, _fma(8.0, ovy, -vpy)))
                        pz, pcz = _kahan(pz, pcz, c12 * _fma(5.0, vz, _fma(8.0, ovz, -vpz)))
                        vpx = ovx
                        vpy = ovy
                        vpz = ovz
                        kw += 1
                        if kw == every:
                            kw = 0
                            if j + 1 < m:
                                w0, w1 = qbuf[j + 1, 0], qbuf[j + 1, 1]
                                w2, w3 = qbuf[j + 1, 2], qbuf[j + 1, 3]
                            else:
                                w0, w1, w2, w3 = q0 - qc0, q1 - qc1, q2 - qc2, q3 - qc3
                            _write(out_p, out_v, out_q, s, (k + j + 1) // every - out_start, prm,
                                   k + j + 1, px - pcx, py - pcy, pz - pcz, vx - vcx, vy - vcy,
                                   vz - vcz, w0, w1, w2, w3, wq)  # fmt: skip
                    k += m
                    i += m
                    n3x, n3y, n3z = n2x, n2y, n2z
                    n2x, n2y, n2z = n1x, n1y, n1z
                    n1x, n1y, n1z = n0x, n0y, n0z
                    n0x, n0y, n0z = Gx, Gy, Gz
                    continue
                # cubic g(tau) = n0 + c1 tau + c2 tau^2 + c3 tau^3 through tau = -2, -1, 0, 1
                c2x = 0.5 * (gex + n1x) - n0x
                c2y = 0.5 * (gey + n1y) - n0y
                c2z = 0.5 * (gez + n1z) - n0z
                sx = 0.5 * (gex - n1x)
                sy = 0.5 * (gey - n1y)
                sz = 0.5 * (gez - n1z)
                c3x = (n0x - n2x + 4.0 * c2x - 2.0 * sx) / 6.0
                c3y = (n0y - n2y + 4.0 * c2y - 2.0 * sy) / 6.0
                c3z = (n0z - n2z + 4.0 * c2z - 2.0 * sz) / 6.0
                c1x = sx - c3x
                c1y = sy - c3y
                c1z = sz - c3z
                # samples inside the block that are stored
                jw = every - kw
                while jw < m:
                    tj = jw * dt
                    _write(out_p, out_v, out_q, s, (k + jw) // every - out_start, prm, k + jw,
                           (px - pcx) + (tj * vx + pbuf[jw, 0]
                                         + (QC[jw, 0] * n0x + QC[jw, 1] * c1x
                                            + QC[jw, 2] * c2x + QC[jw, 3] * c3x)),
                           (py - pcy) + (tj * vy + pbuf[jw, 1]
                                         + (QC[jw, 0] * n0y + QC[jw, 1] * c1y
                                            + QC[jw, 2] * c2y + QC[jw, 3] * c3y)),
                           (pz - pcz) + (tj * vz + pbuf[jw, 2]
                                         + (QC[jw, 0] * n0z + QC[jw, 1] * c1z
                                            + QC[jw, 2] * c2z + QC[jw, 3] * c3z)),
                           (vx - vcx) + (abuf[jw, 0] + (WC[jw, 0] * n0x + WC[jw, 1] * c1x
                                                        + WC[jw, 2] * c2x + WC[jw, 3] * c3x)),
                           (vy - vcy) + (abuf[jw, 1] + (WC[jw, 0] * n0y + WC[jw, 1] * c1y
                                                        + WC[jw, 2] * c2y + WC[jw, 3] * c3y)),
                           (vz - vcz) + (abuf[jw, 2] + (WC[jw, 0] * n0z + WC[jw, 1] * c1z
                                                        + WC[jw, 2] * c2z + WC[jw, 3] * c3z)),
                           qbuf[jw, 0], qbuf[jw, 1], qbuf[jw, 2], qbuf[jw, 3], wq)  # fmt: skip
                    jw += every
                kw += m
                while kw >= every:
                    kw -= every
                # end of the block: one compensated sum each for position and velocity
                j = m - 1
                vpx = vx + (
                    bx + (WC[j, 0] * n0x + WC[j, 1] * c1x + WC[j, 2] * c2x + WC[j, 3] * c3x)
                )
                vpy = vy + (
                    by + (WC[j, 0] * n0y + WC[j, 1] * c1y + WC[j, 2] * c2y + WC[j, 3] * c3y)
                )
                vpz = vz + (bz + (WC[j, 0] * n0z + WC[j, 1] * c1z + WC[j, 2] * c2z
                                          + WC[j, 3] * c3z))  # fmt: skip
                px, pcx = _kahan(
                    px,
                    pcx,
                    T * vx
                    + (Px + (QC[m, 0] * n0x + QC[m, 1] * c1x + QC[m, 2] * c2x + QC[m, 3] * c3x)),
                )
                py, pcy = _kahan(
                    py,
                    pcy,
                    T * vy
                    + (Py + (QC[m, 0] * n0y + QC[m, 1] * c1y + QC[m, 2] * c2y + QC[m, 3] * c3y)),
                )
                pz, pcz = _kahan(
                    pz,
                    pcz,
                    T * vz
                    + (Pz + (QC[m, 0] * n0z + QC[m, 1] * c1z + QC[m, 2] * c2z + QC[m, 3] * c3z)),
                )
                vx, vcx = _kahan(
                    vx,
                    vcx,
                    Ax + (WC[m, 0] * n0x + WC[m, 1] * c1x + WC[m, 2] * c2x + WC[m, 3] * c3x),
                )
                vy, vcy = _kahan(
                    vy,
                    vcy,
                    Ay + (WC[m, 0] * n0y + WC[m, 1] * c1y + WC[m, 2] * c2y + WC[m, 3] * c3y),
                )
                vz, vcz = _kahan(vz, vcz, Az + (WC[m, 0] * n0z + WC[m, 1] * c1z + WC[m, 2] * c2z
                                                + WC[m, 3] * c3z))  # fmt: skip
                k += m
                if kw == 0:
                    _write(out_p, out_v, out_q, s, k // every - out_start, prm, k,
                           px - pcx, py - pcy, pz - pcz, vx - vcx, vy - vcy, vz - vcz,
                           q0 - qc0, q1 - qc1, q2 - qc2, q3 - qc3, wq)  # fmt: skip
                # node at the actual end: point-mass gradient across the prediction error
                dx = (px - pcx) - ppx
                dy = (py - pcy) - ppy
                dz = (pz - pcz) - ppz
                # Gamma d ~ GM/R^3 (3 G (G.d) / |G|^2 - d): radial direction from G itself,
                # radius and |G| at their means (a few 1e-3 of a correction of ~1e-12 m/s^2)
                gd = _IG2 * (gex * dx + gey * dy + gez * dz)
                gex += _K3 * (3.0 * gd * gex - dx)
                gey += _K3 * (3.0 * gd * gey - dy)
                gez += _K3 * (3.0 * gd * gez - dz)
                # the per-step rule continues from the cubic's last two samples
                x = 1.0 - 1.0 / m
                Gpx = n0x + x * (c1x + x * (c2x + x * c3x))
                Gpy = n0y + x * (c1y + x * (c2y + x * c3y))
                Gpz = n0z + x * (c1z + x * (c2z + x * c3z))
                Gx = gex
                Gy = gey
                Gz = gez
                n3x, n3y, n3z = n2x, n2y, n2z
                n2x, n2y, n2z = n1x, n1y, n1z
                n1x, n1y, n1z = n0x, n0y, n0z
                n0x, n0y, n0z = gex, gey, gez
                i += m
                continue
            # ---- one step with the exact gravitation at the predicted end of the step
            if k == 1:
                v0x = vpx
                v0y = vpy
                v0z = vpz
                p1x = px - pcx
                p1y = py - pcy
                p1z = pz - pcz
            # specific-force increment resolved at t_k: a = C_k dv
            ax, ay, az = _qrot(q0, q1, q2, q3, dvb[s, i, 0], dvb[s, i, 1], dvb[s, i, 2])
            if rot:
                # predictor of v_{k+1}, r_{k+1}; gravitation there; 3-point rule for its integral
                sx = vx + ax + dt * Gx
                sy = vy + ay + dt * Gy
                sz = vz + az + dt * Gz
                if k == 0:
                    ppx = px + hdt * (sx + vx)
                    ppy = py + hdt * (sy + vy)
                    ppz = pz + hdt * (sz + vz)
                else:
                    ppx = px + c12 * (5.0 * sx + 8.0 * vx - vpx)
                    ppy = py + c12 * (5.0 * sy + 8.0 * vy - vpy)
                    ppz = pz + c12 * (5.0 * sz + 8.0 * vz - vpz)
                Gnx, Gny, Gnz = earth._gravitation_nb(r0x + ppx, r0y + ppy, r0z + ppz, zx, zy, zz)
                if k == 0:
                    dvx = ax + hdt * (Gnx + Gx)
                    dvy = ay + hdt * (Gny + Gy)
                    dvz = az + hdt * (Gnz + Gz)
                else:
                    dvx = ax + c12 * (5.0 * Gnx + 8.0 * Gx - Gpx)
                    dvy = ay + c12 * (5.0 * Gny + 8.0 * Gy - Gpy)
                    dvz = az + c12 * (5.0 * Gnz + 8.0 * Gz - Gpz)
                Gpx = Gx
                Gpy = Gy
                Gpz = Gz
                Gx = Gnx
                Gy = Gny
                Gz = Gnz
            else:
                dvx = ax
                dvy = ay
                dvz = az - g0dt
            ovx = vx
            ovy = vy
            ovz = vz
            vx, vcx = _kahan(vx, vcx, dvx)
            vy, vcy = _kahan(vy, vcy, dvy)
            vz, vcz = _kahan(vz, vcz, dvz)
            if k == 0:
                px, pcx = _kahan(px, pcx, hdt * (vx + ovx))
                py, pcy = _kahan(py, pcy, hdt * (vy + ovy))
                pz, pcz = _kahan(pz, pcz, hdt * (vz + ovz))
            else:
                px, pcx = _kahan(px, pcx, c12 * _fma(5.0, vx, _fma(8.0, ovx, -vpx)))
                py, pcy = _kahan(py, pcy, c12 * _fma(5.0, vy, _fma(8.0, ovy, -vpy)))
                pz, pcz = _kahan(pz, pcz, c12 * _fma(5.0, vz, _fma(8.0, ovz, -vpz)))
            q0, q1, q2, q3, qc0, qc1, qc2, qc3 = _att_step(
                q0, q1, q2, q3, qc0, qc1, qc2, qc3, dth[s, i, 0], dth[s, i, 1], dth[s, i, 2]
            )
            vpx = ovx
            vpy = ovy
            vpz = ovz
            if k == 1:
                # first interval: dt/12 (5 v0 + 8 v1 - v2) instead of the trapezoid
                dx = c12 * (-v0x + 2.0 * vpx - vx)
                dy = c12 * (-v0y + 2.0 * vpy - vy)
                dz = c12 * (-v0z + 2.0 * vpz - vz)
                px += dx
                py += dy
                pz += dz
                if every == 1:
                    _write(out_p, out_v, out_q, s, 1 - out_start, prm, 1,
                           p1x + dx, p1y + dy, p1z + dz, vpx, vpy, vpz,
                           0.0, 0.0, 0.0, 0.0, False)  # fmt: skip
            k += 1
            i += 1
            km += 1
            if km == m:
                km = 0
            kw += 1
            if kw == every:
                kw = 0
            if rot and km == 0:
                if k >= 4 * m:  # five real nodes: k, k - m, .., k - 4m
                    dpx = Gx - 4.0 * n0x + 6.0 * n1x - 4.0 * n2x + n3x
                    dpy = Gy - 4.0 * n0y + 6.0 * n1y - 4.0 * n2y + n3y
                    dpz = Gz - 4.0 * n0z + 6.0 * n1z - 4.0 * n2z + n3z
                n3x, n3y, n3z = n2x, n2y, n2z
                n2x, n2y, n2z = n1x, n1y, n1z
                n1x, n1y, n1z = n0x, n0y, n0z
                n0x, n0y, n0z = Gx, Gy, Gz
            if kw == 0:
                _write(out_p, out_v, out_q, s, k // every - out_start, prm, k,
                       px - pcx, py - pcy, pz - pcz, vx - vcx, vy - vcy, vz - vcz,
                       q0 - qc0, q1 - qc1, q2 - qc2, q3 - qc3, wq)  # fmt: skip
        # fmt: off
        st[s, :25] = (px, py, pz, pcx, pcy, pcz, vx, vy, vz, vcx, vcy, vcz,
                      q0, q1, q2, q3, vpx, vpy, vpz, Gx, Gy, Gz, Gpx, Gpy, Gpz)
        st[s, S_N:S_N + 12] = (n0x, n0y, n0z, n1x, n1y, n1z, n2x, n2y, n2z,
                               n3x, n3y, n3z)
        # fmt: on
        st[s, S_FB] = nfb
        st[s, S_D4], st[s, S_D4 + 1], st[s, S_D4 + 2] = dpx, dpy, dpz
        st[s, S_QC], st[s, S_QC + 1], st[s, S_QC + 2], st[s, S_QC + 3] = qc0, qc1, qc2, qc3
        st[s, S_K] = k


@njit(cache=True, inline="always")
def _kahan(s, c, d):
    """Compensated s + d; returns the new sum and compensation (true sum = s - c)."""
    y = d - c
    t = s + y
    return t, (t - s) - y


@njit(cache=True, inline="always")
def _att_step(q0, q1, q2, q3, qc0, qc1, qc2, qc3, x, y, z):
    """q <- q (x) Exp(dtheta), as q + dq with dq computed from small quantities, renormalized
    to first order and added with a compensated sum (no systematic rounding drift)."""
    em0, e1, e2, e3 = _qexpm1(x, y, z)
    d0, d1, d2, d3 = _qmul_f(q0, q1, q2, q3, em0, e1, e2, e3)
    # first-order renormalization: scale by 1 - eps/2, eps = |q + dq|^2 - 1
    # = (|q|^2 - 1) + |q|^2 (|1 + e|^2 - 1) (|q (x) x| = |q| |x|): off the q -> dq chain
    ne = _fma(em0, 2.0 + em0, _fma(e1, e1, _fma(e2, e2, e3 * e3)))
    nq = _fma(q0, q0, q1 * q1) + _fma(q2, q2, q3 * q3)
    h = -0.5 * _fma(nq, ne, nq - 1.0)
    d0 = _fma(h, q0 + d0, d0)
    d1 = _fma(h, q1 + d1, d1)
    d2 = _fma(h, q2 + d2, d2)
    d3 = _fma(h, q3 + d3, d3)
    q0, qc0 = _kahan(q0, qc0, d0)
    q1, qc1 = _kahan(q1, qc1, d1)
    q2, qc2 = _kahan(q2, qc2, d2)
    q3, qc3 = _kahan(q3, qc3, d3)
    return q0, q1, q2, q3, qc0, qc1, qc2, qc3


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
        Origin and Earth model (``"flat"``, ``"wgs84"`` or ``"geodetic"``; in ``geodetic`` the
        navigation coordinates are ECEF: position, Earth-relative velocity, ``q_eb``).
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
        """Current position in n [m], shape (S, 3)."""
        return nav_from_state(self.state, self.prm)[0]

    @property
    def v_n(self) -> np.ndarray:
        """Current velocity in n [m/s], shape (S, 3)."""
        return nav_from_state(self.state, self.prm)[1]

    @property
    def q_nb(self) -> np.ndarray:
        """Current attitude q_nb (scalar first), shape (S, 4)."""
        return nav_from_state(self.state, self.prm)[2]

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
    p_0, v_0, q_0 = nav_from_state(st, mech.prm)
    if out_p is not None:
        out_p[:, 0] = p_0
    if out_v is not None:
        out_v[:, 0] = v_0
    if out_q is not None:
        out_q[:, 0] = q_0
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


# --- exact increments of a continuous motion (the inverse of the mechanization) ---------------
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


# --- pure NumPy reference (vectorized across sequences, Python loop over time) -----------------
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
            gd = _IG2 * np.sum(ge * d, axis=1, keepdims=True)
            ge = ge + _K3 * (3.0 * gd * ge - d)
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
