"""Each error source alone, 1,000+ sequences on a still, level IMU (flat Earth), mechanized with
imugen.navigate.mechanize: position-error statistics against closed forms, within 5 %.

Deterministic sources (biases) are compared per sequence with the drawn labels; random ones
(VRW, ARW) through the RMS over sequences and axes: with n pooled samples the standard error of
an RMS is 1/sqrt(2n) (VRW 3000 -> 1.3 %, ARW 2000 -> 1.6 %), so 5 % is >= 3 standard errors.
"""

import math

import numpy as np
import pytest

from imugen.core.earth import OriginFrame
from imugen.sensors.grades import grade_from_config
from imugen.simulate import stage as S
from imugen.simulate.sources import DEFAULT_STATIC_ORIGIN

mechanize = pytest.importorskip("imugen.navigate.mechanize").mechanize

RATE = 20.0
T = 50.0
DT = 1.0 / RATE
FRAME = OriginFrame.from_deg(*DEFAULT_STATIC_ORIGIN, model="flat")
G0 = FRAME.g0


def run(gyro=None, accel=None, M=1000, seed=1):
    g = grade_from_config("t", {"id": 7000, "gyro": gyro or {}, "accel": accel or {}})
    sh = S.simulate(None, g, sequences=M, seed=seed, static_s=T, rate_hz=RATE)
    K = sh.data["dtheta"].shape[1]
    nav = mechanize(
        sh.data["dtheta"][:, 1:],
        sh.data["dv"][:, 1:],
        DT,
        np.zeros(3),
        np.zeros(3),
        np.array([1.0, 0.0, 0.0, 0.0]),
        FRAME,
        every=K - 1,
        outputs=("p",),
    )
    return sh, nav.p_n[:, -1]  # (M, 3) position error at T (truth is at rest at the origin)


def rms(x):
    return float(np.sqrt(np.mean(np.square(x))))


def test_ideal_sensor_closes():
    _, p = run(M=2)
    assert np.max(np.abs(p)) < 1e-9


def test_accelerometer_bias_b_t2_over_2():
    sh, p = run(accel={"turn_on_bias": {"value": 1, "unit": "mg", "kind": "one_sigma"}})
    b = sh.accel.b_on
    pred = b * T**2 / 2
    assert rms(p) / rms(pred) == pytest.approx(1.0, rel=0.05)
    np.testing.assert_allclose(p, pred, rtol=1e-6)


def test_gyro_bias_g_w_t3_over_6():
    sh, p = run(gyro={"turn_on_bias": {"value": 10, "unit": "deg_per_h", "kind": "one_sigma"}})
    w = sh.gyro.b_on
    # tilt about body x (East) by w_x t moves gravity into -North; about y into +East;
    # per sequence to 2 %: the z bias (heading error w_z t ~ 3e-3 rad) couples the axes
    pred_e = G0 * w[:, 1] * T**3 / 6
    pred_n = -G0 * w[:, 0] * T**3 / 6
    assert rms(p[:, :2]) / rms(np.column_stack([pred_e, pred_n])) == pytest.approx(1.0, rel=0.05)
    np.testing.assert_allclose(p[:, 0], pred_e, rtol=2e-2, atol=1e-2 * rms(pred_e))
    np.testing.assert_allclose(p[:, 1], pred_n, rtol=2e-2, atol=1e-2 * rms(pred_n))


def test_vrw_sqrt_t3_over_3():
    N_ds = 0.5  # m/s/sqrt(h)
    _sh, p = run(accel={"white_noise": {"value": N_ds, "unit": "m_per_s_per_sqrt_h"}})
    N = N_ds / 60
    assert rms(p) / (N * math.sqrt(T**3 / 3)) == pytest.approx(1.0, rel=0.05)


def test_arw_tilt_random_walk_g_n_sqrt_t5_over_20():
    N_ds = 1.0  # deg/sqrt(h)
    _sh, p = run(gyro={"white_noise": {"value": N_ds, "unit": "deg_per_sqrt_h"}})
    N = N_ds * math.pi / 180 / 60
    assert rms(p[:, :2]) / (G0 * N * math.sqrt(T**5 / 20)) == pytest.approx(1.0, rel=0.05)
    assert rms(p[:, 2]) < 1e-2 * rms(p[:, :2])  # vertical: second order (1 - cos tilt) only
