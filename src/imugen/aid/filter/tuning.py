"""The filter's noise model: :class:`Tuning` (from a grade's full error model) and the
per-sequence tuning matrix the kernel reads (columns ``T_*``).

Process noise, from the grade's full error model (:meth:`Tuning.from_grade`; every term
:mod:`imugen.sensors.model` injects is a state, in a prior, or in ``Q``; the kernel adds it in
:mod:`imugen.aid.filter.error_model`):

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
  cross-coupling states (``Options.gyro_cross_coupling``) model it exactly: the cross-coupling then leaves
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
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from imugen.aid.companions import CompanionEpochs
from imugen.core import units
from imugen.core.errors import InputError
from imugen.sensors.grades import TERMS, Grade, get_grade

# --- tuning matrix columns (one row per sequence) -----------------------------------------------
T_NG, T_NA, T_QBG, T_QBA, T_GB_SD, T_GB_TAU, T_GW, T_QS = 0, 3, 6, 9, 12, 15, 16, 19
T_OSF_SD, T_BB_SD, T_BB_TAU = 20, 21, 22
# motion-dependent noise (module docstring): per body axis scale-factor, cross-coupling and
# g-sensitivity sigmas, their correlation time
T_MSG, T_MCG, T_MGS, T_MSA, T_MCA = 23, 26, 29, 32, 35
T_MTAU = 38
T_OQ_SD = 39  # odometer tick residual 1-sigma, c / sqrt(12) [m]
N_TUNE = 40

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
    accel_static_cc_sd : (3,)  the part of ``accel_bias_sd`` due to the accelerometer's
        cross-coupling on gravity, ``g0 cc[:, 2]`` (left out when that cross-coupling is
        estimated, ``Options.accel_cross_coupling``)
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
    accel_static_cc_sd: np.ndarray = field(default_factory=lambda: np.zeros(3))

    @classmethod
    def from_grade(
        cls, grade: Grade | str, level: str = "nominal", inflate: float = 1.0,
        motion_corr_s: float = MOTION_CORR_S, terms=None,
    ):  # fmt: skip
        """Tuning from a grade's figures (every term the simulator injects, see the module
        docstring).

        ``level`` (:data:`LEVELS`): ``"nominal"`` (the grade's values), ``"upper"`` (the top
        of each range, for a filter that knows the grade but not the device: conservative on
        average) or ``"law"`` (the root mean square of each figure's log-uniform law,
        :func:`law_rms`, and a Gauss-Markov correlation time ``1 / E[1/tau]``: what a filter
        knowing how the simulator draws the device, not the draw, assumes; consistent over the
        population, NEES/dof 1 on average). Initial bias sigma:
        ``sqrt(turn_on^2 + sigma_GM^2 + static^2)`` (``static``: the error on gravity of an
        uncalibrated grade); bias random walk ``2 sigma_GM^2 / T + K^2`` (the Gauss-Markov's
        short-time growth plus the rate random walk; a ``slow_bias`` adds its ``sigma^2`` and
        ``2 sigma^2 / T``). ``inflate`` scales the white densities.
        ``terms``: the error terms the simulator injected (names of
        :data:`imugen.sensors.grades.TERMS`; default every configured one); the others are left out.
        """
        g = get_grade(grade)
        if level not in LEVELS:
            raise InputError("aided.tuning", f"level must be one of {LEVELS}, got {level!r}")

        def val(p):
            if p is None or (terms is not None and _term_of(spec, p) not in terms):
                return np.zeros(3)
            if level == "law" and p.lo is not None:
                return law_rms(p.lo, p.hi)
            return np.asarray(p.hi if (level == "upper" and p.hi is not None) else p.value)

        def tau_of(p):
            """The correlation time: ``1 / E[1/tau]`` of its law (``law``), else :func:`val`
            (the GM's random-walk density ``2 sigma^2 / tau`` is linear in ``1/tau``)."""
            if level == "law" and p.lo is not None:
                return 1.0 / law_mean_inverse(p.lo, p.hi)
            return val(p)

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
                    tau = float(np.min(tau_of(bi.correlation_time)))
                else:
                    tau = float(bi.flicker_band[0])
                q_gm = 2.0 * sig**2 / tau if tau > 0 else np.zeros(3)
            sb = spec.slow_bias  # a second, slow GM: its variance and driving noise add
            if sb is not None:
                s_sig = np.array([sb.sigma_from_level(x) for x in val(sb.level)])
                T_s = float(np.min(tau_of(sb.correlation_time)))
                sig = np.hypot(sig, s_sig)
                if T_s > 0:
                    q_gm = q_gm + 2.0 * s_sig**2 / T_s
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
                out["accel_static_cc_sd"] = g0 * np.array([cc[0], cc[1], 0.0])
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


LEVELS = ("nominal", "upper", "law")
"""Tuning levels (:meth:`Tuning.from_grade`, :func:`tuning_matrix`)."""


def law_rms(lo, hi) -> np.ndarray:
    """Root mean square of a figure drawn log-uniformly in ``[lo, hi]`` (uniformly when
    ``lo == 0``; ``hi`` when ``hi <= lo``): ``sqrt((hi^2 - lo^2) / (2 ln(hi / lo)))``. Over a
    population of draws an error linear in the figure has this variance: a filter tuned to it
    is consistent on average, one tuned to the top of the range conservative."""
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    with np.errstate(divide="ignore", invalid="ignore"):
        r = np.sqrt((hi**2 - lo**2) / (2.0 * np.log(hi / lo)))
    r = np.where(lo <= 0.0, hi / math.sqrt(3.0), r)
    return np.where(hi <= lo, hi, r)


def law_mean(lo, hi) -> np.ndarray:
    """Mean of a figure drawn log-uniformly in ``[lo, hi]`` (uniformly when ``lo == 0``)."""
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    with np.errstate(divide="ignore", invalid="ignore"):
        m = (hi - lo) / np.log(hi / lo)
    m = np.where(lo <= 0.0, hi / 2.0, m)
    return np.where(hi <= lo, hi, m)


def law_mean_inverse(lo, hi) -> np.ndarray:
    """``E[1/x]`` of a figure drawn log-uniformly in ``[lo, hi]`` (``lo > 0``)."""
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    with np.errstate(divide="ignore", invalid="ignore"):
        m = (1.0 / lo - 1.0 / hi) / np.log(hi / lo)
    return np.where(hi <= lo, 1.0 / hi, m)


def _term_of(spec, p) -> str:
    """Name of the term of ``spec`` whose figure is ``p`` (the bias instability's parts count
    as ``bias_instability``, the slow bias's as ``slow_bias``)."""
    for t in TERMS:
        v = getattr(spec, t)
        if v is p:
            return t
        if t in ("bias_instability", "slow_bias") and v is not None:
            if p is v.level or p is v.correlation_time:
                return t
    return ""


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


def tuning_matrix(
    tun: Tuning, S: int, gnss_params=None, gnss_receiver=None, gnss_level: str = "nominal"
) -> np.ndarray:
    """Per-sequence tuning vectors (S, N_TUNE).

    The GNSS bias model comes from ``gnss_params`` (drawn :class:`imugen.aid.gnss.ReceiverParams`,
    an oracle) or from a receiver's figures (``gnss_receiver``): ``gnss_level="nominal"``
    their nominal values, ``"law"`` what a filter knowing how the figures are drawn (not the
    draw) assumes: each sigma the root mean square of its law (:func:`law_rms`), the bias
    correlation time the law's mean (the mixture of Gauss-Markov biases has variance
    ``E[s^2]`` and low-frequency power ``2 E[s^2] E[tau]``, what the filter's averaging sees;
    the standalone receiver's nominal 60 s against draws in 30-300 s left position NEES/dof
    1.6-1.9, the law 0.9-1.0, r26 study).
    """
    if gnss_level not in ("nominal", "law"):
        raise InputError("aided.tuning", f"gnss_level must be nominal or law, got {gnss_level!r}")
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

        def fig(k, law=law_rms):
            g = f[k]
            if gnss_level == "law" and g.lo is not None:
                return float(law(g.lo, g.hi))
            return g.value

        T[:, T_GB_SD : T_GB_SD + 3] = [fig("position_bias_h_m")] * 2 + [fig("position_bias_v_m")]
        T[:, T_GB_TAU] = fig("position_bias_tau_s", law_mean)
        T[:, T_GW : T_GW + 3] = [fig("position_white_h_m")] * 2 + [fig("position_white_v_m")]
    return T
