"""Truth motion: ENU route -> smooth 6-DoF motion, ideal IMU and exact increments.

One smooth representation of position carries everything
---------------------------------------------------------
*Timed routes* (``time_s`` present): each axis is a quintic penalized smoothing spline of
position against time (knots at the input times, penalty ``lambda * int |d3p/dt3|^2``, the
classical smoothing spline of degree 5, continuous to the 4th derivative). The smoothing is
chosen per axis by the *discrepancy principle*: the RMS residual equals the position noise
estimated from the data itself (robust scale of the residuals of predicting every point from
its neighbours, :func:`noise_estimate`), bounded by ``[fit_floor_m,
fit_tol_max_m]``; ``fit_tol_m`` overrides it by a 3-D RMS tolerance. Input stretches of at
least ``stop_min_s`` whose points stay within ``stop_radius_m`` (or 3x the noise) of their
median and barely move overall (see :func:`_find_stops`) are *stops*: the spline is
constrained to be exactly constant there (its B-spline coefficients over the stop are tied),
so velocity, acceleration, jerk and snap vanish at the stop's edges and the stop is a real stop.

*Untimed routes* (polylines, e.g. KML LineString): the polyline is densified and fitted by
the same smoothing spline against chord length with a corner-rounding length ``corner_m``
(a right-angle corner becomes an arc of radius about ``corner_m``), re-parameterized by arc
length (quintic interpolation), and driven by a speed profile ``s(t)``: time-optimal under
``cruise_mps``, ``accel_mps2`` and the lateral limit ``v <= sqrt(lat_accel_mps2 / kappa)``
(forward/backward passes, at rest at both ends), then filtered twice by a moving average of
width ``T = (max a - min a) / jerk_mps3`` (bounds jerk by ``jerk_mps3``, keeps the
acceleration bound and the non-negative speed; ``s(t)`` is a C^3 piecewise quartic); where
the filtering lifts the lateral acceleration above the limit, the limit is lowered there and
the profile rebuilt. Position is ``G(s(t))``; derivatives by the chain rule.

Attitude
--------
Body x along the velocity; body z along the component perpendicular to x of a reference
vector ``r``: the local geodetic up at the vehicle for cars and pedestrians (roll 0, pitch =
climb angle, level relative to the local level in ``wgs84``), the specific force for aircraft
(coordinated turn, no sideslip; loops and vertical flight work because nothing is measured
in Euler angles). Rates come analytically from velocity, acceleration, jerk and the
derivative of ``r``. When the speed is below ``hold_speed_mps[0]`` (or ``r`` is nearly
parallel to the velocity) the attitude is held; between the two thresholds of a quintic
smoothstep weight ``w`` it is ``q_hold * Exp(w Log(q_hold^-1 q_target))`` (C^2 in time),
with the analytic rate ``w' phi + w J_r(w phi) J_r^-1(phi) omega_target``.

Ideal IMU (per :mod:`imugen.earth` and the issue-3 spec)
---------------------------------------------------------
``omega_ib_b = omega_nb_b + C_nb^T Omega_n``; ``f_b = C_nb^T (a_n + 2 Omega_n x v_n - g_n(p_n))``;
``dtheta_k = Log(C_nb(t_k)^T Exp(Omega_n dt) C_nb(t_k+1))``;
``dv_k = C_nb(t_k)^T [v_I(t_k+1) - v_I(t_k) - int A(tau) G_n(p_n) dtau]`` with the
gravitation integral by 4-node Gauss-Legendre quadrature on the continuous truth position
(exact in ``flat``: ``dv_k = C_nb(t_k)^T (v_k+1 - v_k - g_n dt)``).
"""

from __future__ import annotations

import math
import sys
from dataclasses import asdict, dataclass, field, replace

import numpy as np
import pandas as pd
import scipy.sparse as sp
from scipy.interpolate import BSpline, PPoly, make_interp_spline
from scipy.ndimage import binary_dilation, maximum_filter1d, minimum_filter1d
from scipy.optimize import brentq
from scipy.sparse.linalg import splu

from imugen import __version__
from imugen import columns as col
from imugen import earth as ea
from imugen import rotations as rot
from imugen.errors import InputError
from imugen.tables import enu as tenu
from imugen.tables import truth as ttable

K_SPLINE = 5  # quintic
N_GAUSS = 4  # Gauss-Legendre nodes of the gravitation integral
CHUNK = 1 << 16  # samples per evaluation chunk


@dataclass(frozen=True)
class VehicleParams:
    """Defaults of a vehicle type (SI units). See the module docstring for their roles."""

    attitude: str  # "level" (roll 0) or "coordinated" (body z along specific force)
    cruise_mps: float
    accel_mps2: float
    lat_accel_mps2: float
    jerk_mps3: float
    corner_m: float
    hold_speed_mps: tuple = (0.2, 1.0)
    hold_perp: tuple = (0.05, 0.1)  # |r_perp| thresholds: cos(pitch) (level) or m/s^2 (aircraft)
    stop_speed_mps: float = 0.2
    stop_min_s: float = 2.0
    stop_radius_m: float = 1.0
    fit_tol_max_m: float = 5.0
    fit_floor_m: float = 1e-3


VEHICLES = {
    # car: 50 km/h cruise, 0.2 g longitudinal, 0.3 g lateral, 1 m/s^3 comfort jerk; heading
    # held below 0.2 m/s, fully along the velocity above 1 m/s (GNSS tracks swing the velocity
    # direction at walking pace; a car cannot turn on the spot)
    "car": VehicleParams("level", 13.9, 2.0, 3.0, 1.0, 10.0),
    # pedestrian: 5 km/h, gentle accelerations, corners rounded over ~1 m
    "pedestrian": VehicleParams(
        "level",
        1.4,
        0.5,
        0.5,
        1.0,
        1.0,
        hold_speed_mps=(0.1, 0.5),
        stop_speed_mps=0.1,
        stop_radius_m=1.0,
    ),
    # aircraft: 70 m/s, 0.3 g longitudinal, 0.5 g lateral (~27 deg bank), 2 m/s^3
    "aircraft": VehicleParams(
        "coordinated",
        70.0,
        3.0,
        5.0,
        2.0,
        300.0,
        hold_speed_mps=(0.5, 2.0),
        hold_perp=(0.3, 1.0),
        stop_speed_mps=0.5,
        stop_radius_m=3.0,
        fit_tol_max_m=20.0,
    ),
}


# ------------------------------------------------------------------------------------------
# small helpers
# ------------------------------------------------------------------------------------------
def _smoothstep(x, lo, hi):
    """Quintic smoothstep and its derivative (C^2): 0 below lo, 1 above hi."""
    u = np.clip((x - lo) / (hi - lo), 0.0, 1.0)
    s = u * u * u * (10.0 - 15.0 * u + 6.0 * u * u)
    ds = 30.0 * u * u * (1.0 - u) ** 2 / (hi - lo)
    return s, ds


def _dot(a, b):
    return np.einsum("...i,...i->...", a, b)


def enu_table(enu_m, time_s=None, origin=(0.0, 0.0, 0.0)) -> tuple[pd.DataFrame, dict]:
    """Build an ENU table and its metadata from arrays (synthetic routes, tests).

    Parameters
    ----------
    enu_m : array_like, shape (N, 3)
        East, North, Up relative to the origin [m].
    time_s : array_like, shape (N,), optional
        Times [s]; None for an untimed path.
    origin : (lat_deg, lon_deg, alt_m)

    Returns
    -------
    (DataFrame, dict)
        Columns like ingestion's output and the metadata (``origin``, ``timed``).
    """
    enu_m = np.asarray(enu_m, dtype=float).reshape(-1, 3)
    frame = ea.OriginFrame.from_deg(*origin)
    lat, lon, h = frame.geodetic_from_n(enu_m)
    data = {}
    if time_s is not None:
        data[col.TIME] = np.asarray(time_s, dtype=float)
    data[col.LAT] = np.degrees(lat)
    data[col.LON] = np.degrees(lon)
    data[col.ALT] = h
    data[col.E], data[col.N], data[col.U] = enu_m.T
    meta = {
        "origin": {
            "lat_deg": float(origin[0]),
            "lon_deg": float(origin[1]),
            "alt_m": float(origin[2]),
        },
        "timed": time_s is not None,
        "source": "arrays",
    }
    return pd.DataFrame(data), meta


# ------------------------------------------------------------------------------------------
# penalized quintic smoothing spline
# ------------------------------------------------------------------------------------------
def _predict_noise(t, y, half):
    """Robust noise estimate from the residuals of the degree-(2 half - 1) Lagrange prediction
    of every point from its ``half`` neighbours on each side (normalized by the noise gain)."""
    n = len(t)
    ti = t[half : n - half]
    offs = [o for o in range(-half, half + 1) if o != 0]
    nbr = np.stack([t[half + o : n - half + o] for o in offs])
    w = np.ones_like(nbr)
    for j in range(len(offs)):
        for m in range(len(offs)):
            if m != j:
                w[j] *= (ti - nbr[m]) / (nbr[j] - nbr[m])
    ys = np.stack([y[half + o : n - half + o] for o in offs])
    e = y[half : n - half] - np.einsum("jn,jnd->nd", w, ys)
    e = e / np.sqrt(1.0 + np.sum(w * w, axis=0))[:, None]
    e = e - np.median(e, axis=0)
    sig = 1.4826 * np.median(np.abs(e), axis=0)
    for _ in range(3):  # RMS within 3 sigma (efficient), corrected for the truncation
        inside = np.abs(e) <= 3.0 * sig
        sig = (
            np.sqrt(
                np.sum(np.where(inside, e * e, 0.0), axis=0) / np.maximum(inside.sum(axis=0), 1)
            )
            / 0.98658
        )
    return sig


def noise_estimate(t, y) -> np.ndarray:
    """Robust white-noise estimate of each column of ``y`` sampled at times ``t``.

    Every point is predicted from its neighbours by the cubic through 2 + 2 of them and by the
    quintic through 3 + 3 of them; the residuals, scaled by the noise gain of the predictor
    ``sqrt(1 + sum w^2)``, give a robust scale (``1.4826 MAD``, refined by the RMS within
    3 sigma, corrected for the truncation). The smaller of the two is returned (for white
    noise both are unbiased; on sparse samples of smooth motion the higher-order predictor
    leaks less of the motion into the estimate). East and North share their RMS (GNSS
    horizontal noise is isotropic), which halves the scatter of the estimate.

    Parameters
    ----------
    t : ndarray, shape (N,)
    y : ndarray, shape (N, d)

    Returns
    -------
    ndarray, shape (d,)
        Zeros when N < 5.
    """
    t = np.asarray(t, float)
    y = np.asarray(y, float).reshape(len(t), -1)
    if len(t) < 5:
        return np.zeros(y.shape[1])
    est = _predict_noise(t, y, 2)
    if len(t) >= 7:
        est = np.minimum(est, _predict_noise(t, y, 3))
    if est.shape[0] == 3:
        est[:2] = math.sqrt(0.5 * (est[0] ** 2 + est[1] ** 2))
    return est


class _PenalizedSpline:
    """Quintic B-spline with knots at the data sites; minimizes residual^2 + lam*int(f''')^2.

    ``ties``: list of (i0, i1) coefficient ranges forced equal (constant stretches).
    """

    def __init__(self, x, ties=()):
        x = np.asarray(x, float)
        k = K_SPLINE
        self.x0 = x[0]
        self.scale = float(np.median(np.diff(x)))
        u = (x - self.x0) / self.scale
        self.u = u
        self.tau = np.r_[[u[0]] * k, u, [u[-1]] * k]
        n = len(self.tau) - k - 1
        self.n = n
        B = BSpline.design_matrix(u, self.tau, k).tocsc()
        # tie matrix: c_full = M c_red
        keep = np.ones(n, dtype=bool)
        rows, cols_ = [], []
        red_index = np.full(n, -1)
        for i0, i1 in ties:
            keep[i0 + 1 : i1 + 1] = False
        red_index[keep] = np.arange(keep.sum())
        for i0, i1 in ties:
            red_index[i0 + 1 : i1 + 1] = red_index[i0]
        rows = np.arange(n)
        cols_ = red_index
        self.M = sp.csc_matrix((np.ones(n), (rows, cols_)), shape=(n, keep.sum()))
        self.B = (B @ self.M).tocsc()
        self.P = (self.M.T @ self._penalty() @ self.M).tocsc()
        self.BtB = (self.B.T @ self.B).tocsc()

    def _penalty(self, m=3):
        k = K_SPLINE
        D = sp.identity(self.n, format="csr")
        tt, nn = self.tau, self.n
        for kk in range(k, k - m, -1):
            d = kk / (tt[kk + 1 : kk + nn] - tt[1:nn])
            D = sp.diags([-d, d], [0, 1], shape=(nn - 1, nn)) @ D
            tt, nn = tt[1:-1], nn - 1
        kd = k - m
        xg, wg = np.polynomial.legendre.leggauss(kd + 1)
        a, b = tt[:-1], tt[1:]
        nz = b > a
        a, b = a[nz], b[nz]
        xq = (0.5 * (b - a)[:, None] * xg + 0.5 * (b + a)[:, None]).ravel()
        wq = (0.5 * (b - a)[:, None] * wg).ravel()
        Bq = BSpline.design_matrix(xq, tt, kd)
        G = Bq.T @ sp.diags(wq) @ Bq
        return D.T @ G @ D

    def solve(self, lam, y):
        lu = splu((self.BtB + lam * self.P).tocsc())
        return lu.solve(self.B.T @ y)

    def rms(self, lam, y):
        c = self.solve(lam, y)
        return float(np.sqrt(np.mean((self.B @ c - y) ** 2)))

    def lam_for_rms(self, y, target, lo=-6.0, hi=12.0):
        """log10 lambda (normalized time) whose RMS residual equals ``target``.

        Bandwidth ~ lambda^(1/6) samples, so [lo, hi] spans 0.1 to 100 samples. When the
        fit with lambda = 1 (one-sample bandwidth) already leaves less than a tenth of
        ``target``, the data are smooth well within the noise: lambda = 1 is returned (well
        conditioned). When even the smoothest fit stays below ``target``, ``hi`` is returned.
        """

        def f(ll):
            return math.log(max(self.rms(10.0**ll, y), 1e-300)) - math.log(target)

        if f(0.0) <= math.log(0.1):
            return 0.0
        if f(lo) >= 0:
            return lo
        if f(hi) <= 0:
            return hi
        return brentq(f, lo, hi, xtol=0.01)

    def bspline(self, c_red_cols) -> BSpline:
        """Full-coefficient BSpline in the original variable x (vector-valued)."""
        c = self.M @ c_red_cols
        # map u = (x - x0)/scale back to x: knots scale, coefficients unchanged
        return BSpline(self.tau * self.scale + self.x0, c, K_SPLINE, extrapolate=True)


# ------------------------------------------------------------------------------------------
# motions
# ------------------------------------------------------------------------------------------
class TimedMotion:
    """Position spline p(t) (vector-valued quintic BSpline) and its derivatives."""

    kind = "timed"

    def __init__(self, spline: BSpline, t0: float, t1: float):
        self.spline = spline
        self.d = [spline] + [spline.derivative(nu) for nu in (1, 2, 3)]
        self.t0, self.t1 = t0, t1

    def position(self, t):
        return self.d[0](t)

    def eval(self, t):
        """(p, v, a, j), each shape (m, 3), at times ``t`` (m,)."""
        return tuple(s(t) for s in self.d)


class PathMotion:
    """Position ``G(s(t))``: geometry G(s) (arc length) and speed profile s(t) (PPoly)."""

    kind = "untimed"

    def __init__(self, G: BSpline, s_of_t: PPoly, length: float):
        self.G = [G] + [G.derivative(nu) for nu in (1, 2, 3)]
        self.S = [s_of_t] + [s_of_t.derivative(nu) for nu in (1, 2, 3)]
        self.length = length
        self.t0 = float(s_of_t.x[0])
        self.t1 = float(s_of_t.x[-1])

    def _s(self, t):
        return np.clip(self.S[0](t), 0.0, self.length)

    def position(self, t):
        return self.G[0](self._s(t))

    def eval(self, t):
        s = self._s(t)
        sd, sdd, sddd = (self.S[i](t)[:, None] for i in (1, 2, 3))
        g1, g2, g3 = (self.G[i](s) for i in (1, 2, 3))
        p = self.G[0](s)
        v = g1 * sd
        a = g2 * sd**2 + g1 * sdd
        j = g3 * sd**3 + 3.0 * g2 * sd * sdd + g1 * sddd
        return p, v, a, j


# ------------------------------------------------------------------------------------------
# fitting timed routes
# ------------------------------------------------------------------------------------------
def _find_stops(t, y, noise_m, vp: VehicleParams):
    """Index ranges (i0, i1) of input points that are stops.

    A point is still when the points within ``stop_min_s / 2`` of it span a box of diagonal
    at most ``2 r`` with ``r = max(stop_radius_m, 3 * noise_m)``; runs of still points (and
    their windows) lasting at least ``stop_min_s`` whose points all lie within ``r`` of the
    run's median and whose net displacement (median of the first third to median of the last
    third) is below ``r / 2`` and ``stop_speed_mps`` times the duration are stops.
    """
    n = len(t)
    if n < 3:
        return []
    r = max(vp.stop_radius_m, 3.0 * noise_m)
    half = max(1, round(0.5 * vp.stop_min_s / float(np.median(np.diff(t)))))
    size = 2 * half + 1
    span = maximum_filter1d(y, size, axis=0, mode="nearest") - minimum_filter1d(
        y, size, axis=0, mode="nearest"
    )
    still = np.linalg.norm(span, axis=1) <= 2.0 * r
    mark = binary_dilation(still, structure=np.ones(size, dtype=bool))
    edges = np.flatnonzero(np.diff(np.r_[0, mark.astype(np.int8), 0]))
    stops = []
    for i0, i1 in zip(edges[::2], edges[1::2] - 1, strict=True):
        dur = t[i1] - t[i0]
        if i1 <= i0 or dur < vp.stop_min_s:
            continue
        pts = y[i0 : i1 + 1]
        if np.max(np.linalg.norm(pts - np.median(pts, axis=0), axis=1)) > r:
            continue
        third = max(1, len(pts) // 3)
        net = np.linalg.norm(np.median(pts[-third:], axis=0) - np.median(pts[:third], axis=0))
        if net <= min(0.5 * r, vp.stop_speed_mps * dur):
            stops.append((int(i0), int(i1)))
    return stops


def fit_timed(t, y, vp: VehicleParams, fit_tol_m=None, stops=True):
    """Fit the position spline of a timed route; returns (TimedMotion, report dict)."""
    t = np.asarray(t, float)
    y = np.asarray(y, float)
    n = len(t)
    if n < 3:
        raise InputError(None, f"a timed route needs at least 3 points to fit, got {n}")
    dt = np.diff(t)
    if not np.all(np.isfinite(t)) or np.any(dt <= 0):
        raise InputError(None, "route times must be finite and strictly increasing")
    sig = noise_estimate(t, y)
    norm = float(np.linalg.norm(sig))
    if fit_tol_m is not None:
        if not fit_tol_m > 0:
            raise InputError(None, f"fit tolerance must be > 0, got {fit_tol_m}")
        target = (sig / norm * fit_tol_m) if norm > 0 else np.full(3, fit_tol_m / math.sqrt(3))
        criterion = f"RMS residual = fit_tol_m = {fit_tol_m} m (split by the noise estimate)"
    else:
        target = sig.copy()
        if norm > vp.fit_tol_max_m:
            target *= vp.fit_tol_max_m / norm
        criterion = (
            "discrepancy principle: per-axis RMS residual = robust noise estimate "
            f"(noise_estimate: neighbour-prediction residuals), 3-D bounded by [{vp.fit_floor_m}, "
            f"{vp.fit_tol_max_m}] m"
        )
    target = np.maximum(target, vp.fit_floor_m / math.sqrt(3))
    ps = _PenalizedSpline(t)
    loglam = np.array([ps.lam_for_rms(y[:, i], target[i]) for i in range(3)])
    lam = 10.0**loglam
    coef = np.column_stack([ps.solve(lam[i], y[:, i]) for i in range(3)])
    spline = ps.bspline(coef)
    stop_list = []
    if stops:
        stop_list = _find_stops(t, y, norm, vp)
        if stop_list:
            # coefficients active on [t_i0, t_i1] are i0 .. i1 + k - 1 (knots at data sites)
            ties = [(i0, i1 + K_SPLINE - 1) for i0, i1 in stop_list]
            ps = _PenalizedSpline(t, ties)
            coef = np.column_stack([ps.solve(lam[i], y[:, i]) for i in range(3)])
            spline = ps.bspline(coef)
    motion = TimedMotion(spline, float(t[0]), float(t[-1]))
    dist = np.linalg.norm(spline(t) - y, axis=1)
    report = {
        "method": "quintic penalized smoothing spline (knots at input times, penalty on jerk)",
        "criterion": criterion,
        "noise_estimate_m": sig.tolist(),
        "target_rms_m": target.tolist(),
        "lambda_normalized": lam.tolist(),
        "time_scale_s": ps.scale,
        "rms_distance_m": float(np.sqrt(np.mean(dist**2))),
        "max_distance_m": float(dist.max()),
        "stops": [[float(t[i0]), float(t[i1])] for i0, i1 in stop_list],
    }
    return motion, report


# ------------------------------------------------------------------------------------------
# untimed routes: geometry and speed profile
# ------------------------------------------------------------------------------------------
def fit_path(y, vp: VehicleParams, corner_m=None):
    """Smooth a polyline and re-parameterize by arc length.

    Returns (G BSpline of s, length L, report dict).
    """
    y = np.asarray(y, float)
    seg = np.linalg.norm(np.diff(y, axis=0), axis=1)
    keep = np.r_[True, seg > 1e-9]
    y = y[keep]
    seg = np.linalg.norm(np.diff(y, axis=0), axis=1)
    if len(y) < 2 or seg.sum() <= 0:
        raise InputError(None, "an untimed route needs at least 2 distinct points")
    ell = float(corner_m if corner_m is not None else vp.corner_m)
    if not ell > 0:
        raise InputError(None, f"corner rounding length must be > 0, got {ell}")
    step = ell / 4.0
    nsub = np.maximum(1, np.ceil(seg / step).astype(int))
    frac = np.concatenate([np.arange(m) / m for m in nsub])
    idx = np.repeat(np.arange(len(seg)), nsub)
    dense = np.vstack([y[idx] + frac[:, None] * (y[idx + 1] - y[idx]), y[-1:]])
    u = np.r_[0.0, np.cumsum(np.repeat(seg / nsub, nsub))]
    if len(dense) < 3:  # pragma: no cover - nsub >= 1 gives >= 2 points; make 3
        mid = 0.5 * (dense[0] + dense[-1])
        dense = np.vstack([dense[0], mid, dense[-1]])
        u = np.array([0.0, 0.5 * u[-1], u[-1]])
    ps = _PenalizedSpline(u)
    # equivalent-kernel bandwidth of an order-3 smoothing spline ~ lam^(1/6) samples;
    # calibrated so that a right-angle corner becomes an arc of radius ~ ell (tests check)
    lam = (ell / ps.scale) ** 6 * _CORNER_CAL
    coef = np.column_stack([ps.solve(lam, dense[:, i]) for i in range(3)])
    g = ps.bspline(coef)
    # arc length by 5-node Gauss-Legendre on a fine parameter grid
    nfine = max(64, int(np.ceil(u[-1] / (step / 4.0))))
    uf = np.linspace(0.0, u[-1], nfine + 1)
    xg, wg = np.polynomial.legendre.leggauss(5)
    h = np.diff(uf)
    xq = (uf[:-1, None] + 0.5 * h[:, None] * (xg + 1.0)).ravel()
    speed = np.linalg.norm(g.derivative(1)(xq), axis=1).reshape(-1, 5)
    s = np.r_[0.0, np.cumsum(0.5 * h * (speed @ wg))]
    L = float(s[-1])
    G = make_interp_spline(s, g(uf), k=K_SPLINE)
    # distance from input vertices to the smoothed curve (nearest fine sample)
    from scipy.spatial import cKDTree

    sf = np.linspace(0.0, L, max(2, int(np.ceil(L / (step / 8.0))) + 1))
    d, _ = cKDTree(G(sf)).query(y)
    report = {
        "method": "quintic penalized smoothing spline of the densified polyline vs chord "
        "length, re-parameterized by arc length",
        "corner_m": ell,
        "densify_step_m": step,
        "rms_distance_m": float(np.sqrt(np.mean(d**2))),
        "max_distance_m": float(d.max()),
        "length_m": L,
    }
    return G, L, report


_CORNER_CAL = 1.0  # set by calibration below (see _calibrate_corner)


def _curvature(G: BSpline, s):
    d1 = G.derivative(1)(s)
    d2 = G.derivative(2)(s)
    n1 = np.linalg.norm(d1, axis=1)
    return np.linalg.norm(np.cross(d1, d2), axis=1) / np.maximum(n1, 1e-12) ** 3


def _moving_average(x, m):
    """Causal moving average over m samples with zero history: y_i = mean(x[i-m+1..i])."""
    c = np.cumsum(np.r_[np.zeros(m), x])
    return (c[m:] - c[:-m]) / m


def speed_profile(
    G: BSpline,
    L: float,
    *,
    cruise_mps,
    accel_mps2,
    lat_accel_mps2,
    jerk_mps3,
    max_iter=30,
    lat_tol=0.01,
):
    """Speed profile s(t) along the geometry; returns (PPoly s(t), report).

    The profile starts and ends at rest; see the module docstring for the construction.
    """
    for name, val in (
        ("cruise speed", cruise_mps),
        ("acceleration", accel_mps2),
        ("lateral acceleration", lat_accel_mps2),
        ("jerk", jerk_mps3),
    ):
        if not (val > 0 and math.isfinite(val)):
            raise InputError(None, f"{name} limit must be a positive number, got {val}")
    ns = int(min(400_000, max(200, math.ceil(L / 0.25))))
    s = np.linspace(0.0, L, ns + 1)
    ds = s[1] - s[0]
    kappa = _curvature(G, s)
    A = accel_mps2
    scale_lim = np.ones_like(s)
    for it in range(max_iter):  # noqa: B007 (reported below)
        vlim2 = np.minimum(cruise_mps**2, lat_accel_mps2 / np.maximum(kappa, 1e-12)) * scale_lim
        vlim2[0] = vlim2[-1] = 0.0
        fwd = 2 * A * s + np.minimum.accumulate(vlim2 - 2 * A * s)
        bwd = -2 * A * s + np.minimum.accumulate((vlim2 + 2 * A * s)[::-1])[::-1]
        v = np.sqrt(np.maximum(np.minimum(np.minimum(fwd, bwd), vlim2), 0.0))
        vm = v[:-1] + v[1:]
        if not np.all(vm > 0):
            raise InputError(None, "speed profile stalls (zero speed limit inside the path)")
        dtj = 2.0 * ds / vm
        tj = np.r_[0.0, np.cumsum(dtj)]
        acc = (v[1:] - v[:-1]) / dtj  # uniform acceleration within each s-segment
        T = tj[-1]
        h = min(0.02, T / 200.0)
        ti = np.arange(0.0, T + h, h)
        j = np.clip(np.searchsorted(tj, ti, side="right") - 1, 0, ns - 1)
        V = np.clip(v[j] + acc[j] * (ti - tj[j]), 0.0, None)
        V[-1] = 0.0
        a_raw = np.diff(V) / h
        Tf = max(float(a_raw.max() - a_raw.min()) / jerk_mps3, 2 * h)
        m = math.ceil(Tf / h)
        a_pad = np.r_[a_raw, np.zeros(2 * m + 2)]
        c = np.r_[0.0, 0.0, _moving_average(_moving_average(a_pad, m), m)]
        # accel = sum c_i B2(t/h - i): uniform quadratic B-splines, support [i h, (i+3) h];
        # the two leading zeros put the whole motion inside the base interval [2h, len(c) h]
        acc_sp = BSpline(h * np.arange(len(c) + 3.0), c, 2)
        pp = PPoly.from_spline(acc_sp)  # also holds extrapolated pieces: keep the base interval
        pp = PPoly(pp.c[:, 2 : len(c)], pp.x[2 : len(c) + 1])
        s_pp = pp.antiderivative(2)
        t_end = float(s_pp.x[-1])
        total = float(s_pp(t_end))
        s_pp = PPoly(s_pp.c * (L / total), s_pp.x - s_pp.x[0])
        # check the lateral acceleration on a fine grid
        tt = np.linspace(0.0, s_pp.x[-1], max(2000, int(s_pp.x[-1] / h) + 1))
        sv = np.clip(s_pp(tt), 0.0, L)
        vv = s_pp.derivative(1)(tt)
        ratio = _curvature(G, sv) * vv**2 / lat_accel_mps2
        worst = float(ratio.max())
        if worst <= 1.0 + lat_tol:
            break
        # lower the limit where exceeded, spread over the distance the filter reaches
        bad = ratio > 1.0
        fac = np.ones_like(s)
        idx = np.clip(np.searchsorted(s, sv[bad]), 0, ns)
        np.minimum.at(fac, idx, 1.0 / ratio[bad])
        reach = max(1, math.ceil(2.0 * Tf * float(vv[bad].max()) / ds))
        fac = minimum_filter1d(fac, 2 * reach + 1)
        scale_lim *= np.where(fac < 1.0, 0.98 * fac, 1.0)
    report = {
        "cruise_mps": cruise_mps,
        "accel_mps2": accel_mps2,
        "lat_accel_mps2": lat_accel_mps2,
        "jerk_mps3": jerk_mps3,
        "filter_width_s": Tf,
        "duration_s": float(s_pp.x[-1]),
        "max_lateral_ratio": worst,
        "iterations": it + 1,
        "distance_scale": L / total,
    }
    return s_pp, report


# ------------------------------------------------------------------------------------------
# attitude
# ------------------------------------------------------------------------------------------
def _target_frame(v, a, r, rd):
    """Body frame with x along v and z along r's component perpendicular to x.

    Parameters
    ----------
    v, a : ndarray, shape (m, 3)
        Velocity and acceleration in n.
    r, rd : ndarray, shape (m, 3)
        Reference vector and its time derivative in n.

    Returns
    -------
    C_nb (m, 3, 3), omega_nb_b (m, 3), speed (m,), speed_dot (m,), rperp (m,), rperp_dot (m,)
    """
    sp_ = np.linalg.norm(v, axis=1)
    sps = np.maximum(sp_, 1e-9)
    x = v / sps[:, None]
    xa = _dot(x, a)
    xd = (a - x * xa[:, None]) / sps[:, None]
    xr = _dot(x, r)
    rp = r - x * xr[:, None]
    rpn = np.linalg.norm(rp, axis=1)
    rps = np.maximum(rpn, 1e-9)
    z = rp / rps[:, None]
    rpd = rd - xd * xr[:, None] - x * (_dot(xd, r) + _dot(x, rd))[:, None]
    zrpd = _dot(z, rpd)
    zd = (rpd - z * zrpd[:, None]) / rps[:, None]
    y = np.cross(z, x)
    yd = np.cross(zd, x) + np.cross(z, xd)
    C = np.stack([x, y, z], axis=-1)
    w = np.column_stack([_dot(yd, z), _dot(zd, x), _dot(xd, y)])
    return C, w, sp_, xa, rpn, zrpd


class _Earth:
    """Gravity/up helpers on top of :mod:`imugen.earth` for one origin frame."""

    def __init__(self, frame: ea.OriginFrame):
        self.frame = frame
        self.flat = frame.model == "flat"
        self.Omega = ea.earth_rate_n(frame)

    def gravity(self, p):
        return ea.gravity_n(p, self.frame)

    def gravitation(self, p):
        return ea.gravitation_n(p, self.frame)

    def up_and_rate(self, p, v):
        """Local geodetic up at p in n, and its time derivative for velocity v (m,3)."""
        if self.flat:
            up = np.zeros_like(p)
            up[:, 2] = 1.0
            return up, np.zeros_like(p)
        lat, lon, h = self.frame.geodetic_from_n(p)
        C_ln = ea.C_en_from_geodetic(lat, lon) @ self.frame.C_en.T
        v_l = np.einsum("mij,mj->mi", C_ln, v)
        s2 = np.sin(lat) ** 2
        den = np.sqrt(1.0 - ea.E2_WGS84 * s2)
        RN = ea.A_WGS84 / den
        RM = ea.A_WGS84 * (1.0 - ea.E2_WGS84) / den**3
        ud_l = np.column_stack([v_l[:, 0] / (RN + h), v_l[:, 1] / (RM + h), np.zeros(len(p))])
        return C_ln[:, 2, :].copy(), np.einsum("mji,mj->mi", C_ln, ud_l)

    def gravity_rate(self, p, v):
        """d/dt g_n(p(t)) = (grad g) v by a central difference along v (10 m each side)."""
        if self.flat:
            return np.zeros_like(p)
        spd = np.linalg.norm(v, axis=1, keepdims=True)
        e = np.divide(v, spd, out=np.zeros_like(v), where=spd > 0)
        hstep = 10.0
        return (self.gravity(p + hstep * e) - self.gravity(p - hstep * e)) * (spd / (2 * hstep))


def _level_attitude(up):
    """C_nb with body z = ``up`` and body x toward n's East projected on the level; (3,) -> (3, 3)."""
    x = np.array([1.0, 0.0, 0.0]) - up * up[0]
    if np.linalg.norm(x) < 1e-6:
        x = np.array([0.0, 1.0, 0.0]) - up * up[1]
    x = x / np.linalg.norm(x)
    return np.stack([x, np.cross(up, x), up], axis=-1)


# ------------------------------------------------------------------------------------------
# the truth table
# ------------------------------------------------------------------------------------------
@dataclass
class TruthOptions:
    """Options of :func:`build_truth` beyond rate, Earth model and vehicle (None: defaults)."""

    grade: str | list[str] | None = None
    fit_tol_m: float | None = None
    stops: bool = True
    corner_m: float | None = None
    cruise_mps: float | None = None
    accel_mps2: float | None = None
    lat_accel_mps2: float | None = None
    jerk_mps3: float | None = None
    hold_speed_mps: tuple | None = None
    auto_fraction: float = 0.1
    extra: dict = field(default_factory=dict)


def build_motion(enu: pd.DataFrame, meta: dict, vp: VehicleParams, opts: TruthOptions):
    """Fit the route: returns (motion, fit report, timing report)."""
    for c in col.ENU:
        if c not in enu.columns:
            raise InputError(None, f"ENU table lacks column {c!r}")
    y = enu[list(col.ENU)].to_numpy(dtype=float)
    if not np.all(np.isfinite(y)):
        raise InputError(None, "ENU table holds non-finite coordinates")
    timed = bool(meta.get("timed", col.TIME in enu.columns)) and col.TIME in enu.columns
    if timed:
        motion, fit = fit_timed(enu[col.TIME].to_numpy(float), y, vp, opts.fit_tol_m, opts.stops)
        timing = {"timed": True, "source": "input clock"}
    else:
        G, L, fit = fit_path(y, vp, opts.corner_m)
        prof = {
            "cruise_mps": opts.cruise_mps or vp.cruise_mps,
            "accel_mps2": opts.accel_mps2 or vp.accel_mps2,
            "lat_accel_mps2": opts.lat_accel_mps2 or vp.lat_accel_mps2,
            "jerk_mps3": opts.jerk_mps3 or vp.jerk_mps3,
        }
        s_pp, rep = speed_profile(G, L, **prof)
        motion = PathMotion(G, s_pp, L)
        timing = {"timed": False, "source": "speed profile", **rep}
    return motion, fit, timing


def build_truth(
    enu: pd.DataFrame,
    meta: dict,
    *,
    rate_hz: float = 100.0,
    earth: str = "flat",
    vehicle: str = "car",
    grade: str | list[str] | None = None,
    chunk: int = CHUNK,
    verbose: bool = True,
    **options,
) -> tuple[pd.DataFrame, dict]:
    """ENU route -> truth table at the IMU rate (columns :data:`imugen.columns.TRUTH_COLUMNS`).

    Parameters
    ----------
    enu : DataFrame
        Ingestion's table: ``e_m, n_m, u_m`` and ``time_s`` for timed routes.
    meta : dict
        Ingestion's metadata: ``origin`` {lat_deg, lon_deg, alt_m}, ``timed``.
    rate_hz : float
        IMU rate; samples at ``t0 + k / rate_hz`` over the route.
    earth : {"flat", "wgs84", "auto"}
        Earth model (``auto``: budget printed to stderr and stored in the metadata).
    vehicle : {"car", "pedestrian", "aircraft"}
    grade : str or list of str, optional
        Sensor grade(s) for the ``auto`` budget (default ``consumer``); with several, any
        grade whose budget needs ``wgs84`` makes the truth ``wgs84``.
    **options
        Fields of :class:`TruthOptions` (``fit_tol_m``, ``stops``, ``corner_m``,
        ``cruise_mps``, ``accel_mps2``, ``lat_accel_mps2``, ``jerk_mps3``, ``hold_speed_mps``).

    Returns
    -------
    (DataFrame, dict)
        Truth table (float64) and its metadata.
    """
    if vehicle not in VEHICLES:
        raise InputError("--vehicle", f"unknown vehicle {vehicle!r}; one of {sorted(VEHICLES)}")
    if earth not in ("flat", "wgs84", "auto"):
        raise InputError("--earth", f"unknown Earth model {earth!r}; flat, wgs84 or auto")
    if not (rate_hz > 0 and math.isfinite(rate_hz)):
        raise InputError("--rate-hz", f"IMU rate must be a positive number, got {rate_hz}")
    unknown = set(options) - set(TruthOptions.__dataclass_fields__)
    if unknown:
        raise TypeError(f"unknown options {sorted(unknown)}")
    opts = TruthOptions(grade=grade, **options)
    vp = VEHICLES[vehicle]
    if opts.hold_speed_mps is not None:
        vp = replace(vp, hold_speed_mps=tuple(opts.hold_speed_mps))
    try:
        origin = meta["origin"]
        lat0, lon0, h0 = (float(origin[k]) for k in ("lat_deg", "lon_deg", "alt_m"))
    except (KeyError, TypeError, ValueError):
        raise InputError(None, "ENU metadata lacks the origin (lat_deg, lon_deg, alt_m)") from None

    motion, fit, timing = build_motion(enu, meta, vp, opts)
    dt = 1.0 / rate_hz
    duration = motion.t1 - motion.t0
    K = math.floor(duration * rate_hz + 1e-9) + 1
    if K < 2:
        raise InputError(None, f"route lasts {duration:.3g} s: shorter than one IMU interval")
    times = motion.t0 + np.arange(K) * dt

    budget = None
    model = earth
    if earth == "auto":
        pts = motion.position(np.linspace(motion.t0, motion.t1, min(K, 20001)))
        bt = np.linspace(motion.t0, motion.t1, len(pts))
        from imugen.grades import budget_figures

        names = [opts.grade] if isinstance(opts.grade, str) else list(opts.grade or ["consumer"])
        budgets = [
            ea.choose_earth_model(
                bt, pts, math.radians(lat0), budget_figures(g), fraction=opts.auto_fraction
            )
            for g in names
        ]
        # the most demanding grade decides: any grade that needs wgs84 gets it for all
        budget = next(
            (b for b in budgets if b.model == "wgs84"),
            min(budgets, key=lambda b: b.grade_effect_m),
        )
        model = budget.model
        if verbose:
            for line in budget.lines:
                print(line, file=sys.stderr)
    frame = ea.OriginFrame.from_deg(lat0, lon0, h0, model)
    E = _Earth(frame)

    out = np.zeros((K, len(col.TRUTH_COLUMNS)))
    ci = {c: i for i, c in enumerate(col.TRUTH_COLUMNS)}
    iP = [ci[c] for c in col.POS]
    iV = [ci[c] for c in col.VEL]
    iQ = [ci[c] for c in col.QUAT]
    iG = [ci[c] for c in col.GYRO]
    iA = [ci[c] for c in col.ACCEL]
    iE = [ci[c] for c in col.EULER]
    iDT = [ci[c] for c in col.DTHETA]
    iDV = [ci[c] for c in col.DV]
    out[:, ci[col.TIME]] = times
    sigma = np.empty(K)
    sigma_d = np.empty(K)
    phi_max = 0.0
    # pass 1: kinematics, target attitude, weights; f_b needs C_nb so store a_n - g temporarily
    fn_store = np.empty((K, 3))
    acc_ss, acc_max = 0.0, 0.0
    for k0 in range(0, K, chunk):
        k1 = min(K, k0 + chunk)
        tt = times[k0:k1]
        p, v, a, j = motion.eval(tt)
        an = np.linalg.norm(a, axis=1)
        acc_ss += float(np.sum(an * an))
        acc_max = max(acc_max, float(an.max()))
        g = E.gravity(p)
        f_n = a + 2.0 * np.cross(E.Omega, v) - g
        if vp.attitude == "level":
            r, rd = E.up_and_rate(p, v)
        else:
            r = f_n
            rd = j + 2.0 * np.cross(E.Omega, a) - E.gravity_rate(p, v)
        C, w, spd, spd_d, rpn, rpn_d = _target_frame(v, a, r, rd)
        s1, ds1 = _smoothstep(spd, *vp.hold_speed_mps)
        s2, ds2 = _smoothstep(rpn, *vp.hold_perp)
        sigma[k0:k1] = s1 * s2
        sigma_d[k0:k1] = ds1 * spd_d * s2 + s1 * ds2 * rpn_d
        out[k0:k1, iP[0] : iP[2] + 1] = p
        out[k0:k1, iV[0] : iV[2] + 1] = v
        out[k0:k1, iQ[0] : iQ[3] + 1] = rot.dcm_to_quat(C)
        out[k0:k1, iG[0] : iG[2] + 1] = w
        fn_store[k0:k1] = f_n

    # attitude hold windows: maximal runs of samples with sigma < 1
    below = sigma < 1.0
    edges = np.flatnonzero(np.diff(np.r_[0, below.astype(np.int8), 0]))
    can_flip = vp.attitude == "coordinated"
    sQ = slice(iQ[0], iQ[3] + 1)
    sG = slice(iG[0], iG[2] + 1)
    n_hold = 0
    flip = False  # aircraft: body z along -f_perp in the current segment (pushed over)
    seg_start = 0
    for i0, i1 in zip(edges[::2], edges[1::2], strict=True):  # run = [i0, i1)
        n_hold += 1
        if flip:
            _flip_roll(out, slice(seg_start, i0), sQ, sG)
        if i0 > 0:
            q_h = out[i0 - 1, sQ].copy()
        elif i1 < K:
            q_h = out[i1, sQ].copy()
        else:  # never a defined attitude: level, facing East of the local level
            up, _ = E.up_and_rate(out[:1, iP[0] : iP[2] + 1], np.zeros((1, 3)))
            q_h = rot.dcm_to_quat(_level_attitude(up[0]))
        sl = slice(i0, i1)
        sg = sigma[sl]
        q_rel = rot.quat_mul(rot.quat_conj(q_h)[None, :], out[sl, sQ])
        if can_flip:  # per sample, the roll sign closest to the held attitude
            f = np.abs(q_rel[:, 1]) > np.abs(q_rel[:, 0])
            _flip_roll(out, np.flatnonzero(f) + i0, sQ, sG)
            q_rel[f] = rot.quat_mul(q_rel[f], _QX)
        w_v = out[sl, sG]
        phi = rot.log_quat(q_rel)
        phi[sg <= 0] = 0.0
        if np.any(sg > 0):
            phi_max = max(phi_max, float(np.linalg.norm(phi[sg > 0], axis=1).max()))
        psi = sg[:, None] * phi
        q = rot.quat_mul(q_h, rot.exp_quat(psi))
        w = sigma_d[sl, None] * phi + sg[:, None] * np.einsum(
            "mij,mj->mi", rot.right_jacobian(psi) @ rot.right_jacobian_inv(phi), w_v
        )
        w[sg <= 0] = 0.0
        out[sl, sQ] = q
        out[sl, sG] = w
        if can_flip and i1 < K:
            qe = rot.quat_mul(rot.quat_conj(q_h), out[i1, sQ])
            flip = bool(abs(qe[1]) > abs(qe[0]))
        seg_start = i1
    if flip:
        _flip_roll(out, slice(seg_start, K), sQ, sG)

    # pass 2: continuity of q, rates, specific force, increments, Euler angles
    q_prev = None
    xg, wg = np.polynomial.legendre.leggauss(N_GAUSS)
    tau = 0.5 * dt * (xg + 1.0)
    wq = 0.5 * dt * wg
    A_nodes = rot.exp_dcm(E.Omega[None, :] * tau[:, None])  # (N_GAUSS, 3, 3)
    A_dt_minus_I = _expm1_rot(E.Omega * dt)
    for k0 in range(0, K, chunk):
        k1 = min(K, k0 + chunk)
        q = rot.quat_continuous(out[k0:k1, iQ[0] : iQ[3] + 1], q_prev)
        q = rot.quat_normalize(q)
        out[k0:k1, iQ[0] : iQ[3] + 1] = q
        q_prev = q[-1].copy()
        C = rot.quat_to_dcm(q)
        CT = np.swapaxes(C, 1, 2)
        out[k0:k1, iG[0] : iG[2] + 1] += CT @ E.Omega
        out[k0:k1, iA[0] : iA[2] + 1] = np.einsum("mij,mj->mi", CT, fn_store[k0:k1])
        p = out[k0:k1, iP[0] : iP[2] + 1]
        C_ln = frame.C_ln(p)
        out[k0:k1, iE[0] : iE[2] + 1] = rot.dcm_to_euler(C_ln @ C)
    del fn_store
    # increments of intervals [k, k+1] stored on row k+1
    for k0 in range(0, K - 1, chunk):
        k1 = min(K - 1, k0 + chunk)
        qa = out[k0:k1, iQ[0] : iQ[3] + 1]
        qb = out[k0 + 1 : k1 + 1, iQ[0] : iQ[3] + 1]
        out[k0 + 1 : k1 + 1, iDT[0] : iDT[2] + 1] = rot.relative_rotation_vector(
            qa, qb, E.Omega, dt
        )
        va = out[k0:k1, iV[0] : iV[2] + 1]
        vb = out[k0 + 1 : k1 + 1, iV[0] : iV[2] + 1]
        pa_ = out[k0:k1, iP[0] : iP[2] + 1]
        pb = out[k0 + 1 : k1 + 1, iP[0] : iP[2] + 1]
        Ca = rot.quat_to_dcm(qa)
        if E.flat:
            dV = (vb - va) - dt * E.gravity(pa_[:1])[0]
        else:
            wb = vb + np.cross(E.Omega, frame.r0_n + pb)
            dV = (wb @ A_dt_minus_I.T) + (vb - va) + np.cross(E.Omega, pb - pa_)
            ta = times[k0:k1]
            for jn in range(N_GAUSS):
                Gn = E.gravitation(motion.position(ta + tau[jn]))
                dV -= wq[jn] * (Gn @ A_nodes[jn].T)
        out[k0 + 1 : k1 + 1, iDV[0] : iDV[2] + 1] = np.einsum("mji,mj->mi", Ca, dV)
    out[:, iE[0]] = np.unwrap(out[:, iE[0]])
    out[:, iE[2]] = np.unwrap(out[:, iE[2]])
    if not np.all(np.isfinite(out)):
        raise InputError(None, "truth generation produced non-finite values (report this route)")

    df = pd.DataFrame(out, columns=list(col.TRUTH_COLUMNS), copy=False)
    vmax = float(np.linalg.norm(out[:, iV[0] : iV[2] + 1], axis=1).max())
    tmeta = {
        "stage": "truth",
        "imugen_version": __version__,
        "source": meta.get("source"),
        "origin": {"lat_deg": lat0, "lon_deg": lon0, "alt_m": h0},
        "earth": model,
        "earth_requested": earth,
        "earth_budget": None
        if budget is None
        else {
            "grade": budget.grade,
            "grades_considered": [opts.grade] if isinstance(opts.grade, str) else opts.grade,
            "fraction": budget.fraction,
            "grade_effect_m": budget.grade_effect_m,
            "terms_m": budget.terms_m,
            "lines": budget.lines,
        },
        "rate_hz": float(rate_hz),
        "samples": K,
        "duration_s": float(times[-1] - times[0]),
        "vehicle": vehicle,
        "vehicle_params": asdict(vp),
        "fit": fit,
        "timing": timing,
        "motion": {
            "accel_rms_mps2": math.sqrt(acc_ss / K),
            "accel_max_mps2": acc_max,
            "speed_max_mps": vmax,
            "attitude_hold_windows": n_hold,
            "max_blend_angle_rad": phi_max,
        },
        "conventions": "n = ENU of the origin, b = FLU; C_nb = Rz(yaw) Ry(-pitch) Rx(roll) "
        "relative to the local level at the vehicle; quaternion scalar first; increments on the "
        "row ending their interval (row 0 zeros)",
        "units": {c: col.UNITS[c] for c in col.TRUTH_COLUMNS},
    }
    return df, tmeta


_QX = np.array([0.0, 1.0, 0.0, 0.0])  # rotation by pi about body x


def _flip_roll(out, rows, sQ, sG):
    """Turn the attitude of ``rows`` by pi about body x (z -> -z): q * (0,1,0,0), w -> (wx,-wy,-wz)."""
    out[rows, sQ] = rot.quat_mul(out[rows, sQ], _QX)
    g = out[rows, sG]
    g[..., 1:] *= -1.0
    out[rows, sG] = g


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


# ------------------------------------------------------------------------------------------
# I/O
# ------------------------------------------------------------------------------------------
def read_enu(path) -> tuple[pd.DataFrame, dict]:
    """Read an ENU Parquet written by ``imugen ingest`` (table and metadata)."""
    return tenu.read(path)


def run(
    enu_path, out_path, *, rate_hz: float = 100.0, earth: str = "flat", vehicle: str = "car", **kw
) -> dict:
    """Read the ENU Parquet, build the truth, write it atomically; returns the metadata."""
    enu, meta = read_enu(enu_path)
    try:
        df, tmeta = build_truth(enu, meta, rate_hz=rate_hz, earth=earth, vehicle=vehicle, **kw)
    except InputError as exc:
        if exc.source is None:
            raise InputError(enu_path, exc.message) from None
        raise
    tmeta["source"] = str(enu_path)
    tmeta["route_source"] = meta.get("source")
    ttable.write(df, tmeta, out_path)
    return tmeta
