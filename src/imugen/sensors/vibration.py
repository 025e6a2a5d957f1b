"""Vibration of the IMU case: a vehicle-class spectrum added to the ideal IMU as a real motion.

A car's or an aircraft's IMU shakes: engine (or propeller) harmonics and broadband road (or
airframe) noise; a multirotor's: rotor harmonics locked to the rotor speed. Networks trained
on clean synthetic IMU data must learn to ignore it, so a shard can carry it
(``simulate(..., vibration="car" | "aircraft" | "quadrotor" | "vehicle" | FILE.yaml)``, CLI
``--vibration``, config ``simulate.vibration``; ``quadrotor`` and a model fitted by
``imugen vibration fit`` come from :mod:`imugen.sensors.vibration_model`, whose
:func:`~imugen.sensors.vibration_model.kernel_profile` gives their :class:`Profile`). It is drawn per sequence from its own random
stream and is the same whatever error terms are on.

Motion
------
The case moves relative to the vehicle body ``b`` of the truth by a small rotation
``dtheta_v(t)`` (rad, body axes) and its mounting point by an acceleration ``a_v(t)``
(m/s^2, body axes), each a sum of sinusoids ``A sin(phi(t))``:

* engine harmonics: ``phi = phi_0 + n Theta(t)``, ``n`` the engine order, ``Theta`` the
  crank (or propeller shaft) angle, whose rate follows the vehicle's speed (:func:`shaft_rpm`);
  linear and small angular parts; constant amplitudes (a per-sequence gain);
* road / airframe noise: linear, ``N`` lines per axis with frequencies drawn uniformly in
  the band, equal amplitudes giving the profile's RMS at the reference speed, scaled by
  ``min(speed / v_ref, 2)`` (zero at a stop); angular (a fitted model's gyro broadband,
  ``gyro_noise_radps``): ``gyro_lines`` lines per axis, one drawn uniformly in each equal
  slice of the band (a flat spectrum at the slice width), of rate amplitude
  ``sigma sqrt(2 / N)`` (angle ``rate / omega``), so the rate's variance is ``sigma^2``,
  scaled with the speed alike;
* fixed lines (structural resonances, ``fixed_lines``): linear and angular lines at their own
  frequency, ``phi = phi_0 + 2 pi f t``, at the harmonics' gain.

Frequencies and amplitudes are held over each sample interval (the phase is continuous and
piecewise linear), so every integral over an interval is a closed form. The linear phases start
at ``+-pi/2`` (the case starts at the vehicle's velocity: the oscillation's velocity
``-A cos(phi) / omega`` has no mean), the angular ones anywhere, with ``dtheta_v(t) = sum
B (sin phi(t) - sin phi_0)`` so the case starts at the vehicle's attitude.

What the IMU measures (case frame ``c = b Exp(dtheta_v)``; ``omega``, ``f``, ``dtheta``,
``dv`` the truth's)
    rate: ``omega_c = omega - dtheta_v x omega + d(dtheta_v)/dt - 1/2 dtheta_v x
    d(dtheta_v)/dt`` (second order in the angle, a few 1e-5 rad, so the omitted third-order
    terms are ~1e-10 relative), ``f_c = Exp(-dtheta_v) (f + a_v)`` (exact);
    compensated increments (interval ``[t_{k-1}, t_k]``, mean body rate ``w = dtheta / dt``):
    ``dtheta_c = Log(Exp(-dtheta_v(t_{k-1})) Exp(dtheta) Exp(dtheta_v(t_k)))`` (exact);
    ``dv_c = Exp(-dtheta_v(t_{k-1})) (dv + int a_v + w x int (t - t_{k-1}) a_v)`` -- exact
    for the case rotation, first order in the body rotation within the interval (relative
    error ``(|w| dt)^2 / 6``, 4e-6 at 0.5 rad/s and 100 Hz);
    raw increments (plain integrals): ``dtheta_c = dtheta + dtheta_v(t_k) - dtheta_v(t_{k-1})
    - (int dtheta_v) x w - 1/2 int dtheta_v x d(dtheta_v)/dt`` -- the last term is the coning
    rectification of synchronous angular vibration, integrated in closed form for every pair of
    components but the angular broadband's (independent lines at distinct frequencies: their
    pairs' terms have zero mean, at most ``|dtheta_v| |d(dtheta_v)/dt| dt / 2`` an interval,
    ~1e-9 rad for a quadrotor's 1 deg/s, and are left out); ``dv_c = dv + int a_v - (int
    dtheta_v) x dv / dt`` (first order in the case angle: the product of angular and linear
    vibration, ~1e-5 of ``a_v``, is left out).
Rate samples are instantaneous: lines above the Nyquist frequency alias in them as in an
unfiltered sampled sensor; increments integrate every line exactly.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from imugen.core.errors import InputError
from imugen.core.jit import njit

G0 = 9.80665
KINDS = ("off", "car", "aircraft", "quadrotor", "vehicle")
"""Values of the ``vibration`` option (``vehicle``: the truth's vehicle class decides), besides
a fitted model's YAML file (``*.yaml``, ``*.yml``)."""
VEHICLE_PROFILE = {"car": "car", "aircraft": "aircraft", "multirotor": "quadrotor"}
"""Vehicle class -> profile for ``vibration="vehicle"`` (pedestrians and bicycles: none)."""


@dataclass(frozen=True)
class Profile:
    """A vehicle class's vibration spectrum (nominal levels; a sequence scales them).

    Attributes
    ----------
    name : str
    orders : tuple of float
        Engine (shaft) orders of the harmonics.
    accel_g : (n_orders, 3) tuple
        Linear amplitude of each harmonic per body axis [g].
    angle_rad : (n_orders, 3) tuple
        Angular amplitude of each harmonic per body axis [rad].
    idle_rpm, shift_rpm : float
        Shaft speed at a stop; a car shifts up when the next gear keeps the engine below
        ``shift_rpm`` (aircraft: cruise rpm).
    gears, final_drive, wheel_radius_m : car drivetrain (rpm = speed / r * gear * final * 60 / 2 pi)
    ground_mps, air_mps : aircraft: idle below ``ground_mps``, cruise above ``air_mps``,
        linear in between.
    lag_s : float
        First-order lag of the shaft speed (shifts and throttle are not instantaneous).
    band_hz : (2,) tuple
        Band of the broadband noise lines.
    noise_g : (3,) tuple
        RMS of the broadband noise per body axis at ``ref_mps`` [g].
    ref_mps : float
    lines : int
        Noise lines per axis.
    gain_range : (2,) tuple
        Per-sequence gains of the harmonics and of the noise, log-uniform in this range.
    source : str
        Where the numbers come from.
    """

    name: str
    orders: tuple
    accel_g: tuple
    angle_rad: tuple
    idle_rpm: float
    shift_rpm: float
    gears: tuple = ()
    final_drive: float = 0.0
    wheel_radius_m: float = 0.0
    ground_mps: float = 0.0
    air_mps: float = 0.0
    lag_s: float = 0.3
    band_hz: tuple = (10.0, 100.0)
    noise_g: tuple = (0.0, 0.0, 0.0)
    ref_mps: float = 20.0
    lines: int = 24
    gain_range: tuple = (0.5, 2.0)
    source: str = ""
    rotation: str = "speed"
    """What drives the harmonics: ``"speed"`` (the shaft-speed law of the vehicle speed; the
    broadband scales with the speed), ``"rotor"`` (the truth's rotor speed, its
    ``rotor_*_rpm`` columns, else ``idle_rpm``; broadband at its level) or ``"constant"``
    (``idle_rpm``; broadband at its level)."""
    gyro_noise_radps: tuple = (0.0, 0.0, 0.0)
    """RMS of the angular broadband per body axis [rad/s] (as ``noise_g``: at ``ref_mps``,
    scaled with the speed when ``rotation`` is ``"speed"``): ``gyro_lines`` angular lines per
    axis, one drawn uniformly in each of ``gyro_lines`` equal slices of ``band_hz``, of equal
    rate amplitude ``rms sqrt(2 / gyro_lines)`` (angle ``rate / omega``)."""
    gyro_lines: int = 0
    fixed_lines: tuple = ()
    """Lines at fixed frequencies (structural resonances): ``(freq_hz, accel_g (3,),
    angle_rad (3,))`` each, per body axis, scaled by the harmonics' gain."""

    def as_dict(self) -> dict:
        return {k: getattr(self, k) for k in self.__dataclass_fields__}


PROFILES = {
    "car": Profile(
        name="car",
        # four-stroke inline four: two firings per crank turn, so the firing frequency is
        # engine order 2 (26.7 Hz at 800 rpm idle); orders 4 and 6 are its harmonics
        orders=(2.0, 4.0, 6.0),
        accel_g=((0.01, 0.01, 0.03), (0.005, 0.005, 0.015), (0.0025, 0.0025, 0.0075)),
        # rocking of the body on its mounts (roll > pitch): 2e-5 rad at 26.7 Hz is 0.19 deg/s
        angle_rad=((2e-5, 1e-5, 0.0), (5e-6, 2.5e-6, 0.0), (0.0, 0.0, 0.0)),
        idle_rpm=800.0,
        shift_rpm=2500.0,
        gears=(3.5, 2.0, 1.35, 1.0, 0.8),
        final_drive=4.0,
        wheel_radius_m=0.31,
        lag_s=0.3,
        band_hz=(10.0, 100.0),
        noise_g=(0.05, 0.05, 0.1),
        ref_mps=20.0,
        lines=24,
        source=(
            "documented typical values, not a measurement: car body vibration 0.05-0.5 g RMS "
            "in 10-100 Hz (road noise 0.1 g vertical, 0.05 g lateral/longitudinal at 20 m/s); "
            "engine firing order of an inline four (order 2) and its harmonics at 0.03/0.015/"
            "0.0075 g vertical; a five-speed gearbox (3.5/2.0/1.35/1.0/0.8, final drive 4.0, "
            "0.31 m wheels) shifting up at 2500 rpm"
        ),
    ),
    "aircraft": Profile(
        name="aircraft",
        # two-blade propeller: shaft order 1 (1P imbalance), blade passage 2P and 4P
        orders=(1.0, 2.0, 4.0),
        accel_g=((0.01, 0.01, 0.02), (0.02, 0.02, 0.05), (0.005, 0.005, 0.015)),
        angle_rad=((1e-5, 1e-5, 1e-5), (5e-6, 5e-6, 2.5e-6), (0.0, 0.0, 0.0)),
        idle_rpm=1000.0,
        shift_rpm=2400.0,
        ground_mps=15.0,
        air_mps=30.0,
        lag_s=1.0,
        band_hz=(5.0, 100.0),
        noise_g=(0.02, 0.02, 0.05),
        ref_mps=60.0,
        lines=24,
        source=(
            "documented typical values, not a measurement: light aircraft with a two-blade "
            "propeller, 1000 rpm ground idle below 15 m/s, 2400 rpm above 30 m/s (1P 40 Hz, "
            "blade passage 80 Hz); 1P/2P/4P vertical 0.02/0.05/0.015 g; airframe noise "
            "0.05 g vertical at 60 m/s in 5-100 Hz"
        ),
    ),
}


def profile_for(option, vehicle: str | None = None) -> Profile | None:
    """The profile an option selects (``None``: no vibration).

    Parameters
    ----------
    option : {"off", "car", "aircraft", "vehicle"} or None
    vehicle : str, optional
        The truth's vehicle class, for ``"vehicle"``.
    """
    if option is None or option == "off" or option is False:
        return None
    if option == "vehicle":
        option = VEHICLE_PROFILE.get(vehicle or "")
        if option is None:
            return None
    if option in PROFILES:
        return PROFILES[option]
    if option == "quadrotor" or str(option).endswith((".yaml", ".yml")):
        from imugen.sensors.vibration_model import kernel_profile  # (imports this module)

        return kernel_profile(option)
    raise InputError(
        "--vibration", f"must be one of {', '.join(KINDS)} or a model's .yaml, got {option!r}"
    )


def shaft_rpm(speed_mps, profile: Profile, dt: float) -> np.ndarray:
    """Shaft (engine / propeller) speed [rpm] at each sample of a speed profile.

    Car: the lowest gear that keeps the engine at or below ``shift_rpm`` (the top gear when
    none does), never below idle. Aircraft: idle on the ground, cruise rpm in the air, linear
    in between. Then a first-order lag ``lag_s`` (exact discretization), starting at the
    target.
    """
    v = np.abs(np.asarray(speed_mps, dtype=float))
    if profile.gears:
        wheel_rpm = v / profile.wheel_radius_m * 60.0 / (2.0 * math.pi)
        per_gear = wheel_rpm[:, None] * np.asarray(profile.gears)[None] * profile.final_drive
        ok = per_gear <= profile.shift_rpm
        first = np.where(ok.any(axis=1), ok.argmax(axis=1), len(profile.gears) - 1)
        target = np.maximum(per_gear[np.arange(len(v)), first], profile.idle_rpm)
    else:
        x = np.clip((v - profile.ground_mps) / (profile.air_mps - profile.ground_mps), 0.0, 1.0)
        target = profile.idle_rpm + x * (profile.shift_rpm - profile.idle_rpm)
    if profile.lag_s <= 0 or len(target) == 0:
        return target
    a = math.exp(-dt / profile.lag_s)
    out = np.empty_like(target)
    r = target[0]
    for k, x in enumerate(target):
        r = a * r + (1.0 - a) * x
        out[k] = r
    return out


_SERIES = 1e-2  # below this phase advance per interval the integrals use their Taylor series
_RESYNC = 64
"""Angular lines at a fixed frequency step their sin/cos by a rotation each sample and take
them from the phase at every sample index that is a multiple of this (so a sample's values
depend on its index only, never on the chunks)."""


@njit(cache=True)
def _isin(s0, c0, s1, c1, w, dt):
    """int_0^dt sin(phi) for phi linear at rate w, from (sin, cos) at both ends."""
    x = w * dt
    if abs(x) < _SERIES:
        return dt * (s0 + c0 * x / 2.0 - s0 * x * x / 6.0 - c0 * x**3 / 24.0)
    return (c0 - c1) / w


@njit(cache=True)
def _icos(s0, c0, s1, c1, w, dt):
    """int_0^dt cos(phi) for phi linear at rate w."""
    x = w * dt
    if abs(x) < _SERIES:
        return dt * (c0 - s0 * x / 2.0 - c0 * x * x / 6.0 + s0 * x**3 / 24.0)
    return (s1 - s0) / w


@njit(cache=True)
def _it_sin(s0, c0, s1, c1, w, dt):
    """int_0^dt tau sin(phi(tau)) for phi linear at rate w."""
    x = w * dt
    if abs(x) < _SERIES:
        return dt * dt * (s0 / 2.0 + c0 * x / 3.0 - s0 * x * x / 8.0)
    return -dt * c1 / w + (s1 - s0) / (w * w)


@njit(cache=True)
def _rot_minus(th, v, out):
    """out = Exp(-th) v (Rodrigues)."""
    a = math.sqrt(th[0] * th[0] + th[1] * th[1] + th[2] * th[2])
    if a < 1e-4:
        s, c = 1.0 - a * a / 6.0, 0.5 - a * a / 24.0
    else:
        s, c = math.sin(a) / a, (1.0 - math.cos(a)) / (a * a)
    # Exp(-th) v = v - s (th x v) + c th x (th x v)
    x0 = th[1] * v[2] - th[2] * v[1]
    x1 = th[2] * v[0] - th[0] * v[2]
    x2 = th[0] * v[1] - th[1] * v[0]
    y0 = th[1] * x2 - th[2] * x1
    y1 = th[2] * x0 - th[0] * x2
    y2 = th[0] * x1 - th[1] * x0
    out[0] = v[0] - s * x0 + c * y0
    out[1] = v[1] - s * x1 + c * y1
    out[2] = v[2] - s * x2 + c * y2


@njit(cache=True)
def _qexp(v, q):
    """q = Exp(v), scalar first."""
    a = math.sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2])
    h = 0.5 - a * a / 48.0 if a < 1e-4 else math.sin(0.5 * a) / a
    q[0] = math.cos(0.5 * a)
    q[1] = h * v[0]
    q[2] = h * v[1]
    q[3] = h * v[2]


@njit(cache=True)
def _qmul(p, q, out):
    out[0] = p[0] * q[0] - p[1] * q[1] - p[2] * q[2] - p[3] * q[3]
    out[1] = p[0] * q[1] + p[1] * q[0] + p[2] * q[3] - p[3] * q[2]
    out[2] = p[0] * q[2] - p[1] * q[3] + p[2] * q[0] + p[3] * q[1]
    out[3] = p[0] * q[3] + p[1] * q[2] - p[2] * q[1] + p[3] * q[0]


@njit(cache=True)
def _qlog(q, v):
    """v = Log(q) (rotation vector, |v| <= pi)."""
    w = q[0]
    sgn = 1.0 if w >= 0.0 else -1.0
    n = math.sqrt(q[1] * q[1] + q[2] * q[2] + q[3] * q[3])
    if n < 1e-12:
        k = 2.0 / (sgn * w)
    else:
        k = 2.0 * math.atan2(n, sgn * w) / n
    v[0] = sgn * k * q[1]
    v[1] = sgn * k * q[2]
    v[2] = sgn * k * q[3]


@njit(cache=True)
def _apply_kernel(
    k0,
    dt,
    shaft_angle,
    shaft_rate,
    noise_scale,
    l_axis,
    l_amp,
    l_order,
    l_w,
    l_phi0,
    l_noise,
    a_axis,
    a_amp,
    a_order,
    a_w,
    a_phi0,
    a_noise,
    omega_b,
    f_b,
    dtheta,
    dv,
    gyro,
    f_c,
    dth,
    dv_c,
    raw,
):
    L = omega_b.shape[0]
    Cl = l_amp.shape[0]
    Ca = a_amp.shape[0]
    ls = np.empty(Cl)
    lc = np.empty(Cl)
    as_ = np.empty(Ca)
    ac = np.empty(Ca)
    s0a = np.empty(Ca)
    c0a = np.empty(Ca)
    wa = np.empty(Ca)
    sb = np.empty(Ca)
    syn = np.empty(Ca, np.int64)  # components in the coning pairs: all but the broadband
    n_syn = 0
    rec = np.empty(Ca, np.bool_)  # fixed-frequency components: sin/cos by rotation steps
    cd = np.empty(Ca)
    sd = np.empty(Ca)
    for c in range(Ca):
        sb[c] = math.sin(a_phi0[c])
        rec[c] = a_order[c] == 0.0 and a_w[c] != 0.0
        cd[c] = math.cos(a_w[c] * dt)
        sd[c] = math.sin(a_w[c] * dt)
        if not a_noise[c]:
            syn[n_syn] = c
            n_syn += 1
    th = np.zeros(3)
    th_p = np.zeros(3)
    th_dot = np.zeros(3)
    int_th = np.zeros(3)
    con = np.zeros(3)
    a_v = np.zeros(3)
    int_a = np.zeros(3)
    int_ta = np.zeros(3)
    tmp = np.zeros(3)
    out = np.zeros(3)
    qa = np.zeros(4)
    qb = np.zeros(4)
    qc = np.zeros(4)
    qd = np.zeros(4)
    for j in range(L):
        k = k0 + j
        kp = k - 1 if k > 0 else 0
        if j == 0:  # sin/cos at the sample before the chunk (afterwards carried over)
            for c in range(Cl):
                ph = l_phi0[c] + l_order[c] * shaft_angle[kp] + l_w[c] * kp * dt
                ls[c] = math.sin(ph)
                lc[c] = math.cos(ph)
            for c in range(Ca):
                kb = kp - kp % _RESYNC if rec[c] else kp
                ph = a_phi0[c] + a_order[c] * shaft_angle[kb] + a_w[c] * kb * dt
                s1 = math.sin(ph)
                c1 = math.cos(ph)
                for _ in range(kp - kb):
                    s1, c1 = s1 * cd[c] + c1 * sd[c], c1 * cd[c] - s1 * sd[c]
                as_[c] = s1
                ac[c] = c1
        for i in range(3):
            th[i] = 0.0
            th_p[i] = 0.0
            th_dot[i] = 0.0
            int_th[i] = 0.0
            con[i] = 0.0
            a_v[i] = 0.0
            int_a[i] = 0.0
            int_ta[i] = 0.0
        # angular components
        for c in range(Ca):
            w = a_order[c] * shaft_rate[k] + a_w[c]
            s0 = as_[c]
            c0 = ac[c]
            if rec[c] and k % _RESYNC != 0:
                s1 = s0 * cd[c] + c0 * sd[c]
                c1 = c0 * cd[c] - s0 * sd[c]
            else:
                ph = a_phi0[c] + a_order[c] * shaft_angle[k] + a_w[c] * k * dt
                s1 = math.sin(ph)
                c1 = math.cos(ph)
            B = a_amp[c] * (noise_scale[k] if a_noise[c] else 1.0)
            i = a_axis[c]
            th[i] += B * (s1 - sb[c])
            th_p[i] += B * (s0 - sb[c])
            th_dot[i] += B * w * c1
            int_th[i] += B * (_isin(s0, c0, s1, c1, w, dt) - sb[c] * dt)
            s0a[c] = s0
            c0a[c] = c0
            wa[c] = w
            as_[c] = s1
            ac[c] = c1
        for pa in range(n_syn if raw else 0):  # coning: raw increments only
            for pb in range(n_syn):
                a = syn[pa]
                b = syn[pb]
                ia = a_axis[a]
                ib = a_axis[b]
                if ia == ib:
                    continue
                sa0, ca0, sa1, ca1 = s0a[a], c0a[a], as_[a], ac[a]
                sb0, cb0, sb1, cb1 = s0a[b], c0a[b], as_[b], ac[b]
                plus = _isin(
                    sa0 * cb0 + ca0 * sb0,
                    ca0 * cb0 - sa0 * sb0,
                    sa1 * cb1 + ca1 * sb1,
                    ca1 * cb1 - sa1 * sb1,
                    wa[a] + wa[b],
                    dt,
                )
                minus = _isin(
                    sa0 * cb0 - ca0 * sb0,
                    ca0 * cb0 + sa0 * sb0,
                    sa1 * cb1 - ca1 * sb1,
                    ca1 * cb1 + sa1 * sb1,
                    wa[a] - wa[b],
                    dt,
                )
                i2 = sb[a] * _icos(sb0, cb0, sb1, cb1, wa[b], dt)
                kk = -0.5 * a_amp[a] * a_amp[b] * wa[b] * (0.5 * (plus + minus) - i2)
                # e_ia x e_ib = +-e_third
                third = 3 - ia - ib
                sign = 1.0 if (ib - ia) % 3 == 1 else -1.0
                con[third] += sign * kk
        # linear components
        for c in range(Cl):
            ph = l_phi0[c] + l_order[c] * shaft_angle[k] + l_w[c] * k * dt
            w = l_order[c] * shaft_rate[k] + l_w[c]
            s1 = math.sin(ph)
            c1 = math.cos(ph)
            A = l_amp[c] * (noise_scale[k] if l_noise[c] else 1.0)
            i = l_axis[c]
            a_v[i] += A * s1
            int_a[i] += A * _isin(ls[c], lc[c], s1, c1, w, dt)
            int_ta[i] += A * _it_sin(ls[c], lc[c], s1, c1, w, dt)
            ls[c] = s1
            lc[c] = c1
        # measurements
        wm0 = dtheta[j, 0] / dt
        wm1 = dtheta[j, 1] / dt
        wm2 = dtheta[j, 2] / dt
        ob = omega_b[j]
        gyro[j, 0] = (
            ob[0]
            - (th[1] * ob[2] - th[2] * ob[1])
            + th_dot[0]
            - 0.5 * (th[1] * th_dot[2] - th[2] * th_dot[1])
        )
        gyro[j, 1] = (
            ob[1]
            - (th[2] * ob[0] - th[0] * ob[2])
            + th_dot[1]
            - 0.5 * (th[2] * th_dot[0] - th[0] * th_dot[2])
        )
        gyro[j, 2] = (
            ob[2]
            - (th[0] * ob[1] - th[1] * ob[0])
            + th_dot[2]
            - 0.5 * (th[0] * th_dot[1] - th[1] * th_dot[0])
        )
        for i in range(3):
            tmp[i] = f_b[j, i] + a_v[i]
        _rot_minus(th, tmp, out)
        for i in range(3):
            f_c[j, i] = out[i]
        if raw:
            # integrals of the case's rate and specific force
            dth[j, 0] = dtheta[j, 0] + th[0] - th_p[0] - (int_th[1] * wm2 - int_th[2] * wm1)
            dth[j, 1] = dtheta[j, 1] + th[1] - th_p[1] - (int_th[2] * wm0 - int_th[0] * wm2)
            dth[j, 2] = dtheta[j, 2] + th[2] - th_p[2] - (int_th[0] * wm1 - int_th[1] * wm0)
            fm0, fm1, fm2 = dv[j, 0] / dt, dv[j, 1] / dt, dv[j, 2] / dt
            dv_c[j, 0] = dv[j, 0] + int_a[0] - (int_th[1] * fm2 - int_th[2] * fm1)
            dv_c[j, 1] = dv[j, 1] + int_a[1] - (int_th[2] * fm0 - int_th[0] * fm2)
            dv_c[j, 2] = dv[j, 2] + int_a[2] - (int_th[0] * fm1 - int_th[1] * fm0)
            for i in range(3):
                dth[j, i] += con[i]
        else:
            # rotation vector of Exp(-th_p) Exp(dtheta) Exp(th) (exact), and the velocity
            # change in the case frame at the interval start
            for i in range(3):
                tmp[i] = -th_p[i]
            _qexp(tmp, qa)
            for i in range(3):
                tmp[i] = dtheta[j, i]
            _qexp(tmp, qb)
            _qmul(qa, qb, qc)
            _qexp(th, qa)
            _qmul(qc, qa, qd)
            _qlog(qd, out)
            for i in range(3):
                dth[j, i] = out[i]
            tmp[0] = dv[j, 0] + int_a[0] + (wm1 * int_ta[2] - wm2 * int_ta[1])
            tmp[1] = dv[j, 1] + int_a[1] + (wm2 * int_ta[0] - wm0 * int_ta[2])
            tmp[2] = dv[j, 2] + int_a[2] + (wm0 * int_ta[1] - wm1 * int_ta[0])
            _rot_minus(th_p, tmp, out)
            for i in range(3):
                dv_c[j, i] = out[i]
        if k == 0:
            for i in range(3):
                dth[j, i] = 0.0
                dv_c[j, i] = 0.0


class Vibration:
    """A profile on one truth: the shared shaft angle and speed scaling, per sample.

    Parameters
    ----------
    profile : Profile
    speed_mps : (K,) array
        Vehicle speed at each sample.
    dt : float
        Sample interval [s].
    """

    def __init__(self, profile: Profile, speed_mps, dt: float, rotor_rpm=None):
        self.profile = profile
        self.dt = float(dt)
        speed = np.asarray(speed_mps, dtype=float)
        self.K = len(speed)
        if profile.rotation == "speed":
            rpm = shaft_rpm(speed, profile, self.dt)
        elif profile.rotation == "rotor" and rotor_rpm is not None:
            rpm = np.asarray(rotor_rpm, dtype=float)
        else:
            rpm = np.full(self.K, float(profile.idle_rpm))
        # shaft rate held over interval k (ending at sample k); sample 0 takes interval 1's
        omega = 2.0 * math.pi * rpm / 60.0
        self.shaft_radps = omega
        self.shaft_angle = np.concatenate([[0.0], np.cumsum(omega[1:] * self.dt)])
        self.noise_scale = (
            np.minimum(speed / profile.ref_mps, 2.0)
            if profile.rotation == "speed"
            else np.ones(self.K)
        )

    def draw(self, rng: np.random.Generator) -> SequenceVibration:
        """One sequence's vibration (a fixed number of variates, whatever the profile)."""
        p = self.profile
        n_ord = len(p.orders)
        gains = p.gain_range[0] * (p.gain_range[1] / p.gain_range[0]) ** rng.random(2)
        lin_sign = rng.integers(0, 2, size=(n_ord + p.lines, 3))
        ang_phase = rng.uniform(0.0, 2.0 * math.pi, size=(n_ord, 3))
        freq = rng.uniform(p.band_hz[0], p.band_hz[1], size=(p.lines, 3))
        extra = {}
        if any(p.gyro_noise_radps) or p.fixed_lines:  # (drawn after the others: profiles
            n_g, n_f = p.gyro_lines, len(p.fixed_lines)  # without these draw as before)
            lo, hi = p.band_hz
            slot = (np.arange(n_g)[:, None] + rng.random((n_g, 3))) / max(n_g, 1)
            extra = {
                "gyro_freq_hz": lo + (hi - lo) * slot,
                "gyro_phase": rng.uniform(0.0, 2.0 * math.pi, size=(n_g, 3)),
                "fixed_sign": rng.integers(0, 2, size=(n_f, 3)),
                "fixed_phase": rng.uniform(0.0, 2.0 * math.pi, size=(n_f, 3)),
            }
        return SequenceVibration(self, gains, lin_sign, ang_phase, freq, **extra)


@dataclass
class SequenceVibration:
    """One sequence's drawn vibration, applied to truth chunks (see the module docstring)."""

    vib: Vibration
    gains: np.ndarray  # (2,) harmonics, noise
    lin_sign: np.ndarray  # (orders + lines, 3) 0/1: linear start phase pi/2 or 3 pi/2
    ang_phase: np.ndarray  # (orders, 3) angular start phases
    freq_hz: np.ndarray  # (lines, 3) noise line frequencies
    gyro_freq_hz: np.ndarray | None = None  # (gyro_lines, 3) angular noise line frequencies
    gyro_phase: np.ndarray | None = None  # (gyro_lines, 3) their start phases
    fixed_sign: np.ndarray | None = None  # (fixed lines, 3) 0/1 linear start phases
    fixed_phase: np.ndarray | None = None  # (fixed lines, 3) angular start phases
    lin: dict = field(init=False)
    ang: dict = field(init=False)

    def __post_init__(self):
        p = self.vib.profile
        n_ord = len(p.orders)
        axis, amp, order, w, phi0, noise = [], [], [], [], [], []
        acc = np.asarray(p.accel_g) * G0 * self.gains[0]
        line_amp = np.asarray(p.noise_g) * G0 * self.gains[1] * math.sqrt(2.0 / p.lines)
        for i in range(3):
            for o in range(n_ord):
                if acc[o, i] > 0:
                    axis.append(i)
                    amp.append(acc[o, i])
                    order.append(p.orders[o])
                    w.append(0.0)
                    phi0.append(math.pi * (0.5 + self.lin_sign[o, i]))
                    noise.append(False)
            for n in range(p.lines):
                if line_amp[i] > 0:
                    axis.append(i)
                    amp.append(line_amp[i])
                    order.append(0.0)
                    w.append(2.0 * math.pi * self.freq_hz[n, i])
                    phi0.append(math.pi * (0.5 + self.lin_sign[n_ord + n, i]))
                    noise.append(True)
            for n, (f_hz, acc_g, _) in enumerate(p.fixed_lines):
                if acc_g[i] > 0:
                    axis.append(i)
                    amp.append(acc_g[i] * G0 * self.gains[0])
                    order.append(0.0)
                    w.append(2.0 * math.pi * f_hz)
                    phi0.append(math.pi * (0.5 + self.fixed_sign[n, i]))
                    noise.append(False)
        self.lin = {
            "axis": np.array(axis, int),
            "amp": np.array(amp, float),
            "order": np.array(order, float),
            "w": np.array(w, float),
            "phi0": np.array(phi0, float),
            "noise": np.array(noise, bool),
        }
        self.lin["onehot"] = np.eye(3)[self.lin["axis"]].reshape(-1, 3)
        ang = np.asarray(p.angle_rad) * self.gains[0]
        a_axis, a_amp, a_order, a_w, a_phi0, a_noise = [], [], [], [], [], []

        def add(i, amp, order, w, phi0, noise):
            a_axis.append(i)
            a_amp.append(amp)
            a_order.append(order)
            a_w.append(w)
            a_phi0.append(phi0)
            a_noise.append(noise)

        for o in range(n_ord):
            for i in range(3):
                if ang[o, i] > 0:
                    add(i, ang[o, i], p.orders[o], 0.0, self.ang_phase[o, i], False)
        for n, (f_hz, _, ang_rad) in enumerate(p.fixed_lines):
            for i in range(3):
                if ang_rad[i] > 0:
                    w = 2.0 * math.pi * f_hz
                    add(i, ang_rad[i] * self.gains[0], 0.0, w, self.fixed_phase[n, i], False)
        # angular broadband: rate amplitude rms sqrt(2 / N) per line, angle rate / omega
        rate_amp = (
            np.asarray(p.gyro_noise_radps) * self.gains[1] * math.sqrt(2.0 / max(p.gyro_lines, 1))
        )
        for i in range(3):
            for n in range(p.gyro_lines if rate_amp[i] > 0 else 0):
                w = 2.0 * math.pi * self.gyro_freq_hz[n, i]
                add(i, rate_amp[i] / w, 0.0, w, self.gyro_phase[n, i], True)
        self.ang = {
            "axis": np.array(a_axis, int),
            "amp": np.array(a_amp, float),
            "order": np.array(a_order, float),
            "w": np.array(a_w, float),
            "phi0": np.array(a_phi0, float),
            "noise": np.array(a_noise, bool),
        }
        self.ang["onehot"] = np.eye(3)[self.ang["axis"]].reshape(-1, 3)

    # --- per-sample quantities ---------------------------------------------------------
    def _phase(self, c, ks):
        """Phases (len(ks), C) and the rates held over the intervals ending at ks."""
        v = self.vib
        phi = c["phi0"][None] + c["order"][None] * v.shaft_angle[ks][:, None]
        w = c["order"][None] * v.shaft_radps[ks][:, None]
        if "w" in c:
            phi = phi + c["w"][None] * (ks * v.dt)[:, None]
            w = w + c["w"][None]
        return phi, w

    def _amp(self, c, ks):
        """Amplitudes (len(ks), C): the noise lines scaled with the speed."""
        scale = np.where(c["noise"][None], self.vib.noise_scale[ks][:, None], 1.0)
        return c["amp"][None] * scale

    def angle(self, ks) -> np.ndarray:
        """Case rotation relative to the body ``dtheta_v`` (len(ks), 3) [rad]."""
        c = self.ang
        out = np.zeros((len(ks), 3))
        if len(c["amp"]):
            phi, _ = self._phase(c, ks)
            out += (self._amp(c, ks) * (np.sin(phi) - np.sin(c["phi0"]))) @ c["onehot"]
        return out

    def accel(self, ks) -> np.ndarray:
        """Linear vibration of the mounting point ``a_v`` (len(ks), 3) [m/s^2], body axes."""
        c = self.lin
        out = np.zeros((len(ks), 3))
        if len(c["amp"]):
            phi, _ = self._phase(c, ks)
            out += (self._amp(c, ks) * np.sin(phi)) @ c["onehot"]
        return out

    def labels(self) -> dict:
        return {
            "vibration_harmonic_gain": float(self.gains[0]),
            "vibration_noise_gain": float(self.gains[1]),
        }

    # --- application -------------------------------------------------------------------
    def apply(self, k0, omega_b, f_b, dtheta, dv, raw=False):
        """Truth chunk (samples ``k0 .. k0 + L - 1``) -> what the vibrating case measures.

        Parameters and returns: ``omega_b, f_b, dtheta, dv`` (L, 3) arrays (new arrays; the
        inputs are not modified). Increments of row ``k0 = 0`` stay zero. ``raw``: the
        increments are plain integrals of rate and specific force (else compensated: rotation
        vector and velocity change in the frame at the interval start).
        """
        v, cl, ca = self.vib, self.lin, self.ang
        out = [np.empty((len(omega_b), 3)) for _ in range(4)]
        _apply_kernel(
            int(k0),
            v.dt,
            v.shaft_angle,
            v.shaft_radps,
            v.noise_scale,
            cl["axis"],
            cl["amp"],
            cl["order"],
            cl["w"],
            cl["phi0"],
            cl["noise"],
            ca["axis"],
            ca["amp"],
            ca["order"],
            ca["w"],
            ca["phi0"],
            ca["noise"],
            *(np.ascontiguousarray(x, dtype=np.float64) for x in (omega_b, f_b, dtheta, dv)),
            *out,
            bool(raw),
        )
        return tuple(out)


def truth_speed(truth) -> np.ndarray:
    """Speed [m/s] at each sample of a :class:`imugen.sensors.ideal.TruthSource` (zeros if unknown).

    Uses the truth's ``speed_mps`` attribute when it has one (tables with velocity columns);
    a still IMU has none and stands still.
    """
    s = getattr(truth, "speed_mps", None)
    if s is None:
        return np.zeros(truth.K)
    return np.asarray(s, dtype=float)


def setup_vibration(truth, option) -> Vibration | None:
    """The vibration an option gives on a truth (``None``: off, or no profile for its vehicle)."""
    vehicle = truth.meta.get("vehicle") if isinstance(truth.meta, dict) else None
    profile = profile_for(option, vehicle)
    if profile is None:
        return None
    return Vibration(profile, truth_speed(truth), truth.dt, getattr(truth, "rotor_rpm", None))
