"""Road grade of a timed ground route: the height profile against horizontal distance, and the
vertical of the motion that follows it.

A GNSS track's heights are noisier than its horizontal positions and often step (quantized or
held altimeter records). Fitted in time with the horizontal, they leave the path wiggling up and
down at the sampling scale: a car whose velocity climbs and dives a few degrees every few
metres, which the attitude can neither follow (its pitch rate would be implausible) nor ignore
(the body would slip vertically, breaking the non-holonomic constraint). A road has a profile:
the vertical of the truth is ``H(s(t))``, the height profile ``H`` (smoothed over at least
``grade_smooth_m``, :func:`imugen.truth.fit.fit_height_profile`) at the horizontal distance
``s(t)`` travelled, so the velocity's pitch is the road's grade.
"""

from __future__ import annotations

import numpy as np
from scipy.interpolate import BSpline

from imugen.truth.fit import K_SPLINE, TimedMotion, _PenalizedSpline, fit_height_profile

_GL = np.polynomial.legendre.leggauss(4)
KNOT_MAX_S = 1.0  # knots of the graded vertical at most this far apart in time [s]
KNOTS_PER_SMOOTH = 5  # ... and at most grade_smooth_m / this far apart in distance
_LAM = 1e-2  # penalty of the vertical spline (normalized): near interpolation of H(s(t))
_HEIGHT_ITER = 3  # iterations from the profile's ellipsoidal height to n's Up (wgs84)


def gl_nodes(t):
    """4-node Gauss-Legendre nodes (n-1, 4) and weights (n-1, 4) on the intervals of ``t``."""
    h = np.diff(t)[:, None]
    return t[:-1, None] + 0.5 * h * (_GL[0] + 1.0), 0.5 * h * _GL[1]


def distance_steps(motion, E, t):
    """Horizontal distance travelled over each interval of ``t`` (4-node Gauss-Legendre
    quadrature of the horizontal speed of ``E``, an :class:`~imugen.truth.attitude.EarthField`),
    shape (len(t) - 1,) [m]."""
    tq, wq = gl_nodes(t)
    tq = tq.ravel()
    v = motion.velocity(tq)
    p = motion.position(tq) if E.ecef else None
    vh = E.horizontal_speed(p, v)[0].reshape(wq.shape)
    return np.sum(wq * vh, axis=1)


def _knot_sites(t_in, ds_in, smooth_m):
    """Input times, each interval split into equal parts at most ``KNOT_MAX_S`` long and
    ``smooth_m / KNOTS_PER_SMOOTH`` of distance."""
    dt = np.diff(t_in)
    parts = np.maximum(
        np.ceil(dt / KNOT_MAX_S), np.ceil(ds_in * KNOTS_PER_SMOOTH / smooth_m)
    ).astype(np.int64)
    parts = np.maximum(parts, 1)
    starts = np.repeat(t_in[:-1], parts)
    frac = np.arange(parts.sum()) - np.repeat(np.cumsum(parts) - parts, parts)
    x = starts + np.repeat(dt / parts, parts) * frac
    idx = np.r_[0, np.cumsum(parts)]  # index of each input time in x
    return np.r_[x, t_in[-1]], idx


def graded_motion(motion: TimedMotion, E, vp, heights, noise_up_m, stops):
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
        The graded motion (the input one when the route is too short for a profile), ``H(s)``
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
    x, idx = _knot_sites(t_in, ds_in, vp.grade_smooth_m)
    # distance at the knots and midway between them (quadrature within each input interval)
    z = np.empty(2 * len(x) - 1)
    z[0::2], z[1::2] = x, 0.5 * (x[1:] + x[:-1])
    s_z = np.r_[0.0, np.cumsum(distance_steps(motion, E, z))]
    h_x = H(s_z[0::2])
    u_x = h_x.copy()
    if not E.flat:  # n's Up giving that ellipsoidal height above the same East/North
        p_x = motion.position(x)
        u_x = p_x[:, 2].copy()
        for _ in range(_HEIGHT_ITER):
            p_x[:, 2] = u_x
            u_x = u_x + (h_x - E.height(p_x))
    ties = [
        (int(idx[np.searchsorted(t_in, a)]), int(idx[np.searchsorted(t_in, b)]) + K_SPLINE - 1)
        for a, b in stops
    ]
    ps = _PenalizedSpline(x, ties)
    u0 = float(np.mean(u_x))
    V = ps.bspline(ps.solve(_LAM, u_x - u0))
    V = BSpline(V.t, V.c + u0, V.k, extrapolate=True)  # the B-splines sum to 1
    graded = TimedMotion(motion.spline, motion.t0, motion.t1, vertical=V)
    pz = graded.position(z)
    report = {
        "method": "road profile H(s(t)): heights against horizontal distance (grade), "
        "quintic spline in time through it with knots at the input times and every "
        f"<= {KNOT_MAX_S} s and <= grade_smooth_m / {KNOTS_PER_SMOOTH}",
        "grade": grep,
        "knots": len(x),
        "max_departure_m": float(np.max(np.abs(E.height(pz) - H(s_z)))),
        "max_change_from_time_fit_m": float(np.max(np.abs(pz[:, 2] - motion.position(z)[:, 2]))),
    }
    return graded, H, report
