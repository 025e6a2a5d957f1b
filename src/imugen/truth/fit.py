"""Fitting timed routes and polylines: robust noise estimate, penalized quintic smoothing
spline, stop detection, and the timed motion ``p(t)``."""

from __future__ import annotations

import math

import numpy as np
import scipy.sparse as sp
from scipy.interpolate import BSpline, make_interp_spline
from scipy.ndimage import (
    binary_dilation,
    maximum_filter1d,
    minimum_filter1d,
    uniform_filter1d,
)
from scipy.optimize import brentq
from scipy.sparse.linalg import splu

from imugen.core.errors import InputError
from imugen.truth.vehicles import VehicleParams

K_SPLINE = 5  # quintic
# corner rounding: lambda = (corner_m / spacing)^6 * _CORNER_CAL makes a right-angle corner an
# arc of radius ~ corner_m (tests check)
_CORNER_CAL = 1.0


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


class PenalizedSpline:
    """Quintic B-spline with knots at the data sites; minimizes residual^2 + lam*int(f''')^2.

    ``ties``: list of (i0, i1) coefficient ranges forced equal (constant stretches).
    ``weights``: per-site weights of the squared residuals (default 1).
    ``stiffness``: per-site factors of the penalty on the knot interval that starts at the
    site (default 1): a locally stiffer curve (bandwidth ~ stiffness^(1/6) there).
    """

    def __init__(self, x, ties=(), weights=None, stiffness=None):
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
        self.sw = None if weights is None else np.sqrt(np.asarray(weights, float))
        if self.sw is not None:
            B = (sp.diags(self.sw) @ B).tocsc()
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
        self.stiffness = None if stiffness is None else np.asarray(stiffness, float)
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
        if self.stiffness is not None:
            site = np.clip(np.searchsorted(self.u, xq, side="right") - 1, 0, len(self.u) - 1)
            wq = wq * self.stiffness[site]
        Bq = BSpline.design_matrix(xq, tt, kd)
        G = Bq.T @ sp.diags(wq) @ Bq
        return D.T @ G @ D

    def _w(self, y):
        return y if self.sw is None else self.sw * y

    def solve(self, lam, y):
        lu = splu((self.BtB + lam * self.P).tocsc())
        return lu.solve(self.B.T @ self._w(y))

    def rms(self, lam, y):
        """RMS of the (weighted) residuals."""
        c = self.solve(lam, y)
        return float(np.sqrt(np.mean((self.B @ c - self._w(y)) ** 2)))

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
# timed routes
# ------------------------------------------------------------------------------------------
class TimedMotion:
    """Position spline p(t) (vector-valued quintic BSpline) and its derivatives; with
    ``vertical``, a scalar spline replacing the third coordinate (a road profile,
    :func:`imugen.truth.road.motion_on_road`)."""

    kind = "timed"

    def __init__(self, spline: BSpline, t0: float, t1: float, vertical: BSpline | None = None):
        self.spline = spline
        self.vertical = vertical
        self.d = [spline] + [spline.derivative(nu) for nu in (1, 2, 3)]
        self.dv = (
            None
            if vertical is None
            else [vertical.derivative(nu) if nu else vertical for nu in range(4)]
        )
        self.t0, self.t1 = t0, t1

    def _at(self, nu, t):
        x = self.d[nu](t)
        if self.dv is not None:
            x[..., 2] = self.dv[nu](t)
        return x

    def position(self, t):
        return self._at(0, t)

    def velocity(self, t):
        return self._at(1, t)

    def eval(self, t):
        """(p, v, a, j), each shape (m, 3), at times ``t`` (m,)."""
        return tuple(self._at(nu, t) for nu in range(4))


def _find_stops(t, y, noise_m, vp: VehicleParams, exact=None):
    """Index ranges (i0, i1) of input points that are stops, from the horizontal motion.

    ``y`` holds the coordinates that decide (N, d): horizontal for ground vehicles (GNSS
    heights are noisier and step at stops), 3-D for aircraft; ``noise_m`` is their noise. A point is still when the points within ``stop_min_s / 2`` of it span a box of diagonal
    at most ``2 r`` with ``r = max(stop_radius_m, 3 * noise_m)``; runs of still points (and
    their windows), trimmed to their longest stretch within ``r`` of their median, lasting
    at least ``stop_min_s`` whose points all lie within ``r`` of the run's median and whose net displacement (median of the first third to median of the last
    third) is below ``r / 2`` and ``stop_speed_mps`` times the duration are stops; so is
    the interval between two consecutive fixes at least ``stop_min_s`` apart that moved less
    than that (sparse fixes). Overlapping stops are merged.

    A stop does not reach into the braking or pulling away around it (:func:`_off_ramps`):
    its end fixes lie within :data:`STOP_EDGE_NOISE` noise estimates of its position, and
    ``exact`` (bool, shape (N,), optional) marks points placed exactly (the virtual fixes of a
    bridged gap, :func:`imugen.ingest.segments.bridge_gaps`), which end a stop where they
    start to move.
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
        for _ in range(3):  # trim the run to its longest stretch within r of its median
            if i1 <= i0:
                break
            pts = y[i0 : i1 + 1]
            near = np.linalg.norm(pts - np.median(pts, axis=0), axis=1) <= r
            if near.all() or not near.any():
                break
            e = np.flatnonzero(np.diff(np.r_[0, near.astype(np.int8), 0]))
            j = int(np.argmax(e[1::2] - e[::2]))
            i0, i1 = i0 + int(e[2 * j]), i0 + int(e[2 * j + 1]) - 1
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
    # sparse fixes: two consecutive fixes at least stop_min_s apart that moved less than r
    # (and than stop_speed_mps on average) bracket a stop the window above cannot see
    step = np.linalg.norm(np.diff(y, axis=0), axis=1)
    dt = np.diff(t)
    pairs = np.flatnonzero(
        (dt >= vp.stop_min_s) & (step <= np.minimum(0.5 * r, vp.stop_speed_mps * dt))
    )
    stops += [(int(i), int(i) + 1) for i in pairs]
    merged = []
    for i0, i1 in sorted(stops):
        if merged and i0 <= merged[-1][1]:
            merged[-1] = (merged[-1][0], max(merged[-1][1], i1))
        else:
            merged.append((i0, i1))
    exact = np.zeros(n, bool) if exact is None else np.asarray(exact, bool)
    edge = max(STOP_EDGE_NOISE * noise_m, 0.5 * vp.stop_radius_m)
    merged = [
        (a, b)
        for a, b in (_off_ramps(i0, i1, y, step, exact, edge) for i0, i1 in merged)
        if b > a and t[b] - t[a] >= vp.stop_min_s
    ]
    return merged


#: Largest step (m) between two exactly placed points that stand still (a bridged stop's held
#: fixes are one position; its ramps' fixes move by far more).
STILL_STEP_M = 1e-3

#: A stop's first and last fixes lie within this many noise estimates (the RMS radius of a
#: still fix, ``noise_m``) of the stop's position (the median of its other fixes): one farther
#: is still braking or already pulling away (a still fix of 2-D Gaussian noise lies beyond with
#: probability ``exp(-1)``, and then only shortens the stop by that fix, which the fit still
#: follows within its noise); at least half ``stop_radius_m`` (noiseless fixes that creep).
STOP_EDGE_NOISE = 1.0


def _off_ramps(i0, i1, y, step, exact, edge_m):
    """The stop ``(i0, i1)`` without the fixes at its ends inside the route that still move:
    an exactly placed point (a bridged gap's braking and accelerating ramps) from which the
    next one moves, a measured fix farther than ``edge_m`` from the stop's other fixes' median
    (an abrupt stop whose last moving fix the window test took in: a spline held still from
    there brakes earlier and harder than the vehicle, and makes up the distance by speeding up
    before)."""

    def moving(i, j, inner):  # fix i at an end of the stop, j its neighbour inside
        if exact[j]:
            return step[min(i, j)] > STILL_STEP_M
        return not exact[i] and np.linalg.norm(y[i] - np.median(y[inner], axis=0)) > edge_m

    while i0 > 0 and i1 - i0 > 1 and moving(i0, i0 + 1, slice(i0 + 1, i1 + 1)):
        i0 += 1
    while i1 < len(y) - 1 and i1 - i0 > 1 and moving(i1, i1 - 1, slice(i0, i1)):
        i1 -= 1
    return i0, i1


def fit_timed(t, y, vp: VehicleParams, fit_tol_m=None, stops=True, virtual=None):
    """Fit the position spline of a timed route; returns (TimedMotion, report dict).

    ``virtual`` (bool, shape (n,) or (n, 3) per axis, or None): coordinates that ingestion
    placed (fixes along a bridged gap, heights held while an aircraft stands still): exact,
    noiseless; the noise of the horizontal and of the vertical is estimated from the other
    fixes and the RMS residual target scaled by sqrt(real / all), the placed coordinates'
    residuals being near 0."""
    t = np.asarray(t, float)
    y = np.asarray(y, float)
    n = len(t)
    if n < 3:
        raise InputError(None, f"a timed route needs at least 3 points to fit, got {n}")
    dt = np.diff(t)
    if not np.all(np.isfinite(t)) or np.any(dt <= 0):
        raise InputError(None, "route times must be finite and strictly increasing")
    sig, share = noise_estimate(t, y), np.ones(3)
    real = None
    if virtual is not None:
        virtual = np.asarray(virtual, bool)
        real = ~(virtual if virtual.ndim == 2 else np.repeat(virtual[:, None], 3, axis=1))
        for axes in ((0, 1), (2,)):
            r = real[:, axes[0]]
            if r.sum() >= 8 and not r.all():
                sig[list(axes)] = noise_estimate(t[r], y[r])[list(axes)]
                share[list(axes)] = math.sqrt(r.sum() / n)
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
    target = np.maximum(target, vp.fit_floor_m / math.sqrt(3)) * share
    ps = PenalizedSpline(t)
    loglam = np.array([ps.lam_for_rms(y[:, i], target[i]) for i in range(3)])
    lam = 10.0**loglam
    coef = np.column_stack([ps.solve(lam[i], y[:, i]) for i in range(3)])
    spline = ps.bspline(coef)
    stop_list = []
    if stops:
        # ground vehicles stop horizontally (heights step at stops); aircraft also climb
        # vertically, so their stops are 3-D
        d = 2 if vp.attitude == "ground" else 3
        exact = None if real is None else ~real[:, :d].any(axis=1)
        stop_list = _find_stops(t, y[:, :d], float(np.linalg.norm(sig[:d])), vp, exact)
    held = HeldSites(t, stop_list)
    abrupt, found = None, list(stop_list)
    for _ in range(ABRUPT_SHORTEN + 1) if stop_list else ():
        spline = held.fit(y, lam)
        spline, abrupt = _abrupt_stops(held, spline, y, lam, vp, float(np.linalg.norm(sig[:d])), d)
        shorter = _shorten(stop_list, abrupt, t, vp)
        if shorter == stop_list:
            break
        stop_list = shorter
        held = HeldSites(t, stop_list)
    moved = [
        [float(t[a]), float(t[b])]
        for (a, b), (c, e) in zip(found, stop_list, strict=True)
        for a, b in ((a, c), (b, e))
        if a != b
    ]
    if moved:
        abrupt = dict(abrupt or {}, edges_moved_s=moved)
    spline, limited = _within_limits(spline, t, y, vp, held.spline, lam, float(np.linalg.norm(sig)))
    motion = TimedMotion(spline, float(t[0]), float(t[-1]))
    dist = np.linalg.norm(spline(t) - y, axis=1)
    report = {
        "method": "quintic penalized smoothing spline (knots at input times, penalty on jerk)",
        "criterion": criterion,
        "noise_estimate_m": sig.tolist(),
        "virtual_fixes": 0 if real is None else int((~real).any(axis=1).sum()),
        "target_rms_m": target.tolist(),
        "lambda_normalized": lam.tolist(),
        "time_scale_s": ps.scale,
        "rms_distance_m": float(np.sqrt(np.mean(dist**2))),
        "max_distance_m": float(dist.max()),
        "stops": [[float(t[i0]), float(t[i1])] for i0, i1 in stop_list],
        "abrupt_stops": abrupt,
        "limited": limited,
    }
    return motion, report


STOP_JOIN_MULTIPLICITY = 3
"""Multiplicity of the knot where a timed spline joins a stop inside the route
(:class:`HeldSites`): a quintic is C^(5 - m) across a knot of multiplicity m, so the spline
joins the stop with zero velocity and acceleration (C2), its jerk free."""


class HeldSites:
    """Sites of a timed route's penalized spline held still over ``stops``.

    ``t`` (n,): input times; ``stops``: index ranges (i0, i1) of ``t`` where the spline is
    constant. Each stop edge inside the route is a knot of multiplicity
    :data:`STOP_JOIN_MULTIPLICITY` (zero-weight copies of the site): the spline joins the stop
    with zero velocity and acceleration, as a vehicle braking to rest does. A simple knot would
    join it C4, leaving the quintic one free coefficient on the interval before the stop
    (``p_stop - c (t_stop - t)^5``): at sparse fixes of an abrupt stop (a 1 Hz logger braking
    within its last second) the spline then brakes over several intervals and makes up the
    distance by speeding up before (5.7 -> 8.8 -> 0 m/s); with the triple knot the last
    interval holds the cubic braking ``a s^3 + b s^4 + c s^5`` (s the time to the stop), whose
    speed falls monotonically from the fixes' speed to rest.

    Attributes
    ----------
    x : ndarray, shape (m,)
        The spline's sites (input times with the copies).
    take : ndarray of int, shape (m,)
        Input index of each site.
    real : ndarray of bool, shape (m,)
        False at the copies (weight 0).
    ties : list of (int, int)
        Coefficient ranges of the sites' spline held equal (:class:`PenalizedSpline`).
    """

    def __init__(self, t, stops, multiplicity=None):
        multiplicity = STOP_JOIN_MULTIPLICITY if multiplicity is None else multiplicity
        t = np.asarray(t, float)
        n = len(t)
        self.n, self.t, self.stops = n, t, list(stops)
        self.relax = np.ones(max(n - 1, 0))  # factors of the penalty on the input intervals
        edges = sorted({i for i0, i1 in stops for i in (i0, i1) if 0 < i < n - 1})
        extra = np.zeros(n, int)
        extra[edges] = multiplicity - 1
        self.take = np.repeat(np.arange(n), 1 + extra)
        self.x = t[self.take]
        first = np.searchsorted(self.take, np.arange(n))  # first site of each input point
        last = first + extra  # and its last copy
        self.real = np.r_[True, np.diff(self.take) > 0]
        # coefficients active on [x_a, x_b] (knots at the sites) are a .. b + k - 1: from the
        # last copy of the stop's first site to the first copy of its last
        self.ties = [(int(last[i0]), int(first[i1]) + K_SPLINE - 1) for i0, i1 in stops]

    def spline(self, weights=None):
        """The :class:`PenalizedSpline` of the sites, with input ``weights`` (n,) (default 1);
        its ``solve`` takes values at the input times (n,)."""
        w = np.ones(self.n) if weights is None else np.asarray(weights, float)
        stiff = None
        if np.any(self.relax != 1.0):
            stiff = np.r_[self.relax, 1.0][self.take]  # a site's interval: its input's
        ps = PenalizedSpline(self.x, self.ties, np.where(self.real, w[self.take], 0.0), stiff)
        if len(self.x) == self.n:
            return ps
        return _SitesSpline(ps, self.take)

    def fit(self, y, lam):
        """The fitted curve (BSpline) of ``y`` (n, d) with smoothing ``lam`` (d,)."""
        ps = self.spline()
        return ps.bspline(np.column_stack([ps.solve(lam[i], y[:, i]) for i in range(y.shape[1])]))


class _SitesSpline:
    """A :class:`PenalizedSpline` on :class:`HeldSites`' sites solved for values at the input
    times."""

    def __init__(self, ps, take):
        self.ps, self.take = ps, take

    def solve(self, lam, y):
        return self.ps.solve(lam, np.asarray(y, float)[self.take])

    def bspline(self, c):
        return self.ps.bspline(c)

    @property
    def scale(self):
        return self.ps.scale


ABRUPT_RESIDUAL_NOISE = 3.0
"""A fix next to a stop's edge farther than this many noise estimates (the RMS radius of a fix)
from the fit makes the stop abrupt (:func:`_abrupt_stops`): the smoothing rounds its braking
(or pulling away) over several seconds and the spline speeds up before to make up the
distance. This and the next two distances are at least half ``stop_radius_m`` (as the stop's
edge test): precise fixes (5 cm) of a car that stops while still decelerating (0.6 m/s^2)
miss the zero-acceleration join by a few tenths of a metre, a gentle stop, not a bounce; a
relaxed fit there only steps the jerk at the join (on a suspension, a kink in the pitch rate)."""

ABRUPT_FIT_NOISE = 1.5
"""... and its relaxing goes on until those fixes are within this many noise estimates."""

ABRUPT_LOOK = 5
"""Fixes outside a stop's edge whose distance from the fit is examined (the smoothing rounds
an abrupt stop over a few of its bandwidths)."""

ABRUPT_REACH = 2
"""Input intervals outside an abrupt stop's edge whose smoothing penalty is relaxed: before
its first braking fix (after its last pulling-away fix), the fixes in between lying within
:data:`ABRUPT_NEAR_NOISE` noise estimates of the stop's position (still fixes that the stop's
edge test left out, :data:`STOP_EDGE_NOISE`: a fit free to follow their noise would creep)."""

ABRUPT_NEAR_NOISE = 2.0
"""See :data:`ABRUPT_REACH`."""

ABRUPT_RELAX_STEP = 0.1
"""Factor of that penalty per round."""

ABRUPT_ITERATIONS = 8
"""Rounds of relaxing (the penalty down to ``ABRUPT_RELAX_STEP ** ABRUPT_ITERATIONS``)."""


ABRUPT_SHORTEN = 2
"""Fixes by which an abrupt stop's edge may move into the stop (:func:`_shorten`)."""


def _shorten(stops, abrupt, t, vp):
    """The stops (index ranges of ``t``), each edge that :func:`_abrupt_stops` found beyond the
    vehicle's limits (``abrupt["beyond"]``) moved one fix into its stop, as long as the stop
    lasts ``stop_min_s``: the stop's edge test (:data:`STOP_EDGE_NOISE`) took in a fix still
    braking or already pulling away, within the noise of the stop's position, and the curve,
    held still there, cannot catch up with the fixes beyond within the limits."""
    if not abrupt or not abrupt["beyond"]:
        return stops
    at = {b["t_s"] for b in abrupt["beyond"]}
    out = []
    for i0, i1 in stops:
        j0 = i0 + 1 if float(t[i0]) in at and i0 > 0 else i0
        j1 = i1 - 1 if float(t[i1]) in at and i1 < len(t) - 1 else i1
        out.append((j0, j1) if t[j1] - t[j0] >= vp.stop_min_s else (i0, i1))
    return out


def _abrupt_stops(held, spline, y, lam, vp, noise_m, d):
    """The fit of ``y`` (n, 3) held still over ``held``'s stops, its smoothing penalty relaxed
    at the abrupt ones, and a report (None when none is abrupt).

    A stop edge inside the route is abrupt when one of the :data:`ABRUPT_LOOK` fixes outside
    it lies farther than :data:`ABRUPT_RESIDUAL_NOISE` noise estimates ``noise_m`` from the fit
    (in the ``d`` coordinates that decide stops): a vehicle braking within the last interval
    of sparse fixes, which the smoothing rounds over several seconds (the spline then speeds
    up before the stop to make up the distance). The penalty on the :data:`ABRUPT_REACH`
    intervals outside the edge shrinks by :data:`ABRUPT_RELAX_STEP` per round (the fit brakes
    later and harder, as the fixes do) until those fixes are within :data:`ABRUPT_FIT_NOISE`
    noise estimates; a round that takes the curve there beyond the vehicle's acceleration or
    jerk limit is undone for that edge and ends its relaxing. Where the fixes then still lie
    beyond :data:`ABRUPT_RESIDUAL_NOISE` noise estimates, the fixes stop (or pull away) harder
    than the vehicle can from the stop's edge: the report lists the place (``beyond``: the
    edge's time, the limit, the value the relaxed curve asked for) and :func:`fit_timed` moves
    that edge a fix into the stop (:func:`_shorten`); the curve keeps to the limits."""
    t, n = held.t, held.n
    floor = 0.5 * vp.stop_radius_m  # as the stop's edge test (precise fixes)
    tol = max(ABRUPT_RESIDUAL_NOISE * noise_m, floor)
    goal = max(ABRUPT_FIT_NOISE * noise_m, floor)
    near = max(ABRUPT_NEAR_NOISE * noise_m, floor)
    # per edge: (first, last) fix of the relaxed intervals, (first, last) fix looked at, edge
    spans = []
    for i0, i1 in held.stops:
        mid = np.median(y[i0 : i1 + 1, :d], axis=0)

        def still(k, mid=mid):  # a fix outside the stop within the noise of its position
            return np.linalg.norm(y[k, :d] - mid) <= near

        if i0 > 0:
            k = i0
            while k > max(0, i0 - ABRUPT_LOOK) and still(k - 1):
                k -= 1
            spans.append((max(0, k - ABRUPT_REACH), k, max(0, i0 - ABRUPT_LOOK), i0, i0))
        if i1 < n - 1:
            k = i1
            while k < min(n - 1, i1 + ABRUPT_LOOK) and still(k + 1):
                k += 1
            spans.append((k, min(n - 1, k + ABRUPT_REACH), i1, min(n - 1, i1 + ABRUPT_LOOK), i1))
    # both ends of each interval (a quintic's jerk peaks at its knots, and a stop's join is C2)
    f = np.linspace(0.0, 1.0 - 1e-9, 9)

    def far(c, span, tol=goal):  # fixes looked at farther than tol from the curve
        a, b = span[2:4]
        return np.linalg.norm(c(t[a : b + 1])[:, :d] - y[a : b + 1, :d], axis=1).max() > tol

    def peaks(c, span):  # the curve's largest acceleration and jerk over the relaxed intervals
        a, b = span[:2]
        tq = (t[a:b, None] + f * np.diff(t[a : b + 1])[:, None]).ravel()
        return np.linalg.norm(c(tq, 2), axis=1).max(), np.linalg.norm(c(tq, 3), axis=1).max()

    live = [s for s in spans if far(spline, s, tol=tol)]
    if not live:
        return spline, None
    first, asked, rounds = list(live), {}, 0
    for rounds in range(1, ABRUPT_ITERATIONS + 1):  # noqa: B007 (reported below)
        before = held.relax.copy()
        for s in live:
            held.relax[s[0] : s[1]] = before[s[0] : s[1]] * ABRUPT_RELAX_STEP
        trial = held.fit(y, lam)
        over = []
        for s in live:
            acc, jerk = peaks(trial, s)
            if acc > vp.max_accel_mps2 or jerk > vp.max_jerk_mps3:
                over.append(s)
                asked[s] = (acc, jerk)
        if over:  # those edges keep their last round's penalty and stop relaxing
            for s in over:
                held.relax[s[0] : s[1]] = before[s[0] : s[1]]
            trial = held.fit(y, lam)
        spline = trial
        live = [s for s in live if s not in over and far(spline, s)]
        if not live:
            break
    if not np.any(held.relax < 1.0) and not asked:
        return spline, None
    beyond = []
    for s, (acc, jerk) in asked.items():
        if far(spline, s, tol=tol):
            edge = s[4]
            a_r, j_r = acc / vp.max_accel_mps2, jerk / vp.max_jerk_mps3
            beyond.append(
                {
                    "t_s": float(t[edge]),
                    "limit": "acceleration" if a_r >= j_r else "jerk",
                    "value": float(acc if a_r >= j_r else jerk),
                    "bound": float(vp.max_accel_mps2 if a_r >= j_r else vp.max_jerk_mps3),
                    "unit": "m/s^2" if a_r >= j_r else "m/s^3",
                }
            )
    return spline, {
        "method": "smoothing penalty relaxed outside the edges of stops whose braking or "
        "pulling away the fit rounded beyond the fixes' noise",
        "residual_tolerance_m": tol,
        "edges_s": [float(t[s[4]]) for s in first],
        "rounds": rounds,
        "least_relax": float(held.relax.min()),
        "beyond": beyond,
    }


LIMIT_ITERATIONS = 12
"""Rounds of local smoothing of a fit beyond its vehicle's limits (:func:`_within_limits`)."""

LIMIT_WEIGHT_STEP = 0.2
"""Factor of the weights of the points around a place beyond the limits, per round."""

LIMIT_RESIDUAL_NOISE = 4.0
"""Largest residual of a locally smoothed point, in noise estimates (3-D; at least
``fit_tol_max_m``): beyond it the input itself is the implausible motion (the gate refuses)."""


def _excess(spline, x, vp, ground, per=4):
    """Parameters (of ``x``'s range) where the curve exceeds the vehicle's limits:
    |acceleration| beyond ``max_accel_mps2`` (timed), and for ground vehicles a horizontal
    curvature beyond ``max_curvature_1pm`` while faster than twice ``stop_speed_mps``
    (``x`` the input times)."""
    f = np.linspace(0.0, 1.0, per, endpoint=False)
    xq = np.r_[(x[:-1, None] + f * np.diff(x)[:, None]).ravel(), x[-1]]
    d1, d2 = spline(xq, 1), spline(xq, 2)
    bad = np.zeros(len(xq), bool)
    vh2 = d1[:, 0] ** 2 + d1[:, 1] ** 2
    if ground:
        kappa = np.abs(d1[:, 0] * d2[:, 1] - d1[:, 1] * d2[:, 0]) / np.maximum(vh2, 1e-30) ** 1.5
        bad |= kappa > vp.max_curvature_1pm
    bad &= vh2 > (2.0 * vp.stop_speed_mps) ** 2
    bad |= np.linalg.norm(d2, axis=1) > vp.max_accel_mps2
    return xq[bad]


def _within_limits(spline, x, y, vp, make, lam, noise_m):
    """A fitted curve smoothed locally until it is within its vehicle's limits
    (:func:`_excess`): the weights of the input points around each place beyond them shrink
    by :data:`LIMIT_WEIGHT_STEP` per round (the smoothing there grows, the rest of the fit is
    unchanged); a round that leaves an input point farther from the curve than
    :data:`LIMIT_RESIDUAL_NOISE` noise estimates (at least ``fit_tol_max_m`` and than the fit
    already was) is undone and
    ends the smoothing: there the input itself is beyond the limits. ``make(weights)`` builds the
    :class:`PenalizedSpline`, ``lam`` its smoothing (per coordinate). Returns the curve and
    a report (None when nothing was smoothed)."""
    ground = vp.attitude == "ground"
    w = np.ones(len(x))
    # no fix farther than 4 noise estimates (at least fit_tol_max_m) or than the fit already was
    cap = max(
        LIMIT_RESIDUAL_NOISE * noise_m,
        vp.fit_tol_max_m,
        float(np.max(np.linalg.norm(spline(x) - y, axis=1))),
    )
    best, rounds = spline, 0
    for _ in range(LIMIT_ITERATIONS):
        xb = _excess(best, x, vp, ground)
        if not len(xb):
            break
        i = np.clip(np.searchsorted(x, xb), 1, len(x) - 1)
        near = np.zeros(len(x), bool)
        for d in (-2, -1, 0, 1):
            near[np.clip(i + d, 0, len(x) - 1)] = True
        res = np.linalg.norm(best(x) - y, axis=1)
        near &= (res < cap) & (w > 1e-6)
        if not near.any():
            break
        w_try = w.copy()
        w_try[near] *= LIMIT_WEIGHT_STEP
        ps = make(w_try)
        coef = np.column_stack([ps.solve(lam[j], y[:, j]) for j in range(y.shape[1])])
        trial = ps.bspline(coef)
        if np.linalg.norm(trial(x) - y, axis=1).max() > cap:
            break  # the input itself turns or brakes beyond the limit: keep the last round
        best, w, rounds = trial, w_try, rounds + 1
    if not rounds:
        return spline, None
    left = _excess(best, x, vp, ground)
    res = np.linalg.norm(best(x) - y, axis=1)
    smoothed = w < 1.0
    return best, {
        "method": "local smoothing where the fit exceeds the vehicle's curvature or "
        "acceleration limit (input weights reduced there)",
        "rounds": rounds,
        "points_smoothed": int(smoothed.sum()),
        "max_residual_smoothed_m": float(res[smoothed].max()),
        "residual_cap_m": cap,
        "places_left": len(left),
    }


# ------------------------------------------------------------------------------------------
# untimed routes: geometry
# ------------------------------------------------------------------------------------------
def fit_path(y, vp: VehicleParams, corner_m=None, vertices=False, max_curvature=None):
    """Smooth a polyline and re-parameterize by arc length.

    Returns (G BSpline of s, length L, report dict) and, with ``vertices``, the arc length
    [m] of the curve's point nearest each input point (N,): the smoothed point of its chord
    length (repeated points share it), monotonic along the path.

    ``max_curvature`` (callable of the polyline's chord length [m], optional): the largest
    horizontal curvature [1/m] along the path (an aircraft's turn at its bank limit and the
    speed it flies there, :func:`imugen.truth.flight.turn_curvature`); ground vehicles take
    their ``max_curvature_1pm``, and their bends tighter are built as fillets of clothoids and
    arcs (:func:`_construct_corners`, :mod:`imugen.truth.corners`; the report's ``corners``).
    Bends still tighter are widened (:func:`_bound_curvature`).
    """
    y = np.asarray(y, float)
    seg = np.linalg.norm(np.diff(y, axis=0), axis=1)
    keep = np.r_[True, seg > 1e-9]
    kept = np.cumsum(keep) - 1  # index of each input point among the kept ones
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
    ps = PenalizedSpline(u)
    # equivalent-kernel bandwidth of an order-3 smoothing spline ~ lam^(1/6) samples;
    # calibrated so that a right-angle corner becomes an arc of radius ~ ell (tests check)
    lam = (ell / ps.scale) ** 6 * _CORNER_CAL
    coef = np.column_stack([ps.solve(lam, dense[:, i]) for i in range(3)])
    g = ps.bspline(coef)
    bound, built, base, v_u = None, None, None, np.r_[0.0, np.cumsum(seg)]
    if max_curvature is None and vp.attitude == "ground":
        max_curvature = lambda x: np.full(len(x), vp.max_curvature_1pm)  # noqa: E731
        if (got := _construct_corners(g, y, u, dense, lam, vp.max_curvature_1pm, ell)) is not None:
            g, u, dense, base, v_u, built = got
    if max_curvature is not None:
        g, bound = _bound_curvature(g, u, dense, lam, max_curvature, base=base)
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
    d = distance_to_curve(G, L, y, step / 8.0)
    report = {
        "method": "quintic penalized smoothing spline of the densified polyline vs chord "
        "length, re-parameterized by arc length",
        "corner_m": ell,
        "densify_step_m": step,
        "rms_distance_m": float(np.sqrt(np.mean(d**2))),
        "max_distance_m": float(d.max()),
        "length_m": L,
    }
    if built is not None:
        report["corners"] = built
    if bound is not None:
        report["curvature_bound"] = bound
    if vertices:
        s_v = np.interp(v_u, uf, s)
        return G, L, report, s_v[kept]
    return G, L, report


CURVATURE_MARGIN = 0.85
"""Share of a ground vehicle's ``max_curvature_1pm`` that an untimed path's geometry may
reach (:func:`_bound_curvature`): the margin covers the re-parameterization by arc length and
the heading's sampling (:class:`imugen.truth.attitude.GroundAttitude`)."""

CURVATURE_ITERATIONS = 20
"""Rounds of local smoothing of an untimed ground path beyond its curvature bound."""

CURVATURE_STIFFNESS_STEP = 1.0
"""log10 of the factor of the smoothing penalty around a bend too tight, per round (its
bandwidth grows by ``10^(1/6)``, 1.47, per round there)."""

CURVATURE_RESIDUAL_RADII = 6.0
"""Farthest a widened bend strays from the input polyline, in least turning radii
(``1 / max_curvature_1pm``; at least the corner rounding's own distance): a bend that needs
more (two legs closer than the turning diameter) is left tight, and the gate refuses the
truth's slip there."""

CURVATURE_REACH = 1.0
"""Half-width of the stiffer stretch around a bend too tight, in bandwidths of the spline
there (``lam^(1/6)`` samples times ``stiffness^(1/6)``); its stiffness tapers over as much."""

CURVATURE_STIFFNESS_MAX = 9.0
"""Largest log10 of that factor (bandwidth x 32): beyond, the bend stays too tight (the
gate refuses the truth's slip)."""


def _horizontal_curvature(g, x):
    """Horizontal curvature [1/m] of the curve ``g`` at the parameters ``x``."""
    d1, d2 = g(x, 1), g(x, 2)
    vh2 = d1[:, 0] ** 2 + d1[:, 1] ** 2
    return np.abs(d1[:, 0] * d2[:, 1] - d1[:, 1] * d2[:, 0]) / np.maximum(vh2, 1e-30) ** 1.5


#: log10 of the smoothing penalty's factor on a constructed corner's samples
#: (:mod:`imugen.truth.corners`): the spline passes through them (bandwidth / 10).
CORNER_STIFFNESS = -6.0


def _tight_groups(g, u, uv, kmax_1pm, reach_m, to_old=None, per=4):
    """Vertex groups (i0, i1) of the polyline (its vertexes' chord lengths ``uv``) around
    the stretches where the curve ``g(u)`` turns tighter than :data:`CURVATURE_MARGIN` x
    ``kmax_1pm``: each stretch widened by ``reach_m`` either side (``to_old`` maps the
    curve's chord lengths to the polyline's)."""
    f = np.linspace(0.0, 1.0, per, endpoint=False)
    uq = np.r_[(u[:-1, None] + f * np.diff(u)[:, None]).ravel(), u[-1]]
    bad = _horizontal_curvature(g, uq) > CURVATURE_MARGIN * kmax_1pm
    if to_old is not None:
        uq = to_old(uq)
    n = len(uv)
    e = np.flatnonzero(np.diff(np.r_[0, bad.astype(np.int8), 0]))
    runs: list[list[float]] = []  # the bends too tight, widened by the reach, merged
    for a, b in zip(e[::2], e[1::2] - 1, strict=True):
        if runs and uq[a] - reach_m <= runs[-1][1]:
            runs[-1][1] = uq[b] + reach_m
        else:
            runs.append([uq[a] - reach_m, uq[b] + reach_m])
    groups: list[tuple[int, int]] = []
    for ua, ub in runs:
        idx = np.flatnonzero((uv >= ua) & (uv <= ub))
        idx = idx[(idx >= 1) & (idx <= n - 2)]
        if not len(idx):
            idx = np.array([int(np.clip(np.argmin(np.abs(uv - 0.5 * (ua + ub))), 1, n - 2))])
        groups.append((int(idx.min()), int(idx.max())))
    return groups


def _merge_groups(groups):
    """Vertex groups (i0, i1) sorted, those that overlap or touch merged."""
    out: list[tuple[int, int]] = []
    for i0, i1 in sorted(groups):
        if out and i0 <= out[-1][1] + 1:
            out[-1] = (out[-1][0], max(out[-1][1], i1))
        else:
            out.append((i0, i1))
    return out


def _construct_corners(g, y, u, dense, lam, kmax_1pm, reach_m):
    """The smoothed polyline ``g(u)`` of an untimed ground path with its bends tighter than
    :data:`CURVATURE_MARGIN` x ``kmax_1pm`` built explicitly (:mod:`imugen.truth.corners`):
    the polyline's vertexes within ``reach_m`` of each such bend are one group, replaced by a
    fillet or a hairpin of arcs and clothoids tangent to the legs either side, whose samples
    the spline then passes through (:data:`CORNER_STIFFNESS`); the rest of the path is fitted
    as before. A bend still too tight next to a built corner joins its group, and the
    corners are built again (:data:`CORNER_ROUNDS` at most). Returns None when no bend is too
    tight or none could be built, else (curve, new chord lengths u, new densified polyline,
    log10 stiffness per site, the vertexes' new chord lengths, report)."""
    from imugen.truth import corners as cn

    if len(y) < 3:
        return None
    uv = np.r_[0.0, np.cumsum(np.linalg.norm(np.diff(y[:, :2], axis=0), axis=1))]
    groups = _merge_groups(_tight_groups(g, u, uv, kmax_1pm, reach_m))
    if not groups:
        return None
    R = cn.fillet_radius_m(kmax_1pm)
    cap = CURVATURE_RESIDUAL_RADII / (CURVATURE_MARGIN * kmax_1pm)
    got = None
    for _ in range(CORNER_ROUNDS):
        built = cn.build_corners(y, groups, R, cap)
        if not built:
            break
        got = _through_corners(built, u, dense, lam, R, uv)
        to_old = lambda x, bn=got[5], bo=got[6]: np.interp(x, bn, bo)  # noqa: E731
        more = _merge_groups(groups + _tight_groups(got[0], got[1], uv, kmax_1pm, reach_m, to_old))
        if more == groups:
            break
        groups = more
    if got is None:
        return None
    # a corner whose stretch of the fitted curve is still beyond the class limit (a short leg
    # between it and the next bend, where the smoothed curve cannot join it) is not built
    f = np.linspace(0.0, 1.0, 4, endpoint=False)
    uq = np.r_[(got[1][:-1, None] + f * np.diff(got[1])[:, None]).ravel()]
    kq = _horizontal_curvature(got[0], uq)
    bn = got[5]
    keep = [
        c
        for i, c in enumerate(built)
        if kq[(uq >= bn[1 + 2 * i] - reach_m) & (uq <= bn[2 + 2 * i] + reach_m)].max(initial=0.0)
        <= kmax_1pm  # the bound takes what is left within the class limit
    ]
    if not keep:
        return None
    if len(keep) < len(built):
        built = keep
        got = _through_corners(built, u, dense, lam, R, uv)
    g2, u_new, new, base, v_u = got[:5]
    k_was = _horizontal_curvature(g, np.r_[(u[:-1, None] + f * np.diff(u)[:, None]).ravel()])
    k_now = _horizontal_curvature(
        g2, np.r_[(u_new[:-1, None] + f * np.diff(u_new)[:, None]).ravel()]
    )
    if k_now.max() >= k_was.max():  # the corners left a bend as tight: not built
        return None
    kinds = [c.kind for c in built]
    report = {
        "method": "bends tighter than the turning radius built as fillets of clothoids and "
        "arcs tangent to the legs (hairpins: a straight across or a bulb), the spline "
        "through their samples",
        "radius_m": R,
        "groups": len(groups),
        "built": len(built),
        **{k: kinds.count(k) for k in ("fillet", "hairpin", "bulb")},
        "max_curvature_1pm": float(max(np.abs(c.curvature).max() for c in built)),
    }
    return g2, u_new, new, base, v_u, report


#: Length [m] of the legs either side of a constructed corner over which the smoothing
#: penalty tapers from the corner's (:data:`CORNER_STIFFNESS`) back to the legs'.
CORNER_TAPER_M = 10.0

#: Rounds of :func:`_construct_corners` (a bend left tight next to a built corner joins it).
CORNER_ROUNDS = 3


def _through_corners(built, u, dense, lam, R, uv):
    """The densified polyline ``dense`` (chord lengths ``u``) with the corners ``built``
    in place of its stretches, and the spline through it (stiffness
    :data:`CORNER_STIFFNESS` on the corners' samples): (curve, new chord lengths, new
    polyline, log10 stiffness per site, vertexes' new chord lengths, breakpoints new, old)."""
    from imugen.truth.corners import SAMPLE_RADII

    ds = SAMPLE_RADII * R
    parts, marks = [], []
    lo = 0.0  # old chord where the kept stretch starts
    for c in built:
        keep = (u > lo + 0.5 * ds if lo > 0.0 else u >= 0.0) & (u < c.u_in - 0.5 * ds)
        z = np.interp(np.linspace(c.u_in, c.u_out, len(c.points)), u, dense[:, 2])
        parts += [dense[keep], np.column_stack([c.points, z])]
        marks += [np.zeros(int(keep.sum())), np.ones(len(c.points))]
        lo = c.u_out
    keep = u > lo + 0.5 * ds
    parts.append(dense[keep])
    marks.append(np.zeros(int(keep.sum())))
    new = np.vstack(parts)
    mark = np.concatenate(marks).astype(bool)
    u_new = np.r_[0.0, np.cumsum(np.linalg.norm(np.diff(new, axis=0), axis=1))]
    # the vertexes' new chord lengths: shifted along the kept stretches, the corners'
    # vertexes spread over the corner
    bp_old, bp_new = [0.0], [0.0]
    starts = np.flatnonzero(np.diff(np.r_[0, mark.astype(np.int8)]) > 0)
    for c, i in zip(built, starts, strict=True):
        bp_old += [c.u_in, c.u_out]
        bp_new += [u_new[i], u_new[i + len(c.points) - 1]]
    bp_old.append(u[-1])
    bp_new.append(u_new[-1])
    # the stiffness tapers back to the legs' over CORNER_TAPER_M of the legs either side:
    # the smoothed legs join the corner without a kink in curvature
    base = np.where(mark, CORNER_STIFFNESS, 0.0)
    for c, i in zip(built, starts, strict=True):
        a, b = u_new[i], u_new[i + len(c.points) - 1]
        gap = np.maximum(a - u_new, u_new - b)
        ramp = (~mark) & (gap < CORNER_TAPER_M)
        base[ramp] = np.minimum(base[ramp], CORNER_STIFFNESS * (1.0 - gap[ramp] / CORNER_TAPER_M))
    ps = PenalizedSpline(u_new, stiffness=10.0**base)
    g2 = ps.bspline(np.column_stack([ps.solve(lam, new[:, j]) for j in range(3)]))
    bo, bn = np.array(bp_old), np.array(bp_new)
    return g2, u_new, new, base, np.interp(uv, bo, bn), bn, bo


def _bound_curvature(g, u, dense, lam, max_curvature, per=4, base=None):
    """An untimed ground path's smoothed polyline ``g(u)`` (u: chord length of the densified
    polyline ``dense``) with its horizontal curvature bounded by :data:`CURVATURE_MARGIN`
    x ``max_curvature(u)`` (the vehicle's least turning radius there): where a bend is tighter
    (a hairpin, an acute corner that the corner rounding leaves tight) the spline's penalty
    grows by :data:`CURVATURE_STIFFNESS_STEP` decades per round over a few bandwidths around it
    (tapered), so the smoothing spline takes the bend wider there (the rest of the path is
    unchanged) until the bound holds; a bend that would stray farther than
    :data:`CURVATURE_RESIDUAL_RADII` turning radii from the polyline (two legs closer than
    the turning diameter) is left as it was, and the gate refuses the slip it causes. The speed profile then slows the vehicle
    through the bend to its lateral-acceleration limit (:func:`imugen.truth.profile.speed_profile`),
    so the body follows the path without sliding sideways. Returns the curve and a report
    (None when no bend was too tight)."""
    f = np.linspace(0.0, 1.0, per, endpoint=False)
    uq = np.r_[(u[:-1, None] + f * np.diff(u)[:, None]).ravel(), u[-1]]
    kmax = CURVATURE_MARGIN * np.asarray(max_curvature(uq), float)
    k0 = _horizontal_curvature(g, uq)
    if not np.any(k0 > kmax):
        return g, None
    from scipy.spatial import cKDTree

    tree = cKDTree(dense[:, :2])

    def off(g):  # distance of the curve from the densified polyline (its nearest point)
        return tree.query(g(uq)[:, :2])[0]

    cap = np.maximum(CURVATURE_RESIDUAL_RADII * CURVATURE_MARGIN / kmax, off(g))
    raw = np.zeros(len(u))  # log10 of the stiffness asked for at each site
    frozen = np.zeros(len(u), bool)  # bends that cannot be widened within the cap
    best, best_k, best_field, rounds = g, float(np.max(k0 / kmax)), raw, 0
    kq = k0

    def solve(raw):
        reach = math.ceil(CURVATURE_REACH * lam ** (1.0 / 6.0) * 10.0 ** (raw.max() / 6.0))
        # the stiffer stretch spans a few bandwidths around each bend too tight, and its
        # stiffness tapers linearly over as much (a step would turn the curve at its edges)
        field = uniform_filter1d(maximum_filter1d(raw, 2 * reach + 1), 2 * reach + 1)
        ps = PenalizedSpline(u, stiffness=10.0 ** (field if base is None else field + base))
        return (
            ps.bspline(np.column_stack([ps.solve(lam, dense[:, j]) for j in range(3)])),
            field,
            reach,
        )

    for rounds in range(1, CURVATURE_ITERATIONS + 1):  # noqa: B007 (reported below)
        bad = np.clip(np.searchsorted(u, uq[kq > kmax]), 0, len(u) - 1)
        bad = bad[~frozen[bad]]
        if not len(bad):
            break
        trial = raw.copy()
        trial[bad] += CURVATURE_STIFFNESS_STEP
        g, field, reach = solve(trial)
        over = off(g) > cap
        if over.any():  # a bend the vehicle cannot take within the cap: left as it was
            at = np.zeros(len(u), bool)
            at[np.clip(np.searchsorted(u, uq[over]), 0, len(u) - 1)] = True
            grown = maximum_filter1d(at.astype(np.int8), 4 * reach + 1).astype(bool)
            frozen |= grown
            trial = np.where(grown, raw, trial)
            g, field, reach = solve(trial)
        raw = trial
        kq = _horizontal_curvature(g, uq)
        if np.max(kq / kmax) < best_k:
            best, best_k, best_field = g, float(np.max(kq / kmax)), field
        if not best_k > 1.0 or raw.max() >= CURVATURE_STIFFNESS_MAX:
            break
    over = _horizontal_curvature(best, uq) > kmax
    return best, {
        "method": "local smoothing of the bends tighter than the vehicle's least turning "
        "radius (the spline's penalty raised there)",
        "curvature_margin": CURVATURE_MARGIN,
        "least_curvature_limit_1pm": float(kmax.min()),
        "max_curvature_ratio_before": float(np.max(k0 / kmax)),
        "max_curvature_ratio": best_k,
        "rounds": rounds,
        "points_smoothed": int((best_field > 0.0).sum()),
        "least_residual_cap_m": float(cap.min()),
        "bends_left": int(np.sum(np.diff(np.r_[0, over.astype(np.int8)]) > 0)),
    }


def floor_heights(G, L, s_v, h_v, window_m, taper_m, spacing_m):
    """A path ``G(s)`` (arc length, ENU) raised where it runs below the input's heights.

    The floor at ``s`` is the lowest input height (``h_v`` at arc lengths ``s_v``, the
    vertical of the input points) within ``window_m`` of it: the terrain or runway the input
    stood on, and in the air the lower edge of its noise. Where the path is below it, the
    deficit is spread over ``taper_m`` either side (a running maximum, then two running
    means: quadratic ramps, so the vertical acceleration of the correction stays small) and
    added to the path's vertical; the result is re-parameterized by arc length on a grid
    ``spacing_m`` apart.

    Returns
    -------
    (BSpline, float, dict or None)
        The path, its length, and a report (None when nothing was below the floor).
    """
    n = max(8, math.ceil(L / spacing_m))
    s = np.linspace(0.0, L, n + 1)
    ds = s[1] - s[0]
    order = np.argsort(s_v, kind="stable")
    sv, hv = np.asarray(s_v, float)[order], np.asarray(h_v, float)[order]
    # lowest input height within the window of each grid point
    m = max(1, math.ceil(window_m / ds))
    floor = minimum_filter1d(np.interp(s, sv, hv), 2 * m + 1, mode="nearest")
    P = G(s)
    deficit = np.maximum(floor - P[:, 2], 0.0)
    if not deficit.max() > 0.0:
        return G, L, None
    w = 2 * max(1, math.ceil(taper_m / ds)) + 1
    bump = maximum_filter1d(deficit, 2 * w + 1, mode="nearest")
    bump = uniform_filter1d(uniform_filter1d(bump, w, mode="nearest"), w, mode="nearest")
    P[:, 2] += bump
    u = np.r_[0.0, np.cumsum(np.linalg.norm(np.diff(P, axis=0), axis=1))]
    G2 = make_interp_spline(u, P, k=K_SPLINE)
    return (
        G2,
        float(u[-1]),
        {
            "method": "raised to the lowest input height within the window, ramps tapered",
            "window_m": window_m,
            "taper_m": taper_m,
            "max_deficit_m": float(deficit.max()),
            "raised_length_m": float(ds * np.count_nonzero(bump > 0.0)),
        },
    )


def distance_to_curve(G, L, y, spacing):
    """Distance [m] of each point ``y`` (N, 3) to the curve ``G(s)``, s in [0, L]: to the
    polyline of samples ``spacing`` apart next to the nearest sample (chord error
    ``spacing^2 kappa / 8``, not the ``spacing / 2`` of the nearest sample alone)."""
    from scipy.spatial import cKDTree

    sf = np.linspace(0.0, L, max(2, int(np.ceil(L / spacing)) + 1))
    P = G(sf)
    _, k = cKDTree(P).query(y)
    best = np.full(len(y), np.inf)
    for a in (np.maximum(k - 1, 0), k):
        b = np.minimum(a + 1, len(P) - 1)
        seg = P[b] - P[a]
        w = np.einsum("ij,ij->i", y - P[a], seg) / np.maximum(
            np.einsum("ij,ij->i", seg, seg), 1e-30
        )
        q = P[a] + np.clip(w, 0.0, 1.0)[:, None] * seg
        best = np.minimum(best, np.linalg.norm(y - q, axis=1))
    return best


# ------------------------------------------------------------------------------------------
# height against horizontal distance (road grade)
# ------------------------------------------------------------------------------------------
GRADE_BIN_RATIO = 8.0
"""Largest ratio of the points' median spacing to the height profile's bin width
(:func:`fit_height_profile`)."""


def _grade_bin(s, bin_m):
    """Bin width [m] of a height profile: ``bin_m``, widened to the points' median spacing
    (moving) over :data:`GRADE_BIN_RATIO`.

    The spline's knots are the bins and its penalty is normalized at their median spacing:
    bins far denser than that (an airliner's 0.1 s samples taxiing at 5 m/s, 0.5 m apart, on a
    route sampled 24 m apart at cruise) scale the penalty there by the spacing ratio^6 (1e10),
    and the solve then loses the profile's level at the route's ends (a 4 m, 9 deg height
    ramp, grade 0.15, on the final taxi of a 7,600 km flight: the airliner taxied nose-up)."""
    ds = np.diff(s)
    moved = ds[ds > 0.0]
    if not len(moved):
        return bin_m
    return max(bin_m, float(np.median(moved)) / GRADE_BIN_RATIO)


def fit_height_profile(s, h, noise_m, bin_m, smooth_m, floor_m=1e-3):
    """Height against horizontal distance, smoothed at the height noise.

    Points are binned by distance (``bin_m``, at least their median spacing over
    :data:`GRADE_BIN_RATIO`; a stop's points fall into one bin, so height
    noise or a height step at a stop is averaged, never a slope), and a quintic penalized
    smoothing spline (penalty on the third derivative) is fitted to the bin means weighted by
    their counts; its smoothing makes the count-weighted RMS residual equal to ``noise_m``
    (discrepancy principle, the noise of one point), and is at least that of a bandwidth of
    ``smooth_m`` (GNSS heights step and wander; quantized heights have no noise to measure).

    Parameters
    ----------
    s : ndarray, shape (N,)
        Horizontal distance travelled [m] (non-decreasing).
    h : ndarray, shape (N,)
        Height [m].
    noise_m : float
        White-noise level of ``h`` [m].
    bin_m : float
        Bin width [m].
    smooth_m : float
        Least smoothing length [m].
    floor_m : float
        Smallest residual target [m].

    Returns
    -------
    (BSpline or None, dict)
        ``H(s)`` (None when fewer than 6 bins: level) and a report.
    """
    s = np.asarray(s, float)
    h = np.asarray(h, float)
    bin_m = _grade_bin(s, bin_m)
    b = np.floor((s - s[0]) / bin_m).astype(np.int64)
    _, inv, cnt = np.unique(b, return_inverse=True, return_counts=True)
    sm = np.bincount(inv, s) / cnt
    hm = np.bincount(inv, h) / cnt
    if len(sm) < 6:
        return None, {"bins": len(sm), "method": "level (too short)"}
    ps = PenalizedSpline(sm, weights=cnt)
    target = max(float(noise_m), floor_m)
    h0 = float(np.average(hm, weights=cnt))  # fitted about the mean: no offset to round off
    # smoothing beyond the bins' own extent (bandwidth ~ lambda^(1/6) bins) changes nothing (the
    # fit is the least-squares quadratic) but the conditioning: few bins cap it
    hi = min(12.0, 6.0 * math.log10(len(sm)))
    lam = min(
        max(10.0 ** ps.lam_for_rms(hm - h0, target, hi=hi), (smooth_m / ps.scale) ** 6), 10**hi
    )
    H = ps.bspline(ps.solve(lam, hm - h0))
    H = BSpline(H.t, H.c + h0, H.k, extrapolate=True)  # the B-splines sum to 1
    res = H(sm) - hm
    report = {
        "method": "quintic penalized smoothing spline of binned height against distance",
        "bins": len(sm),
        "bin_m": bin_m,
        "smooth_m": smooth_m,
        "lambda_normalized": lam,
        "noise_m": float(noise_m),
        "rms_residual_m": float(np.sqrt(np.sum(cnt * res**2) / np.sum(cnt))),
    }
    return H, report
