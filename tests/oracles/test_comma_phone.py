"""comma2k19 oracle prototype: the pose-implied IMU closes, the real phone's residuals."""

import math

import numpy as np
import pytest

from oracles import comma as C

pytestmark = pytest.mark.skipif(not C.DATA.exists(), reason="needs ../shared/data/imu")
D2H = 180 / math.pi * 3600


@pytest.fixture(scope="module")
def d():
    return C.load()


def test_orientation_convention_and_gravity(d):
    conv, info = C.orientation_convention(d)
    assert conv == "device_to_ecef"
    # a car on a highway: the specific force is ~ g up (reads -g on the down axis)
    assert info[conv]["mean_f_b"][2] == pytest.approx(-9.80, abs=0.05)
    assert min(info[conv]["rate_corr"]) > 0.9
    assert abs(C.time_offset(d, conv)) < 0.02


def test_pose_implied_imu_closes(d):
    # strapdown of the pose-implied IMU returns to the pose: ~1 m after 60 s at 17.6 m/s
    conv = "device_to_ecef"
    t = d["t_imu"][(d["t_imu"] > d["t_pose"][1]) & (d["t_imu"] < d["t_pose"][-2])]
    f, w = C.truth_imu(d, conv, t)
    r = C.free_inertial(d, conv, 0.0, gyro=w, accel=f, t=t)
    assert np.linalg.norm(r["dp_n"][-1]) < 2.0
    assert np.degrees(np.linalg.norm(r["dth_b"][-1])) < 0.02


def test_real_phone_residuals(d):
    res = C.residuals(d, "device_to_ecef", -0.004, n=10)
    b = np.array(res["gyro_uncal"]["bias"]) * D2H
    # the figures: 2,100 / 7,300 / 14,000 deg/h
    assert np.allclose(np.abs(b), [2140, 7340, 13990], rtol=0.02)
    # Android's own estimate leaves ~100 deg/h per axis
    ba = np.abs(res["gyro_android_calibrated"]["bias"]) * D2H
    assert np.all((ba > 60) & (ba < 160))
    acc = np.abs(res["accel"]["mean_diff"]) / 9.80665e-3
    assert np.all(acc < 30) and np.all(acc > 3)  # mg


def test_real_free_inertial_drift(d):
    r = C.free_inertial(d, "device_to_ecef", -0.004)
    dp = r["dp_n"][-1]
    assert r["t"][-1] > 59
    assert 50 < np.hypot(dp[0], dp[1]) < 120 and 200 < dp[2] < 300
    assert np.all(np.abs(np.degrees(r["dth_b"][-1])) < 3)


# --- the phone presets against the real phone ---------------------------------------------
FLU = np.array([1.0, -1.0, -1.0])  # comma's forward-right-down <-> imugen's body (x, y, z up)


def _draws(name, S, seed):
    """S sequences' drawn parameters of a preset (imugen's own draw, all terms)."""
    from imugen.sensors.grades import TERMS, presets
    from imugen.sensors.model import SensorParams, draw_sensor

    g = presets()[name]
    rng = np.random.default_rng(seed)
    gp, ap = [], []
    for _ in range(S):
        gp.append(draw_sensor(g.gyro, rng, frozenset(TERMS)))
        ap.append(draw_sensor(g.accel, rng, frozenset(TERMS)))
    return SensorParams.stack(gp), SensorParams.stack(ap)


def _err_matrix(p):
    return p.cc + p.sf[:, :, None] * np.eye(3)[None]


def test_real_phone_residuals_inside_the_phone_presets_population():
    """Issue 24: the real phone's residual against the IMU implied by its fused pose lies, per
    axis, inside the 1-99 % band of the phone preset's population: the uncalibrated gyro
    bias, the accelerometer's mean residual (bias and scale/cross-coupling on gravity, the
    mounting tilt included), and the gyro's own noise below the preset's top."""
    d = C.load()
    res = C.residuals(d, "device_to_ecef", -0.004, n=10)
    gp, ap = _draws("phone", 20000, 24)
    # gyro bias at rest: turn-on + g-sensitivity on gravity (imugen's body axes, then FRD)
    g_rest = np.abs(gp.b_on + gp.gs[:, :, 2] * C.G0)
    lo, hi = np.percentile(g_rest, [1, 99], axis=0)
    real = np.abs(np.array(res["gyro_uncal"]["bias"]))
    assert np.all((real > lo) & (real < hi)), (real, lo, hi)
    a_rest = np.abs(ap.b_on + _err_matrix(ap)[:, :, 2] * C.G0)
    lo, hi = np.percentile(a_rest, [1, 99], axis=0)
    real = np.abs(np.array(res["accel"]["mean_diff"]))
    assert np.all((real > lo) & (real < hi)), (real / 9.80665e-3, lo / 9.80665e-3)
    # the oracle discriminates: the datasheet-level consumer preset never reads these biases
    cp, _ = _draws("consumer", 20000, 28)
    hi_c = np.percentile(np.abs(cp.b_on + cp.gs[:, :, 2] * C.G0), 99, axis=0)
    assert np.all(np.abs(np.array(res["gyro_uncal"]["bias"])) > hi_c)
    # the calibrated twin: Android's estimate leaves 95-125 deg/h
    gc, _ = _draws("phone_calibrated", 20000, 25)
    c_rest = np.abs(gc.b_on + gc.gs[:, :, 2] * C.G0)
    lo, hi = np.percentile(c_rest, [1, 99], axis=0)
    real = np.abs(np.array(res["gyro_android_calibrated"]["bias"]))
    assert np.all((real > lo) & (real < hi)), (real * D2H, lo * D2H, hi * D2H)


def test_real_phone_drift_inside_the_calibrated_presets_band():
    """Issue 24: the free-inertial drift of the real phone IMU over the minute (Android's gyro
    bias removed) lies inside the 5-95 % band of the calibrated phone preset's drift on the
    same truth: 3-D position, vertical and attitude. (Horizontal position alone is not held
    to it: in this minute the real gyro and accelerometer errors cancel -- 237 m and 210 m
    alone, 80 m together -- and put it at the 3rd percentile of any preset tried.)"""
    d = C.load()
    conv, off = "device_to_ecef", -0.004
    t = d["t_imu"] - off
    t = t[(t >= d["t_pose"][0]) & (t <= d["t_pose"][-1])]
    real = C.free_inertial(d, conv, off)
    r_dp, r_dth = real["dp_n"][-1], real["dth_b"][-1]
    S = 300
    gp, ap = _draws("phone_calibrated", S, 26)
    f, w = C.truth_imu(d, conv, t)
    dt = float(np.median(np.diff(t)))
    rng = np.random.default_rng(27)
    # imugen's error model in its body axes (FLU), back to the data's FRD
    fF, wF = f * FLU, w * FLU
    g = wF[None] + np.einsum("sij,kj->ski", _err_matrix(gp), wF) + gp.b_on[:, None]
    g += np.einsum("sij,kj->ski", gp.gs, fF)
    g += gp.white[:, None, :] / np.sqrt(dt) * rng.standard_normal(g.shape)
    a = fF[None] + np.einsum("sij,kj->ski", _err_matrix(ap), fF) + ap.b_on[:, None]
    a += ap.white[:, None, :] / np.sqrt(dt) * rng.standard_normal(a.shape)
    p_t, v_t, C_t = C.pose_at(d, conv, t)
    P, _, Cf = C.mechanize_batch(t, g * FLU, a * FLU, p_t[0], v_t[0], C_t[0])
    lat, lon, _ = C.ecef_to_geodetic(p_t[:1])
    dp = (P[:, -1] - p_t[-1]) @ C.C_en(lat, lon)[0].T
    from scipy.spatial.transform import Rotation

    dth = Rotation.from_matrix(np.einsum("ji,sjl->sil", C_t[-1], Cf)).as_rotvec()
    for name, sim, rv in (
        ("3-D position [m]", np.linalg.norm(dp, axis=1), np.linalg.norm(r_dp)),
        ("vertical [m]", np.abs(dp[:, 2]), abs(r_dp[2])),
        ("attitude [deg]", np.degrees(np.linalg.norm(dth, axis=1)), np.degrees(np.linalg.norm(r_dth))),
    ):  # fmt: skip
        lo, hi = np.percentile(sim, [5, 95])
        assert lo < rv < hi, (name, rv, lo, hi)
