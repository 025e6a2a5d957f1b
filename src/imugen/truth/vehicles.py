"""Vehicle classes of the truth: defaults and physical limits (SI units).

See :mod:`imugen.truth` for the role of each field.
"""

from __future__ import annotations

from dataclasses import dataclass


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
