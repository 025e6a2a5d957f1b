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
least ``stop_min_s`` whose horizontal positions (3-D for aircraft) stay within
``stop_radius_m`` (or 3x the noise) of their median and barely move overall, and intervals
between sparse fixes that barely moved (see :func:`imugen.truth.fit._find_stops`), are *stops*: the spline is
constrained to be exactly constant there (its B-spline coefficients over the stop are tied),
and joins it through a triple knot, so velocity and acceleration vanish at the stop's edges
(the jerk is free: a vehicle braking within one interval of sparse fixes) and the stop is a
real stop; next to an abrupt stop the smoothing is relaxed within the vehicle's limits
(:func:`imugen.truth.fit._abrupt_stops`).

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

Routes of any length (``earth="geodetic"``; ``auto`` beyond 64 km from the origin)
-----------------------------------------------------------------------------------
The motion is fitted as above in the origin's ENU coordinates (exact Cartesian at any range)
and expressed in ECEF by :class:`imugen.truth.build.EcefMotion`; the attitude below is built
in the local level at the vehicle and expressed in ECEF (``C_eb = C_el C_lb``); the table's
position, velocity and quaternion are then ECEF, with ``lat_deg, lon_deg, alt_m`` columns
(:mod:`imugen.tables.truth`).

Attitude (per vehicle class, :mod:`imugen.truth.vehicles`)
----------------------------------------------------------
*Ground vehicles* (car, bicycle, pedestrian; an aircraft below its take-off speed): where
the path is plausible for the vehicle, heading and pitch are those of the velocity in the
local level at the vehicle, so the body velocity is along x (the non-holonomic constraint);
near stops, turns tighter than ``max_curvature_1pm`` and height wiggles of the fit, the
attitude is a function of the horizontal distance travelled ``s``, blended in by weights of
``s`` (:class:`imugen.truth.attitude.GroundAttitude`): heading ``Psi(s)`` along the horizontal
velocity, its slope bounded by ``max_curvature_1pm`` (the yaw rate ``Psi'(s) v_h`` never
exceeds speed x max curvature: no turning on the spot; a reversal through a stop is a U-turn
on the vehicle's radius, never a branch flip); pitch from the grade of the height profile
against distance, smoothed at the height noise and over at least ``grade_smooth_m``,
bounded by ``max_pitch_rad``; roll zero, or for a bicycle the lean of a coordinated turn.
Where the vehicle does not move, ``s`` and the whole attitude are exactly constant. Rates
are the Euler-angle rates plus the transport rate of the local level, exact.

*Aircraft in flight*: body x along the velocity, body z along the specific force's component
perpendicular to it (coordinated turn, no sideslip; loops and vertical flight work because
nothing is measured in Euler angles); rates analytic from velocity, acceleration and jerk;
held below ``hold_speed_mps`` by ``q_hold Exp(w Log(q_hold^-1 q_target))``. Between the
ground (slow and low) and flight (fast, or high above the route's lowest point, in ellipsoidal
height: see ``airborne_speed_mps``, ``airborne_height_m``) the attitudes are blended the same
way, with the exact rate of the blend; ground limits are checked where the ground attitude is
used alone. Untimed ``airliner`` routes are flown in phases (:mod:`imugen.truth.flight`).

*Multirotors* (``vehicle: multirotor``): attitude by differential flatness (thrust along body
z, yaw along the path or constant, optional linear rotor drag) and rotor speeds from thrust and
the hover figures (:mod:`imugen.truth.multirotor`).

*Pose trajectories* (an ENU table with the attitude columns ``q_w .. q_z``: TUM, EuRoC ground
truth, pose CSV, ROS 2 bags): the given attitude, fitted jointly with the position on
SO(3) x R^3 (:mod:`imugen.truth.pose`), whatever the vehicle class (which then only sets the
plausibility limits).

Every truth carries a plausibility report (:mod:`imugen.truth.report`).

Ideal IMU (per :mod:`imugen.core.earth` and the issue-3 spec)
---------------------------------------------------------
``omega_ib_b = omega_nb_b + C_nb^T Omega_n``; ``f_b = C_nb^T (a_n + 2 Omega_n x v_n - g_n(p_n))``;
``dtheta_k = Log(C_nb(t_k)^T Exp(Omega_n dt) C_nb(t_k+1))``;
``dv_k = C_nb(t_k)^T [v_I(t_k+1) - v_I(t_k) - int A(tau) G_n(p_n) dtau]`` with the
gravitation integral by 4-node Gauss-Legendre quadrature on the continuous truth position
(exact in ``flat``: ``dv_k = C_nb(t_k)^T (v_k+1 - v_k - g_n dt)``).
"""

from __future__ import annotations

import importlib

_LAZY = {
    "CHUNK": "build",
    "BuildOptions": "build",
    "build_motion": "build",
    "build_truth": "build",
    "enu_table": "build",
    "earth_budget": "budget",
    "TimedMotion": "fit",
    "fit_path": "fit",
    "fit_timed": "fit",
    "noise_estimate": "fit",
    "PathMotion": "profile",
    "speed_profile": "profile",
    "read_enu": "stage",
    "run": "stage",
    "TruthOptions": "options",
    "VEHICLES": "vehicles",
    "VehicleParams": "vehicles",
    "PoseSettings": "pose",
    "fit_poses": "pose",
}
"""Names of the package's modules, loaded on first use: ``imugen.truth.options`` (what the
command line's parser reads) loads no numerical code."""

__all__ = sorted(_LAZY)


def __getattr__(name):
    if name in _LAZY:
        value = getattr(importlib.import_module(f"{__name__}.{_LAZY[name]}"), name)
        globals()[name] = value
        return value
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def __dir__():
    return sorted({*globals(), *_LAZY})
