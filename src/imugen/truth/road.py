"""Road grade of a ground route: the height profile against horizontal distance, and the
vertical of the motion (timed) or of the path geometry (untimed) that follows it.

A GNSS track's heights are noisier than its horizontal positions and often step (quantized or
held altimeter records). Fitted in time with the horizontal, they leave the path wiggling up and
down at the sampling scale: a car whose velocity climbs and dives a few degrees every few
metres, which the attitude can neither follow (its pitch rate would be implausible) nor ignore
(the body would slip vertically, breaking the non-holonomic constraint). A road has a profile:
the vertical of the truth is ``H(s(t))``, the height profile ``H`` (smoothed over at least
``grade_smooth_m``, :func:`imugen.truth.fit.fit_height_profile`) at the horizontal distance
``s(t)`` travelled, so the velocity's pitch is the road's grade. An untimed path's geometry
``G`` gets the vertical ``H(s_h)`` at its horizontal distance ``s_h`` before its speed profile
(:func:`path_on_road`): the polyline's heights step and wander like a track's.
"""

from __future__ import annotations

import numpy as np
from scipy.interpolate import BSpline, make_interp_spline

from imugen.truth.fit import (
    K_SPLINE,
    HeldSites,
    TimedMotion,
    distance_to_curve,
    fit_height_profile,
    noise_estimate,
)

_GL = np.polynomial.legendre.leggauss(4)
KNOT_MAX_S = 1.0  # knots of the road-profile vertical at most this far apart in time [s]
KNOTS_PER_SMOOTH = 5  # ... and at most grade_smooth_m / this far apart in distance
STOP_KNOT_INTERVALS = 5  # input intervals either side of a stop's edge (fit.ABRUPT_LOOK) ...
STOP_KNOT_PARTS = 8  # ... split into at least this many (a braking within one interval)
_LAM = 1e-2  # penalty of the vertical spline (normalized): near interpolation of H(s(t))
_HEIGHT_ITER = 3  # iterations from the profile's ellipsoidal height to n's Up (wgs84)


def gl_nodes(t):
    """4-node Gauss-Legendre nodes (n-1, 4) and weights (n-1, 4) on the intervals of ``t``."""
    h = np.diff(t)[:, None]
    return t[:-1, None] + 0.5 * h * (_GL[0] + 1.0), 0.5 * h * _GL[1]


def _integrals(f, x):
    """Integral of ``f`` (callable, (m,) -> (m,)) over each interval of ``x`` (N,): 4-node
    Gauss-Legendre, in chunks; shape (N - 1,)."""
    out = np.empty(len(x) - 1)
    step = 1 << 17
    for i in range(0, len(x) - 1, step):
        xq, wq = gl_nodes(x[i : i + step + 1])
        out[i : i + len(wq)] = np.sum(wq * f(xq.ravel()).reshape(wq.shape), axis=1)
    return out


def distance_steps(motion, E, t):
    """Horizontal distance travelled over each interval of ``t`` (4-node Gauss-Legendre
    quadrature of the horizontal speed of ``E``, an :class:`~imugen.truth.attitude.EarthField`),
    shape (len(t) - 1,) [m]."""

    def speed(tq):
        return E.horizontal_speed(motion.position(tq) if E.ecef else None, motion.velocity(tq))[0]

    return _integrals(speed, np.asarray(t, float))


def _up_of_height(E, p, h):
    """n's Up giving the heights ``h`` (m,) above the East/North of ``p`` (m, 3): ``h`` itself
    in ``flat``, else by fixed-point iteration on the ellipsoidal height."""
    if E.flat:
        return np.array(h, float)
    p = np.array(p, float)
    u = p[:, 2].copy()
    for _ in range(_HEIGHT_ITER):
        p[:, 2] = u
        u = u + (h - E.height(p))
    return u


def _knot_sites(t_in, ds_in, smooth_m, stop_edges=()):
    """Input times, each interval split into equal parts at most ``KNOT_MAX_S`` long and
    ``smooth_m / KNOTS_PER_SMOOTH`` of distance, and the :data:`STOP_KNOT_INTERVALS` intervals
    either side of each stop edge (input indexes ``stop_edges``) into at least
    :data:`STOP_KNOT_PARTS`."""
    dt = np.diff(t_in)
    parts = np.maximum(
        np.ceil(dt / KNOT_MAX_S), np.ceil(ds_in * KNOTS_PER_SMOOTH / smooth_m)
    ).astype(np.int64)
    parts = np.maximum(parts, 1)
    for e in stop_edges:
        lo, hi = max(0, e - STOP_KNOT_INTERVALS), min(len(dt), e + STOP_KNOT_INTERVALS)
        parts[lo:hi] = np.maximum(parts[lo:hi], STOP_KNOT_PARTS)
    starts = np.repeat(t_in[:-1], parts)
    frac = np.arange(parts.sum()) - np.repeat(np.cumsum(parts) - parts, parts)
    x = starts + np.repeat(dt / parts, parts) * frac
    idx = np.r_[0, np.cumsum(parts)]  # index of each input time in x
    return np.r_[x, t_in[-1]], idx


def motion_on_road(motion: TimedMotion, E, vp, heights, noise_up_m, stops):
    """The timed motion with its vertical replaced by the road profile ``H(s(t))``.

    Parameters
    ----------
    motion : TimedMotion
        Fitted in the route origin's ENU [m].
    E : imugen.truth.attitude.EarthField
        ``flat`` or ``wgs84`` field of that ENU (heights: n's Up, or ellipsoidal).
    vp : imugen.truth.vehicles.VehicleParams
    heights : (ndarray (N,), ndarray (N,))
        Input times [s] (the motion's knots) and heights [m].
    noise_up_m : float
        Noise of those heights [m].
    stops : list of [t0, t1]
        Stops of the motion [s] (input times): the vertical is exactly constant there too.

    Returns
    -------
    (TimedMotion, BSpline or None, dict)
        The motion on the road profile (the input one when the route is too short for a profile), ``H(s)``
        and a report (grade fit, knots, largest departure of the vertical from ``H(s(t))``).
    """
    t_in, h_in = (np.asarray(a, float) for a in heights)
    ds_in = distance_steps(motion, E, t_in)
    s_in = np.r_[0.0, np.cumsum(ds_in)]
    H, grep = fit_height_profile(
        s_in, h_in, noise_up_m, vp.grade_bin_m, vp.grade_smooth_m, vp.fit_floor_m
    )
    if H is None:
        return motion, None, {"grade": grep, "method": "time fit (too short for a profile)"}
    # the horizontal distance brakes into a stop within an interval or two of sparse fixes
    # (~ (t_stop - t)^3, :class:`imugen.truth.fit.HeldSites`): finer knots there follow it
    edges = [int(np.searchsorted(t_in, e)) for st in stops for e in st]
    x, idx = _knot_sites(t_in, ds_in, vp.grade_smooth_m, edges)
    # distance at the knots and midway between them (quadrature within each input interval)
    z = np.empty(2 * len(x) - 1)
    z[0::2], z[1::2] = x, 0.5 * (x[1:] + x[:-1])
    s_z = np.r_[0.0, np.cumsum(distance_steps(motion, E, z))]
    h_x = H(s_z[0::2])
    u_x = _up_of_height(E, motion.position(x) if not E.flat else None, h_x)
    # held still over the stops, joining them as the horizontal does (zero velocity and
    # acceleration: the vertical H(s(t)) brakes with the distance, ~ (t_stop - t)^3)
    held = HeldSites(
        x,
        [
            (int(idx[np.searchsorted(t_in, a)]), int(idx[np.searchsorted(t_in, b)]))
            for a, b in stops
        ],
    )
    ps = held.spline()
    u0 = float(np.mean(u_x))
    V = ps.bspline(ps.solve(_LAM, u_x - u0))
    V = BSpline(V.t, V.c + u0, V.k, extrapolate=True)  # the B-splines sum to 1
    on_road = TimedMotion(motion.spline, motion.t0, motion.t1, vertical=V)
    pz = on_road.position(z)
    report = {
        "method": "road profile H(s(t)): heights against horizontal distance (grade), "
        "quintic spline in time through it with knots at the input times and every "
        f"<= {KNOT_MAX_S} s and <= grade_smooth_m / {KNOTS_PER_SMOOTH}",
        "grade": grep,
        "knots": len(x),
        "max_departure_m": float(np.max(np.abs(E.height(pz) - H(s_z)))),
        "max_change_from_time_fit_m": float(np.max(np.abs(pz[:, 2] - motion.position(z)[:, 2]))),
    }
    return on_road, H, report


def path_on_road(G, L, E, vp, vertices, y, spacing_m):
    """An untimed path whose vertical is the road profile ``H(s_h)``, re-parameterized by
    arc length.

    ``H`` is fitted to the input heights against the horizontal distance ``s_h`` of their
    points on ``G`` (:func:`imugen.truth.fit.fit_height_profile`; noise from the heights'
    neighbour predictions along ``s_h``, :func:`imugen.truth.fit.noise_estimate`). The
    curve keeps the East/North of ``G`` and takes n's Up giving ``H(s_h)``: both sampled
    every ``spacing_m`` of ``G`` are interpolated (quintic) against their new arc length.

    Parameters
    ----------
    G : BSpline
        Path geometry of its arc length, in the route origin's ENU [m] (:func:`fit_path`).
    L : float
        Its length [m].
    E : imugen.truth.attitude.EarthField
        ``flat`` or ``wgs84`` field of that ENU (heights: n's Up, or ellipsoidal; horizontal:
        its East/North).
    vp : imugen.truth.vehicles.VehicleParams
    vertices : (ndarray (N,), ndarray (N,))
        Arc length on ``G`` of the input points [m] and their heights [m].
    y : ndarray, shape (N, 3)
        Input points (ENU) [m], for the distances of the report.
    spacing_m : float
        Sampling of ``G`` [m] (its own interpolation sites' spacing keeps its horizontal).

    Returns
    -------
    (BSpline, float, BSpline or None, dict)
        Graded geometry ``G`` and its length (the input ones when the path is too short for a
        profile), ``H(s_h)`` and a report (grade fit, largest departure of the vertical from
        ``H(s_h)``, distances of the input points to the path on the road profile).
    """
    sig_v, h_v = (np.asarray(a, float) for a in vertices)
    n = max(64, int(np.ceil(L / spacing_m)))
    x = np.linspace(0.0, L, n + 1)
    G1 = G.derivative(1)
    sh = np.r_[0.0, np.cumsum(_integrals(lambda q: E.horizontal_speed(None, G1(q))[0], x))]
    s_v = np.interp(sig_v, x, sh)
    up = np.r_[True, np.diff(s_v) > 1e-9 * max(sh[-1], 1.0)]  # distinct abscissae
    noise = float(noise_estimate(s_v[up], h_v[up, None])[0])
    H, grep = fit_height_profile(s_v, h_v, noise, vp.grade_bin_m, vp.grade_smooth_m, vp.fit_floor_m)
    if H is None:
        return G, L, None, {"grade": grep, "method": "path heights (too short for a profile)"}
    P = G(x)
    u0 = P[:, 2].copy()
    P[:, 2] = _up_of_height(E, P, H(sh))
    U1 = make_interp_spline(x, P[:, 2], k=K_SPLINE).derivative(1)

    def speed(q):  # |dP/dx|: East/North of G, Up of the road-profile vertical
        d = G1(q)
        return np.sqrt(d[:, 0] ** 2 + d[:, 1] ** 2 + U1(q) ** 2)

    lam = np.r_[0.0, np.cumsum(_integrals(speed, x))]
    G2 = make_interp_spline(lam, P, k=K_SPLINE)
    L2 = float(lam[-1])
    xm = 0.5 * (lam[1:] + lam[:-1])  # between the sites: interpolation's largest errors
    G21 = G2.derivative(1)
    shm = np.cumsum(_integrals(lambda q: E.horizontal_speed(None, G21(q))[0], np.r_[0.0, xm]))
    dh = E.height(G2(np.interp(sig_v, x, lam))) - h_v
    d = distance_to_curve(G2, L2, y, spacing_m / 2.0)
    report = {
        "method": "road profile H(s_h): input heights against horizontal distance (grade), "
        "the path's East/North with the Up of H, quintic against its new arc length",
        "grade": grep,
        "samples": n + 1,
        "max_departure_m": float(np.max(np.abs(E.height(G2(xm)) - H(shm)))),
        "max_change_from_path_m": float(np.max(np.abs(P[:, 2] - u0))),
        "rms_vertical_distance_m": float(np.sqrt(np.mean(dh**2))),
        "rms_distance_m": float(np.sqrt(np.mean(d**2))),
        "max_distance_m": float(d.max()),
    }
    return G2, L2, H, report
