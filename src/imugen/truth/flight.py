"""Flight phases of an untimed airliner route: speed cap and height along the distance.

An untimed route of a vehicle class with ``phases`` (``airliner``) is flown as taxi, take-off
roll, climb, cruise, descent, approach, landing roll and taxi. The plan is laid along the
horizontal distance ``d`` of the route (the arc length of its ground geometry, :func:`fit_path`):

* taxi ``taxi_m`` at ``taxi_mps`` at each end;
* take-off roll: the speed profile accelerates at ``accel_mps2`` to ``rotate_mps``
  (``(rotate^2 - taxi^2) / (2 accel)`` of runway), lift-off at its end;
* climb at ``climb_rate_mps`` while the speed follows the schedule ``rotate_mps`` at the
  runway, ``climb_speed_mps`` at ``speed_limit_alt_m`` above it (250 kt below FL100), then
  ``cruise_mps`` at ``cruise_alt_m`` (linear in height between), so the climb gradient is
  ``climb_rate / v(h)``;
* cruise at ``cruise_alt_m``, or lower when the route is too short to reach it (the highest
  level from which the descent still fits);
* descent at the flight-path angle ``descent_angle_rad`` (the 3 deg glide slope: the 3-to-1
  rule of descent planning), the speed schedule mirrored down to ``approach_mps`` at the
  runway; landing roll braking at ``accel_mps2`` to taxi speed.

Every change of flight-path angle (rotation, level-off, top of descent, flare) is a smooth
(quintic smoothstep) change of slope over ``1.875 v^2 |d gamma| / vertical_accel_mps2`` of
distance: the vertical acceleration stays below ``vertical_accel_mps2``; the rotation
starts at the end of the roll and the flare ends at the touchdown, so the wheels stay on the
runway until then. Heights of the plan are ellipsoidal; climb and descent are counted from
the heights of the route's ends. A route whose heights vary by less than
``airborne_height_m`` has no heights (a KML LineString without altitudes): the plan's
heights replace them. A route with heights keeps them; only its speed follows the plan. A
route too short to climb ``airborne_height_m`` and land is taxied.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.interpolate import make_interp_spline

from imugen.core import earth as ea
from imugen.truth.vehicles import VehicleParams

GRID_M = 25.0
"""Spacing of the plan's distance grid [m] (the flare, the shortest transition, spans ~500 m)."""

_SMOOTHSTEP_PEAK = 1.875  # max of d/du (10u^3 - 15u^4 + 6u^5)


def _ramp_integral(u):
    """Integral of the quintic smoothstep from 0 to u (u >= 0 beyond 1 continues linearly)."""
    uc = np.clip(u, 0.0, 1.0)
    return 2.5 * uc**4 - 3.0 * uc**5 + uc**6 + np.maximum(u - 1.0, 0.0)


class _Climb:
    """Distance flown while climbing ``x`` [m] at ``roc`` [m/s] with the speed linear in height
    between breakpoints (the schedule), and its inverse, both exact.

    ``d(x) = int_0^x v(h0 + xi) / roc dxi`` is a quadratic on each piece of the schedule, so
    the height is a closed form of the distance: smooth within each piece. (A linear
    interpolation of the inverse on a grid of heights put a kink every grid step into the
    climb, up to 1.7e-4 m off, every ~50 m, which the geometry's quintic turned into a 2 mg vertical
    acceleration at ~4 Hz, beyond what a 10 Hz IMU integrates.)

    Parameters
    ----------
    points : (list, list)
        Breakpoints of the schedule: heights [m] (the first is the climb's start), speeds [m/s].
    roc : float
        Rate of climb [m/s].
    """

    def __init__(self, points, roc: float):
        h, v = (np.asarray(a, float) for a in points)
        self.x = h - h[0]  # breakpoints above the start (the speed is constant beyond the last)
        self.v = v
        self.b = np.diff(v) / np.maximum(np.diff(self.x), 1e-300)  # dv/dh on each piece
        self.roc = float(roc)
        # distance at each breakpoint
        dx = np.diff(self.x)
        self.d = np.r_[0.0, np.cumsum((v[:-1] + 0.5 * self.b * dx) * dx)] / self.roc

    def distance(self, x):
        """Distance [m] flown to climb ``x`` [m] (x >= 0)."""
        x = np.asarray(x, float)
        i = np.clip(np.searchsorted(self.x, x, side="right") - 1, 0, len(self.x) - 1)
        b = np.where(i < len(self.b), self.b[np.minimum(i, len(self.b) - 1)], 0.0)
        u = x - self.x[i]
        return self.d[i] + (self.v[i] + 0.5 * b * u) * u / self.roc

    def height(self, d):
        """Height [m] above the start climbed over the distance ``d`` [m] (d >= 0)."""
        d = np.asarray(d, float)
        i = np.clip(np.searchsorted(self.d, d, side="right") - 1, 0, len(self.d) - 1)
        b = np.where(i < len(self.b), self.b[np.minimum(i, len(self.b) - 1)], 0.0)
        w = 2.0 * self.roc * (d - self.d[i])
        vi = self.v[i]
        # u = (sqrt(v^2 + b w) - v) / b without cancellation
        return self.x[i] + w / (vi + np.sqrt(np.maximum(vi * vi + b * w, 0.0)))


class FlightPlan:
    """Speed cap and height of a flight along the horizontal distance (see the module).

    Parameters
    ----------
    D : float
        Horizontal length of the route [m].
    h0, h1 : float
        Heights of its ends [m].
    vp : VehicleParams
        The class's phase parameters.
    """

    def __init__(self, D: float, h0: float, h1: float, vp: VehicleParams):
        self.vp = vp
        n = max(200, math.ceil(D / GRID_M))
        self.d = np.linspace(0.0, D, n + 1)
        A, roc, av = vp.accel_mps2, vp.climb_rate_mps, vp.vertical_accel_mps2
        tan_d = math.tan(vp.descent_angle_rad)
        roll = max(vp.rotate_mps**2 - vp.taxi_mps**2, 0.0) / (2.0 * A)
        land = max(vp.approach_mps**2 - vp.taxi_mps**2, 0.0) / (2.0 * A)
        d_roll_end = vp.taxi_m + roll
        d_touch = D - vp.taxi_m - land
        w_lo = _SMOOTHSTEP_PEAK * vp.rotate_mps * roc / av
        w_td = _SMOOTHSTEP_PEAK * vp.approach_mps**2 * tan_d / av
        lo = d_roll_end + 0.5 * w_lo  # kinks of the raw (unsmoothed) profile
        td = d_touch - 0.5 * w_td
        # candidate tops: climb and descent distances and the level-off transitions
        base = max(h0, h1)
        tops = np.linspace(base, max(vp.cruise_alt_m, base + 1.0), 2001)
        climb = _Climb(self._sched_points(h0, vp.rotate_mps), roc)
        v_top_c = self._sched(tops, h0, vp.rotate_mps)
        v_top_d = self._sched(tops, h1, vp.approach_mps)
        w_toc = _SMOOTHSTEP_PEAK * v_top_c * roc / av
        w_tod = _SMOOTHSTEP_PEAK * v_top_d**2 * tan_d / av
        climb_m = climb.distance(tops - h0)
        desc_m = (tops - h1) / tan_d
        # the climb and descent fit, and no two transitions overlap
        ok = (climb_m + desc_m + 0.5 * (w_toc + w_tod) <= td - lo) & (
            tops - base >= vp.airborne_height_m
        )
        ok &= (climb_m >= 0.5 * (w_lo + w_toc)) & (desc_m >= 0.5 * (w_tod + w_td))
        self.report = {
            "taxi_m": vp.taxi_m,
            "takeoff_roll_m": roll,
            "landing_roll_m": land,
            "length_m": D,
        }
        if not ok.any():
            self.h = np.interp(self.d, [0.0, D], [h0, h1])
            self.v_cap = np.full_like(self.d, vp.taxi_mps)
            self.report.update(phases="taxi only (too short to fly)", top_m=None)
            return
        k = int(np.flatnonzero(ok)[-1])
        top = float(tops[k])
        d_toc = lo + float(climb.distance(top - h0))
        d_tod = td - (top - h1) / tan_d
        d = self.d
        h_raw = np.full_like(d, top)
        up = d < d_toc
        h_raw[up] = h0 + climb.height(d[up] - lo)
        h_raw[d < lo] = h0
        desc = d > d_tod
        h_raw[desc] = h1 + np.maximum(td - d[desc], 0.0) * tan_d
        # smooth each change of slope over its transition length
        g_lo = roc / vp.rotate_mps
        g_toc = roc / float(v_top_c[k])
        kinks = [
            (lo, g_lo, w_lo),
            (d_toc, -g_toc, float(w_toc[k])),
            (d_tod, -tan_d, float(w_tod[k])),
            (td, tan_d, w_td),
        ]
        h = h_raw.copy()
        for dk, dg, w in kinks:
            m = np.abs(d - dk) < 0.5 * w
            x = d[m] - dk
            h[m] += dg * (w * _ramp_integral(x / w + 0.5) - np.maximum(x, 0.0))
        self.h = h
        # the speed cap of each phase (continuous: the schedule of the raw height)
        v = np.full_like(d, vp.taxi_mps)
        roll_m = (d >= vp.taxi_m) & (d <= lo)
        v[roll_m] = vp.rotate_mps
        air = (d > lo) & (d < d_toc)
        v[air] = self._sched(h_raw[air], h0, vp.rotate_mps)
        cr = (d >= d_toc) & (d <= d_tod)
        f = (d[cr] - d_toc) / max(d_tod - d_toc, 1e-9)
        v[cr] = (1.0 - f) * v_top_c[k] + f * v_top_d[k]
        dsc = (d > d_tod) & (d <= D - vp.taxi_m)
        v[dsc] = self._sched(h_raw[dsc], h1, vp.approach_mps)
        self.v_cap = v
        self.report.update(
            phases="taxi, take-off roll, climb, cruise, descent, approach, landing roll, taxi",
            top_m=top,
            lift_off_m=d_roll_end,
            top_of_climb_m=d_toc,
            top_of_descent_m=d_tod,
            touchdown_m=d_touch,
            cruise_speed_mps=float(v_top_c[k]),
            transitions_m=[w_lo, float(w_toc[k]), float(w_tod[k]), w_td],
        )

    def _sched_points(self, h_rwy, v_ground):
        """Breakpoints (heights [m], speeds [m/s]) of the speed schedule (:meth:`_sched`)."""
        vp = self.vp
        hs = h_rwy + vp.speed_limit_alt_m
        return (
            [h_rwy, hs, max(vp.cruise_alt_m, hs + 1.0)],
            [v_ground, vp.climb_speed_mps, vp.cruise_mps],
        )

    def _sched(self, h, h_rwy, v_ground):
        """Speed [m/s] at height ``h`` [m]: ``v_ground`` at the runway's ``h_rwy``,
        ``climb_speed_mps`` ``speed_limit_alt_m`` above it, ``cruise_mps`` at ``cruise_alt_m``
        (linear between)."""
        return np.interp(h, *self._sched_points(h_rwy, v_ground))

    def cap(self, d):
        """Speed cap [m/s] at horizontal distance(s) ``d`` [m]."""
        return np.interp(d, self.d, self.v_cap)


def flight_geometry(G, L, origin, alt_m, vp: VehicleParams):
    """Lift the ground geometry onto the flight plan's heights.

    Parameters
    ----------
    G : BSpline
        Ground geometry of the route against its arc length [m] (ENU of ``origin``).
    L : float
        Its length [m].
    origin : (lat_deg, lon_deg, alt_m)
        Origin of the ENU frame.
    alt_m : ndarray, shape (N,)
        Heights of the route's points [m].
    vp : VehicleParams

    Returns
    -------
    (BSpline, float, callable, dict)
        Flight geometry against its arc length, its length, the speed cap [m/s] as a function
        of that arc length, and the plan's report.
    """
    alt_m = np.asarray(alt_m, float)
    plan = FlightPlan(L, float(alt_m[0]), float(alt_m[-1]), vp)
    has_heights = bool(np.ptp(alt_m) >= vp.airborne_height_m)
    plan.report["heights"] = "route's own" if has_heights else "flight plan"
    if has_heights:
        return G, L, plan.cap, plan.report
    frame = ea.OriginFrame.from_deg(*origin)
    lat, lon, _ = frame.geodetic_from_n(G(plan.d))
    P = frame.n_from_geodetic(lat, lon, plan.h)
    u = np.r_[0.0, np.cumsum(np.linalg.norm(np.diff(P, axis=0), axis=1))]
    Gf = make_interp_spline(u, P, k=5)
    d = plan.d
    return Gf, float(u[-1]), lambda s: plan.cap(np.interp(s, u, d)), plan.report


def turn_curvature(s_m, alt_m, vp: VehicleParams):
    """The largest horizontal curvature [1/m] of an untimed flight's path, against the input
    polyline's chord length: a turn at the lateral-acceleration (bank) limit
    ``lat_accel_mps2`` at the speed flown there (``v^2 kappa <= lat_accel``), and on the
    ground at most ``max_curvature_1pm`` (taxiing).

    The speed is that of the plan (:class:`FlightPlan`) on a route without heights; on a route
    with its own heights, the speed schedule at the input's height above the nearer end
    (``rotate_mps`` at the runway to ``cruise_mps`` at ``cruise_alt_m``) where the input is more
    than ``airborne_height_m`` above it, else taxiing (``taxi_mps``): a logger's taxi turns
    stay tight wherever the plan lays its taxi distance.

    Parameters
    ----------
    s_m : ndarray, shape (N,)
        Chord length of the input points [m] (non-decreasing).
    alt_m : ndarray, shape (N,)
        Their heights [m].
    vp : VehicleParams

    Returns
    -------
    callable
        Curvature limit [1/m] at chord length(s) [m].
    """
    s_m = np.asarray(s_m, float)
    alt_m = np.asarray(alt_m, float)
    plan = FlightPlan(float(s_m[-1]), float(alt_m[0]), float(alt_m[-1]), vp)
    if np.ptp(alt_m) < vp.airborne_height_m:  # the plan's heights: its speeds

        def speed(x):
            return plan.cap(x)

    else:

        def speed(x):
            h = np.interp(x, s_m, alt_m)
            first = x < 0.5 * s_m[-1]
            h_rwy = np.where(first, alt_m[0], alt_m[-1])
            v_air = np.where(first, 1.0, 0.0) * plan._sched(h, alt_m[0], vp.rotate_mps) + np.where(
                first, 0.0, 1.0
            ) * plan._sched(h, alt_m[-1], vp.approach_mps)
            return np.where(h > h_rwy + vp.airborne_height_m, v_air, vp.taxi_mps)

    def limit(x):
        v = np.maximum(speed(np.asarray(x, float)), vp.taxi_mps)
        return np.minimum(vp.lat_accel_mps2 / v**2, vp.max_curvature_1pm)

    return limit


FLIGHT_CORNER_MIN_M = 100.0
"""Least corner-rounding length of an untimed flight [m] (:func:`flight_corner`)."""


def flight_corner(y, alt_m, vp: VehicleParams, corner_m=None):
    """Corner rounding and turn limit of an untimed flight's path (:func:`fit_path`).

    The rounding is the input's short point spacing (10th percentile), within [:data:`FLIGHT_CORNER_MIN_M`,
    ``corner_m`` of the class] (``corner_m`` given: that): a logger's dense path is followed
    within its noise, a waypoint route is rounded as before; the turns are then bounded by the
    bank limit at the speed flown (:func:`turn_curvature`), which widens a waypoint's corner to
    a fly-by turn and a noisy wiggle to what the aircraft can fly.

    Parameters
    ----------
    y : ndarray, shape (N, 3)
        Input points (ENU) [m].
    alt_m : ndarray, shape (N,)
        Their heights [m].
    vp : VehicleParams
    corner_m : float, optional

    Returns
    -------
    (float, callable)
        Corner-rounding length [m] and the curvature limit against chord length.
    """
    y = np.asarray(y, float)
    s_m = np.r_[0.0, np.cumsum(np.linalg.norm(np.diff(y, axis=0), axis=1))]
    return corner_length_m(y, vp, corner_m), turn_curvature(s_m, alt_m, vp)


def corner_length_m(y, vp: VehicleParams, corner_m=None) -> float:
    """Corner-rounding length [m] an untimed path of points ``y`` (N, 3) [m] is fitted with.

    ``corner_m`` when given; for a flight (``vp.phases``) the input's short point spacing
    (10th percentile of the legs that move) within [:data:`FLIGHT_CORNER_MIN_M`,
    ``vp.corner_m``]; otherwise the class's ``vp.corner_m``. The fit's grid is a sixteenth of
    it, so :mod:`imugen.preflight` sizes the truth's memory with it.
    """
    if corner_m is not None:
        return float(corner_m)
    if not vp.phases:
        return float(vp.corner_m)
    seg = np.linalg.norm(np.diff(np.asarray(y, float), axis=0), axis=1)
    moved = seg[seg > 1e-9]
    spacing = float(np.percentile(moved, 10)) if len(moved) else vp.corner_m
    return float(min(vp.corner_m, max(FLIGHT_CORNER_MIN_M, spacing)))
