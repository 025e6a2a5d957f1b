"""Loosely-coupled GNSS/INS: a batched error-state Kalman filter on the project's increments.

Frames, conventions and the strapdown are those of :mod:`imugen.navigate.mechanize` (n = Earth-fixed
ENU of the route origin in ``flat`` and ``wgs84``, ECEF in ``geodetic``: the same rotating-frame
step with ``Omega = (0, 0, Omega)`` and no transport rate); one step per IMU interval:
``C_{k+1} = Exp(-Omega dt) C_k Exp(dtheta)``,
``A(dt) (v_{k+1} + W r_{k+1}) = v_k + W r_k + C_k dv + dt/2 (A G_{k+1} + G_k)`` (solved with the
kernel's ``(I + dt/2 W)^-1``; in ``flat`` exactly ``v_{k+1} = v_k + C_k dv + g dt``) and the
trapezoid for position. Increments are corrected with the estimated biases and scale factors,
``dtheta_hat = (dtheta - b_g dt) / (1 + s_g)`` (likewise ``dv``).

Error state (estimate minus truth), ``n = 15 (+3) (+6) (+1) (+1) (+2) (+6) (+2)``
    ``dp, dv`` [m, m/s] in n; ``psi`` [rad] with ``C_hat = Exp(psi) C``; gyro and accelerometer
    bias errors; optionally the GNSS receiver's Gauss-Markov position bias (E, N, U), then
    gyro and accelerometer scale-factor errors, then the odometer scale factor and the
    barometer drift (companions), then the IMU's pitch and yaw misalignment from the vehicle
    (constants, NHC only), then the gyro's six cross-coupling elements (constants,
    ``Options.gyro_cross_coupling``; ``psi' = ... - C cc omega``), then the odometer's tick
    residuals at the start and end of its window [m] (odometer on). Continuous model
    ``dp' = dv``; ``dv' = -[f_n x] psi - C (db_a + diag(f) ds_a) - 2 Omega x dv + Gamma dp``;
    ``psi' = -Omega x psi - C (db_g + diag(omega) ds_g)``; biases random walks; GNSS bias
    first-order Gauss-Markov. The transition over one GNSS interval ``T`` uses the integrals
    accumulated by the strapdown (``int C dt``, ``int C f dt``, ``int C diag(f) dt``, ``int C
    diag(omega) dt``), second order in ``T`` for the position rows; ``Gamma`` is the gravity
    gradient ``g/R diag(-1, -1, 2)`` (``wgs84``; ``g/R (3 u u^T - I)`` with ``u`` the geocentric
    vertical at the vehicle in ``geodetic``).

Process noise, from the grade's full error model (:meth:`Tuning.from_grade`; every term
    :mod:`imugen.sensors.model` injects is a state, in a prior, or in ``Q``):
    * white noise: ``N_g^2 T`` (attitude), ``N_a^2 T`` (velocity, with ``T^3/3``, ``T^2/2``
      into position);
    * turn-on bias and bias instability: bias states, prior ``sqrt(b_on^2 + sigma_GM^2)``,
      random walk ``2 sigma_GM^2 / tau + K^2`` (GM growth plus rate random walk);
    * static error on gravity of an uncalibrated grade (a constant bias while the vehicle is
      level): gyro ``sigma_G g0``, accelerometer ``sigma_cc g0`` (x, y) and ``sigma_s g0`` (z)
      added to the bias priors (the z part left to the scale-factor state when estimated);
    * scale factor and cross-coupling of the gyro, per interval with the corrected angle
      ``t`` (body): the error ``E t`` along the rotation accumulates with the turned angle
      (a car's heading error ``s_z Theta``) and is coherent over a turn, so it enters as
      ``c sum_i (t_i/|t|)^2 v_i`` (``v_i = s_i^2 t_i^2 + cc_i^2 (|t|^2 - t_i^2)``,
      ``c = max(1, tau / T)``, ``tau`` :data:`MOTION_CORR_S`) on the rotation axis; across
      the rotation the error integrates to a bounded vector turning with the body (``(R(Theta)
      - I) u``, ``|u| = |cc|``): a body-fixed tilt, which the filter takes for an
      accelerometer bias ``g x u`` (``g0 sigma_cc`` added to the x, y accelerometer bias
      priors), the rest entering uncorrelated per interval, ``(sum v_i - v_par) / 2`` per
      axis. No process noise stands for that tilt: modelled as coherent noise, the filter
      forgets the tilt/bias separation at every turn (consistent, NEES 1.3 at tau 5 s, but
      the consumer's 30 s outage drift grows from 5 m to 46 m); as this bounded noise,
      position stays consistent but tilt and bias NEES are 3-8 (consumer, industrial). The
      cross-coupling states
      (``Options.gyro_cross_coupling``) model it exactly: the cross-coupling then leaves
      ``Q`` and the bias prior;
    * gyro g-sensitivity on the kinematic acceleration (``d`` = integrated ``f`` plus
      gravitation, body), coherent over a turn like the scale factor: ``c sum_i
      sigma_G,i^2 |d|^2 / 3`` per axis per interval;
    * accelerometer scale factor and cross-coupling on ``d``: ``c (s_i^2 d_i^2 + cc_i^2
      (|d|^2 - d_i^2))`` per body axis, rotated to n, into velocity and position;
    * quantization with residual carry: a bounded error of variance ``(q dt)^2 / 12`` on the
      integrated angle and velocity (2e-5 rad, 3e-4 m/s for the consumer grade), not a random
      walk, below the GNSS noise: not modelled; temperature terms (only with a temperature
      profile) and vibration (a real motion of the case, zero mean) are not modelled either.
    Scale factors as states (``Options.scale_factors``) take the ``s_i`` terms out of ``Q``.

Measurements, at each GNSS epoch (sequential scalar updates, per-axis variances)
    * GNSS position of the antenna ``p + C l_b (+ b_gnss)`` and velocity ``v + C (omega x l_b)``
      taken back to the fix's time of validity (``- v L + a L^2 / 2`` and ``- a L``, ``a`` the
      acceleration of the last IMU interval, ``L`` the latency). With GNSS bias states, the reported sigma is split between the
      white part (``R``) and the modelled bias in the tuning's proportions; without them ``R``
      is the reported variance.
    * NHC (cars): lateral and vertical velocity of the vehicle reference point zero in the
      vehicle frame ``v``: ``(R (C^T v - omega x l))_{y,z} = 0`` (the whole body vector
      rotated: its x part, ``-(omega x l)_x``, enters the y row through the mounting yaw),
      ``l`` the IMU's lever arm from that point (body axes): the nominal
      ``nhc_lever_arm_m`` (the filter does not know the drawn one, :mod:`imugen.sensors.mounting`)
      plus, with ``nhc_lever_arm_sd_m`` set, three random-constant states (prior that sigma
      plus the misalignment's rotation of the nominal, ``[l x] theta``). A constant lever-arm
      error is no white noise: taken as ``(omega x sd_l)^2`` it averaged down over each turn
      (mounting NEES 20, pitch z^2 166 against 60). The states' Jacobian ``-(r x omega)``
      (``r`` the vehicle row in body axes) keeps only the rate components above 15.8 times
      their noise: at the noisy rate it correlates with the innovation's own noise and pulls
      the lever arm to zero (errors in variables: 0.5 m -> 0.1 m in 25 s of straight road).
      The rate's error enters ``r . (dw x l) = dw . (l x r)``: the gyro-bias error as a
      sensitivity, the extrapolated rate's white noise (``2.5 N_g^2 / dt`` per axis: the two
      intervals' means weighted 1.5 and -0.5) as variance; the Earth rate's part, ``7e-5
      |l|`` m/s, is left out. The variance is what is uncertain in that zero, per component:
      the vehicle's own residual slip ``nhc_sd_mps`` (lateral, vertical; none for the
      simulator's vehicles, whose body velocity has no y, z component: 4e-9 m/s RMS, the
      truth's plausibility report), the rate's noise above, plus the constraint's second-order
      error, state-dependent: with ``psi``, ``dv`` in vehicle axes, ``v_b,hat - v_b = ... -
      psi x dv + u/2 psi psi_x``, so row y has ``var(u/2 psi_y psi_x - psi_z dv_x + psi_x
      dv_z)`` from ``P`` (Gaussian products, ``var(a b) = s_a^2 s_b^2 + s_ab^2``), likewise
      row z; 1e-3 m/s after a moving alignment (tilt 1 deg, 14 m/s), 1e-5 m/s converged.
      Without that term an exact constraint is overconfident after the alignment (NEES 130-200
      at the first epoch, at 3e-5 m/s); a constant noise instead (the former 0.1 m/s, or even
      1e-3 m/s) over-covers the two attitude directions NHC fixes (NEES 0.3 per direction
      where 1 is due, measured in P's eigenbasis, car rectangle of tests/aid/test_companions.py).
      ``R`` is the nominal mounting (identity), or, with ``nhc_misalignment_sd_rad`` set,
      ``Rz(yaw) Ry(-pitch)`` of two more error states, the IMU's pitch and yaw from the vehicle
      (random constants with that prior sigma): a misaligned IMU driving straight at ``u`` sees
      ``v_b = u (1, -yaw, -pitch)``, a bias no white NHC noise can cover (measured: NEES 80-280
      against a bound of 11 on a car scene with the noise inflated by ``u sd``). NHC observes
      the direction of the vehicle's forward axis in IMU axes only, so the two states converge
      to its angles (:func:`imugen.sensors.mounting.forward_axis_angles`), not to the roll-dependent
      Euler pitch and yaw of the labels (they differ by ``roll x yaw``).
    * Odometer (marked epochs, :class:`CompanionEpochs`): the distance counted over the window
      since the previous mark, ``z = (1 + k) d + w + e_b - e_a``: ``d`` the forward distance
      of the odometer point along the vehicle's x (trapezoid of ``r . (C^T v) + omega . a``,
      ``r = R^T e_x`` the vehicle's forward axis in IMU axes through the estimated mounting,
      ``a = (l_o - l) x r`` with ``l_o`` the odometer point from the vehicle reference point
      and ``l`` the IMU's, nominal plus its states; sensitivities to the gyro bias ``-a T_w``
      and to the lever-arm states ``-(r x theta_w)``, ``theta_w`` the window's angle, gated
      as NHC's; the rate's white noise adds ``N_g^2 T_w a^2``; the mounting angles' effect is
      second order, ``u theta dtheta``, and left out: with large misalignments, 3, 3, 5 deg,
      and a 1 m lever arm, NEES 9.3, 192 with the wheel along the IMU's x at the IMU), ``k``
      the scale
      factor (a state, or its prior added to the variance), ``w`` the white speed noise
      integrated over the window (variance ``n (s_w T_o)^2``), and ``e = (1/2 - r) c`` the
      residual of the tick count at each end (``c`` the tick length, ``r`` the fraction of a
      tick counted late, uniform: variance ``c^2 / 12``). The residual at a window's end is
      the next window's start, so it is not white noise: both ends are states (start, end),
      the end's drawn fresh at each mark and then becoming the next window's start (the
      start's marginalized). Taken as white noise of ``c^2 / 6`` per window instead, the
      telescoping of the residuals is lost: the scale factor's NEES is 0.09 (10 times
      conservative) and the velocity's too (per-component 0.85 along-track).
    * Barometer: the height above the origin's plus a first-order Gauss-Markov drift state
      (the labelled model, :mod:`imugen.aid.companions`), white noise ``s_w^2``.
    * ZUPT: velocity zero when the interval was still (every sample's corrected rate below
      ``zupt_gyro_radps``, specific-force magnitude within ``zupt_accel_mps2`` of gravity) and
      the speed (GNSS when valid, else the filter's) below ``zupt_speed_mps``.
    * An optional innovation gate rejects a scalar update whose normalized innovation exceeds
      ``gate_sigma`` (0: off).
In ``geodetic`` (n = ECEF) the receiver's errors are independent along East, North, Up at the
antenna, not along ECEF axes: each GNSS scalar update is one local axis (rows of ``C_le`` at
the predicted antenna applied to the residual and the sensitivities), which is the update with
the full ECEF covariance ``C_el diag(s^2) C_le``; the GNSS bias states are along the local axes;
the barometer predicts the ellipsoidal height of the position; the output sigmas of position,
velocity and attitude are along the local axes at the estimate (the stored ``P`` stays in n).
After the updates the error state is fed back (``C <- Exp(-psi) C``, ...) and reset to zero.

The time recursion is one numba kernel: sequences outside, time inside, no allocation per
step, no I/O. Initial alignment (:func:`align`) is vectorized NumPy.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from imugen.aid.companions import C_BARO, C_BARO_VAR, C_ODO, C_ODO_VAR, CompanionEpochs
from imugen.core import earth, units
from imugen.core.earth import OriginFrame
from imugen.core.errors import InputError
from imugen.core.jit import njit
from imugen.core.rotations import dcm_to_quat, euler_to_dcm, quat_to_dcm
from imugen.core.rotations_nb import qexpm1, qmul
from imugen.sensors.grades import TERMS, Grade, get_grade

# --- nominal state layout (one row per sequence) ------------------------------------------------
X_P, X_V, X_Q, X_BG, X_BA, X_SG, X_SA, X_GB, X_OSF, X_BB, X_MT = (
    0,
    3,
    6,
    10,
    13,
    16,
    19,
    22,
    25,
    26,
    27,
)
X_CG = 29  # gyro cross-coupling (6, off-diagonal elements in _CC_PAIRS order)
X_OQ = 35  # odometer tick residual at the start of the current window [m]
X_LA = 36  # NHC lever arm's departure from the nominal (3, body) [m]
NX = 39
# --- error-state indices (fixed part) -----------------------------------------------------------
I_P, I_V, I_PSI, I_BG, I_BA = 0, 3, 6, 9, 12
N_BASE = 15
# --- tuning vector (per sequence) ---------------------------------------------------------------
T_NG, T_NA, T_QBG, T_QBA, T_GB_SD, T_GB_TAU, T_GW, T_QS = 0, 3, 6, 9, 12, 15, 16, 19
T_OSF_SD, T_BB_SD, T_BB_TAU = 20, 21, 22
# motion-dependent noise (module docstring, "Process noise"): per body axis scale-factor,
# cross-coupling and g-sensitivity sigmas, their correlation time, quantization variances
T_MSG, T_MCG, T_MGS, T_MSA, T_MCA = 23, 26, 29, 32, 35
T_MTAU = 38
T_OQ_SD = 39  # odometer tick residual 1-sigma, c / sqrt(12) [m]
N_TUNE = 40
# --- options vector (shared) --------------------------------------------------------------------
(O_SF, O_GB, O_NHC, O_NHC_SD, O_ZUPT, O_ZUPT_SD, O_ZUPT_GYRO, O_ZUPT_ACC, O_ZUPT_SPEED) = range(9)
O_GATE, O_USE_VEL, O_LATENCY = 9, 10, 11
O_ODO, O_ODO_SF, O_BARO = 12, 13, 14
O_NHC_LEVER, O_MT = 15, 18  # nominal lever arm: 3 slots
O_NHC_SD_V, O_LA, O_CG = 19, 20, 21  # vertical NHC sigma (O_NHC_SD: lateral), lever states
N_OPT = 22
_CC_PAIRS = ((0, 1), (0, 2), (1, 0), (1, 2), (2, 0), (2, 1))
"""Off-diagonal (row, column) of the gyro cross-coupling states, as :mod:`imugen.sensors.model`."""
# --- flags per epoch ----------------------------------------------------------------------------
F_GNSS_P, F_GNSS_V, F_ZUPT, F_NHC, F_REJECT, F_ALIGNED, F_ODO, F_BARO = 1, 2, 4, 8, 16, 32, 64, 128
LEVEL_SD_RAD = math.radians(1.0)
"""Roll/pitch 1-sigma of a moving-start alignment (land vehicle assumed level)."""
HEADING_SD_RAD = math.radians(0.5)
"""Heading-along-velocity 1-sigma margin of a moving-start alignment."""


def n_states(
    scale_factors: bool,
    gnss_bias: bool,
    odo_sf: bool = False,
    baro: bool = False,
    mounting: bool = False,
    gyro_cc: bool = False,
    odometer: bool = False,
    lever: bool = False,
) -> int:
    """Size of the error state (``odo_sf``: odometer scale factor, ``baro``: barometer drift,
    ``mounting``: the IMU's pitch and yaw from the vehicle, ``gyro_cc``: the gyro's six
    cross-coupling elements, ``odometer``: the tick residuals at the two ends of a window,
    ``lever``: the NHC lever arm's departure from its nominal; :func:`state_names` in order)."""
    return len(
        state_names(scale_factors, gnss_bias, odo_sf, baro, mounting, gyro_cc, odometer, lever)
    )


def state_names(
    scale_factors: bool,
    gnss_bias: bool,
    odo_sf: bool = False,
    baro: bool = False,
    mounting: bool = False,
    gyro_cc: bool = False,
    odometer: bool = False,
    lever: bool = False,
) -> list[str]:
    """Names of the error-state components, in order."""
    names = [f"{g}_{a}" for g in ("dp", "dv", "psi", "dbg", "dba") for a in "enu"[:3]]
    names[9:15] = [f"{g}_{a}" for g in ("dbg", "dba") for a in "xyz"]
    if gnss_bias:
        names += [f"dgnss_bias_{a}" for a in "enu"]
    if scale_factors:
        names += [f"dsg_{a}" for a in "xyz"] + [f"dsa_{a}" for a in "xyz"]
    if odo_sf:
        names.append("dodo_sf")
    if baro:
        names.append("dbaro_bias")
    if mounting:
        names += ["dmount_pitch", "dmount_yaw"]
    if lever:
        names += [f"dlever_{a}" for a in "xyz"]
    if gyro_cc:
        names += [f"dcg_{'xyz'[i]}{'xyz'[j]}" for i, j in _CC_PAIRS]
    if odometer:
        names += ["dodo_tick_start_m", "dodo_tick_end_m"]
    return names


# --- tuning -------------------------------------------------------------------------------------
MOTION_CORR_S = 10.0
"""Default correlation time [s] of the motion-dependent noise (scale factor, cross-coupling,
g-sensitivity): a constant error times a rate or an acceleration held for about a turn. Set
on the consistency benchmark (``benchmarks/bench_aided_nees.py``, a car's 90-degree turns of
about 5 s): consumer attitude NEES per dof 2.9 / 1.5 / 1.0 / 0.7 at 2 / 5 / 10 / 20 s."""


@dataclass(frozen=True)
class Tuning:
    """Filter noise model (SI, per body axis), derived from the grade's full error model.

    Attributes
    ----------
    gyro_white, accel_white : (3,)  ARW [rad/sqrt(s)], VRW [m/s/sqrt(s)]
    gyro_bias_sd, accel_bias_sd : (3,)  initial bias 1-sigma [rad/s, m/s^2], with the static
        error on gravity of an uncalibrated grade (``sigma_G g0``; ``sigma_cc g0`` on x, y and
        ``sigma_s g0`` on z for the accelerometer)
    gyro_bias_q, accel_bias_q : (3,)  bias random-walk PSD [(rad/s)^2/s, (m/s^2)^2/s]
    gyro_sf_sd, accel_sf_sd : (3,)  scale-factor 1-sigma
    sf_q : float  scale-factor random-walk PSD [1/s]
    gyro_cc_sd, accel_cc_sd : (3,)  cross-coupling 1-sigma of each element of a row
    gyro_gs_sd : (3,)  g-sensitivity 1-sigma of each element of a row [rad/s per m/s^2]
    accel_static_sf_sd : (3,)  the part of ``accel_bias_sd`` due to the scale factor on
        gravity (left out of the bias prior when the scale factors are states)
    accel_tilt_cc_sd : (3,)  the part of ``accel_bias_sd`` standing for the gyro
        cross-coupling's body-fixed tilt (left out when the cross-coupling is estimated)
    motion_corr_s : float  correlation time of the motion-dependent noise [s]
    """

    gyro_white: np.ndarray
    accel_white: np.ndarray
    gyro_bias_sd: np.ndarray
    accel_bias_sd: np.ndarray
    gyro_bias_q: np.ndarray
    accel_bias_q: np.ndarray
    gyro_sf_sd: np.ndarray
    accel_sf_sd: np.ndarray
    sf_q: float = 0.0
    gyro_cc_sd: np.ndarray = field(default_factory=lambda: np.zeros(3))
    accel_cc_sd: np.ndarray = field(default_factory=lambda: np.zeros(3))
    gyro_gs_sd: np.ndarray = field(default_factory=lambda: np.zeros(3))
    accel_static_sf_sd: np.ndarray = field(default_factory=lambda: np.zeros(3))
    accel_tilt_cc_sd: np.ndarray = field(default_factory=lambda: np.zeros(3))
    motion_corr_s: float = MOTION_CORR_S

    @classmethod
    def from_grade(
        cls, grade: Grade | str, level: str = "nominal", inflate: float = 1.0,
        motion_corr_s: float = MOTION_CORR_S, terms=None,
    ):  # fmt: skip
        """Tuning from a grade's figures (every term the simulator injects, see the module
        docstring).

        ``level``: ``"nominal"`` (the grade's values) or ``"upper"`` (the top of each range,
        for a filter that knows the grade but not the device). Initial bias sigma:
        ``sqrt(turn_on^2 + sigma_GM^2 + static^2)`` (``static``: the error on gravity of an
        uncalibrated grade); bias random walk ``2 sigma_GM^2 / T + K^2`` (the Gauss-Markov's
        short-time growth plus the rate random walk). ``inflate`` scales the white densities.
        ``terms``: the error terms the simulator injected (names of
        :data:`imugen.sensors.grades.TERMS`; default every configured one); the others are left out.
        """
        g = get_grade(grade)
        if level not in ("nominal", "upper"):
            raise InputError("aided.tuning", f"level must be nominal or upper, got {level!r}")

        def val(p):
            if p is None or (terms is not None and _term_of(spec, p) not in terms):
                return np.zeros(3)
            return np.asarray(p.hi if (level == "upper" and p.hi is not None) else p.value)

        g0 = units.G0
        out = {"motion_corr_s": float(motion_corr_s)}
        for s in ("gyro", "accel"):
            spec = g.sensor(s)
            on = val(spec.turn_on_bias)
            bi = spec.bias_instability
            if bi is None:
                sig, q_gm = np.zeros(3), np.zeros(3)
            else:
                lv = val(bi.level)
                comp = bi.components
                sig = np.array([bi.sigma_from_level(x) for x in lv]) * math.sqrt(comp)
                if bi.model == "gauss_markov":
                    tau = float(np.min(val(bi.correlation_time)))
                else:
                    tau = float(bi.flicker_band[0])
                q_gm = 2.0 * sig**2 / tau if tau > 0 else np.zeros(3)
            rrw = val(spec.rate_random_walk)
            sf, cc = val(spec.scale_factor), val(spec.cross_coupling)
            # static error on gravity (0, 0, g0), a constant bias unless calibrated away
            if spec.static_g_removed:
                static = np.zeros(3)
            elif s == "gyro":
                static = val(spec.g_sensitivity) * g0
            else:
                static = g0 * np.array([cc[0], cc[1], sf[2]])
                out["accel_static_sf_sd"] = g0 * np.array([0.0, 0.0, sf[2]])
            out[f"{s}_white"] = inflate * val(spec.white_noise)
            if s == "accel":
                # the gyro cross-coupling across a rotation: a bounded, body-fixed tilt, seen
                # as an accelerometer bias g x u (module docstring)
                gcc = out["gyro_cc_sd"]
                out["accel_tilt_cc_sd"] = g0 * np.array([gcc[1], gcc[0], 0.0])
                static = np.hypot(static, out["accel_tilt_cc_sd"])
            out[f"{s}_bias_sd"] = np.sqrt(on**2 + sig**2 + static**2)
            out[f"{s}_bias_q"] = q_gm + rrw**2
            out[f"{s}_sf_sd"] = sf
            out[f"{s}_cc_sd"] = cc
        spec = g.sensor("gyro")
        out["gyro_gs_sd"] = val(spec.g_sensitivity)
        return cls(**out)


def _term_of(spec, p) -> str:
    """Name of the term of ``spec`` whose figure is ``p`` (the bias instability's parts count
    as ``bias_instability``)."""
    for t in TERMS:
        v = getattr(spec, t)
        if v is p:
            return t
        if t == "bias_instability" and v is not None:
            if p is v.level or p is v.correlation_time:
                return t
    return ""


@dataclass(frozen=True)
class Options:
    """Filter switches and thresholds (SI).

    ``scale_factors``: estimate gyro/accel scale factors; ``gnss_bias``: model the receiver's
    Gauss-Markov position bias as states (needs ``gnss_bias_sd_m``, ``gnss_bias_tau_s``,
    ``gnss_white_m`` per axis); ``nhc``: non-holonomic constraint (cars); ``zupt``: zero-velocity
    updates at detected stops; ``use_velocity``: GNSS velocity updates; ``latency``:
    compensate the GNSS latency to first order; ``gate_sigma``: innovation gate (0: off);
    ``odometer``: odometer distance updates (needs :class:`CompanionEpochs`), with an
    odometer scale-factor state if ``odo_scale_state`` (else the noise is inflated by the
    scale factor's prior); ``baro``: barometric height updates with a drift state.
    ``nhc_sd_mps``: residual slip of the vehicle reference point, 1-sigma of its lateral and
    vertical body speed [m/s] (a pair, or one number for both; the simulator's vehicles have
    none, :mod:`imugen.aid.stage` takes the truth's plausibility report); the NHC variance adds the
    lever arm's and the constraint's second-order terms (module docstring).
    ``nhc_lever_arm_m``: nominal IMU position from the vehicle reference point (vehicle
    axes, m) where NHC applies; ``nhc_misalignment_sd_rad``: (pitch, yaw) 1-sigma of the
    unknown mounting misalignment: when not zero (and NHC on) the two angles are estimated as
    random constants with that prior (:attr:`mounting`; see the module docstring);
    ``nhc_lever_arm_sd_m``: 1-sigma of the lever arm about its nominal, per vehicle axis [m]:
    when not zero (and NHC on) the lever arm is three states (:attr:`lever_states`), used by
    NHC and the odometer.
    ``gyro_cross_coupling``: estimate the gyro's six cross-coupling elements (random
    constants, prior the grade's sigma; they then leave the process noise and the
    accelerometer bias prior, see the module docstring).
    """

    scale_factors: bool = False
    gnss_bias: bool = True
    nhc: bool = False
    nhc_sd_mps: tuple = (0.0, 0.0)
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

    @property
    def n(self) -> int:
        """Size of the error state."""
        return n_states(
            self.scale_factors, self.gnss_bias, self.odo_sf, self.baro, self.mounting,
            self.gyro_cross_coupling, self.odometer, self.lever_states,
        )  # fmt: skip

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

    def names(self) -> list[str]:
        """Names of the error-state components."""
        return state_names(
            self.scale_factors, self.gnss_bias, self.odo_sf, self.baro, self.mounting,
            self.gyro_cross_coupling, self.odometer, self.lever_states,
        )  # fmt: skip

    def vector(self) -> np.ndarray:
        o = np.zeros(N_OPT)
        o[O_SF] = self.scale_factors
        o[O_GB] = self.gnss_bias
        o[O_NHC] = self.nhc
        o[O_NHC_SD], o[O_NHC_SD_V] = np.broadcast_to(np.asarray(self.nhc_sd_mps, float), (2,))
        o[O_ZUPT] = self.zupt
        o[O_ZUPT_SD] = self.zupt_sd_mps
        o[O_ZUPT_GYRO] = self.zupt_gyro_radps
        o[O_ZUPT_ACC] = self.zupt_accel_mps2
        o[O_ZUPT_SPEED] = self.zupt_speed_mps
        o[O_GATE] = self.gate_sigma
        o[O_USE_VEL] = self.use_velocity
        o[O_LATENCY] = self.latency
        o[O_ODO] = self.odometer
        o[O_ODO_SF] = self.odo_sf
        o[O_BARO] = self.baro
        o[O_NHC_LEVER : O_NHC_LEVER + 3] = self.nhc_lever_arm_m
        o[O_MT] = self.mounting
        o[O_CG] = self.gyro_cross_coupling
        o[O_LA] = self.lever_states
        return o


def companion_tuning(T: np.ndarray, companions: CompanionEpochs) -> np.ndarray:
    """A copy of the tuning matrix ``T`` (S, N_TUNE) with the companion columns set from
    ``companions`` (:class:`imugen.aid.companions.CompanionEpochs`)."""
    T = np.array(T, float)
    T[:, T_OSF_SD] = companions.odo_sf_sd
    T[:, T_BB_SD] = companions.baro_sd_m
    T[:, T_BB_TAU] = companions.baro_tau_s
    if companions.odo_tick_m is not None:
        T[:, T_OQ_SD] = np.asarray(companions.odo_tick_m, float) / math.sqrt(12.0)
    return T


def tuning_matrix(tun: Tuning, S: int, gnss_params=None, gnss_receiver=None) -> np.ndarray:
    """Per-sequence tuning vectors (S, N_TUNE).

    The GNSS bias model comes from ``gnss_params`` (drawn :class:`imugen.aid.gnss.ReceiverParams`,
    an oracle) or from a receiver's nominal figures (``gnss_receiver``).
    """
    T = np.zeros((S, N_TUNE))
    T[:, T_NG : T_NG + 3] = tun.gyro_white
    T[:, T_NA : T_NA + 3] = tun.accel_white
    T[:, T_QBG : T_QBG + 3] = tun.gyro_bias_q
    T[:, T_QBA : T_QBA + 3] = tun.accel_bias_q
    T[:, T_QS] = tun.sf_q
    T[:, T_MSG : T_MSG + 3] = tun.gyro_sf_sd
    T[:, T_MCG : T_MCG + 3] = tun.gyro_cc_sd
    T[:, T_MGS : T_MGS + 3] = tun.gyro_gs_sd
    T[:, T_MSA : T_MSA + 3] = tun.accel_sf_sd
    T[:, T_MCA : T_MCA + 3] = tun.accel_cc_sd
    T[:, T_MTAU] = tun.motion_corr_s
    T[:, T_GB_TAU] = 60.0
    T[:, T_BB_TAU] = 3600.0
    if gnss_params is not None:
        T[:, T_GB_SD : T_GB_SD + 3] = gnss_params.axis("position_bias_h_m", "position_bias_v_m")
        T[:, T_GB_TAU] = gnss_params.position_bias_tau_s
        T[:, T_GW : T_GW + 3] = gnss_params.axis("position_white_h_m", "position_white_v_m")
    elif gnss_receiver is not None:
        f = gnss_receiver.figures
        T[:, T_GB_SD : T_GB_SD + 3] = [f["position_bias_h_m"].value] * 2 + [
            f["position_bias_v_m"].value
        ]
        T[:, T_GB_TAU] = f["position_bias_tau_s"].value
        T[:, T_GW : T_GW + 3] = [f["position_white_h_m"].value] * 2 + [
            f["position_white_v_m"].value
        ]
    return T


# --- numba helpers ------------------------------------------------------------------------------

# --- the filter's own strapdown step (trapezoidal, Earth-fixed n frame) ------------------------
# parameter vector: the Earth model's (earth.N_PARAMS) then these slots
A_DT = earth.N_PARAMS  # dt
A_A = A_DT + 1  # A(dt) = Exp(W dt), 9 row-major
A_D = A_A + 9  # D = A(dt)^T - I, 9 (computed without cancellation)
A_MT = A_D + 9  # (I + dt/2 W)^{-1}, 9
A_QW = A_MT + 9  # quaternion of Exp(-Omega dt) minus (1, 0, 0, 0), 4
A_H0 = A_QW + 4  # origin's ellipsoidal height [m] (the barometer's reference)
N_STEP_PARAMS = A_H0 + 1


def step_params(frame, dt: float) -> np.ndarray:
    """Parameters of the filter's strapdown step: the Earth model's and precomputed rotations."""
    prm = np.zeros(N_STEP_PARAMS)
    prm[: earth.N_PARAMS] = frame.params()
    prm[A_DT] = dt
    w = np.asarray(earth.earth_rate_n(frame), float).reshape(3)
    wn = float(np.linalg.norm(w))
    W = np.array([[0.0, -w[2], w[1]], [w[2], 0.0, -w[0]], [-w[1], w[0], 0.0]])
    if wn > 0.0:
        th = wn * dt
        s1 = math.sin(th) / wn
        s2 = 2.0 * math.sin(th / 2.0) ** 2 / wn**2  # (1 - cos) / |w|^2
        A = np.eye(3) + s1 * W + s2 * (W @ W)
        D = -s1 * W + s2 * (W @ W)
        qw = np.array([-2.0 * math.sin(th / 4.0) ** 2, *(-math.sin(th / 2.0) * w / wn)])
    else:
        A, D, qw = np.eye(3), np.zeros((3, 3)), np.zeros(4)
    c = dt / 2.0
    MT = (np.eye(3) - c * W + c * c * np.outer(w, w)) / (1.0 + c * c * (w @ w))
    prm[A_A : A_A + 9] = A.ravel()
    prm[A_D : A_D + 9] = D.ravel()
    prm[A_MT : A_MT + 9] = MT.ravel()
    prm[A_QW : A_QW + 4] = qw
    prm[A_H0] = frame.h0_m
    return prm


@njit(cache=True, inline="always")
def _level_nb(x, y, z):
    """ECEF -> ``(sin lat, cos lat, cos lon, sin lon, h)``: the numba twin of
    :func:`imugen.core.earth.geodetic_parts` (same operations, same order)."""
    p = math.sqrt(x * x + y * y)
    su = z * earth.A_WGS84
    cu = p * earth.B_WGS84
    ir = 1.0 / math.sqrt(su * su + cu * cu)
    su = su * ir
    cu = cu * ir
    num = z + earth.EP2_WGS84 * earth.B_WGS84 * su * su * su
    den = p - earth.E2_WGS84 * earth.A_WGS84 * cu * cu * cu
    ir = 1.0 / math.sqrt(num * num + den * den)
    sl = num * ir
    cl = den * ir
    h = p * cl + z * sl - earth.A_WGS84 * math.sqrt(1.0 - earth.E2_WGS84 * sl * sl)
    if p > 0.0:
        return sl, cl, x / p, y / p, h
    return sl, cl, 1.0, 0.0, h


@njit(cache=True)
def _local_level_nb(x, y, z, L):
    """``L = C_le`` (ECEF -> East, North, Up at the ECEF point ``(x, y, z)``); returns ``h``."""
    sl, cl, co, so, hgt = _level_nb(x, y, z)
    L[0, 0] = -so
    L[0, 1] = co
    L[0, 2] = 0.0
    L[1, 0] = -sl * co
    L[1, 1] = -sl * so
    L[1, 2] = cl
    L[2, 0] = cl * co
    L[2, 1] = cl * so
    L[2, 2] = sl
    return hgt


@njit(cache=True)
def _local_sd(P, L, i0, out, o0):
    """``out[o0 + a] = sqrt(L_a P_blk L_a^T)``: 1-sigma along the rows of ``L`` of the 3x3
    block of ``P`` starting at ``i0``."""
    for a in range(3):
        acc = 0.0
        for b in range(3):
            for c in range(3):
                acc += L[a, b] * P[i0 + b, i0 + c] * L[a, c]
        out[o0 + a] = math.sqrt(max(acc, 0.0))


@njit(cache=True, inline="always")
def _mv(m, o, x, y, z):
    return (
        m[o] * x + m[o + 1] * y + m[o + 2] * z,
        m[o + 3] * x + m[o + 4] * y + m[o + 5] * z,
        m[o + 6] * x + m[o + 7] * y + m[o + 8] * z,
    )


@njit(cache=True, inline="always")
def _dcm(q0, q1, q2, q3, C):
    C[0, 0] = 1.0 - 2.0 * (q2 * q2 + q3 * q3)
    C[0, 1] = 2.0 * (q1 * q2 - q0 * q3)
    C[0, 2] = 2.0 * (q1 * q3 + q0 * q2)
    C[1, 0] = 2.0 * (q1 * q2 + q0 * q3)
    C[1, 1] = 1.0 - 2.0 * (q1 * q1 + q3 * q3)
    C[1, 2] = 2.0 * (q2 * q3 - q0 * q1)
    C[2, 0] = 2.0 * (q1 * q3 - q0 * q2)
    C[2, 1] = 2.0 * (q2 * q3 + q0 * q1)
    C[2, 2] = 1.0 - 2.0 * (q1 * q1 + q2 * q2)


@njit(cache=True, inline="always")
def _skew(x, y, z, M):
    M[0, 0] = 0.0
    M[0, 1] = -z
    M[0, 2] = y
    M[1, 0] = z
    M[1, 1] = 0.0
    M[1, 2] = -x
    M[2, 0] = -y
    M[2, 1] = x
    M[2, 2] = 0.0


@njit(cache=True, inline="always")
def _sparse_rows_times(Phi, nnz, nzc, P, T, n):
    """``T = Phi P`` using only the ``nnz[i]`` non-zero columns ``nzc[i, :]`` of each row of Phi."""
    for i in range(n):
        for j in range(n):
            T[i, j] = 0.0
        for m in range(nnz[i]):
            c = nzc[i, m]
            f = Phi[i, c]
            for j in range(n):
                T[i, j] += f * P[c, j]


@njit(cache=True)
def _scalar_update(P, dx, h, nz, nnz, r, var, gate, PHt):
    """One scalar update ``z_pred - z = h dx + noise`` (r = z_pred - z); returns accepted.

    ``P`` symmetric: ``P h`` is a sum of the rows named in ``nz``; the rank-one downdate is
    applied to full rows (contiguous) and stays symmetric to rounding (re-symmetrized per epoch).
    """
    n = P.shape[0]
    for i in range(n):
        PHt[i] = 0.0
    for m in range(nnz):
        k = nz[m]
        f = h[k]
        for i in range(n):
            PHt[i] += f * P[k, i]
    s = var
    innov = r
    for m in range(nnz):
        k = nz[m]
        s += h[k] * PHt[k]
        innov -= h[k] * dx[k]
    if gate > 0.0 and innov * innov > gate * gate * s:
        return False
    inv = 1.0 / s
    for i in range(n):
        dx[i] += PHt[i] * inv * innov
    for i in range(n):
        ki = PHt[i] * inv
        for j in range(n):
            P[i, j] -= ki * PHt[j]
    return True


@njit(cache=True)
def _fresh_state(P, dx, i, sd):
    """Start state ``i`` afresh: uncorrelated, zero mean error, variance ``sd^2``."""
    for j in range(P.shape[0]):
        P[i, j] = 0.0
        P[j, i] = 0.0
    P[i, i] = sd * sd
    dx[i] = 0.0


@njit(cache=True)
def _odometer_update(
    P, dx, h, hz, PHt, z, var, d_hat, hv, hpsi, hbg, hla, k_hat, i_od, sf_state, e_hat, i_oq,
    la_on, i_la, gate,
):  # fmt: skip
    """Odometer distance ``z`` over a window: ``z_pred = (1 + k) d - e_a`` with ``d`` the
    predicted forward distance, ``e_a`` the estimated tick residual at the window's start
    (state ``i_oq``; the end's, state ``i_oq + 1``, has prior mean 0); ``hv``, ``hpsi`` the
    sensitivities of ``d`` to the velocity and attitude errors (``int C^T e_x dt``, ``int (C
    e_x) x v dt``; errors taken constant over the window), ``hbg``, ``hla`` to the gyro bias
    and the IMU lever-arm errors (:func:`_odo_axes`)."""
    for i in range(P.shape[0]):
        h[i] = 0.0
    g = 1.0 + k_hat
    for a in range(3):
        h[3 + a] = g * hv[a]
        hz[a] = 3 + a
        h[6 + a] = g * hpsi[a]
        hz[3 + a] = 6 + a
        h[9 + a] = g * hbg[a]
        hz[6 + a] = 9 + a
    h[i_oq] = -1.0
    h[i_oq + 1] = 1.0
    hz[9] = i_oq
    hz[10] = i_oq + 1
    m = 11
    if la_on:
        for a in range(3):
            h[i_la + a] = g * hla[a]
            hz[m] = i_la + a
            m += 1
    if sf_state:
        h[i_od] = d_hat
        hz[m] = i_od
        m += 1
    return _scalar_update(P, dx, h, hz, m, g * d_hat - e_hat - z, var, gate, PHt)


@njit(cache=True)
def _odo_axes(x, opt, l_odo, mt_on, la_on, ra):
    """The odometer's geometry in IMU axes: ``ra[:3]`` the vehicle's forward axis ``r``
    (``R^T e_x`` with the estimated mounting ``R = Rz(yaw) Ry(-pitch)``, else ``e_x``),
    ``ra[3:]`` ``a = (l_odo - l_imu) x r`` (``l_imu`` the NHC lever arm, nominal plus its
    estimate): the wheel's forward speed is ``r . (C^T v) + omega . a``."""
    if mt_on:
        mcp, msp = math.cos(x[X_MT]), math.sin(x[X_MT])
        mcy, msy = math.cos(x[X_MT + 1]), math.sin(x[X_MT + 1])
        ra[0], ra[1], ra[2] = mcy * mcp, -msy, -mcy * msp
    else:
        ra[0], ra[1], ra[2] = 1.0, 0.0, 0.0
    d0 = l_odo[0] - opt[O_NHC_LEVER]
    d1 = l_odo[1] - opt[O_NHC_LEVER + 1]
    d2 = l_odo[2] - opt[O_NHC_LEVER + 2]
    if la_on:
        d0 -= x[X_LA]
        d1 -= x[X_LA + 1]
        d2 -= x[X_LA + 2]
    ra[3] = d1 * ra[2] - d2 * ra[1]
    ra[4] = d2 * ra[0] - d0 * ra[2]
    ra[5] = d0 * ra[1] - d1 * ra[0]


@njit(cache=True)
def _odo_window_sens(tw, Tw, ra, tn, dt, hbg, hla):
    """Sensitivities of the window's distance to the gyro bias (``-a T_w``) and to the IMU
    lever arm (``-(r x theta_w)``, ``theta_w`` the window's corrected angle, only its components
    well above their noise ``N_g^2 T_w``: see the NHC's lever arm in :func:`_kernel`)."""
    g0 = tw[0] if tw[0] * tw[0] > 250.0 * tn[T_NG] ** 2 * Tw else 0.0
    g1 = tw[1] if tw[1] * tw[1] > 250.0 * tn[T_NG + 1] ** 2 * Tw else 0.0
    g2 = tw[2] if tw[2] * tw[2] > 250.0 * tn[T_NG + 2] ** 2 * Tw else 0.0
    for a in range(3):
        hbg[a] = -ra[3 + a] * Tw
    hla[0] = -(ra[1] * g2 - ra[2] * g1)
    hla[1] = -(ra[2] * g0 - ra[0] * g2)
    hla[2] = -(ra[0] * g1 - ra[1] * g0)


@njit(cache=True)
def _baro_update(P, dx, h, hz, PHt, z, var, px, py, pz, b_hat, i_bb, wgs, gate):
    """Barometric height above the origin's: ``z_pred = p_u (+ (p_e^2 + p_n^2) / 2R in wgs84)
    + b`` with ``b`` the drift state."""
    for i in range(P.shape[0]):
        h[i] = 0.0
    pred = pz + b_hat
    h[2] = 1.0
    hz[0] = 2
    m = 1
    if wgs:
        pred += (px * px + py * py) / (2.0 * earth.R_MEAN)
        h[0] = px / earth.R_MEAN
        h[1] = py / earth.R_MEAN
        hz[1] = 0
        hz[2] = 1
        m = 3
    h[i_bb] = 1.0
    hz[m] = i_bb
    return _scalar_update(P, dx, h, hz, m + 1, pred - z, var, gate, PHt)


@njit(cache=True, inline="always")
def _body_cov(P, i0, Cv, i, j):
    """``Cv[:, i]^T P_blk Cv[:, j]``: covariance of components ``i``, ``j`` (vehicle axes) of
    the 3x3 block of ``P`` starting at ``i0``."""
    acc = 0.0
    for a in range(3):
        for b in range(3):
            acc += Cv[a, i] * P[i0 + a, i0 + b] * Cv[b, j]
    return acc


@njit(cache=True)
def _nhc_second_order_var(P, Cv, u, row):
    """Variance of the NHC prediction's second-order error (module docstring,
    "Measurements"): with ``psi``, ``dv`` in vehicle axes, ``v_b,hat - v_b = -(psi x dv) +
    u/2 psi (psi_x) + ...``, so row y carries ``u/2 psi_y psi_x - psi_z dv_x + psi_x dv_z``
    and row z ``u/2 psi_z psi_x - psi_x dv_y + psi_y dv_x``; products of zero-mean Gaussian
    components, ``var(a b) = s_a^2 s_b^2 + s_ab^2`` (the products taken uncorrelated)."""
    sxx = _body_cov(P, 6, Cv, 0, 0)
    o = 1 if row == 1 else 2  # the row's own axis, and the remaining one
    r = 2 if row == 1 else 1
    soo = _body_cov(P, 6, Cv, o, o)
    sxo = _body_cov(P, 6, Cv, 0, o)
    srr = _body_cov(P, 6, Cv, r, r)
    vxx = _body_cov(P, 3, Cv, 0, 0)
    vrr = _body_cov(P, 3, Cv, r, r)
    return 0.25 * u * u * (sxx * soo + sxo * sxo) + srr * vxx + sxx * vrr


@njit(cache=True, inline="always")
def _motion_axis(tn, i, ti, di, t2, d2, sf_on, cg_on):
    """Gyro variance of body axis ``i`` along the rotation (times ``|t|^2``) and
    accelerometer variance of axis ``i`` over one interval (see :func:`_motion_noise`)."""
    sg = 0.0 if sf_on else tn[T_MSG + i] ** 2
    sa = 0.0 if sf_on else tn[T_MSA + i] ** 2
    cg = 0.0 if cg_on else tn[T_MCG + i] ** 2
    vi = sg * ti * ti + cg * (t2 - ti * ti)
    va = sa * di * di + tn[T_MCA + i] ** 2 * (d2 - di * di)
    return vi, va


@njit(cache=True)
def _motion_noise(P, C, tx, ty, tz, ux, uy, uz, tn, T, sf_on, cg_on):
    """Add the motion-dependent process noise of one interval of length ``T`` to ``P``
    (module docstring, "Process noise").

    ``t`` (body) the corrected angle increment over the interval, ``u`` (n) the kinematic
    velocity change (specific force plus gravitation, integrated), ``d = C^T u``,
    ``c = max(1, tau / T)``, ``v_i = s_g,i^2 t_i^2 + cc_g,i^2 (|t|^2 - t_i^2)``. Gyro: along
    the rotation axis ``e = C t / |t|`` the variance ``c sum_i (t_i / |t|)^2 v_i`` (rank one),
    across it ``(sum_i v_i - v_par) / 2`` per axis, plus ``c sum_i G_i^2 |d|^2 / 3`` per axis
    (g-sensitivity). Accelerometer per body axis ``c (s_a,i^2 d_i^2 + cc_a,i^2 (|d|^2 -
    d_i^2))``, rotated to n, into velocity and (``T^2/3``, ``T/2``) position. Scale-factor
    (cross-coupling) terms are left out when they are states.
    """
    dx = C[0, 0] * ux + C[1, 0] * uy + C[2, 0] * uz
    dy = C[0, 1] * ux + C[1, 1] * uy + C[2, 1] * uz
    dz = C[0, 2] * ux + C[1, 2] * uy + C[2, 2] * uz
    t2 = tx * tx + ty * ty + tz * tz
    d2 = dx * dx + dy * dy + dz * dz
    c = max(1.0, tn[T_MTAU] / T)
    vg0, va0 = _motion_axis(tn, 0, tx, dx, t2, d2, sf_on, cg_on)
    vg1, va1 = _motion_axis(tn, 1, ty, dy, t2, d2, sf_on, cg_on)
    vg2, va2 = _motion_axis(tn, 2, tz, dz, t2, d2, sf_on, cg_on)
    # along the rotation: c vpar e e^T with e = C t / |t|, i.e. c vpar / |t|^2 (C t)(C t)^T
    vpar = (tx * tx * vg0 + ty * ty * vg1 + tz * tz * vg2) / t2 if t2 > 0.0 else 0.0
    vperp = (vg0 + vg1 + vg2 - vpar) / 2.0  # per axis across the rotation, uncorrelated
    kpar = (c * vpar - vperp) / t2 if t2 > 0.0 else 0.0
    e0 = C[0, 0] * tx + C[0, 1] * ty + C[0, 2] * tz
    e1 = C[1, 0] * tx + C[1, 1] * ty + C[1, 2] * tz
    e2 = C[2, 0] * tx + C[2, 1] * ty + C[2, 2] * tz
    ev = (e0, e1, e2)
    viso = c * (tn[T_MGS] ** 2 + tn[T_MGS + 1] ** 2 + tn[T_MGS + 2] ** 2) * d2 / 3.0
    viso += vperp
    va0, va1, va2 = c * va0, c * va1, c * va2
    for a in range(3):
        for b in range(3):
            qa = C[a, 0] * C[b, 0] * va0 + C[a, 1] * C[b, 1] * va1 + C[a, 2] * C[b, 2] * va2
            P[6 + a, 6 + b] += kpar * ev[a] * ev[b]
            P[3 + a, 3 + b] += qa
            P[a, 3 + b] += 0.5 * T * qa
            P[3 + a, b] += 0.5 * T * qa
            P[a, b] += T * T * qa / 3.0
        P[6 + a, 6 + a] += viso


@njit(cache=True)
def _gnss_update_geo(
    P, dx, h, hz, PHt, Lm, Xc, C, x, zp, zv, sp, sv, pred, predv, clv, cwv, lever, Lat, gb_on,
    i_gb, tun, use_vel, gate,
):  # fmt: skip
    """GNSS position (and velocity) updates in ``geodetic`` (n = ECEF), one scalar update per
    local-level axis: rows ``Lm = C_le`` (at the predicted antenna) applied to the n-frame
    residual and sensitivities. The receiver's errors are independent per local axis, so this
    equals one update with the full ECEF covariance ``C_el diag(s^2) C_le``; the GNSS bias
    states are along the local axes. Returns the flag bits."""
    n = P.shape[0]
    flag = 0
    _skew(clv[0], clv[1], clv[2], Xc)
    for a in range(3):
        for i in range(n):
            h[i] = 0.0
        r = 0.0
        for c in range(3):
            h[c] = Lm[a, c]
            hz[c] = c
            r += Lm[a, c] * (pred[c] - zp[c])
            # dp - [(C l) x] psi - Lat dv
            acc = 0.0
            for e in range(3):
                acc -= Lm[a, e] * Xc[e, c]
            h[6 + c] = acc
            hz[3 + c] = 6 + c
        m = 6
        if Lat > 0.0:
            for c in range(3):
                h[3 + c] = -Lat * Lm[a, c]
                hz[m] = 3 + c
                m += 1
        var = sp[a] ** 2
        if gb_on:
            h[i_gb + a] = 1.0
            hz[m] = i_gb + a
            m += 1
            r += x[X_GB + a]
            wsd = tun[T_GW + a]
            tot = wsd * wsd + tun[T_GB_SD + a] ** 2
            var = var * (wsd * wsd / tot) if tot > 0.0 else var
        var = max(var, 1e-12)
        if _scalar_update(P, dx, h, hz, m, r, var, gate, PHt):
            flag |= F_GNSS_P
        else:
            flag |= F_REJECT
    if not use_vel:
        return flag
    _skew(cwv[0], cwv[1], cwv[2], Xc)
    lx, ly, lz = lever[0], lever[1], lever[2]
    for a in range(3):
        for i in range(n):
            h[i] = 0.0
        r = 0.0
        for c in range(3):
            h[3 + c] = Lm[a, c]
            hz[c] = 3 + c
            r += Lm[a, c] * (predv[c] - zv[c])
            acc = 0.0
            for e in range(3):
                acc -= Lm[a, e] * Xc[e, c]
            h[6 + c] = acc
            hz[3 + c] = 6 + c
            # d(C (w x l))/d dbg = C [l x] (w_hat = w - dbg)
            eb0 = 1.0 if c == 0 else 0.0
            eb1 = 1.0 if c == 1 else 0.0
            eb2 = 1.0 if c == 2 else 0.0
            lxe0 = ly * eb2 - lz * eb1
            lxe1 = lz * eb0 - lx * eb2
            lxe2 = lx * eb1 - ly * eb0
            acc = 0.0
            for e in range(3):
                acc += Lm[a, e] * (C[e, 0] * lxe0 + C[e, 1] * lxe1 + C[e, 2] * lxe2)
            h[9 + c] = acc
            hz[6 + c] = 9 + c
        var = max(sv[a] ** 2, 1e-12)
        if _scalar_update(P, dx, h, hz, 9, r, var, gate, PHt):
            flag |= F_GNSS_V
        else:
            flag |= F_REJECT
    return flag


@njit(cache=True)
def _baro_update_geo(P, dx, h, hz, PHt, z, var, Lm, px, py, pz, h0, b_hat, i_bb, gate):
    """Barometric height in ``geodetic``: ``z_pred = h(p) - h0 + b`` with ``h`` the ellipsoidal
    height of the ECEF position, ``dh = u^T dp`` (``u`` the local Up, row 2 of ``Lm``)."""
    for i in range(P.shape[0]):
        h[i] = 0.0
    hgt = _local_level_nb(px, py, pz, Lm)
    for c in range(3):
        h[c] = Lm[2, c]
        hz[c] = c
    h[i_bb] = 1.0
    hz[3] = i_bb
    return _scalar_update(P, dx, h, hz, 4, hgt - h0 + b_hat - z, var, gate, PHt)


@njit(cache=True)
def _kernel(
    dth, dvb, k0, ep_idx, zp, zv, sp, sv, ok, lever, lat, x0, P0, prm, tun, opt,
    out_x, out_sd, out_P, out_flag, cz, cmark, clever,
):  # fmt: skip
    """Filter every sequence from its start sample ``k0[s]`` through the epochs ``ep_idx``.

    dth, dvb : (S, K, 3) increments (row k: interval ending at t_k); zp, zv, sp, sv : (S, J, 3)
    GNSS position/velocity and reported sigmas; ok : (S, J) usable epochs; lever : (S, 3);
    lat : (S,) latency [s]; x0 : (S, NX) state at t_{k0}; P0 : (S, n, n); outputs per epoch:
    out_x (S, J, NX) (NaN before the start), out_sd (S, J, n), out_P (S, J or 0, n, n),
    out_flag (S, J); companions (:class:`CompanionEpochs`): cz (S, J, 4), cmark (J,),
    clever (S, 3).
    """
    S = dth.shape[0]
    J = ep_idx.shape[0]
    n = P0.shape[1]
    wgs = prm[earth.P_MODEL] != 0.0
    geo = prm[earth.P_MODEL] == 2.0
    dt = prm[A_DT]
    g0 = prm[earth.P_G0]
    w0 = prm[earth.P_OMEGA]
    w1 = prm[earth.P_OMEGA + 1]
    w2 = prm[earth.P_OMEGA + 2]
    sf_on = opt[O_SF] != 0.0
    gb_on = opt[O_GB] != 0.0
    i_gb = N_BASE
    i_sg = N_BASE + (3 if gb_on else 0)
    i_sa = i_sg + 3
    odo_on = opt[O_ODO] != 0.0
    osf_on = opt[O_ODO_SF] != 0.0
    baro_on = opt[O_BARO] != 0.0
    i_od = i_sa + 3 if sf_on else i_sg
    i_bb = i_od + (1 if osf_on else 0)
    hv = np.zeros(3)
    hpsi = np.zeros(3)
    hbg = np.zeros(3)
    hla = np.zeros(3)
    tw = np.zeros(3)  # corrected angle over the odometer window (body)
    ra = np.zeros(6)  # odometer geometry (_odo_axes)
    Cn = np.zeros((3, 3))
    mt_on = opt[O_MT] != 0.0
    i_mt = i_bb + (1 if baro_on else 0)
    cg_on = opt[O_CG] != 0.0
    la_on = opt[O_LA] != 0.0
    i_la = i_mt + (2 if mt_on else 0)
    i_cg = i_la + (3 if la_on else 0)
    i_oq = i_cg + (6 if cg_on else 0)  # odometer tick residuals: window start, end
    Ccc = np.zeros((3, 6))  # int C[:, r] omega_c dt of each cross-coupling pair (r, c)
    store_P = out_P.shape[1] > 0
    # transition sparsity pattern: columns that may be non-zero in each row
    nzc = np.zeros((n, n), np.int64)
    nnz = np.zeros(n, np.int64)
    for i in range(n):
        cols = np.zeros(n, np.bool_)
        cols[i] = True
        if i < 3:  # position rows
            for k in range(3, 15):
                cols[k] = True
            if sf_on:
                for k in range(i_sg, i_sa + 3):
                    cols[k] = True
        elif i < 6:  # velocity rows
            for k in range(3, 15):
                cols[k] = True
            if wgs:
                for k in range(3):
                    cols[k] = True
            if sf_on:
                for k in range(i_sg, i_sa + 3):
                    cols[k] = True
        elif i < 9:  # attitude rows
            for k in range(6, 12):
                cols[k] = True
            if sf_on:
                for k in range(i_sg, i_sg + 3):
                    cols[k] = True
            if cg_on:
                for k in range(i_cg, i_cg + 6):
                    cols[k] = True
        m = 0
        for k in range(n):
            if cols[k]:
                nzc[i, m] = k
                m += 1
        nnz[i] = m
    P = np.zeros((n, n))
    Phi = np.zeros((n, n))
    T = np.zeros((n, n))
    dx = np.zeros(n)
    h = np.zeros(n)
    hz = np.zeros(n, np.int64)
    PHt = np.zeros(n)
    C = np.zeros((3, 3))
    Cf = np.zeros((3, 3))
    Cw = np.zeros((3, 3))
    Cv = np.zeros((3, 3))
    Cint = np.zeros((3, 3))
    dvn = np.zeros(3)
    x = np.zeros(NX)
    qdiag = np.zeros(n)
    R_gamma = g0 / earth.R_MEAN
    Xm = np.zeros((3, 3))
    Wm = np.zeros((3, 3))
    Lm = np.zeros((3, 3))
    Xc = np.zeros((3, 3))
    _skew(w0, w1, w2, Wm)
    for s in range(S):
        for i in range(NX):
            x[i] = x0[s, i]
        for i in range(n):
            for j in range(n):
                P[i, j] = P0[s, i, j]
        k = k0[s]
        px, py, pz = x[0], x[1], x[2]
        vx, vy, vz = x[3], x[4], x[5]
        q0, q1, q2, q3 = x[6], x[7], x[8], x[9]
        if wgs:
            Gx, Gy, Gz = earth.gravitation_nb(prm, px, py, pz)
        else:
            Gx, Gy, Gz = 0.0, 0.0, -g0
        # odometer window: predicted forward distance and its sensitivities since the last mark
        armed = False
        dist = 0.0
        for a in range(3):
            hv[a] = 0.0
            hpsi[a] = 0.0
        Tw = 0.0  # duration of the odometer window [s]
        for a in range(3):
            tw[a] = 0.0
        for jj in range(J):
            ke = ep_idx[jj]
            if ke < k:
                for i in range(NX):
                    out_x[s, jj, i] = np.nan
                for i in range(n):
                    out_sd[s, jj, i] = np.nan
                out_flag[s, jj] = 0
                continue
            # --- strapdown from k to ke, accumulating the transition integrals ---------------
            for a in range(3):
                dvn[a] = 0.0
                for b in range(3):
                    Cint[a, b] = 0.0
                    Cf[a, b] = 0.0
                    Cw[a, b] = 0.0
            still = ke > k
            thx, thy, thz = 0.0, 0.0, 0.0  # corrected angle over the interval (motion noise)
            if cg_on:
                for a in range(3):
                    for m in range(6):
                        Ccc[a, m] = 0.0
            bgx, bgy, bgz = x[X_BG], x[X_BG + 1], x[X_BG + 2]
            bax, bay, baz = x[X_BA], x[X_BA + 1], x[X_BA + 2]
            sgx, sgy, sgz = x[X_SG], x[X_SG + 1], x[X_SG + 2]
            sax, say, saz = x[X_SA], x[X_SA + 1], x[X_SA + 2]
            ovx, ovy, ovz = vx, vy, vz
            if odo_on:  # forward speed at t_k (lever-arm term: the first interval's rate)
                _odo_axes(x, opt, clever[s], mt_on, la_on, ra)
                _dcm(q0, q1, q2, q3, C)
                cr0 = C[0, 0] * ra[0] + C[0, 1] * ra[1] + C[0, 2] * ra[2]
                cr1 = C[1, 0] * ra[0] + C[1, 1] * ra[1] + C[1, 2] * ra[2]
                cr2 = C[2, 0] * ra[0] + C[2, 1] * ra[1] + C[2, 2] * ra[2]
                u0 = cr0 * vx + cr1 * vy + cr2 * vz
                if ke > k:
                    u0 += (
                        (dth[s, k + 1, 0] - bgx * dt) * ra[3]
                        + (dth[s, k + 1, 1] - bgy * dt) * ra[4]
                        + (dth[s, k + 1, 2] - bgz * dt) * ra[5]
                    ) / dt
            for i in range(k + 1, ke + 1):
                tx = (dth[s, i, 0] - bgx * dt) / (1.0 + sgx)
                ty = (dth[s, i, 1] - bgy * dt) / (1.0 + sgy)
                tz = (dth[s, i, 2] - bgz * dt) / (1.0 + sgz)
                ux = (dvb[s, i, 0] - bax * dt) / (1.0 + sax)
                uy = (dvb[s, i, 1] - bay * dt) / (1.0 + say)
                uz = (dvb[s, i, 2] - baz * dt) / (1.0 + saz)
                if cg_on:  # minus the estimated cross-coupling (first order)
                    ttx = tx - x[X_CG] * ty - x[X_CG + 1] * tz
                    tty = ty - x[X_CG + 2] * tx - x[X_CG + 3] * tz
                    tz = tz - x[X_CG + 4] * tx - x[X_CG + 5] * ty
                    tx, ty = ttx, tty
                thx += tx
                thy += ty
                thz += tz
                if still:
                    wn = math.sqrt(tx * tx + ty * ty + tz * tz) / dt
                    fn = math.sqrt(ux * ux + uy * uy + uz * uz) / dt
                    if wn > opt[O_ZUPT_GYRO] or abs(fn - g0) > opt[O_ZUPT_ACC]:
                        still = False
                _dcm(q0, q1, q2, q3, C)
                ax = C[0, 0] * ux + C[0, 1] * uy + C[0, 2] * uz
                ay = C[1, 0] * ux + C[1, 1] * uy + C[1, 2] * uz
                az = C[2, 0] * ux + C[2, 1] * uy + C[2, 2] * uz
                dvn[0] += ax
                dvn[1] += ay
                dvn[2] += az
                for a in range(3):
                    Cint[a, 0] += C[a, 0] * dt
                    Cint[a, 1] += C[a, 1] * dt
                    Cint[a, 2] += C[a, 2] * dt
                if sf_on:
                    for a in range(3):
                        Cf[a, 0] += C[a, 0] * ux
                        Cf[a, 1] += C[a, 1] * uy
                        Cf[a, 2] += C[a, 2] * uz
                        Cw[a, 0] += C[a, 0] * tx
                        Cw[a, 1] += C[a, 1] * ty
                        Cw[a, 2] += C[a, 2] * tz
                if cg_on:  # pairs (0,1) (0,2) (1,0) (1,2) (2,0) (2,1): C[:, row] t_col
                    for a in range(3):
                        Ccc[a, 0] += C[a, 0] * ty
                        Ccc[a, 1] += C[a, 0] * tz
                        Ccc[a, 2] += C[a, 1] * tx
                        Ccc[a, 3] += C[a, 1] * tz
                        Ccc[a, 4] += C[a, 2] * tx
                        Ccc[a, 5] += C[a, 2] * ty
                ovx, ovy, ovz = vx, vy, vz
                if wgs:
                    rx = prm[earth.P_R0N] + px
                    ry = prm[earth.P_R0N + 1] + py
                    rz = prm[earth.P_R0N + 2] + pz
                    wrx = w1 * rz - w2 * ry
                    wry = w2 * rx - w0 * rz
                    wrz = w0 * ry - w1 * rx
                    wvx = w1 * vz - w2 * vy
                    wvy = w2 * vx - w0 * vz
                    wvz = w0 * vy - w1 * vx
                    cfx = w1 * wrz - w2 * wry
                    cfy = w2 * wrx - w0 * wrz
                    cfz = w0 * wry - w1 * wrx
                    sx = vx + ax + dt * (Gx - 2.0 * wvx - cfx)
                    sy = vy + ay + dt * (Gy - 2.0 * wvy - cfy)
                    sz = vz + az + dt * (Gz - 2.0 * wvz - cfz)
                    Gnx, Gny, Gnz = earth.gravitation_nb(
                        prm, px + 0.5 * dt * (sx + vx), py + 0.5 * dt * (sy + vy),
                        pz + 0.5 * dt * (sz + vz),
                    )  # fmt: skip
                    AGx, AGy, AGz = _mv(prm, A_A, Gnx, Gny, Gnz)
                    Jx = 0.5 * dt * (AGx + Gx)
                    Jy = 0.5 * dt * (AGy + Gy)
                    Jz = 0.5 * dt * (AGz + Gz)
                    dsx, dsy, dsz = _mv(
                        prm, A_D, vx + wrx + ax + Jx, vy + wry + ay + Jy, vz + wrz + az + Jz
                    )
                    ex = ax + Jx + dsx - dt * wvx
                    ey = ay + Jy + dsy - dt * wvy
                    ez = az + Jz + dsz - dt * wvz
                    ddx, ddy, ddz = _mv(prm, A_MT, ex, ey, ez)
                    vx += ddx
                    vy += ddy
                    vz += ddz
                    Gx, Gy, Gz = Gnx, Gny, Gnz
                else:
                    vx += ax
                    vy += ay
                    vz += az - g0 * dt
                px += 0.5 * dt * (vx + ovx)
                py += 0.5 * dt * (vy + ovy)
                pz += 0.5 * dt * (vz + ovz)
                e0, e1, e2, e3 = qexpm1(tx, ty, tz)
                e0 += 1.0
                q0, q1, q2, q3 = qmul(q0, q1, q2, q3, e0, e1, e2, e3)
                if wgs:
                    q0, q1, q2, q3 = qmul(
                        1.0 + prm[A_QW], prm[A_QW + 1], prm[A_QW + 2],
                        prm[A_QW + 3], q0, q1, q2, q3,
                    )  # fmt: skip
                nq = 1.0 / math.sqrt(q0 * q0 + q1 * q1 + q2 * q2 + q3 * q3)
                q0 *= nq
                q1 *= nq
                q2 *= nq
                q3 *= nq
                if odo_on:  # trapezoid of the forward speed, as the odometer's truth
                    _dcm(q0, q1, q2, q3, Cn)  # C r before (C) and after (Cn) the step
                    cx = Cn[0, 0] * ra[0] + Cn[0, 1] * ra[1] + Cn[0, 2] * ra[2]
                    cy = Cn[1, 0] * ra[0] + Cn[1, 1] * ra[1] + Cn[1, 2] * ra[2]
                    cz_ = Cn[2, 0] * ra[0] + Cn[2, 1] * ra[1] + Cn[2, 2] * ra[2]
                    cr0 = C[0, 0] * ra[0] + C[0, 1] * ra[1] + C[0, 2] * ra[2]
                    cr1 = C[1, 0] * ra[0] + C[1, 1] * ra[1] + C[1, 2] * ra[2]
                    cr2 = C[2, 0] * ra[0] + C[2, 1] * ra[1] + C[2, 2] * ra[2]
                    u1 = cx * vx + cy * vy + cz_ * vz + (tx * ra[3] + ty * ra[4] + tz * ra[5]) / dt
                    dist += 0.5 * dt * (u0 + u1)
                    u0 = u1
                    tw[0] += tx
                    tw[1] += ty
                    tw[2] += tz
                    Tw += dt
                    hv[0] += 0.5 * dt * (cr0 + cx)
                    hv[1] += 0.5 * dt * (cr1 + cy)
                    hv[2] += 0.5 * dt * (cr2 + cz_)
                    hpsi[0] += dt * (cy * vz - cz_ * vy)
                    hpsi[1] += dt * (cz_ * vx - cx * vz)
                    hpsi[2] += dt * (cx * vy - cy * vx)
            Tint = (ke - k) * dt
            if ke > k:  # acceleration of the last IMU interval (latency of the fix)
                acx = (vx - ovx) / dt
                acy = (vy - ovy) / dt
                acz = (vz - ovz) / dt
            else:
                acx, acy, acz = 0.0, 0.0, 0.0
            # --- covariance propagation P <- Phi P Phi^T + Q ---------------------------------
            if ke > k:
                for i in range(n):
                    for j in range(n):
                        Phi[i, j] = 0.0
                    Phi[i, i] = 1.0
                    qdiag[i] = 0.0
                _skew(dvn[0], dvn[1], dvn[2], Xm)  # [dv_n x]
                for a in range(3):
                    Phi[a, 3 + a] = Tint
                    for b in range(3):
                        # -[dv x] and -int C
                        Phi[3 + a, 6 + b] = -Xm[a, b]
                        Phi[a, 6 + b] = -0.5 * Tint * Xm[a, b]
                        Phi[3 + a, 12 + b] = -Cint[a, b]
                        Phi[a, 12 + b] = -0.5 * Tint * Cint[a, b]
                        Phi[6 + a, 9 + b] = -Cint[a, b]
                        # psi driven by gyro bias, then velocity by psi: +1/2 [dv x] int C
                        acc = Xm[a, 0] * Cint[0, b] + Xm[a, 1] * Cint[1, b] + Xm[a, 2] * Cint[2, b]
                        Phi[3 + a, 9 + b] = 0.5 * acc
                        Phi[a, 9 + b] = Tint * acc / 6.0
                        if sf_on:
                            Phi[3 + a, i_sa + b] = -Cf[a, b]
                            Phi[a, i_sa + b] = -0.5 * Tint * Cf[a, b]
                            Phi[6 + a, i_sg + b] = -Cw[a, b]
                    if cg_on:
                        for m in range(6):
                            Phi[6 + a, i_cg + m] = -Ccc[a, m]
                if wgs:
                    for a in range(3):
                        for b in range(3):
                            Phi[3 + a, 3 + b] -= 2.0 * Wm[a, b] * Tint
                            Phi[6 + a, 6 + b] -= Wm[a, b] * Tint
                    if geo:  # gravity gradient g/R (3 u u^T - I), u = r / |r| in ECEF
                        ir = 1.0 / math.sqrt(px * px + py * py + pz * pz)
                        ur = (px * ir, py * ir, pz * ir)
                        for a in range(3):
                            for b in range(3):
                                d = 3.0 * ur[a] * ur[b] - (1.0 if a == b else 0.0)
                                Phi[3 + a, b] = R_gamma * Tint * d
                    else:  # gravity gradient at the origin, local ENU: g/R diag(-1, -1, 2)
                        Phi[3, 0] = -R_gamma * Tint
                        Phi[4, 1] = -R_gamma * Tint
                        Phi[5, 2] = 2.0 * R_gamma * Tint
                for a in range(3):
                    qa = tun[s, T_NA + a] ** 2
                    qdiag[3 + a] = qa * Tint
                    qdiag[6 + a] = tun[s, T_NG + a] ** 2 * Tint
                    qdiag[9 + a] = tun[s, T_QBG + a] * Tint
                    qdiag[12 + a] = tun[s, T_QBA + a] * Tint
                if gb_on:
                    phig = math.exp(-Tint / tun[s, T_GB_TAU])
                    for a in range(3):
                        Phi[i_gb + a, i_gb + a] = phig
                        qdiag[i_gb + a] = tun[s, T_GB_SD + a] ** 2 * (1.0 - phig * phig)
                if sf_on:
                    for a in range(6):
                        qdiag[i_sg + a] = tun[s, T_QS] * Tint
                if baro_on:
                    phib = math.exp(-Tint / tun[s, T_BB_TAU])
                    Phi[i_bb, i_bb] = phib
                    qdiag[i_bb] = tun[s, T_BB_SD] ** 2 * (1.0 - phib * phib)
                # P <- Phi (Phi P)^T (= Phi P Phi^T for symmetric P): two sparse-row products
                # with contiguous inner loops, then the transpose in between
                _sparse_rows_times(Phi, nnz, nzc, P, T, n)
                for i in range(n):
                    for j in range(n):
                        P[i, j] = T[j, i]
                _sparse_rows_times(Phi, nnz, nzc, P, T, n)
                for i in range(n):
                    for j in range(i, n):
                        acc = 0.5 * (T[i, j] + T[j, i])
                        P[i, j] = acc
                        P[j, i] = acc
                    P[i, i] += qdiag[i]
                # white VRW also integrates into position over the interval
                for a in range(3):
                    qa = tun[s, T_NA + a] ** 2
                    P[a, a] += qa * Tint**3 / 3.0
                    P[a, 3 + a] += qa * Tint**2 / 2.0
                    P[3 + a, a] += qa * Tint**2 / 2.0
                # motion-dependent noise (scale factor, cross-coupling, g-sensitivity, quant.)
                _dcm(q0, q1, q2, q3, C)
                _motion_noise(
                    P, C, thx, thy, thz, dvn[0] + Gx * Tint, dvn[1] + Gy * Tint,
                    dvn[2] + Gz * Tint, tun[s], Tint, sf_on, cg_on,
                )  # fmt: skip
            k = ke
            # --- measurement updates -----------------------------------------------------------
            flag = F_ALIGNED
            for i in range(n):
                dx[i] = 0.0
            _dcm(q0, q1, q2, q3, C)
            gate = opt[O_GATE]
            # corrected angular rate at t_ke (lever-arm velocity), extrapolated from the
            # mean rates of the last two intervals (second order)
            if ke > 1:
                wbx = ((1.5 * dth[s, ke, 0] - 0.5 * dth[s, ke - 1, 0]) / dt - x[X_BG]) / (
                    1.0 + x[X_SG]
                )
                wby = ((1.5 * dth[s, ke, 1] - 0.5 * dth[s, ke - 1, 1]) / dt - x[X_BG + 1]) / (
                    1.0 + x[X_SG + 1]
                )
                wbz = ((1.5 * dth[s, ke, 2] - 0.5 * dth[s, ke - 1, 2]) / dt - x[X_BG + 2]) / (
                    1.0 + x[X_SG + 2]
                )
            elif ke > 0:
                wbx = (dth[s, ke, 0] / dt - x[X_BG]) / (1.0 + x[X_SG])
                wby = (dth[s, ke, 1] / dt - x[X_BG + 1]) / (1.0 + x[X_SG + 1])
                wbz = (dth[s, ke, 2] / dt - x[X_BG + 2]) / (1.0 + x[X_SG + 2])
            else:
                wbx, wby, wbz = 0.0, 0.0, 0.0
            lx, ly, lz = lever[s, 0], lever[s, 1], lever[s, 2]
            # C l and C (w x l)
            cl0 = C[0, 0] * lx + C[0, 1] * ly + C[0, 2] * lz
            cl1 = C[1, 0] * lx + C[1, 1] * ly + C[1, 2] * lz
            cl2 = C[2, 0] * lx + C[2, 1] * ly + C[2, 2] * lz
            cwx = wby * lz - wbz * ly
            cwy = wbz * lx - wbx * lz
            cwz = wbx * ly - wby * lx
            # C ((w_ib - C^T Omega) x l) = C (w_ib x l) - Omega x (C l)
            cw0 = C[0, 0] * cwx + C[0, 1] * cwy + C[0, 2] * cwz - (w1 * cl2 - w2 * cl1)
            cw1 = C[1, 0] * cwx + C[1, 1] * cwy + C[1, 2] * cwz - (w2 * cl0 - w0 * cl2)
            cw2 = C[2, 0] * cwx + C[2, 1] * cwy + C[2, 2] * cwz - (w0 * cl1 - w1 * cl0)
            gnss_ok = ok[s, jj]
            if gnss_ok and geo:
                L = lat[s] if opt[O_LATENCY] != 0.0 else 0.0
                hL = 0.5 * L * L
                pred = (
                    px + cl0 - L * (vx + cw0) + hL * acx,
                    py + cl1 - L * (vy + cw1) + hL * acy,
                    pz + cl2 - L * (vz + cw2) + hL * acz,
                )
                predv = (vx + cw0 - L * acx, vy + cw1 - L * acy, vz + cw2 - L * acz)
                _local_level_nb(pred[0], pred[1], pred[2], Lm)
                flag |= _gnss_update_geo(
                    P, dx, h, hz, PHt, Lm, Xc, C, x, zp[s, jj], zv[s, jj], sp[s, jj], sv[s, jj],
                    pred, predv, (cl0, cl1, cl2), (cw0, cw1, cw2), lever[s], L, gb_on, i_gb,
                    tun[s], opt[O_USE_VEL] != 0.0, gate,
                )  # fmt: skip
            elif gnss_ok:
                L = lat[s] if opt[O_LATENCY] != 0.0 else 0.0
                va0 = vx + cw0
                va1 = vy + cw1
                va2 = vz + cw2
                # antenna at t - L, second order: p - L v + L^2/2 a
                hL = 0.5 * L * L
                pred = (
                    px + cl0 - L * va0 + hL * acx,
                    py + cl1 - L * va1 + hL * acy,
                    pz + cl2 - L * va2 + hL * acz,
                )
                clv = (cl0, cl1, cl2)
                for a in range(3):
                    for i in range(n):
                        h[i] = 0.0
                    # dp - [(C l) x] psi (+ gnss bias)
                    h[a] = 1.0
                    hz[0] = a
                    b1 = (a + 1) % 3
                    b2 = (a + 2) % 3
                    # row a of -[c x]: entries (a, b1) = c[b2], (a, b2) = -c[b1]
                    h[6 + b1] = clv[b2]
                    h[6 + b2] = -clv[b1]
                    hz[1] = 6 + b1
                    hz[2] = 6 + b2
                    m = 3
                    if L > 0.0:  # the fix is p(t - L) = p - L v: velocity error enters too
                        h[3 + a] = -L
                        hz[m] = 3 + a
                        m += 1
                    var = sp[s, jj, a] ** 2
                    r = pred[a] - zp[s, jj, a]
                    if gb_on:
                        h[i_gb + a] = 1.0
                        hz[m] = i_gb + a
                        m += 1
                        r += x[X_GB + a]
                        wsd = tun[s, T_GW + a]
                        tot = wsd * wsd + tun[s, T_GB_SD + a] ** 2
                        var = var * (wsd * wsd / tot) if tot > 0.0 else var
                    var = max(var, 1e-12)
                    if _scalar_update(P, dx, h, hz, m, r, var, gate, PHt):
                        flag |= F_GNSS_P
                    else:
                        flag |= F_REJECT
                if opt[O_USE_VEL] != 0.0:
                    predv = (vx + cw0 - L * acx, vy + cw1 - L * acy, vz + cw2 - L * acz)
                    cwv = (cw0, cw1, cw2)
                    # C [l x] columns for the gyro-bias term: C (l x e_b)
                    for a in range(3):
                        for i in range(n):
                            h[i] = 0.0
                        h[3 + a] = 1.0
                        hz[0] = 3 + a
                        b1 = (a + 1) % 3
                        b2 = (a + 2) % 3
                        h[6 + b1] = cwv[b2]
                        h[6 + b2] = -cwv[b1]
                        hz[1] = 6 + b1
                        hz[2] = 6 + b2
                        # d(C (w x l))/d dbg = C [l x] (w_hat = w - dbg)
                        for b in range(3):
                            eb0 = 1.0 if b == 0 else 0.0
                            eb1 = 1.0 if b == 1 else 0.0
                            eb2 = 1.0 if b == 2 else 0.0
                            lxe0 = ly * eb2 - lz * eb1
                            lxe1 = lz * eb0 - lx * eb2
                            lxe2 = lx * eb1 - ly * eb0
                            h[9 + b] = C[a, 0] * lxe0 + C[a, 1] * lxe1 + C[a, 2] * lxe2
                            hz[3 + b] = 9 + b
                        var = max(sv[s, jj, a] ** 2, 1e-12)
                        r = predv[a] - zv[s, jj, a]
                        if _scalar_update(P, dx, h, hz, 6, r, var, gate, PHt):
                            flag |= F_GNSS_V
                        else:
                            flag |= F_REJECT
            if opt[O_ZUPT] != 0.0 and still and ke > k0[s]:
                if gnss_ok:
                    spd = math.sqrt(zv[s, jj, 0] ** 2 + zv[s, jj, 1] ** 2 + zv[s, jj, 2] ** 2)
                else:
                    spd = math.sqrt(vx * vx + vy * vy + vz * vz)
                if spd < opt[O_ZUPT_SPEED]:
                    vcur = (vx, vy, vz)
                    for a in range(3):
                        for i in range(n):
                            h[i] = 0.0
                        h[3 + a] = 1.0
                        hz[0] = 3 + a
                        _scalar_update(P, dx, h, hz, 1, vcur[a], opt[O_ZUPT_SD] ** 2, 0.0, PHt)
                    flag |= F_ZUPT
            if opt[O_NHC] != 0.0:
                # v_b = C^T v - w x l; rows y, z: dv_b = C^T dv + C^T [v x] psi
                _skew(vx, vy, vz, Xm)
                nlx, nly, nlz = opt[O_NHC_LEVER], opt[O_NHC_LEVER + 1], opt[O_NHC_LEVER + 2]
                if la_on:  # the estimated lever arm
                    nlx += x[X_LA]
                    nly += x[X_LA + 1]
                    nlz += x[X_LA + 2]
                # the reference point's whole body velocity C^T v - omega x l (its x part
                # matters once rotated by the mounting: yaw x (omega x l)_x, 0.02 m/s in a
                # turn at 5 deg and 0.5 m)
                ub = C[0, 0] * vx + C[1, 0] * vy + C[2, 0] * vz - (wby * nlz - wbz * nly)
                vby = C[0, 1] * vx + C[1, 1] * vy + C[2, 1] * vz - (wbz * nlx - wbx * nlz)
                vbz = C[0, 2] * vx + C[1, 2] * vy + C[2, 2] * vz - (wbx * nly - wby * nlx)
                for a in range(3):
                    for b in range(3):
                        Cv[a, b] = C[a, b]
                if mt_on:
                    # vehicle axes v = R b, R = Rz(yaw) Ry(-pitch) (estimated angles; roll is
                    # not observable by NHC): d(v_v,y)/d yaw = d(v_v,z)/d pitch = u to first
                    # order; the velocity and attitude rows use C R^T
                    mcp, msp = math.cos(x[X_MT]), math.sin(x[X_MT])
                    mcy, msy = math.cos(x[X_MT + 1]), math.sin(x[X_MT + 1])
                    ax = mcp * ub - msp * vbz
                    vbz = msp * ub + mcp * vbz
                    vby_ = msy * ax + mcy * vby
                    ub = mcy * ax - msy * vby
                    vby = vby_
                    for a in range(3):
                        c0, c1, c2 = C[a, 0], C[a, 1], C[a, 2]
                        Cv[a, 1] = msy * (mcp * c0 - msp * c2) + mcy * c1
                        Cv[a, 2] = msp * c0 + mcp * c2
                # the lever arm is observed through the rate components well above their
                # noise (the extrapolated rate's, 2.5 N_g^2 / dt): a Jacobian taken at a noisy
                # rate, correlated with the innovation's own noise, pulls the lever arm towards
                # zero (errors in variables; 0.5 m -> 0.1 m in 25 s of straight road)
                wgx = wbx if wbx * wbx > 250.0 * tun[s, T_NG] ** 2 / dt else 0.0
                wgy = wby if wby * wby > 250.0 * tun[s, T_NG + 1] ** 2 / dt else 0.0
                wgz = wbz if wbz * wbz > 250.0 * tun[s, T_NG + 2] ** 2 / dt else 0.0
                for row in (1, 2):
                    for i in range(n):
                        h[i] = 0.0
                    vb = vby if row == 1 else vbz
                    slip = opt[O_NHC_SD] if row == 1 else opt[O_NHC_SD_V]
                    var = slip * slip + _nhc_second_order_var(P, Cv, ub, row)
                    # the vehicle row r (body) and l x r: the rate's error enters as
                    # r . (dw x l) = dw . (l x r); its white noise (the rate extrapolated from
                    # two intervals' means, 1.5 and -0.5: 2.5 N_g^2 / dt per axis) as noise,
                    # the gyro bias error as a sensitivity (dw = -dbg)
                    r0 = C[0, 0] * Cv[0, row] + C[1, 0] * Cv[1, row] + C[2, 0] * Cv[2, row]
                    r1 = C[0, 1] * Cv[0, row] + C[1, 1] * Cv[1, row] + C[2, 1] * Cv[2, row]
                    r2 = C[0, 2] * Cv[0, row] + C[1, 2] * Cv[1, row] + C[2, 2] * Cv[2, row]
                    lr0 = nly * r2 - nlz * r1
                    lr1 = nlz * r0 - nlx * r2
                    lr2 = nlx * r1 - nly * r0
                    var += (2.5 / dt) * (
                        (tun[s, T_NG] * lr0) ** 2 + (tun[s, T_NG + 1] * lr1) ** 2
                        + (tun[s, T_NG + 2] * lr2) ** 2
                    )  # fmt: skip
                    for a in range(3):
                        h[3 + a] = Cv[a, row]
                        hz[a] = 3 + a
                    # (Cv^T [v x])[row, b]
                    for b in range(3):
                        h[6 + b] = (
                            Cv[0, row] * Xm[0, b] + Cv[1, row] * Xm[1, b] + Cv[2, row] * Xm[2, b]
                        )
                        hz[3 + b] = 6 + b
                    h[9] = lr0
                    h[10] = lr1
                    h[11] = lr2
                    hz[6] = 9
                    hz[7] = 10
                    hz[8] = 11
                    m = 9
                    if mt_on:
                        h[i_mt + (1 if row == 1 else 0)] = ub
                        hz[m] = i_mt + (1 if row == 1 else 0)
                        m += 1
                    if la_on:  # d(-omega x l)/dl: -(r x omega)
                        h[i_la] = -(r1 * wgz - r2 * wgy)
                        h[i_la + 1] = -(r2 * wgx - r0 * wgz)
                        h[i_la + 2] = -(r0 * wgy - r1 * wgx)
                        for a in range(3):
                            hz[m + a] = i_la + a
                        m += 3
                    _scalar_update(P, dx, h, hz, m, vb, var, 0.0, PHt)
                flag |= F_NHC
            # --- companions: odometer distance over the window, barometric height -------------
            if odo_on and cmark[jj] != 0:
                zo = cz[s, jj, C_ODO]
                # the residual of the count at this epoch ends this window and starts the next
                _fresh_state(P, dx, i_oq + 1, tun[s, T_OQ_SD])
                if armed and ke > k0[s] and math.isfinite(zo):
                    vo = cz[s, jj, C_ODO_VAR]
                    if not osf_on:
                        vo += (tun[s, T_OSF_SD] * zo) ** 2
                    _odo_window_sens(tw, Tw, ra, tun[s], dt, hbg, hla)
                    # the rate's white noise in omega . a over the window: N_g^2 T_w a^2
                    for a in range(3):
                        vo += (tun[s, T_NG + a] * ra[3 + a]) ** 2 * Tw
                    if _odometer_update(
                        P, dx, h, hz, PHt, zo, vo, dist, hv, hpsi, hbg, hla, x[X_OSF], i_od,
                        osf_on, x[X_OQ], i_oq, la_on, i_la, gate,
                    ):  # fmt: skip
                        flag |= F_ODO
                    else:
                        flag |= F_REJECT
                # the end's residual becomes the next window's start (the start's marginalized)
                for i in range(n):
                    P[i_oq, i] = P[i_oq + 1, i]
                for i in range(n):
                    P[i, i_oq] = P[i, i_oq + 1]
                P[i_oq, i_oq] = P[i_oq + 1, i_oq + 1]
                dx[i_oq] = dx[i_oq + 1]
                x[X_OQ] = 0.0
                _fresh_state(P, dx, i_oq + 1, 0.0)
                armed = True
                dist = 0.0
                Tw = 0.0
                for a in range(3):
                    hv[a] = 0.0
                    hpsi[a] = 0.0
                    tw[a] = 0.0
            if baro_on and geo and math.isfinite(cz[s, jj, C_BARO]):
                if _baro_update_geo(
                    P, dx, h, hz, PHt, cz[s, jj, C_BARO], cz[s, jj, C_BARO_VAR], Lm, px, py, pz,
                    prm[A_H0], x[X_BB], i_bb, gate,
                ):  # fmt: skip
                    flag |= F_BARO
                else:
                    flag |= F_REJECT
            elif baro_on and math.isfinite(cz[s, jj, C_BARO]):
                if _baro_update(
                    P, dx, h, hz, PHt, cz[s, jj, C_BARO], cz[s, jj, C_BARO_VAR], px, py, pz,
                    x[X_BB], i_bb, wgs, gate,
                ):  # fmt: skip
                    flag |= F_BARO
                else:
                    flag |= F_REJECT
            # --- feedback ------------------------------------------------------------------------
            px -= dx[0]
            py -= dx[1]
            pz -= dx[2]
            vx -= dx[3]
            vy -= dx[4]
            vz -= dx[5]
            e0, e1, e2, e3 = qexpm1(-dx[6], -dx[7], -dx[8])
            q0, q1, q2, q3 = qmul(e0 + 1.0, e1, e2, e3, q0, q1, q2, q3)
            nq = 1.0 / math.sqrt(q0 * q0 + q1 * q1 + q2 * q2 + q3 * q3)
            q0 *= nq
            q1 *= nq
            q2 *= nq
            q3 *= nq
            for a in range(3):
                x[X_BG + a] -= dx[9 + a]
                x[X_BA + a] -= dx[12 + a]
                if gb_on:
                    x[X_GB + a] -= dx[i_gb + a]
                if sf_on:
                    x[X_SG + a] -= dx[i_sg + a]
                    x[X_SA + a] -= dx[i_sa + a]
            if osf_on:
                x[X_OSF] -= dx[i_od]
            if odo_on:
                x[X_OQ] -= dx[i_oq]
            if baro_on:
                x[X_BB] -= dx[i_bb]
            if odo_on and armed:  # a window spans this epoch: correct its distance so far
                _odo_window_sens(tw, Tw, ra, tun[s], dt, hbg, hla)
                for a in range(3):
                    dist -= hv[a] * dx[3 + a] + hpsi[a] * dx[6 + a] + hbg[a] * dx[9 + a]
                    if la_on:
                        dist -= hla[a] * dx[i_la + a]
            if mt_on:
                x[X_MT] -= dx[i_mt]
                x[X_MT + 1] -= dx[i_mt + 1]
            if la_on:
                for a in range(3):
                    x[X_LA + a] -= dx[i_la + a]
            if cg_on:
                for m in range(6):
                    x[X_CG + m] -= dx[i_cg + m]
            x[0], x[1], x[2] = px, py, pz
            x[3], x[4], x[5] = vx, vy, vz
            x[6], x[7], x[8], x[9] = q0, q1, q2, q3
            if wgs and (dx[0] != 0.0 or dx[1] != 0.0 or dx[2] != 0.0):
                Gx, Gy, Gz = earth.gravitation_nb(prm, px, py, pz)
            for i in range(n):
                for j in range(i + 1, n):
                    acc = 0.5 * (P[i, j] + P[j, i])
                    P[i, j] = acc
                    P[j, i] = acc
            for i in range(NX):
                out_x[s, jj, i] = x[i]
            for i in range(n):
                out_sd[s, jj, i] = math.sqrt(max(P[i, i], 0.0))
            if geo:  # position, velocity and attitude sigmas along the local E, N, U
                _local_level_nb(px, py, pz, Lm)
                for i0 in (I_P, I_V, I_PSI):
                    _local_sd(P, Lm, i0, out_sd[s, jj], i0)
            if store_P:
                for i in range(n):
                    for j in range(n):
                        out_P[s, jj, i, j] = P[i, j]
            out_flag[s, jj] = flag
            if gb_on and jj + 1 < J:
                # predicted GNSS bias mean decays over the next interval
                phin = math.exp(-(ep_idx[jj + 1] - ke) * dt / tun[s, T_GB_TAU])
                for a in range(3):
                    x[X_GB + a] *= phin
            if baro_on and jj + 1 < J:
                x[X_BB] *= math.exp(-(ep_idx[jj + 1] - ke) * dt / tun[s, T_BB_TAU])


# --- Python drivers -----------------------------------------------------------------------------
@dataclass
class Initial:
    """Filter start: sample index ``k0`` (S,), nominal state ``x0`` (S, NX), covariance ``P0``."""

    k0: np.ndarray
    x0: np.ndarray
    P0: np.ndarray


@dataclass
class AidedResult:
    """Filter output at the GNSS epochs (after the updates; NaN before the filter starts).

    Attributes
    ----------
    time_s, index : (J,)        epoch times [s] and IMU sample indices
    p_n, v_n : (S, J, 3)        position [m] and velocity [m/s] of the IMU in n
    q_nb : (S, J, 4)            attitude
    gyro_bias, accel_bias : (S, J, 3)  estimated biases [rad/s, m/s^2]
    gyro_sf, accel_sf : (S, J, 3)      estimated scale factors (zeros when not estimated)
    gnss_bias : (S, J, 3)       estimated receiver position bias [m]
    sd : (S, J, n)              1-sigma of every error state (:func:`state_names`; position,
                                velocity, attitude along the local E, N, U in ``geodetic``)
    P : (S, J, n, n) or None    full covariance (``store_P``)
    odo_sf : (S, J)             estimated odometer scale factor (zeros when not estimated)
    baro_bias : (S, J)          estimated barometer drift [m] (zeros when not estimated)
    flags : (S, J) int16        bits F_GNSS_P, F_GNSS_V, F_ZUPT, F_NHC, F_REJECT, F_ALIGNED,
                                F_ODO, F_BARO
    names : list of str         error-state names
    mount_angles : (S, J, 2)    estimated IMU pitch and yaw from the vehicle [rad] (zeros when
                                not estimated, :attr:`Options.mounting`)
    gyro_cc : (S, J, 6)         estimated gyro cross-coupling, pairs :data:`_CC_PAIRS` (zeros
                                when not estimated, ``Options.gyro_cross_coupling``)
    nhc_lever_b_m : (S, J, 3)   estimated NHC lever arm, body [m] (the nominal when not
                                estimated, :attr:`Options.lever_states`)
    """

    time_s: np.ndarray
    index: np.ndarray
    p_n: np.ndarray
    v_n: np.ndarray
    q_nb: np.ndarray
    gyro_bias: np.ndarray
    accel_bias: np.ndarray
    gyro_sf: np.ndarray
    accel_sf: np.ndarray
    gnss_bias: np.ndarray
    sd: np.ndarray
    P: np.ndarray | None
    flags: np.ndarray
    names: list
    odo_sf: np.ndarray | None = None
    baro_bias: np.ndarray | None = None
    mount_angles: np.ndarray | None = None
    gyro_cc: np.ndarray | None = None
    nhc_lever_b_m: np.ndarray | None = None


def initial_state(k0, p_n, v_n, q_nb, P0, gyro_bias=None, accel_bias=None) -> Initial:
    """An :class:`Initial` from explicit values (S rows each; biases default 0)."""
    p = np.atleast_2d(np.asarray(p_n, float))
    v = np.atleast_2d(np.asarray(v_n, float))
    q = np.atleast_2d(np.asarray(q_nb, float))
    P0 = np.asarray(P0, float)
    S = max(len(p), len(v), len(q), len(P0) if P0.ndim == 3 else 1)
    x0 = np.zeros((S, NX))
    x0[:, X_P : X_P + 3] = p
    x0[:, X_V : X_V + 3] = v
    x0[:, X_Q : X_Q + 4] = q / np.linalg.norm(q, axis=1, keepdims=True)
    if gyro_bias is not None:
        x0[:, X_BG : X_BG + 3] = gyro_bias
    if accel_bias is not None:
        x0[:, X_BA : X_BA + 3] = accel_bias
    k = np.broadcast_to(np.asarray(k0, np.int64), (S,)).copy()
    return Initial(k, x0, np.ascontiguousarray(np.broadcast_to(P0, (S, *np.shape(P0)[-2:]))))


def initial_covariance(
    tun: Tuning, opts: Options, sd_p, sd_v, sd_att, gnss_bias_sd=None, odo_sf_sd=0.0,
    baro_sd_m=0.0,
) -> np.ndarray:  # fmt: skip
    """Block-diagonal initial covariance from per-axis sigmas (arrays broadcast to (S, 3)).

    With GNSS bias states, a position taken from a fix has error ``b + w``: its covariance
    with the bias error ``-b`` is ``-sigma_b^2`` (``gnss_bias_sd``). ``odo_sf_sd``,
    ``baro_sd_m`` (scalars or (S,)): priors of the companion states (when in ``opts``).
    """
    sd_p, sd_v, sd_att = (np.atleast_2d(np.asarray(a, float)) for a in (sd_p, sd_v, sd_att))
    S = max(len(sd_p), len(sd_v), len(sd_att))
    P = np.zeros((S, opts.n, opts.n))
    ix = np.arange(3)
    P[:, ix, ix] = np.broadcast_to(sd_p, (S, 3)) ** 2
    P[:, 3 + ix, 3 + ix] = np.broadcast_to(sd_v, (S, 3)) ** 2
    P[:, 6 + ix, 6 + ix] = np.broadcast_to(sd_att, (S, 3)) ** 2
    P[:, 9 + ix, 9 + ix] = tun.gyro_bias_sd**2
    P[:, 12 + ix, 12 + ix] = tun.accel_bias_sd**2
    if opts.scale_factors:  # the scale-factor state carries its error on gravity
        P[:, 12 + ix, 12 + ix] -= tun.accel_static_sf_sd**2
    if opts.gyro_cross_coupling:  # the cross-coupling states carry the body-fixed tilt
        P[:, 12 + ix, 12 + ix] -= tun.accel_tilt_cc_sd**2
    i = N_BASE
    if opts.gnss_bias:
        gb = np.broadcast_to(
            np.atleast_2d(gnss_bias_sd if gnss_bias_sd is not None else 0.0), (S, 3)
        )
        P[:, i + ix, i + ix] = gb**2
        P[:, ix, i + ix] = -(gb**2)
        P[:, i + ix, ix] = -(gb**2)
        i += 3
    if opts.scale_factors:
        P[:, i + ix, i + ix] = tun.gyro_sf_sd**2
        P[:, i + 3 + ix, i + 3 + ix] = tun.accel_sf_sd**2
        i += 6
    if opts.odo_sf:
        P[:, i, i] = np.broadcast_to(np.asarray(odo_sf_sd, float), (S,)) ** 2
        i += 1
    if opts.baro:
        P[:, i, i] = np.broadcast_to(np.asarray(baro_sd_m, float), (S,)) ** 2
        i += 1
    if opts.mounting:
        P[:, i, i], P[:, i + 1, i + 1] = np.square(opts.nhc_misalignment_sd_rad)
        i += 2
    if opts.lever_states:
        # body axes: C_bv l = l + [l x] theta to first order, theta the misalignment (pitch,
        # yaw; roll not modelled)
        lx = np.cross(np.asarray(opts.nhc_lever_arm_m, float), np.eye(3))  # [l x] = lx.T
        sth = np.diag([0.0, *np.square(opts.nhc_misalignment_sd_rad)])
        P[:, i : i + 3, i : i + 3] = np.diag(np.square(opts.nhc_lever_arm_sd_m)) + lx.T @ sth @ lx
        i += 3
    if opts.gyro_cross_coupling:
        for m, (r, _) in enumerate(_CC_PAIRS):
            P[:, i + m, i + m] = tun.gyro_cc_sd[r] ** 2
    return P


def align(
    dtheta_b,
    dv_b,
    dt,
    gnss,
    tun: Tuning,
    opts: Options,
    frame: OriginFrame,
    *,
    speed_mps=5.0,
    static_s=10.0,
    level_sd_rad=LEVEL_SD_RAD,
    heading_sd_rad=HEADING_SD_RAD,
    tuning_T=None,
) -> Initial:
    """Initial alignment of every sequence from its first seconds.

    * Static start (every sample of the first ``static_s`` seconds still by the ZUPT
      thresholds) in ``wgs84`` or ``geodetic`` with gyros good enough to gyrocompass (heading sigma
      ``sqrt(sigma_bg^2 + N_g^2 / T) / (Omega cos lat) < 5 deg`` over the window ``T``): coarse
      alignment -- roll and pitch from the mean specific force (sigma ``sqrt(sigma_ba^2 +
      N_a^2 / T) / g``), yaw from the levelled mean angular rate -- at the end of the window.
    * Otherwise (moving start, flat Earth or MEMS gyros), at the first GNSS epoch whose
      horizontal speed reaches ``speed_mps``: yaw along the GNSS velocity, pitch its climb
      angle, roll 0 (a land vehicle), sigmas ``level_sd_rad`` and ``hypot(sigma_v / speed,
      heading_sd_rad)``.
    Angles are relative to the local level at the fix (in ``geodetic``, ``C_nb = C_ln^T C_lb``
    and the initial covariance of position, velocity and attitude is rotated likewise).
    Position and velocity come from the fix at that epoch (lever arm removed, position carried
    forward over the latency).

    Sequences that never qualify start at sample K (no output).
    """
    dth = np.asarray(dtheta_b, float)
    dvb = np.asarray(dv_b, float)
    S, K = dth.shape[:2]
    g0 = frame.g0
    idx = np.asarray(gnss.index)
    valid = np.asarray(gnss.valid)
    v_l = np.asarray(gnss.v_n, float)
    if frame.model == "geodetic":  # horizontal speed in the local level at each fix
        p_ok = np.where(valid[..., None], gnss.p_n, [earth.A_WGS84, 0.0, 0.0])
        v_l = np.einsum("sjik,sjk->sji", frame.C_ln(p_ok), v_l)
    vh = np.hypot(v_l[..., 0], v_l[..., 1])
    moving = valid & (np.nan_to_num(vh) >= speed_mps)
    k0 = np.full(S, K, np.int64)
    rpy = np.zeros((S, 3))
    sd_att = np.zeros((S, 3))
    p0 = np.zeros((S, 3))
    v0 = np.zeros((S, 3))
    sd_p = np.ones((S, 3))
    sd_v = np.ones((S, 3))
    ns = round(static_s / dt)
    Om = earth.OMEGA_IE * math.cos(frame.lat0_rad)
    # coarse alignment errors: bias plus the white noise averaged over the window
    Tw = max(ns, 1) * dt
    gyro_sd = math.sqrt(
        float(np.max(tun.gyro_bias_sd)) ** 2 + float(np.max(tun.gyro_white)) ** 2 / Tw
    )
    acc_sd = np.sqrt(tun.accel_bias_sd**2 + tun.accel_white**2 / Tw)
    can_compass = frame.model != "flat" and gyro_sd < math.radians(5.0) * Om
    geo = frame.model == "geodetic"
    C_ln = np.broadcast_to(np.eye(3), (S, 3, 3)).copy()  # n -> local level at the start fix
    for s in range(S):
        done = False
        if geo:
            jv = np.flatnonzero(valid[s])
            if len(jv):
                C_ln[s] = frame.C_ln(gnss.p_n[s, jv[0]])
        if can_compass and 1 <= ns < K:
            w = dth[s, 1 : ns + 1] / dt
            f = dvb[s, 1 : ns + 1] / dt
            still = np.all(np.linalg.norm(w, axis=1) < opts.zupt_gyro_radps) and np.all(
                np.abs(np.linalg.norm(f, axis=1) - g0) < opts.zupt_accel_mps2
            )
            je = np.searchsorted(idx, ns)
            if geo and je < len(idx) and valid[s, je]:
                C_ln[s] = frame.C_ln(gnss.p_n[s, je])
            if still and je < len(idx) and valid[s, je]:
                fm, wm = f.mean(0), w.mean(0)
                roll = math.atan2(fm[1], fm[2])
                pitch = math.atan2(fm[0], math.hypot(fm[1], fm[2]))
                Cl = euler_to_dcm(roll, pitch, 0.0)  # body -> level (yaw 0)
                wl = Cl @ wm
                yaw = math.atan2(wl[0], wl[1])  # w_level = Rz(-yaw) (0, Om, .)
                rpy[s] = roll, pitch, yaw
                sd_att[s] = acc_sd[1] / g0, acc_sd[0] / g0, gyro_sd / Om
                k0[s] = idx[je]
                j0 = je
                done = True
        if not done:
            js = np.flatnonzero(moving[s])
            if len(js) == 0:
                continue
            j0 = js[0]
            if geo:
                C_ln[s] = frame.C_ln(gnss.p_n[s, j0])
            v = C_ln[s] @ gnss.v_n[s, j0]  # heading from the velocity in the local level
            sp = math.hypot(v[0], v[1])
            rpy[s] = 0.0, math.atan2(v[2], sp), math.atan2(v[1], v[0])
            svh = float(gnss.sigma_v_n[s, j0, 0])
            sd_att[s] = (
                level_sd_rad,
                math.hypot(level_sd_rad, svh / sp),
                math.hypot(svh / sp, heading_sd_rad),
            )
            k0[s] = idx[j0]
        C = C_ln[s].T @ euler_to_dcm(*rpy[s])
        lb = gnss.params.lever_arm_b_m[s]
        v0[s] = gnss.v_n[s, j0]
        # the fix is late by the latency: carry it forward to the epoch
        lat = float(gnss.params.latency_s[s]) if opts.latency else 0.0
        p0[s] = gnss.p_n[s, j0] - C @ lb + lat * v0[s]
        if done:
            v0[s] = 0.0
        sd_p[s] = gnss.sigma_p_n[s, j0]
        sd_v[s] = gnss.sigma_v_n[s, j0]
    C0 = euler_to_dcm(rpy[:, 0], rpy[:, 1], rpy[:, 2])
    q0 = dcm_to_quat(np.swapaxes(C_ln, 1, 2) @ C0 if geo else C0)
    gb = None
    if opts.gnss_bias and tuning_T is not None:
        gb = tuning_T[:, T_GB_SD : T_GB_SD + 3]
        sd_p = np.sqrt(gb**2 + tuning_T[:, T_GW : T_GW + 3] ** 2)
    osd, bsd = (0.0, 0.0) if tuning_T is None else (tuning_T[:, T_OSF_SD], tuning_T[:, T_BB_SD])
    P0 = initial_covariance(tun, opts, sd_p, sd_v, sd_att, gb, osd, bsd)
    if geo:  # the sigmas are along the local axes: P_n = T P_l T^T, T = C_nl on p, v, psi
        Tr = np.broadcast_to(np.eye(opts.n), (S, opts.n, opts.n)).copy()
        for i0 in (I_P, I_V, I_PSI):
            Tr[:, i0 : i0 + 3, i0 : i0 + 3] = np.swapaxes(C_ln, 1, 2)
        P0 = Tr @ P0 @ np.swapaxes(Tr, 1, 2)
    return initial_state(k0, p0, v0, q0, P0)


def run(
    dtheta_b,
    dv_b,
    dt,
    frame: OriginFrame,
    gnss,
    tun: Tuning,
    opts: Options | None = None,
    init: Initial | None = None,
    *,
    tuning_T=None,
    store_P=False,
    seq_chunk=64,
    companions: CompanionEpochs | None = None,
) -> AidedResult:
    """Run the filter over a batch of sequences.

    Parameters
    ----------
    dtheta_b, dv_b : ndarray, shape (S, K, 3)
        IMU increments as in a shard (row k: interval ending at t_k; row 0 unused).
    dt : float
        IMU sample interval [s].
    frame : OriginFrame
        Origin and Earth model (``flat``, ``wgs84`` or ``geodetic``).
    gnss : imugen.aid.gnss.GnssData
        Fixes of the same S sequences (possibly altered by :mod:`imugen.aid.scenarios`): only
        ``index``, ``p_n``, ``v_n``, ``sigma_p_n``, ``sigma_v_n``, ``valid``,
        ``params.lever_arm_b_m`` and ``params.latency_s`` are read.
    tun : Tuning
    opts : Options
    init : Initial, optional
        Start state; default :func:`align`.
    tuning_T : ndarray (S, N_TUNE), optional
        Per-sequence tuning (default :func:`tuning_matrix` with the receiver's nominal figures);
        its companion columns are taken from ``companions`` when given.
    store_P : bool
        Also return the full covariance at every epoch.
    seq_chunk : int
        Sequences per kernel call.
    companions : CompanionEpochs, optional
        Odometer and barometer measurements at the GNSS epochs (needed by ``opts.odometer``
        and ``opts.baro``; :func:`imugen.aid.companions.filter_input`).
    """
    opts = opts or Options()
    dth = np.asarray(dtheta_b, float)
    dvb = np.asarray(dv_b, float)
    if dth.ndim != 3 or dth.shape != dvb.shape or dth.shape[2] != 3:
        raise InputError("aided", f"increments must be (S, K, 3), got {dth.shape}, {dvb.shape}")
    S = dth.shape[0]
    if gnss.p_n.shape[0] != S:
        raise InputError("aided", f"GNSS has {gnss.p_n.shape[0]} sequences, IMU {S}")
    if tuning_T is None:
        tuning_T = tuning_matrix(tun, S, gnss_receiver=gnss.receiver)
    J = len(gnss.index)
    if companions is None:
        if opts.odometer or opts.baro:
            raise InputError("aided", "odometer/barometer updates need companion measurements")
        companions = CompanionEpochs(
            np.full((S, J, 4), np.nan), np.zeros(J, np.int8), np.zeros((S, 3)), *np.zeros((3, S))
        )
    else:
        tuning_T = companion_tuning(tuning_T, companions)
    if companions.z.shape != (S, J, 4):
        raise InputError("aided", f"companion epochs {companions.z.shape}, expected {(S, J, 4)}")
    if init is None:
        init = align(dth, dvb, dt, gnss, tun, opts, frame, tuning_T=tuning_T)
    n = opts.n
    if init.P0.shape[1:] != (n, n):
        raise InputError("aided", f"P0 must be ({n}, {n}) for these options")
    idx = np.ascontiguousarray(gnss.index, np.int64)
    J = len(idx)
    prm = step_params(frame, float(dt))
    ov = opts.vector()
    out_x = np.empty((S, J, NX))
    out_sd = np.empty((S, J, n))
    out_P = np.empty((S, J if store_P else 0, n, n))
    flags = np.zeros((S, J), np.int16)
    cz = np.asarray(companions.z, float)
    cmark = np.ascontiguousarray(companions.mark, np.int8)
    clever = np.asarray(companions.lever_b_m, float)
    zp = np.nan_to_num(np.asarray(gnss.p_n, float))
    zv = np.nan_to_num(np.asarray(gnss.v_n, float))
    ok = np.asarray(gnss.valid, bool)
    lever = np.asarray(gnss.params.lever_arm_b_m, float)
    lat = np.asarray(gnss.params.latency_s, float)
    for a in range(0, S, seq_chunk):
        b = min(S, a + seq_chunk)
        _kernel(
            np.ascontiguousarray(dth[a:b]),
            np.ascontiguousarray(dvb[a:b]),
            np.ascontiguousarray(init.k0[a:b], np.int64),
            idx,
            np.ascontiguousarray(zp[a:b]),
            np.ascontiguousarray(zv[a:b]),
            np.ascontiguousarray(gnss.sigma_p_n[a:b], float),
            np.ascontiguousarray(gnss.sigma_v_n[a:b], float),
            np.ascontiguousarray(ok[a:b]),
            np.ascontiguousarray(lever[a:b]),
            np.ascontiguousarray(lat[a:b]),
            np.ascontiguousarray(init.x0[a:b]),
            np.ascontiguousarray(init.P0[a:b]),
            prm,
            np.ascontiguousarray(tuning_T[a:b]),
            ov,
            out_x[a:b],
            out_sd[a:b],
            out_P[a:b],
            flags[a:b],
            np.ascontiguousarray(cz[a:b]),
            cmark,
            np.ascontiguousarray(clever[a:b]),
        )
    return AidedResult(
        time_s=np.asarray(gnss.time_s),
        index=idx,
        p_n=out_x[..., X_P : X_P + 3],
        v_n=out_x[..., X_V : X_V + 3],
        q_nb=out_x[..., X_Q : X_Q + 4],
        gyro_bias=out_x[..., X_BG : X_BG + 3],
        accel_bias=out_x[..., X_BA : X_BA + 3],
        gyro_sf=out_x[..., X_SG : X_SG + 3],
        accel_sf=out_x[..., X_SA : X_SA + 3],
        gnss_bias=out_x[..., X_GB : X_GB + 3],
        sd=out_sd,
        P=out_P if store_P else None,
        flags=flags,
        names=opts.names(),
        odo_sf=out_x[..., X_OSF],
        baro_bias=out_x[..., X_BB],
        mount_angles=out_x[..., X_MT : X_MT + 2],
        nhc_lever_b_m=out_x[..., X_LA : X_LA + 3] + np.asarray(opts.nhc_lever_arm_m, float),
        gyro_cc=out_x[..., X_CG : X_CG + 6],
    )


def attitude_error(q_est, q_true) -> np.ndarray:
    """``psi`` with ``C_est = Exp(psi) C_true`` (rad, resolved in n); (..., 4) x2 -> (..., 3)."""
    from imugen.core.rotations import log_dcm

    return log_dcm(quat_to_dcm(q_est) @ np.swapaxes(quat_to_dcm(q_true), -1, -2))
