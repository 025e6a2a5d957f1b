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
(:mod:`imugen.navigate._kernel`, ``cache=True``): sequences in the outer loop, time inside, state in registers, no
allocation per step; it resumes from a state array, so long runs can be fed in time chunks
and outputs can be decimated (every N-th sample) or restricted to positions.

:func:`increments_from_rates` turns instantaneous rate samples into increments with the
standard second-order scheme (trapezoid + coning + sculling for linearly varying rates), and
:func:`mechanize_rates` feeds them to the same kernel. The inverse of the mechanization (the
exact increments of a continuous motion) and a NumPy twin of the kernel are test oracles
(``tests/oracles/strapdown.py``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from imugen.core import earth
from imugen.core.earth import OriginFrame
from imugen.core.rotations import quat_mul
from imugen.navigate._kernel import (
    K_D4,
    K_DT,
    K_MB,
    N_KPARAMS,
    N_STATE,
    S_D4,
    S_G,
    S_GP,
    S_K,
    S_N,
    S_P,
    S_PC,
    S_Q,
    S_QC,
    S_V,
    S_VC,
    S_VP,
    compensate,
    heights_n,
    kernel,
)

GRAVITY_TOL_MPS2 = 1e-8
"""Allowed error of the interpolated gravitation [m/s^2]: 1 ng, 1/15,000 of the smallest
accelerometer bias the grades model (``navigation_calibrated``, 15 ug); module docstring."""
GRAVITY_NODE_S = 0.2
"""Spacing of the exact gravitation evaluations in the rotating-Earth kernels [s]: the cubic's
error ``T^4/24 |Gamma| snap`` stays within :data:`GRAVITY_TOL_MPS2` up to a snap of
``24 tol / (GAMMA_MAX T^4)`` = 48 m/s^4; blocks beyond the check's limit take the exact
gravitation every step (module docstring). Zero-error closure sets the spacing: an error
within the tolerance but of one sign while a car starts from rest (jerk steps every 0.02 s)
leaves a velocity error that the Schuler loop turns into a swing of ``dv / omega_s``; at
0.4 s, 3.3e-9 m/s on the 264 km road's start, a 2.0e-6 m closure at 50 Hz (1.7e-6 m at
10 Hz); at 0.2 s the closure is that of the exact gravitation every step (9.8e-9 m and
8.0e-9 m at 50 Hz), for ~3 % more CPU at 50 Hz (docs/explanation/earth.md)."""
GRAVITY_CHECK_MARGIN = 2.0
"""Safety factor of the a-posteriori check: a block is accepted when its estimated error
is within ``GRAVITY_TOL_MPS2 / GRAVITY_CHECK_MARGIN``."""
GAMMA_MAX = 2.0 * earth.GM_WGS84 / (earth.B_WGS84 - 1000.0) ** 3
"""Largest gravity-gradient eigenvalue anywhere on the routes (2 GM / r^3, r >= b - 1 km)
[1/s^2], 3.1e-6."""


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
    gains : array_like, shape (3,), optional
        Gains ``(k1, k2, k3)`` of the height loop (:mod:`imugen.navigate.vertical`); None or
        zeros: the free vertical channel. When damped, :meth:`run` needs reference heights.
    """

    def __init__(
        self, frame: OriginFrame, dt: float, p0_n, v0_n, q0_nb, S: int | None = None, gains=None
    ):
        self.frame = frame
        self.dt = float(dt)
        self.prm = kernel_params(frame, self.dt)
        self.state = initial_state(p0_n, v0_n, q0_nb, frame, S)
        self.gains = np.zeros(3) if gains is None else np.asarray(gains, dtype=float).reshape(3)

    @property
    def damped(self) -> bool:
        """True when the height loop is on."""
        return bool(np.any(self.gains != 0.0))

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

    def run(
        self, dtheta_b, dv_b, out_p=None, out_v=None, out_q=None, every=1, out_start=0, href=None
    ):
        """Integrate a time chunk of increments for all sequences.

        Parameters
        ----------
        dtheta_b, dv_b : ndarray, shape (S, N, 3)
            Angle [rad] and velocity [m/s] increments of the next N intervals.
        out_p, out_v, out_q : ndarray, shape (S, M, 3|4), optional
            Preallocated outputs; sample ``j`` (global index) goes to slot
            ``j // every - out_start`` when ``j % every == 0``; None to skip.
        href : ndarray, shape (1 or S, N + 1), optional
            Reference heights [m] of samples ``steps .. steps + N`` (NaN: none there); needed
            when the loop is on (:attr:`damped`).
        """
        dth = np.ascontiguousarray(dtheta_b, dtype=np.float64)
        dvb = np.ascontiguousarray(dv_b, dtype=np.float64)
        S = self.state.shape[0]
        if dth.shape != dvb.shape or dth.ndim != 3 or dth.shape[0] != S or dth.shape[2] != 3:
            raise ValueError(f"increments must be (S={S}, N, 3), got {dth.shape}, {dvb.shape}")
        empty3 = np.empty((S, 0, 3))
        empty4 = np.empty((S, 0, 4))
        kernel(
            dth,
            dvb,
            self.state,
            self.prm,
            int(every),
            empty3 if out_p is None else out_p,
            empty3 if out_v is None else out_v,
            empty4 if out_q is None else out_q,
            int(out_start),
            _reference(href, self.damped, S, dth.shape[1]),
            self.gains,
        )


def _reference(href, damped: bool, S: int, N: int) -> np.ndarray:
    """Reference heights for the kernel: (1 or S, N + 1) float64, checked when damped."""
    if not damped:
        return np.empty((1, 0))
    if href is None:
        raise ValueError("the damped vertical channel needs reference heights (href)")
    h = np.ascontiguousarray(np.atleast_2d(href), dtype=np.float64)
    if h.shape[0] not in (1, S) or h.shape[1] != N + 1:
        raise ValueError(f"href must be (1 or {S}, {N + 1}), got {h.shape}")
    return h


def reference_heights(p_n, frame: OriginFrame, with_up: bool = False):
    """Heights above the ellipsoid [m] of n-frame positions ``p_n`` (..., 3), by the height
    loop's own conversion (a reference that holds the truth's height exactly); ``with_up``:
    also the local up (unit, in n), shape (..., 3)."""
    p = np.ascontiguousarray(np.asarray(p_n, dtype=float).reshape(-1, 3))
    h = np.empty(len(p))
    up = np.empty((len(p), 3))
    heights_n(kernel_params(frame, 1.0), p, h, up)
    shape = np.shape(p_n)[:-1]
    if with_up:
        return h.reshape(shape), up.reshape(*shape, 3)
    return h.reshape(shape)


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
    gains=None,
    href=None,
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
    gains : array_like, shape (3,), optional
        Height-loop gains (:class:`Mechanizer`); None: the free vertical channel.
    href : ndarray, shape (1 or S, K), optional
        Reference heights [m] of samples ``0 .. K-1`` (needed when ``gains`` damp).

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
    mech = Mechanizer(frame, dt, p0_n, v0_n, q0_nb, S, gains=gains)
    href = _reference(href, mech.damped, S, N)
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
        kernel(
            np.ascontiguousarray(dth[a:b]),
            np.ascontiguousarray(dvb[a:b]),
            st[a:b],
            mech.prm,
            every,
            empty3 if out_p is None else out_p[a:b],
            empty3 if out_v is None else out_v[a:b],
            empty4 if out_q is None else out_q[a:b],
            0,
            href if len(href) == 1 else href[a:b],
            mech.gains,
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
    compensate(a, b)
    return dtheta_b, dv_b


def mechanize_rates(omega_ib_b, f_b, dt, p0_n, v0_n, q0_nb, frame: OriginFrame, **kw):
    """Mechanize instantaneous rate samples: :func:`increments_from_rates` + :func:`mechanize`."""
    dtheta, dv = increments_from_rates(omega_ib_b, f_b, dt)
    return mechanize(dtheta, dv, dt, p0_n, v0_n, q0_nb, frame, **kw)
