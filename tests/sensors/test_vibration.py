"""Vibration of the IMU case: spectrum, exact increments, coning rectification, navigation."""

import dataclasses
import math

import numpy as np
import pytest

from imugen.core.earth import OriginFrame
from imugen.core.rotations import exp_quat, quat_conj, quat_mul
from imugen.navigate.mechanize import mechanize
from imugen.sensors import vibration as V
from imugen.sensors.grades import grade_from_config
from imugen.simulate import stage as S
from imugen.simulate.sources import DEFAULT_STATIC_ORIGIN, StaticTruth

CAR = V.PROFILES["car"]
G = V.G0
NO_ERRORS = grade_from_config("clean", {"id": 5000})


def _draw(profile, speed, dt, seed=1):
    vib = V.Vibration(profile, speed, dt)
    return vib, vib.draw(np.random.default_rng(seed))


def _still(L, dt):
    """A still, level, non-rotating truth chunk: omega 0, f = (0, 0, g)."""
    f = np.tile([0.0, 0.0, G], (L, 1))
    dv = f * dt
    dv[0] = 0.0
    return np.zeros((L, 3)), f, np.zeros((L, 3)), dv


def test_shaft_speed_follows_the_gearbox():
    dt = 0.01
    v = np.array([0.0, 5.0, 8.0, 20.0, 40.0])
    rpm = V.shaft_rpm(v, dataclasses.replace(CAR, lag_s=0.0), dt)
    wheel = v / CAR.wheel_radius_m * 60 / (2 * math.pi) * CAR.final_drive
    # stop: idle; 5 m/s: first gear (2156 rpm); 8 m/s: second (first would be 3450 rpm)
    assert rpm[0] == CAR.idle_rpm
    assert rpm[1] == pytest.approx(wheel[1] * 3.5)
    assert rpm[2] == pytest.approx(wheel[2] * 2.0)
    assert rpm[3] == pytest.approx(wheel[3] * 1.0)
    assert rpm[4] == pytest.approx(wheel[4] * 0.8)  # top gear even above the shift speed
    # the lag: a step from idle to 2000 rpm approaches as 1 - exp(-t / lag)
    steps = np.r_[0.0, np.full(100, 9.3)]
    r = V.shaft_rpm(steps, CAR, dt)
    target = 9.3 / CAR.wheel_radius_m * 60 / (2 * math.pi) * CAR.final_drive * 2.0
    k = 30
    expect = target + (CAR.idle_rpm - target) * math.exp(-k * dt / CAR.lag_s)
    assert r[k] == pytest.approx(expect, rel=1e-12)


def test_spectrum_peaks_at_the_engine_harmonics_with_their_amplitudes():
    # car at a stop: engine at 800 rpm idle, no road noise; orders 2/4/6 at 26.67/53.33/80 Hz
    dt, T = 1e-3, 3.0
    K = round(T / dt)
    _, sv = _draw(CAR, np.zeros(K + 1), dt)
    a = sv.accel(np.arange(K))
    spec = np.abs(np.fft.rfft(a, axis=0)) * 2.0 / K
    freqs = np.fft.rfftfreq(K, dt)
    f_shaft = CAR.idle_rpm / 60.0
    expect = np.zeros_like(spec)
    for o, order in enumerate(CAR.orders):
        b = np.argmin(np.abs(freqs - order * f_shaft))
        assert freqs[b] == pytest.approx(order * f_shaft)  # on a bin: whole periods in T
        expect[b] = np.asarray(CAR.accel_g[o]) * G * sv.gains[0]
    np.testing.assert_allclose(spec, expect, atol=1e-9)


def test_aircraft_propeller_orders_at_cruise():
    # airborne at 60 m/s: 2400 rpm, propeller orders 1/2/4 at 40/80/160 Hz (noise off here)
    prof = dataclasses.replace(V.PROFILES["aircraft"], noise_g=(0.0, 0.0, 0.0))
    dt, K = 1e-3, 2000
    assert V.shaft_rpm(np.full(3, 60.0), prof, dt)[0] == pytest.approx(prof.shift_rpm)
    assert V.shaft_rpm(np.zeros(3), prof, dt)[0] == pytest.approx(prof.idle_rpm)
    _, sv = _draw(prof, np.full(K + 1, 60.0), dt)
    spec = np.abs(np.fft.rfft(sv.accel(np.arange(K)), axis=0)) * 2.0 / K
    freqs = np.fft.rfftfreq(K, dt)
    for o, order in enumerate(prof.orders):
        b = np.argmin(np.abs(freqs - order * 40.0))
        assert freqs[b] == pytest.approx(order * 40.0)
        np.testing.assert_allclose(spec[b], np.asarray(prof.accel_g[o]) * G * sv.gains[0])


def test_increments_are_the_exact_integrals_of_the_motion():
    # linear vibration at constant speed (engine in gear + road noise), no rotation: each dv is
    # the integral of a_v over its interval (independent: composite Simpson on a fine grid)
    prof = dataclasses.replace(CAR, angle_rad=((0.0,) * 3,) * 3)
    dt, K, n = 0.01, 41, 400
    speed = 20.0
    _, sv = _draw(prof, np.full(K, speed), dt)
    _, fine = _draw(prof, np.full((K - 1) * n + 1, speed), dt / n)
    w, f, dth, dv = _still(K, dt)
    _, _, dth_c, dv_c = sv.apply(0, w, f, dth, dv)
    a = fine.accel(np.arange((K - 1) * n + 1))
    h = dt / n
    simpson = np.array(
        [
            h
            / 3
            * (
                a[i * n]
                + 4 * a[i * n + 1 : (i + 1) * n : 2].sum(0)
                + 2 * a[i * n + 2 : (i + 1) * n : 2].sum(0)
                + a[(i + 1) * n]
            )
            for i in range(K - 1)
        ]
    )
    np.testing.assert_allclose(dv_c[1:] - dv[1:], simpson, rtol=0, atol=1e-9)
    assert np.all(dth_c == 0.0) and np.all(dv_c[0] == 0.0)
    # and the rate samples are the same signal at the sample times
    _, f_c, _, _ = sv.apply(0, w, f, dth, dv)
    # (phases from cumulative sums of different lengths: 1e-11 of rounding)
    np.testing.assert_allclose(f_c - f, a[::n], rtol=0, atol=1e-10)


def test_integral_over_whole_periods_is_zero():
    # one harmonic (order 2 at 1200 rpm: 40 Hz, 4 samples per period at 160 Hz)
    prof = dataclasses.replace(
        CAR,
        orders=(2.0,),
        accel_g=((0.1, 0.2, 0.3),),
        angle_rad=((0.0, 0.0, 0.0),),
        idle_rpm=1200.0,
        noise_g=(0.0, 0.0, 0.0),
    )
    dt = 1.0 / 160.0
    K = 4 * 25 + 1
    _, sv = _draw(prof, np.zeros(K), dt)
    w, f, dth, dv = _still(K, dt)
    _, _, _, dv_c = sv.apply(0, w, f, dth, dv)
    vib_dv = dv_c - dv
    per_period = vib_dv[1:].reshape(25, 4, 3).sum(axis=1)
    amp = 0.3 * G * sv.gains[0] / (2 * math.pi * 40)  # velocity amplitude of the largest axis
    assert np.max(np.abs(per_period)) < 1e-12 * amp * 1e3
    assert np.max(np.abs(np.cumsum(vib_dv, 0))) > 0.5 * amp  # the motion itself is there


def _coning(B, f_hz, dt, K):
    prof = dataclasses.replace(
        CAR,
        orders=(1.0,),
        accel_g=((0.0, 0.0, 0.0),),
        angle_rad=((B, B, 0.0),),
        idle_rpm=60.0 * f_hz,
        noise_g=(0.0, 0.0, 0.0),
    )
    vib = V.Vibration(prof, np.zeros(K), dt)
    # x and y in quadrature: the classic coning motion about z
    sv = V.SequenceVibration(
        vib,
        np.array([1.0, 1.0]),
        np.zeros((1 + prof.lines, 3), int),
        np.array([[0.0, math.pi / 2, 0.0]]),
        np.full((prof.lines, 3), 10.0),
    )
    return sv


def test_coning_rectification_matches_its_closed_form():
    B, f_hz, dt, K = 1e-3, 20.0, 1e-3, 1001  # 20 periods
    sv = _coning(B, f_hz, dt, K)
    w, f, dth, dv = _still(K, dt)
    gyro, _, dth_c, _ = sv.apply(0, w, f, dth, dv, raw=True)  # integrals of the rate
    Om = 2 * math.pi * f_hz
    # dtheta_v = B (sin Om t, cos Om t - 1, 0): the case returns to its start every period, yet
    # the integrated rate drifts about z by B^2 Om / 2 per second (second order in B)
    drift = dth_c[1:, 2].sum()
    assert drift == pytest.approx(0.5 * B**2 * Om * (K - 1) * dt, rel=2e-3)
    np.testing.assert_allclose(dth_c[1:, :2].sum(0), 0.0, atol=1e-12)
    # independent: body rate of q(t) = Exp(dtheta_v(t)) by differentiation on a fine grid
    n = 50
    t = np.arange((K - 1) * n + 1) * dt / n
    th = B * np.stack([np.sin(Om * t), np.cos(Om * t) - 1.0, 0 * t], axis=1)
    q = exp_quat(th)
    qdot = np.gradient(q, dt / n, axis=0, edge_order=2)
    omega = 2.0 * quat_mul(quat_conj(q), qdot)[:, 1:]
    h = dt / n
    inc = np.array(
        [
            h
            / 3
            * (
                omega[i * n]
                + 4 * omega[i * n + 1 : (i + 1) * n : 2].sum(0)
                + 2 * omega[i * n + 2 : (i + 1) * n : 2].sum(0)
                + omega[(i + 1) * n]
            )
            for i in range(K - 1)
        ]
    )
    # third-order terms B^3 Om dt ~ 1.3e-10 per interval
    np.testing.assert_allclose(dth_c[1:], inc, rtol=0, atol=5e-10)
    # rates to third order, |dtheta_v|^2 |d(dtheta_v)/dt| / 6 with |dtheta_v| up to 2 B (end
    # samples: one-sided differences, left out)
    np.testing.assert_allclose(gyro[1:-1], omega[::n][1:-1], rtol=0, atol=3 * B**3 * Om)
    assert drift == pytest.approx(inc[:, 2].sum(), rel=1e-4)
    # compensated increments are rotation vectors: they compose back to the case's attitude,
    # identity after whole periods (no drift to correct)
    _, _, comp, _ = sv.apply(0, w, f, dth, dv)
    q = np.array([1.0, 0.0, 0.0, 0.0])
    for k in range(1, K):
        q = quat_mul(q, exp_quat(comp[k]))
        if k % 100 == 37:
            np.testing.assert_allclose(q, exp_quat(th[k * n]), atol=1e-12)
    np.testing.assert_allclose(q, [1.0, 0.0, 0.0, 0.0], atol=1e-12)


def _navigate(vibration, grade=NO_ERRORS, seconds=60.0, rate=100.0, seed=3):
    sh = S.simulate(
        None, grade, sequences=2, seed=seed, static_s=seconds, rate_hz=rate, vibration=vibration
    )
    frame = OriginFrame.from_deg(*DEFAULT_STATIC_ORIGIN, model="flat")
    q0 = np.array([1.0, 0.0, 0.0, 0.0])
    nav = mechanize(
        sh.data["dtheta"][:, 1:],
        sh.data["dv"][:, 1:],
        1 / rate,
        np.zeros(3),
        np.zeros(3),
        q0,
        frame,
        outputs=("p",),
    )
    return sh, nav.p_n


def test_vibration_has_a_small_zero_mean_effect_on_navigation():
    sh, p = _navigate("car")
    _, p0 = _navigate("off")
    assert np.max(np.abs(p0)) < 1e-6  # closure without vibration
    # an idling car for 60 s: engine harmonics up to 0.06 g and rocking of 2e-5 rad. The
    # navigation follows the case, whose mounting point oscillates about the vehicle's by
    # at most sum A / omega^2 per axis (about 1e-5 m); the coning of the rocking (up to
    # B_x B_y Om / 2 = 1.7e-8 rad/s in the integrated rates) is compensated by the strapdown,
    # else it would tilt gravity into g * drift * T^3 / 6 = 6 mm
    g0 = sh.labels["vibration_harmonic_gain"].to_numpy()
    Om = 2 * math.pi * np.asarray(CAR.orders) * CAR.idle_rpm / 60
    disp = (np.asarray(CAR.accel_g) * G / Om[:, None] ** 2).sum(axis=0)  # per axis at gain 1
    err = np.abs(p[:, -1])
    B = np.asarray(CAR.angle_rad)[0]
    coning = G * 0.5 * B[0] * B[1] * Om[0] * 60.0**3 / 6.0
    for s in range(2):
        assert np.all(err[s] <= 1.5 * g0[s] * disp + 1e-7)
        assert np.max(err[s]) < 0.01 * coning * g0[s] ** 2
    assert np.max(err) > 1e-7  # the vibration is felt


def test_seeded_streams_and_labels(tmp_path):
    wn = grade_from_config(
        "wn", {"id": 5000, "gyro": {"white_noise": {"value": 0.1, "unit": "deg_per_sqrt_h"}}}
    )
    # same id as NO_ERRORS: the same spawn keys, so the same vibration draws
    kw = {"sequences": 2, "seed": 5, "static_s": 2.0, "rate_hz": 100.0}
    a = S.simulate(None, wn, vibration="car", **kw)
    b = S.simulate(None, wn, vibration="car", **kw)
    off = S.simulate(None, wn, **kw)
    vib_only = S.simulate(None, NO_ERRORS, vibration="car", **kw)
    clean = S.simulate(None, NO_ERRORS, **kw)
    assert np.array_equal(a.data["dtheta"], b.data["dtheta"])
    # the vibration leaves the white noise's realization unchanged (its own stream)
    np.testing.assert_allclose(
        a.data["dtheta"] - off.data["dtheta"],
        vib_only.data["dtheta"] - clean.data["dtheta"],
        rtol=0,
        atol=1e-15,
    )
    g = a.labels["vibration_harmonic_gain"].to_numpy()
    assert np.all((g >= 0.5) & (g <= 2.0)) and g[0] != g[1]
    assert a.meta["vibration"]["profile"]["name"] == "car"
    assert "vibration_harmonic_gain" not in off.labels and off.meta["vibration"] is None


def test_vehicle_option_follows_the_truth():
    tr = StaticTruth(1.0, 100.0)
    tr.meta["vehicle"] = "pedestrian"
    assert V.setup_vibration(tr, "vehicle") is None
    tr.meta["vehicle"] = "aircraft"
    assert V.setup_vibration(tr, "vehicle").profile.name == "aircraft"
    with pytest.raises(Exception, match="vibration"):
        V.profile_for("boat")
