"""Vehicle classes of the truth: motion models, defaults and physical limits (SI units).

Every field can be overridden per truth (``build_truth(..., vehicle_params={...})``, CLI
``imugen truth --vehicle-param NAME=VALUE``). Roles:

* ``attitude``: ``"thrust"`` (multirotor: differential flatness), ``"ground"`` (heading and pitch of the velocity where the path is plausible,
  else heading from the horizontal velocity bounded by the curvature limit and pitch from the
  road grade; roll zero or the lean of a coordinated turn) or ``"coordinated"`` (aircraft: ground model
  when slow and low, coordinated flight when fast or high).
* speed profile of untimed paths: ``cruise_mps``, ``accel_mps2``, ``lat_accel_mps2``,
  ``jerk_mps3``, ``corner_m`` (corner-rounding length of the polyline).
* ground attitude: ``max_curvature_1pm`` (the heading turns at most ``speed x
  max_curvature``: no turning on the spot), ``heading_smooth_m``, ``heading_smooth_s``
  (Gaussian smoothing of the distance-based heading, used where the attitude does not follow
  the velocity: at least this length, and this time at the route's median moving speed,
  default 0), ``max_pitch_rad`` (bound of the pitch), ``lean`` (bicycle: roll = ``atan(v^2 kappa / g)``), ``max_roll_rad`` (bound of
  that lean), ``grade_bin_m`` (bin of the height-against-distance fit),
  ``grade_smooth_m`` (least smoothing length of that fit: roads and paths change grade over
  vertical curves, not at a GNSS height step; the pitch follows the velocity where the path's
  vertical curvature is within 3 x ``max_pitch_rad / grade_smooth_m`` over this length).
* coordinated flight: ``hold_speed_mps``, ``hold_perp`` (attitude held below these speed and
  perpendicular-force thresholds), ``airborne_speed_mps``, ``airborne_height_m`` (blend from
  ground to flight between 0.8x and 1x this speed, or 0.5x and 1x this height above the
  route's lowest point: a slow glider circling high is flying).
* suspension (ground vehicles without ``lean``, :mod:`imugen.truth.suspension`):
  ``suspension`` (``"rigid"``: the body keeps the path's attitude; ``"damped"``: it rolls and
  pitches on its suspension, a damped second-order response to the lateral and longitudinal
  acceleration), ``roll_gradient_radpmps2``, ``pitch_gradient_radpmps2`` (steady roll and pitch
  per m/s^2; 0 turns that angle off), ``roll_hz``, ``pitch_hz`` (natural frequencies),
  ``roll_damping``, ``pitch_damping`` (damping ratios); a car is ``damped`` by default, every
  other class ``rigid`` (``imugen truth --suspension=rigid|damped``, config
  ``routes.<name>.suspension``), the figures are passenger-car ones (5 deg/g roll, 2 deg/g
  pitch, 1.5 / 1.2 Hz, 0.5 / 0.4), the input is capped at ``max_accel_mps2`` (the tyres'
  limit), and a car's roll limit ``max_roll_rad`` (8 deg) then bounds the suspension roll.
* fit and stops: ``stop_speed_mps``, ``stop_min_s``, ``stop_radius_m``, ``fit_tol_max_m``,
  ``fit_floor_m``.
* plausibility (the truth's pre-write gate, :mod:`imugen.truth.gate`): ``max_speed_mps``,
  ``max_accel_mps2``, ``max_jerk_mps3``, the attitude bounds above and, in flight, ``max_pitch_airborne_rad`` and
  ``max_yaw_rate_airborne_radps`` (default unbounded); on the ground ``max_slip_mps``, the
  body's largest lateral speed (sideways slide) of an untimed path's truth: a car's tyres
  slip a few degrees at most in ordinary driving (2 deg at 50 km/h: 0.5 m/s), a bicycle's
  and a walker's less (0.3 m/s). The jerk limit is per class
  (:data:`JERK_SOURCES`): the class's acceleration limit reached in the shortest rise time
  the vehicle has (its brakes, a step, its thrust vector's rotation), an engineering bound
  checked against published figures where there are some; the comfortable ``jerk_mps3``
  (untimed speed profiles, reversals) stays far below it.
* multirotor (``attitude = "thrust"``, :mod:`imugen.truth.multirotor`): ``mass_kg``,
  ``arm_m``, ``hover_rpm``, ``blades``, ``k_m_m`` (yaw torque per thrust), ``inertia_*_kgm2``,
  ``drag_x_1ps``, ``drag_y_1ps`` (linear rotor drag, 0: none), the limits
  ``max_thrust_to_weight``, ``max_tilt_rad``, ``max_rate_rp_radps``, ``max_rate_yaw_radps``,
  and the yaw: ``yaw_path`` (along the horizontal velocity above ``yaw_speed_mps``, smoothed
  at ``yaw_cutoff_hz``) or the constant ``yaw_rad``.
* flight phases of untimed routes (``phases``, :mod:`imugen.truth.flight`): ``taxi_mps``,
  ``taxi_m``, ``rotate_mps``, ``climb_rate_mps``, ``climb_speed_mps``,
  ``speed_limit_alt_m``, ``cruise_alt_m``, ``descent_angle_rad``, ``approach_mps``,
  ``vertical_accel_mps2``; ``cruise_mps`` is the speed at ``cruise_alt_m`` and
  ``accel_mps2`` that of the take-off roll and of the braking after touchdown.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields, replace

from imugen.core.errors import InputError


@dataclass(frozen=True)
class VehicleParams:
    """Model and limits of a vehicle class (SI units, radians); see the module docstring."""

    attitude: str
    cruise_mps: float
    accel_mps2: float
    lat_accel_mps2: float
    jerk_mps3: float
    corner_m: float
    max_curvature_1pm: float
    max_pitch_rad: float
    max_roll_rad: float = 0.0
    lean: bool = False
    grade_bin_m: float = 0.5
    heading_smooth_m: float = 2.0
    heading_smooth_s: float = 0.0
    grade_smooth_m: float = 50.0
    max_speed_mps: float = 70.0
    max_accel_mps2: float = 8.0
    max_jerk_mps3: float = 30.0
    max_slip_mps: float = 0.5
    airborne_speed_mps: float = math.inf
    airborne_height_m: float = math.inf
    hold_speed_mps: tuple = (0.2, 1.0)
    hold_perp: tuple = (0.05, 0.1)  # |r_perp| thresholds [m/s^2] of coordinated flight
    stop_speed_mps: float = 0.2
    stop_min_s: float = 2.0
    stop_radius_m: float = 1.0
    fit_tol_max_m: float = 5.0
    fit_floor_m: float = 1e-3
    max_pitch_airborne_rad: float = math.inf
    max_yaw_rate_airborne_radps: float = math.inf
    phases: bool = False
    taxi_mps: float = 8.0
    taxi_m: float = 1000.0
    rotate_mps: float = 75.0
    climb_rate_mps: float = 10.16
    climb_speed_mps: float = 128.6
    speed_limit_alt_m: float = 3048.0
    cruise_alt_m: float = 10668.0
    descent_angle_rad: float = 0.0524
    approach_mps: float = 70.0
    vertical_accel_mps2: float = 1.0
    mass_kg: float = 1.0
    arm_m: float = 0.225
    hover_rpm: float = 5500.0
    blades: float = 2.0
    k_m_m: float = 0.016
    inertia_x_kgm2: float = 0.011
    inertia_y_kgm2: float = 0.011
    inertia_z_kgm2: float = 0.021
    drag_x_1ps: float = 0.0
    drag_y_1ps: float = 0.0
    max_thrust_to_weight: float = 2.5
    max_tilt_rad: float = 1.05
    max_rate_rp_radps: float = 6.0
    max_rate_yaw_radps: float = 3.0
    yaw_path: bool = True
    yaw_rad: float = 0.0
    yaw_speed_mps: float = 0.5
    yaw_cutoff_hz: float = 1.0
    suspension: str = "rigid"
    roll_gradient_radpmps2: float = math.radians(5.0) / 9.80665
    pitch_gradient_radpmps2: float = math.radians(2.0) / 9.80665
    roll_hz: float = 1.5
    pitch_hz: float = 1.2
    roll_damping: float = 0.5
    pitch_damping: float = 0.4


VEHICLES = {
    # car: 50 km/h cruise, 0.2 g longitudinal, 0.3 g lateral, 1 m/s^3 comfort jerk; turning
    # radius >= 5 m; road grade within +-20 deg (steepest public roads ~35 %), changing over
    # vertical curves of 50 m at least;
    # plausible up to 250 km/h and 0.8 g; on its suspension by default (suspension="damped"):
    # the body rolls and pitches on it (imugen.truth.suspension: 5 deg/g roll, 2 deg/g
    # pitch), roll plausible to 8 deg (0.8 g x 5 deg/g with the step response's overshoot,
    # and a margin)
    "car": VehicleParams(
        "ground",
        13.9,
        2.0,
        3.0,
        1.0,
        10.0,
        max_curvature_1pm=0.2,
        max_pitch_rad=0.35,
        max_roll_rad=0.14,
        max_jerk_mps3=30.0,
        suspension="damped",
    ),
    # bicycle: 20 km/h, 0.1 g, 0.25 g lateral (14 deg lean), radius >= 3 m, lean <= 45 deg
    "bicycle": VehicleParams(
        "ground",
        5.5,
        1.0,
        2.5,
        1.0,
        3.0,
        max_curvature_1pm=1.0 / 3.0,
        max_pitch_rad=0.35,
        max_roll_rad=0.785,
        lean=True,
        heading_smooth_m=3.0,
        grade_smooth_m=10.0,
        max_speed_mps=25.0,
        max_accel_mps2=5.0,
        max_slip_mps=0.3,
        max_jerk_mps3=15.0,
    ),
    # pedestrian: 5 km/h, gentle accelerations, corners rounded over ~1 m; turns on a 0.5 m
    # radius at least; slopes up to 35 deg (stairs); plausible up to a 12 m/s sprint
    "pedestrian": VehicleParams(
        "ground",
        1.4,
        0.5,
        0.5,
        1.0,
        1.0,
        max_curvature_1pm=2.0,
        max_pitch_rad=0.61,
        heading_smooth_m=0.5,
        grade_smooth_m=5.0,
        max_speed_mps=12.0,
        max_accel_mps2=5.0,
        max_slip_mps=0.3,
        max_jerk_mps3=10.0,
        hold_speed_mps=(0.1, 0.5),
        stop_speed_mps=0.1,
        stop_radius_m=1.0,
    ),
    # aircraft: 70 m/s, 0.3 g longitudinal, 0.5 g lateral (~27 deg bank), 2 m/s^3; on the
    # ground (below 25 m/s) a taxiing vehicle: radius >= 10 m, pitch within 5 deg
    "aircraft": VehicleParams(
        "coordinated",
        70.0,
        3.0,
        5.0,
        2.0,
        300.0,
        max_curvature_1pm=0.1,
        max_pitch_rad=0.087,
        heading_smooth_m=5.0,
        grade_smooth_m=50.0,
        max_roll_rad=1.05,
        max_speed_mps=300.0,
        max_accel_mps2=30.0,
        max_jerk_mps3=30.0,
        airborne_speed_mps=25.0,
        airborne_height_m=40.0,
        hold_speed_mps=(0.5, 2.0),
        hold_perp=(0.3, 1.0),
        stop_speed_mps=0.5,
        stop_radius_m=3.0,
        fit_tol_max_m=20.0,
    ),
    # airliner (A320 / B737-800 class), flown in phases when untimed (imugen.truth.flight):
    # taxi 8 m/s (~15 kt) for 1 km at each end; take-off roll at 2 m/s^2 (0.2 g; ~1.4 km to
    # rotation) to Vr 75 m/s (146 kt); climb 2,000 ft/min (10.16 m/s) with 250 kt
    # (128.6 m/s) at FL100 (the speed limit below 10,000 ft, 14 CFR 91.117) and cruise at
    # FL350 (10,668 m) at Mach 0.80 (236 m/s TAS, 850 km/h); descent on a 3 deg path (the
    # glide slope; 3 NM per 1,000 ft) to Vapp 70 m/s (136 kt), braking at 2 m/s^2; changes
    # of flight-path angle at <= 1 m/s^2 (0.1 g) vertical; turns at <= 25 deg bank (4.57
    # m/s^2 lateral), plausible up to 35 deg bank, 15 deg pitch and 5 deg/s of turn (a
    # rate-one turn is 3 deg/s); waypoint corners rounded over 2 km (a 30 deg
    # waypoint is then turned at ~22 deg bank at 214 m/s, cut by ~330 m like a fly-by turn); the ground
    # model (a taxiing vehicle) below 80 m/s and 20 m above the runway, flight above 100 m/s
    # or 40 m
    "airliner": VehicleParams(
        "coordinated",
        236.0,
        2.0,
        4.57,
        1.0,
        2_000.0,
        max_curvature_1pm=0.05,
        max_pitch_rad=0.087,
        heading_smooth_m=5.0,
        grade_smooth_m=50.0,
        max_roll_rad=0.61,
        max_pitch_airborne_rad=0.26,
        max_yaw_rate_airborne_radps=0.087,
        max_speed_mps=300.0,
        max_accel_mps2=30.0,
        max_jerk_mps3=30.0,
        airborne_speed_mps=100.0,
        airborne_height_m=40.0,
        hold_speed_mps=(0.5, 2.0),
        hold_perp=(0.3, 1.0),
        stop_speed_mps=0.5,
        stop_radius_m=3.0,
        fit_tol_max_m=20.0,
        phases=True,
    ),
    # multirotor: a small quadrotor (1 kg, 450 mm class X frame, 5500 rpm hover on two-blade
    # props); untimed paths flown at 5 m/s, 2 m/s^2, corners over 1 m; plausible up to 20 m/s,
    # 25 m/s^2, 60 deg tilt, 6 rad/s roll/pitch and 3 rad/s yaw rate, T/W 2.5
    "multirotor": VehicleParams(
        "thrust",
        5.0,
        2.0,
        3.0,
        5.0,
        1.0,
        max_curvature_1pm=2.0,
        max_pitch_rad=1.05,
        max_roll_rad=1.05,
        heading_smooth_m=0.5,
        grade_smooth_m=5.0,
        max_speed_mps=20.0,
        max_accel_mps2=25.0,
        max_jerk_mps3=150.0,
        hold_speed_mps=(0.1, 0.5),
        stop_speed_mps=0.1,
        stop_radius_m=0.5,
        fit_tol_max_m=2.0,
    ),
}


JERK_SOURCES = {
    "car": "30 m/s^3: the 0.8 g limit reached in 0.27 s of brake build-up, an emergency stop "
    "(engineering bound); emergency braking is classed from 14-21 m/s^3 at 50-80 km/h "
    "(Sensors 21(4):1427, 2021, table 8), UN R157's reference driver brakes at 1.2 g/s "
    "(11.8 m/s^3) and AEB at 1.44 g/s (14.1 m/s^3); comfort is ~1 m/s^3",
    "bicycle": "15 m/s^3: its 5 m/s^2 limit (a hard stop on a dry road) reached in 0.33 s of "
    "braking (engineering bound)",
    "pedestrian": "10 m/s^3: its 5 m/s^2 limit (a sprint start) reached within one step, "
    "0.5 s (engineering bound; the truth is the body's path, not its gait)",
    "aircraft": "30 m/s^3: its 3 g limit (a pull-up) reached in 1 s (engineering bound)",
    "airliner": "30 m/s^3: its 3 g limit (a firm touchdown, the flare) reached in 1 s "
    "(engineering bound)",
    "multirotor": "150 m/s^3: its 25 m/s^2 thrust acceleration turned at its 6 rad/s "
    "roll/pitch rate limit (engineering bound)",
}
"""The per-class jerk limit of the gate (``max_jerk_mps3``): figure, derivation and source."""

ROLL_GRADIENT_URL = "https://archit-rstg.medium.com/on-a-roll-roll-rates-in-a-vehicle-75de3650930"
PITCH_EXERCISE_URL = (
    "https://askfilo.com/user-question-answers-smart-solutions/"
    "question-five-a-vehicle-has-the-following-data-parameter-3430363734353530"
)
SUSPENSION_SOURCES = {
    "roll_gradient_radpmps2": "5 deg/g: typical roll gradients 4.0 deg/g for sports cars, 5.0 "
    "for small and 7.0 for large passenger cars (A. Rastogi, 'On a Roll: Roll rates in a "
    f"Vehicle', 2020, {ROLL_GRADIENT_URL}); Gillespie and Milliken not reached (unverified "
    "against the books); a calculator site's 0.5-1.5 deg/g (stone-calculator.com) is a race-car "
    "range",
    "pitch_gradient_radpmps2": "2 deg/g, braking and accelerating alike: no published typical "
    "figure found; a textbook braking exercise (1,140 kg, springs 11.5 / 14 N/mm, wheelbase "
    f"2.5 m, CG 0.58 m; {PITCH_EXERCISE_URL}) gives 3.4 deg at 0.8 g, about 4 deg/g, with no "
    "anti-dive geometry (our computation from its data, per-spring rates assumed), which "
    "anti-dive and stiffer springs lower; NVIDIA DriveWorks' suspension model takes separate "
    "accelerating and braking gradients without typical values",
    "roll_hz": "1.5 Hz (pitch_hz 1.2 Hz): body modes of passenger cars 1-1.5 Hz (Audi A6 "
    "self-study programme 242)",
    "roll_damping": "0.5 (pitch_damping 0.4): 0.2-0.6 of critical (NVIDIA DriveWorks egomotion "
    "torsionalSpringPitchDampingRatio, default 0.6); 0.2-0.5 (Unreal Engine Chaos Vehicles, "
    "FSuspensionUtility::ComputeDamping)",
}
"""The car's suspension defaults (:class:`VehicleParams` ``roll_gradient_radpmps2`` ...):
figure and published source, or what is unverified."""

_MAY_BE_ZERO = (
    "max_roll_rad",
    "heading_smooth_s",
    "drag_x_1ps",
    "drag_y_1ps",
    "yaw_rad",
    "roll_gradient_radpmps2",
    "pitch_gradient_radpmps2",
)
SUSPENSIONS = ("rigid", "damped")
"""Suspension models of ground vehicles (:mod:`imugen.truth.suspension`)."""


def vehicle_params(vehicle: str, overrides: dict | None = None) -> VehicleParams:
    """The vehicle class ``vehicle`` with fields replaced by ``overrides`` (validated)."""
    if vehicle not in VEHICLES:
        raise InputError("--vehicle", f"unknown vehicle {vehicle!r}; one of {sorted(VEHICLES)}")
    vp = VEHICLES[vehicle]
    if not overrides:
        return vp
    known = {f.name: f for f in fields(VehicleParams)}
    new = {}
    for name, value in overrides.items():
        if name not in known or name == "attitude":
            raise InputError("--vehicle-param", f"unknown vehicle parameter {name!r}")
        old = getattr(vp, name)
        try:
            if isinstance(old, tuple):
                value = tuple(float(x) for x in value)
                ok = len(value) == 2 and 0 <= value[0] < value[1]
            elif name == "suspension":
                ok = value in SUSPENSIONS
            elif isinstance(old, bool):
                text = str(value).lower()
                ok = text in ("true", "false", "1", "0")
                value = text in ("true", "1")
            else:
                value = float(value)
                ok = math.isfinite(value) and (value > 0 or (value == 0 and name in _MAY_BE_ZERO))
        except (TypeError, ValueError):
            ok = False
        if not ok:
            raise InputError("--vehicle-param", f"{name}: invalid value {value!r}")
        new[name] = value
    vp = replace(vp, **new)
    if vp.lean and not vp.max_roll_rad > 0:
        raise InputError("--vehicle-param", "a leaning vehicle needs max_roll_rad > 0")
    return vp


def has_suspension(vp: VehicleParams) -> bool:
    """Whether the ground attitude of ``vp`` rolls and pitches on a suspension."""
    return (
        vp.suspension == "damped"
        and vp.attitude != "thrust"
        and not vp.lean
        and (vp.roll_gradient_radpmps2 != 0.0 or vp.pitch_gradient_radpmps2 != 0.0)
    )
