"""The filter's switches and thresholds (:class:`Options`) and their compiled view."""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from imugen.aid.filter.state import StateLayout


class Switches(NamedTuple):
    """What the compiled kernel reads of :class:`Options` (the measurement switches and
    thresholds, SI; the state blocks come from :class:`~imugen.aid.filter.state.StateLayout`)."""

    nhc: bool
    nhc_sd_lat: float
    nhc_sd_vert: float
    nhc_pitch_sd: float
    nhc_lever_m: tuple[float, float, float]
    zupt: bool
    zupt_sd: float
    zupt_gyro: float
    zupt_accel: float
    zupt_speed: float
    zupt_min_still: float
    zupt_speed_conf: float
    zupt_crawl: float
    nhc_gate: float
    nhc_speed_ratio: float
    gate: float
    use_velocity: bool
    latency: bool
    odometer: bool
    baro: bool


@dataclass(frozen=True)
class Options:
    """Filter switches and thresholds (SI).

    ``scale_factors``: estimate gyro/accel scale factors; ``gnss_bias``: model the receiver's
    Gauss-Markov position bias as states (needs ``gnss_bias_sd_m``, ``gnss_bias_tau_s``,
    ``gnss_white_m`` per axis); ``nhc``: non-holonomic constraint (cars); ``zupt``: zero-velocity
    updates at detected stops; ``use_velocity``: GNSS velocity updates; ``latency``:
    compensate the GNSS latency to first order; ``gate_sigma``: innovation gate (0: off);
    ``odometer``: odometer distance updates (needs
    :class:`~imugen.aid.companions.CompanionEpochs`), with an odometer scale-factor state if
    ``odo_scale_state`` (else the noise is inflated by the scale factor's prior); ``baro``:
    barometric height updates with a drift state.
    ``nhc_sd_mps``: residual slip of the vehicle reference point, 1-sigma of its lateral and
    vertical body speed [m/s] (a pair, or one number for both; the simulator's vehicles have
    none, :mod:`imugen.aid.stage` takes the truth's plausibility report); the NHC variance adds
    the lever arm's and the constraint's second-order terms (:mod:`imugen.aid.filter.nhc`).
    ``nhc_pitch_sd_rad``: 1-sigma of the body's pitch on its suspension relative to its
    velocity (a car's dive and squat, ``theta_s``): the vertical row adds ``(u sd)^2`` at the
    estimated forward speed ``u``, the body's vertical speed ``-u sin theta_s`` (a roll on the
    suspension moves no velocity into y); 0: a rigid body (:mod:`imugen.aid.stage` sets a
    car's from its class's pitch gradient, :func:`imugen.aid.stage.suspension_pitch_sd`).
    ``nhc_lever_arm_m``: nominal IMU position from the vehicle reference point (vehicle
    axes, m) where NHC applies; ``nhc_misalignment_sd_rad``: (pitch, yaw) 1-sigma of the
    unknown mounting misalignment: when not zero (and NHC on) the two angles are estimated as
    random constants with that prior (:attr:`mounting`); ``nhc_lever_arm_sd_m``: 1-sigma of
    the lever arm about its nominal, per vehicle axis [m]: when not zero (and NHC on) the
    lever arm is three states (:attr:`lever_states`), used by NHC and the odometer.
    ``gyro_cross_coupling``: estimate the gyro's six cross-coupling elements (random
    constants, prior the grade's sigma; they then leave the process noise and the
    accelerometer bias prior, :mod:`imugen.aid.filter.tuning`).
    ``accel_cross_coupling``: likewise the accelerometer's six (its error on gravity,
    ``g0 cc[:, 2]``, then leaves the accelerometer bias prior): as motion noise beside the
    gyro's states it left tilt NEES/dof 3.4 (consumer, every term drawn), 1.2-1.5 as states.
    ``nhc_gate_sigma``: NHC's own innovation gate (the slip bursts of an implausible path,
    which white noise of the RMS slip cannot cover; 0: off); ``nhc_speed_ratio``: NHC only
    while ``|v|^2 > ratio^2 tr(P_vv)`` (its attitude rows linearize at the estimated
    velocity: at a stop inside an outage they turned the heading towards the velocity
    error; 0: always).
    ``zupt_min_still_s``: the IMU still at least this long before a ZUPT; ``zupt_speed_conf``:
    without a fix the filter's speed plus this many of its sigmas must pass the speed gate
    (a cruise is as still to the IMU as a stop); ``zupt_crawl_mps``: the crawl a detector
    cannot exclude, ``crawl^2 / 3`` added to the ZUPT variance per axis (velocity NEES at
    ZUPT epochs p95 3.2-4.0 with 0, 1.9-2.2 with 0.2 m/s). Zero for each of these five gives
    the former rules (outputs bit-identical).
    """

    scale_factors: bool = False
    gnss_bias: bool = True
    nhc: bool = False
    nhc_sd_mps: tuple = (0.0, 0.0)
    nhc_pitch_sd_rad: float = 0.0
    zupt: bool = False
    zupt_sd_mps: float = 0.02
    zupt_gyro_radps: float = 0.02
    zupt_accel_mps2: float = 0.3
    zupt_speed_mps: float = 0.2
    gate_sigma: float = 0.0
    use_velocity: bool = True
    latency: bool = True
    odometer: bool = False
    odo_scale_state: bool = True
    baro: bool = False
    nhc_lever_arm_m: tuple = (0.0, 0.0, 0.0)
    nhc_misalignment_sd_rad: tuple = (0.0, 0.0)
    nhc_lever_arm_sd_m: tuple = (0.0, 0.0, 0.0)
    gyro_cross_coupling: bool = True
    accel_cross_coupling: bool = True
    nhc_gate_sigma: float = 3.0
    nhc_speed_ratio: float = 5.0
    zupt_min_still_s: float = 1.0
    zupt_speed_conf: float = 1.0
    zupt_crawl_mps: float = 0.2

    @property
    def odo_sf(self) -> bool:
        """The odometer scale factor is a state."""
        return self.odometer and self.odo_scale_state

    @property
    def lever_states(self) -> bool:
        """Whether the NHC lever arm's departure from its nominal is a state."""
        return bool(self.nhc) and any(x > 0 for x in self.nhc_lever_arm_sd_m)

    @property
    def mounting(self) -> bool:
        """Whether the IMU's pitch and yaw misalignment from the vehicle are states."""
        return bool(self.nhc) and any(x > 0 for x in self.nhc_misalignment_sd_rad)

    @property
    def layout(self) -> StateLayout:
        """The error state these options switch on."""
        return StateLayout.of(
            scale_factors=self.scale_factors, gnss_bias=self.gnss_bias, odo_sf=self.odo_sf,
            baro=self.baro, mounting=self.mounting, gyro_cc=self.gyro_cross_coupling,
            odometer=self.odometer, lever=self.lever_states, accel_cc=self.accel_cross_coupling,
        )  # fmt: skip

    @property
    def n(self) -> int:
        """Size of the error state."""
        return self.layout.n

    def names(self) -> list[str]:
        """Names of the error-state components."""
        return self.layout.names

    def switches(self) -> Switches:
        """The kernel's view (every number a Python float or bool: one compiled signature)."""
        lat, vert = (float(x) for x in np.broadcast_to(np.asarray(self.nhc_sd_mps, float), (2,)))
        lx, ly, lz = (float(x) for x in self.nhc_lever_arm_m)
        return Switches(
            nhc=bool(self.nhc), nhc_sd_lat=lat, nhc_sd_vert=vert,
            nhc_pitch_sd=float(self.nhc_pitch_sd_rad), nhc_lever_m=(lx, ly, lz),
            zupt=bool(self.zupt), zupt_sd=float(self.zupt_sd_mps),
            zupt_gyro=float(self.zupt_gyro_radps), zupt_accel=float(self.zupt_accel_mps2),
            zupt_speed=float(self.zupt_speed_mps), zupt_min_still=float(self.zupt_min_still_s),
            zupt_speed_conf=float(self.zupt_speed_conf), zupt_crawl=float(self.zupt_crawl_mps),
            nhc_gate=float(self.nhc_gate_sigma), nhc_speed_ratio=float(self.nhc_speed_ratio),
            gate=float(self.gate_sigma),
            use_velocity=bool(self.use_velocity), latency=bool(self.latency),
            odometer=bool(self.odometer), baro=bool(self.baro),
        )  # fmt: skip
