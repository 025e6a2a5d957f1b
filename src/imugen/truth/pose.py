"""Pose trajectories as truth: timed poses -> one smooth 6-DoF motion (SO(3) x R^3).

Noisy timed poses (motion capture at 100-400 Hz, RTK/INS at 20 Hz, VIO), as ingested
(:mod:`imugen.ingest.pose`: positions in the origin's ENU, attitude relative to the local ENU
at each pose) give the IMU's motion with its *given* attitude; the truth's ideal IMU and
increments follow from it exactly (:mod:`imugen.truth.increments`), so they close like any
other truth.

Representation (SO(3) x R^3, split; not SE(3))
----------------------------------------------
*Position*: per axis a uniform quintic B-spline (knot spacing ``h = dt_med 2^m``, the
coarsest not above ``1 / (8 f_c)``: the passband is represented exactly and the banded system
stays well conditioned), the penalized least-squares fit
``min sum_i w_i (y_i - p(t_i))^2 + lam int |p^(3)|^2 dt`` (the integrated-jerk penalty of
:mod:`imugen.truth.fit`, one banded Cholesky system). For dense data its transfer function is
``H(f) = 1 / (1 + (f / f_c)^6)`` with ``lam = 1 / (dt_mean (2 pi f_c)^6)``: the smoothing is
parameterized by the cutoff ``f_c`` [Hz].

*Attitude*: the sign-continuous unit quaternions are fitted component-wise by the same
P-spline ``s(t)`` and normalized, ``qbar = s / |s|``; then one Gauss-Newton step in the
tangent space: the residual rotation vectors ``r_i = Log(qbar(t_i)^-1 q_i)`` are fitted by a
vector P-spline ``delta(t)`` at the same cutoff and ``q(t) = qbar(t) Exp(delta(t))``. Body
rate in closed form: ``omega_bar = 2 vec(conj(qbar) ds/dt) / |s|``,
``omega = Exp(-delta) omega_bar + J_r(delta) d(delta)/dt``.

Noise-aware smoothing (discrepancy principle)
---------------------------------------------
The pose noise (per position axis [m], attitude per axis [rad]) is given or estimated
(neighbour prediction, as :func:`imugen.truth.fit.noise_estimate`); the cutoff is the one
whose mean squared residual equals the noise variance (Morozov's discrepancy principle, as
:mod:`imugen.truth.fit`), at most the pose Nyquist rate. Outliers (residual beyond
``outlier_sigma`` sigma: marker swaps) are dropped and the fit redone. Gaps are bridged by
the penalty (minimum jerk) and reported.

Frames
------
n: the origin's ENU (the fit frame; :meth:`PoseMotion.rigid` re-expresses the motion in ECEF
for the ``geodetic`` model); pose body ``s``; IMU ``b`` (FLU) with ``C_sb`` (``pose_body``
axes ``flu | frd | rdf`` and the IMU's rotation in them); ``C_nb = C_ns C_sb``; the IMU point
``p_n = p_s + C_ns (l_s - m_s)`` with the lever arm ``l_s`` and the marker (tracked point)
offset ``m_s``, applied with the *fitted* attitude (no attitude noise leaks into the
position); ``t_imu = t_pose + time_offset_s``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.interpolate import BSpline
from scipy.linalg import solveh_banded
from scipy.optimize import brentq

from imugen.core import rotations as rot
from imugen.core.errors import InputError
from imugen.truth.fit import _predict_noise

K = 5  # spline degree (quintic: jerk and snap continuous)


def _local_poly(k=K):
    """M (k+1, k+1): on a knot interval, basis j = sum_m M[j, m] u^m, u in [0, 1)."""
    b = BSpline.basis_element(np.arange(k + 2), extrapolate=False)
    u = 0.5 - 0.5 * np.cos(np.pi * (np.arange(k + 1) + 0.5) / (k + 1))  # Chebyshev nodes
    V = np.vander(u, k + 1, increasing=True)
    return np.stack([np.linalg.solve(V, b(u + k - j)) for j in range(k + 1)])


_M = _local_poly()


def _dpow(u, nu, k=K):
    """(m, k+1): d^nu/du^nu of u^0..u^k."""
    out = np.zeros((len(u), k + 1))
    for m in range(nu, k + 1):
        out[:, m] = math.factorial(m) / math.factorial(m - nu) * u ** (m - nu)
    return out


def _gram(nu=3, k=K):
    """int_0^1 P_j^(nu)(u) P_l^(nu)(u) du of the local basis, (k+1, k+1)."""
    xg, wg = np.polynomial.legendre.leggauss(k + 1)
    u = 0.5 * (xg + 1.0)
    B = _dpow(u, nu) @ _M.T
    return (B * (0.5 * wg)[:, None]).T @ B


_G3 = _gram(3)


class USpline:
    """Vector-valued uniform B-spline of degree :data:`K`: ``t0``, spacing ``h`` [s],
    coefficients ``c`` (n_int + K, d)."""

    def __init__(self, t0, h, c):
        self.t0, self.h = float(t0), float(h)
        self.c = np.asarray(c, float)
        self.n_int = len(self.c) - K

    def _span(self, t):
        x = (np.asarray(t, float) - self.t0) / self.h
        i = np.clip(np.floor(x).astype(np.int64), 0, self.n_int - 1)
        return i, x - i

    def __call__(self, t, nu=0):
        """Derivative ``nu`` at times ``t`` (m,) -> (m, d)."""
        i, u = self._span(t)
        B = _dpow(u, nu) @ _M.T
        idx = i[:, None] + np.arange(K + 1)
        return np.einsum("mj,mjd->md", B, self.c[idx]) / self.h**nu


class _Design:
    """Normal equations of the P-spline on fixed sites: banded ``B^T W B`` and the penalty."""

    def __init__(self, t, t0, t1, h):
        n_int = max(1, round((t1 - t0) / h))
        h = (t1 - t0) / n_int  # the last knot at t1
        self.t0, self.h = t0, h
        self.n_int, self.n = n_int, n_int + K
        x = (t - t0) / h
        self.i = np.clip(np.floor(x).astype(np.int64), 0, n_int - 1)
        self.B = _dpow(x - self.i, 0) @ _M.T  # (N, K+1)
        P = np.zeros((K + 1, self.n))
        for p in range(K + 1):
            for q in range(p, K + 1):
                P[K + p - q, q : q + n_int] += _G3[p, q]
        self.P = P / h**5

    def normal(self, w):
        ab = np.zeros((K + 1, self.n))
        for p in range(K + 1):
            for q in range(p, K + 1):
                ab[K + p - q] += np.bincount(self.i + q, w * self.B[:, p] * self.B[:, q], self.n)
        return ab

    def rhs(self, w, y):
        out = np.zeros((self.n, y.shape[1]))
        for p in range(K + 1):
            wb = w * self.B[:, p]
            for d in range(y.shape[1]):
                out[:, d] += np.bincount(self.i + p, wb * y[:, d], self.n)
        return out

    def at_sites(self, c):
        idx = self.i[:, None] + np.arange(K + 1)
        return np.einsum("mj,mjd->md", self.B, c[idx])

    def solve(self, ab_data, rhs, lam):
        return solveh_banded(ab_data + lam * self.P, rhs, lower=False, check_finite=False)


def lam_of_cutoff(fc, dt_mean):
    """Penalty weight of the cutoff ``fc`` [Hz] (``H(fc) = 1/2``) for data every ``dt_mean``."""
    return 1.0 / (dt_mean * (2.0 * math.pi * fc) ** 6)


def noise_estimate(t, y) -> np.ndarray:
    """Robust white-noise scale of each column of ``y`` (N, d) sampled at ``t`` (N,) (the
    neighbour prediction of :func:`imugen.truth.fit.noise_estimate`, columns kept apart)."""
    t = np.asarray(t, float)
    y = np.asarray(y, float).reshape(len(t), -1)
    if len(t) < 7:
        return np.zeros(y.shape[1])
    return np.minimum(_predict_noise(t, y, 2), _predict_noise(t, y, 3))


class _Designs:
    """P-spline designs on the pose times, one per knot spacing ``h = dt_med 2^m``, the
    coarsest with ``h <= 1 / (8 f_c)`` (a quintic spline represents such a cutoff's passband
    exactly, and ``lam P`` stays within ~300x ``B^T B``: the banded Cholesky keeps full
    precision even for a 0.05 Hz cutoff on 1 kHz poses)."""

    def __init__(self, t, dt_med):
        self.t, self.dt = t, dt_med
        self.cache = {}
        self.T = float(t[-1] - t[0])

    def get(self, fc):
        m = max(0, math.floor(math.log2(1.0 / (8.0 * fc * self.dt))))
        h = min(self.dt * 2.0**m, self.T / 2.0)
        if h not in self.cache:
            self.cache[h] = _Design(self.t, self.t[0], self.t[-1], h)
        return self.cache[h]


def _smooth(designs, fc, w, y, dt_mean):
    """(design, coefficients) of the P-spline of ``y`` (N, d) at cutoff ``fc``."""
    d = designs.get(fc)
    return d, d.solve(d.normal(w), d.rhs(w, y), lam_of_cutoff(fc, dt_mean))


class _Stack:
    """Columns of several splines as one vector spline."""

    def __init__(self, splines):
        self.splines = splines

    def __call__(self, t, nu=0):
        return np.column_stack([s(t, nu) for s in self.splines])


def _search_cutoff(resid_ms, target_var, f_hi, f_lo):
    """Cutoff [Hz] whose mean squared residual equals ``target_var`` (the residual grows as
    the cutoff falls); ``f_hi`` when even that leaves less, ``f_lo`` when even that leaves
    more."""

    def g(lf):
        return math.log(max(resid_ms(math.exp(lf)), 1e-300)) - math.log(target_var)

    if g(math.log(f_hi)) >= 0.0:
        return f_hi
    if g(math.log(f_lo)) <= 0.0:
        return f_lo
    return math.exp(brentq(g, math.log(f_lo), math.log(f_hi), xtol=1e-3))


BODY_AXES = {
    "flu": np.eye(3),
    "frd": np.diag([1.0, -1.0, -1.0]),
    "rdf": np.array([[0.0, -1.0, 0.0], [0.0, 0.0, -1.0], [1.0, 0.0, 0.0]]),
}
"""``C_sb`` of an FLU IMU in a pose body of these axes (``rdf``: a camera, x right, y down,
z forward)."""


@dataclass(frozen=True)
class PoseSettings:
    """Frames, time offset and smoothing of a pose truth (SI units; None: estimated).

    Attributes
    ----------
    pose_body : {"flu", "frd", "rdf"}
        Axes of the pose body.
    imu_rotation_rad : (3,)
        Roll, pitch, yaw of the IMU's FLU axes in the pose body's FLU-ordered axes.
    lever_arm_m, marker_offset_m : (3,)
        IMU origin and tracked point in the pose body axes [m].
    time_offset_s : float
        Added to the pose clock to give the IMU clock.
    sigma_m, sigma_rad : float or None
        Pose noise per position axis [m] and per attitude axis [rad].
    cutoff_hz : float or None
        Smoothing cutoff of position and attitude, instead of the discrepancy principle.
    """

    pose_body: str = "flu"
    imu_rotation_rad: tuple = (0.0, 0.0, 0.0)
    lever_arm_m: tuple = (0.0, 0.0, 0.0)
    marker_offset_m: tuple = (0.0, 0.0, 0.0)
    time_offset_s: float = 0.0
    sigma_m: float | None = None
    sigma_rad: float | None = None
    cutoff_hz: float | None = None
    floor_m: float = 1e-5
    floor_rad: float = 1e-6
    outlier_sigma: float = 6.0
    min_cutoff_hz: float = 0.05

    def C_sb(self) -> np.ndarray:
        """IMU axes -> pose body axes, (3, 3)."""
        if self.pose_body not in BODY_AXES:
            raise InputError("--pose-body", f"{self.pose_body!r} is not flu, frd or rdf")
        r, p, y = (float(x) for x in self.imu_rotation_rad)
        return BODY_AXES[self.pose_body] @ rot.euler_to_dcm(r, p, y)


class PoseMotion:
    """The fitted 6-DoF motion of the IMU: position, velocity, acceleration, jerk (n) and
    ``q_nb``, ``omega_nb_b`` at any time in ``[t0, t1]``; :meth:`rigid` re-expresses it in
    another Earth-fixed Cartesian frame (ECEF)."""

    kind = "timed"

    def __init__(self, pos, s, delta, C_sb, t0, t1):
        self.pos, self.s, self.delta = pos, s, delta
        self.C_sb = np.asarray(C_sb, float)
        self.q_sb = rot.dcm_to_quat(self.C_sb)
        self.t0, self.t1 = float(t0), float(t1)
        self.C = np.eye(3)
        self.r0 = np.zeros(3)

    def rigid(self, C, r0) -> PoseMotion:
        """A copy in another Earth-fixed Cartesian frame: ``x' = r0 + C x``."""
        m = PoseMotion(self.pos, self.s, self.delta, self.C_sb, self.t0, self.t1)
        m.C = np.asarray(C, float) @ self.C
        m.r0 = np.asarray(r0, float) + np.asarray(C, float) @ self.r0
        return m

    def position(self, t):
        return self.r0 + self.pos(t) @ self.C.T

    def velocity(self, t):
        return self.pos(t, 1) @ self.C.T

    def eval(self, t):
        """(p, v, a, j), each (m, 3), at times ``t`` (m,)."""
        return (self.position(t), *(self.pos(t, nu) @ self.C.T for nu in (1, 2, 3)))

    def attitude_s(self, t):
        """``q_ns`` (m, 4) of the pose body in the fit frame and ``omega_ns_s`` (m, 3)."""
        s, sd = self.s(t), self.s(t, 1)
        ns = np.linalg.norm(s, axis=1)
        qb = s / ns[:, None]
        wb = 2.0 * rot.quat_mul(rot.quat_conj(qb), sd)[:, 1:] / ns[:, None]
        d, dd = self.delta(t), self.delta(t, 1)
        q = rot.quat_mul(qb, rot.exp_quat(d))
        w = np.einsum("mji,mj->mi", rot.exp_dcm(d), wb) + np.einsum(
            "mij,mj->mi", rot.right_jacobian(d), dd
        )
        return q, w

    def attitude(self, t):
        """``q_nb`` (m, 4) and ``omega_nb_b`` (m, 3) of the IMU."""
        q, w = self.attitude_s(t)
        q = rot.quat_mul(q, self.q_sb[None, :])
        if not np.array_equal(self.C, np.eye(3)):
            q = rot.quat_mul(rot.dcm_to_quat(self.C)[None, :], q)
        return q, w @ self.C_sb  # omega_b = C_sb^T omega_s


def _gaps(t) -> dict:
    dt = np.diff(t)
    med = float(np.median(dt))
    gaps = dt > 5.0 * med
    return {
        "rows": len(t),
        "median_interval_s": med,
        "rate_hz": 1.0 / med,
        "gaps": int(gaps.sum()),
        "max_gap_s": float(dt.max()),
        "gap_time_fraction": float(dt[gaps].sum() / (t[-1] - t[0])),
    }


def fit_poses(t, p_n, q_ns, settings: PoseSettings | None = None, v_n=None):
    """Fit the IMU's smooth motion to timed poses.

    Parameters
    ----------
    t : ndarray, shape (N,)
        Strictly increasing pose times [s].
    p_n : ndarray, shape (N, 3)
        Positions of the tracked point in n [m].
    q_ns : ndarray, shape (N, 4)
        Unit quaternions of the pose body in n (scalar first; signs may flip).
    settings : PoseSettings, optional
    v_n : ndarray, shape (N, 3), optional
        The source's velocities, compared with the fit's in the report.

    Returns
    -------
    (PoseMotion, dict)
        The IMU's motion in n and the fit report: gaps, sign flips, noise estimates, cutoffs,
        knot spacings, residuals (position RMS/max [m], attitude RMS/max [rad]), outliers.
    """
    o = settings or PoseSettings()
    t = np.asarray(t, float) + o.time_offset_s
    p_n = np.asarray(p_n, float)
    q_ns = np.asarray(q_ns, float)
    N = len(t)
    if N < 8:
        raise InputError(None, f"{N} poses: a pose truth needs at least 8")
    if not np.all(np.diff(t) > 0):
        raise InputError(None, "pose times must increase")
    d = np.einsum("ij,ij->i", q_ns[1:], q_ns[:-1])
    rep = {
        "method": "P-splines on SO(3) x R^3 (imugen.truth.pose)",
        "sign_flips": int(np.sum(d < 0)),
    }
    rep.update(_gaps(t))
    q_ns = rot.quat_continuous(rot.quat_normalize(q_ns))
    dt_med = rep["median_interval_s"]
    dt_mean = float(t[-1] - t[0]) / (N - 1)
    f_nyq = 0.5 / dt_med
    designs = _Designs(t, dt_med)
    w = np.ones(N)

    # attitude: normalized quaternion spline + tangent-space Gauss-Newton step
    sigma_rad = o.sigma_rad
    if sigma_rad is None:  # quaternion noise per component -> rotation noise per axis
        sig_q = noise_estimate(t, q_ns)
        sigma_rad = max(math.sqrt(4.0 / 3.0 * float(np.sum(sig_q**2))), o.floor_rad)
    rep["attitude_noise_rad"] = float(sigma_rad)
    rep["attitude_noise_source"] = "given" if o.sigma_rad is not None else "estimated"

    def fit_att(fc, w):
        d, c_s = _smooth(designs, fc, w, q_ns, dt_mean)
        s_i = d.at_sites(c_s)
        qb = s_i / np.linalg.norm(s_i, axis=1)[:, None]
        r = rot.log_quat(rot.quat_mul(rot.quat_conj(qb), q_ns))
        c_d = d.solve(d.normal(w), d.rhs(w, r), lam_of_cutoff(fc, dt_mean))
        q_i = rot.quat_mul(qb, rot.exp_quat(d.at_sites(c_d)))
        r = rot.log_quat(rot.quat_mul(rot.quat_conj(q_i), q_ns))
        return d, c_s, c_d, r

    def att_ms(fc):
        return float(np.sum(w * np.sum(fit_att(fc, w)[3] ** 2, 1)) / np.sum(w))

    for _pass in range(2):
        if o.cutoff_hz is not None:
            fc_att = min(float(o.cutoff_hz), f_nyq)
        else:
            fc_att = _search_cutoff(att_ms, 3.0 * sigma_rad**2, f_nyq, o.min_cutoff_hz)
        d_att, c_s, c_d, r = fit_att(fc_att, w)
        e = np.linalg.norm(r, axis=1)
        bad = e > o.outlier_sigma * math.sqrt(3.0) * sigma_rad
        if not bad.any() or _pass == 1:
            break
        w = np.where(bad, 0.0, w)
    s_spl = USpline(t[0], d_att.h, c_s)
    d_spl = USpline(t[0], d_att.h, c_d)
    rep["attitude_cutoff_hz"] = fc_att
    rep["attitude_knot_s"] = d_att.h
    rep["attitude_residual_rms_rad"] = float(np.sqrt(np.mean(e[w > 0] ** 2)))
    rep["attitude_residual_max_rad"] = float(e[w > 0].max())
    rep["attitude_outliers"] = int((w == 0).sum())

    # position of the IMU point (lever arm and marker offset with the fitted attitude)
    q_fit, _ = PoseMotion(None, s_spl, d_spl, np.eye(3), t[0], t[-1]).attitude_s(t)
    off = np.asarray(o.lever_arm_m, float) - np.asarray(o.marker_offset_m, float)
    y = p_n + rot.quat_to_dcm(q_fit) @ off
    sig_p = o.sigma_m
    if sig_p is None:
        sig_p = np.maximum(noise_estimate(t, y), o.floor_m)
    sig_p = np.broadcast_to(np.asarray(sig_p, float), (3,)).copy()
    rep["position_noise_m"] = sig_p.tolist()
    rep["position_noise_source"] = "given" if o.sigma_m is not None else "estimated"
    wp = w.copy()
    for _pass in range(2):
        fcs, spl, res = [], [], np.empty_like(y)
        for ax in range(3):

            def pos_ms(fc, ax=ax, w_=wp):
                d, c = _smooth(designs, fc, w_, y[:, ax : ax + 1], dt_mean)
                return float(np.sum(w_ * (d.at_sites(c)[:, 0] - y[:, ax]) ** 2) / np.sum(w_))

            if o.cutoff_hz is not None:
                fc = min(float(o.cutoff_hz), f_nyq)
            else:
                fc = _search_cutoff(pos_ms, sig_p[ax] ** 2, f_nyq, o.min_cutoff_hz)
            d, c = _smooth(designs, fc, wp, y[:, ax : ax + 1], dt_mean)
            res[:, ax] = d.at_sites(c)[:, 0] - y[:, ax]
            fcs.append(fc)
            spl.append(USpline(t[0], d.h, c))
        bad = np.any(np.abs(res) > o.outlier_sigma * sig_p, axis=1) & (wp > 0)
        if not bad.any() or _pass == 1:
            break
        wp = np.where(bad, 0.0, wp)
    pos = _Stack(spl)
    dist = np.linalg.norm(res, axis=1)[wp > 0]
    rep["position_cutoff_hz"] = fcs
    rep["position_knot_s"] = [s.h for s in spl]
    rep["position_residual_rms_m"] = float(np.sqrt(np.mean(dist**2)))
    rep["position_residual_max_m"] = float(dist.max())
    rep["position_outliers"] = int((wp == 0).sum() - (w == 0).sum())
    if v_n is not None:
        dv = pos(t, 1) - np.asarray(v_n, float)
        rep["velocity_vs_source_rms_mps"] = float(np.sqrt(np.mean(np.sum(dv**2, 1))))
    # the truth report's distances of the motion to the input points
    rep["rms_distance_m"] = rep["position_residual_rms_m"]
    rep["max_distance_m"] = rep["position_residual_max_m"]
    return PoseMotion(pos, s_spl, d_spl, o.C_sb(), t[0], t[-1]), rep


def pose_pass(out, ci, motion, times, E, chunk):
    """Kinematics and the given attitude of every sample, written into ``out`` (as
    :func:`imugen.truth.attitude.attitude_pass` for the vehicle models).

    Returns
    -------
    f_n : ndarray, shape (K, 3)
        Specific force in n [m/s^2].
    stats : dict
        Acceleration and jerk figures; ``airborne`` (K,) all True (the ground-vehicle
        limits of :func:`imugen.truth.report.plausibility` do not apply to a given attitude).
    """
    K = len(times)
    f_n_all = np.empty((K, 3))
    acc_ss, acc_max, jerk_max = 0.0, 0.0, 0.0
    for k0 in range(0, K, chunk):
        k1 = min(K, k0 + chunk)
        p, v, a, j = motion.eval(times[k0:k1])
        an = np.linalg.norm(a, axis=1)
        acc_ss += float(np.sum(an * an))
        acc_max = max(acc_max, float(an.max()))
        jerk_max = max(jerk_max, float(np.linalg.norm(j, axis=1).max()))
        f_n_all[k0:k1] = a + 2.0 * np.cross(E.Omega, v) - E.gravity(p)
        q, w = motion.attitude(times[k0:k1])
        out[k0:k1, ci["pos"]] = p
        out[k0:k1, ci["vel"]] = v
        out[k0:k1, ci["quat"]] = q
        out[k0:k1, ci["gyro"]] = w
    stats = {
        "accel_rms_mps2": float(np.sqrt(acc_ss / K)),
        "accel_max_mps2": acc_max,
        "jerk_max_mps3": jerk_max,
        "attitude": "given (pose trajectory)",
        # the ground-vehicle limits (roll, slip, heading) do not apply to a given attitude
        "airborne": np.ones(K, dtype=bool),
    }
    return f_n_all, stats


def motion_figures(t, v, w, f_b, q=None) -> dict:
    """Figures of a 6-DoF truth a carrier class bounds: speed, acceleration and jerk (from
    velocity differences), body rate and angular acceleration, the angle of the specific
    force from body z (a multirotor's thrust axis: small up to rotor drag; a pose truth whose
    attitude is not a multirotor's shows here).

    Parameters
    ----------
    t : (K,) [s]; v : (K, 3) [m/s]; w : (K, 3) body rate [rad/s]; f_b : (K, 3) [m/s^2]
    """
    dt = float(np.median(np.diff(t)))
    acc = np.gradient(v, dt, axis=0)
    jerk = np.gradient(acc, dt, axis=0)
    wd = np.gradient(w, dt, axis=0)
    off_z = np.arctan2(np.hypot(f_b[:, 0], f_b[:, 1]), f_b[:, 2])
    inner = slice(2, -2) if len(t) > 8 else slice(None)
    return {
        "max_jerk_mps3": float(np.linalg.norm(jerk[inner], axis=1).max()),
        "max_rate_radps": float(np.linalg.norm(w, axis=1).max()),
        "max_ang_accel_radps2": float(np.linalg.norm(wd[inner], axis=1).max()),
        "specific_force_off_z_rms_rad": float(np.sqrt(np.mean(off_z**2))),
        "specific_force_off_z_max_rad": float(off_z.max()),
    }
