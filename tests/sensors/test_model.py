"""Error model: each term alone against its definition (exact where deterministic, statistical
where random; tolerances are ~4 standard errors of the estimate, noted per test)."""

import math

import numpy as np
import pytest

from imugen.sensors import model as sensors
from imugen.sensors.grades import grade_from_config
from imugen.sensors.ideal import ArrayTruth
from imugen.simulate import stage as S
from imugen.simulate.sources import StaticTruth

DT = 0.01


def grade(gyro=None, accel=None, gid=5000):
    return grade_from_config("t", {"id": gid, "gyro": gyro or {}, "accel": accel or {}})


def moving_truth(K=500, dt=DT):
    t = np.arange(K) * dt
    w = np.tile([0.1, -0.2, 0.3], (K, 1))
    f = np.tile([0.5, -1.0, 9.8], (K, 1))
    dth, dv = w * dt, f * dt
    dth[0] = dv[0] = 0.0
    return ArrayTruth(t, w, f, dth, dv)


TB = {"value": 100, "unit": "deg_per_h", "kind": "one_sigma"}
WN = {"value": 0.5, "unit": "deg_per_sqrt_h"}


def test_turn_on_bias_is_constant_and_exact():
    g = grade(
        gyro={"turn_on_bias": TB},
        accel={"turn_on_bias": {"value": 1, "unit": "mg", "kind": "one_sigma"}},
    )
    tr = moving_truth()
    sh = S.simulate(tr, g, sequences=4, seed=3, outputs="both")
    b = sh.gyro.b_on  # (4, 3)
    np.testing.assert_allclose(
        sh.data["dtheta"][:, 1:] - tr.dth[1:],
        np.broadcast_to(b[:, None] * DT, (4, 499, 3)),
        rtol=0,
        atol=1e-17,
    )
    np.testing.assert_allclose(
        sh.data["gyro"] - tr.w, np.broadcast_to(b[:, None], (4, 500, 3)), rtol=0, atol=1e-16
    )
    assert np.all(sh.data["dtheta"][:, 0] == 0)
    # 1-sigma of the draw: 100 deg/h (4 x 3 values: only a sanity bound here)
    assert 0.2 < np.std(b) / (100 * math.pi / 180 / 3600) < 3


def test_scale_factor_cross_coupling_and_g_sensitivity_are_linear_maps():
    g = grade(
        gyro={
            "scale_factor": {"value": 1000, "unit": "ppm"},
            "cross_coupling": {"value": 1, "unit": "mrad"},
            "g_sensitivity": {"value": 10, "unit": "deg_per_h_per_g"},
        },
        accel={
            "scale_factor": {"value": 500, "unit": "ppm"},
            "cross_coupling": {"value": 0.1, "unit": "percent"},
        },
    )
    tr = moving_truth()
    sh = S.simulate(tr, g, sequences=3, seed=4, outputs="both")
    for j in range(3):
        E = np.diag(sh.gyro.sf[j]) + sh.gyro.cc[j]
        assert np.all(np.diag(sh.gyro.cc[j]) == 0) and np.count_nonzero(sh.gyro.cc[j]) == 6
        exp_inc = tr.dth + tr.dth @ E.T + tr.dv @ sh.gyro.gs[j].T
        np.testing.assert_allclose(sh.data["dtheta"][j, 1:], exp_inc[1:], rtol=1e-14, atol=1e-19)
        exp_rate = tr.w + tr.w @ E.T + tr.f @ sh.gyro.gs[j].T
        np.testing.assert_allclose(sh.data["gyro"][j], exp_rate, rtol=1e-14)
        Ea = np.diag(sh.accel.sf[j]) + sh.accel.cc[j]
        np.testing.assert_allclose(sh.data["dv"][j, 1:], (tr.dv + tr.dv @ Ea.T)[1:], rtol=1e-14)


def test_white_noise_levels_and_rate_increment_consistency():
    N = 0.5 * math.pi / 180 / 60
    g = grade(gyro={"white_noise": WN, "turn_on_bias": TB})
    tr = moving_truth(K=20000)
    sh = S.simulate(tr, g, sequences=3, seed=5, outputs="both")
    e_inc = sh.data["dtheta"][:, 1:] - tr.dth[1:] - sh.gyro.b_on[:, None] * DT
    e_rate = sh.data["gyro"][:, 1:] - tr.w[1:] - sh.gyro.b_on[:, None]
    # same normal drives both outputs: rate noise * dt == increment noise
    np.testing.assert_allclose(e_rate * DT, e_inc, rtol=1e-9, atol=1e-18)
    # std: 6e4 samples per axis -> standard error 0.3 %; tolerance 1.5 %
    assert np.std(e_inc, axis=(0, 1)) == pytest.approx(np.full(3, N * math.sqrt(DT)), rel=0.015)
    assert np.std(e_rate, axis=(0, 1)) == pytest.approx(np.full(3, N / math.sqrt(DT)), rel=0.015)


def test_gauss_markov_stationary_and_correlation():
    sig = 10.0  # deg/h GM sigma
    T = 2.0
    g = grade(
        gyro={
            "bias_instability": {
                "value": sig,
                "unit": "deg_per_h",
                "kind": "gm_sigma",
                "correlation_time": {"value": T, "unit": "s"},
            }
        }
    )
    M, K = 3000, 301
    sh = S.simulate(StaticTruth((K - 1) * DT, 1 / DT), g, sequences=M, seed=6, series=True)
    x = sh.data["gyro_bias"] / (math.pi / 180 / 3600)  # deg/h, (M, K, 3)
    # stationary from the start: variance at k = 0 and k = K-1 equals sigma^2
    # (9000 samples each -> standard error of a variance 1.5 %; tolerance 6 %)
    for k in (0, K - 1):
        assert np.var(x[:, k]) == pytest.approx(sig**2, rel=0.06)
    # correlation over 3 s: exp(-3/2)
    lag = 300
    r = np.mean(x[:, 0] * x[:, lag]) / sig**2
    assert r == pytest.approx(math.exp(-lag * DT / T), abs=0.04)
    # increments integrate the bias by the trapezoid of the end states
    inc = sh.data["dtheta"][:, 1:]
    b = sh.data["gyro_bias"]
    np.testing.assert_allclose(inc, 0.5 * (b[:, 1:] + b[:, :-1]) * DT, rtol=1e-12, atol=1e-20)


def test_rate_random_walk_variance_grows_linearly():
    K_rrw = 50.0  # deg/h/sqrt(h)
    g = grade(
        accel={"rate_random_walk": {"value": 100, "unit": "ug_per_sqrt_s"}},
        gyro={"rate_random_walk": {"value": K_rrw, "unit": "deg_per_h_per_sqrt_h"}},
    )
    M, K = 2000, 1001
    sh = S.simulate(StaticTruth((K - 1) * DT, 1 / DT), g, sequences=M, seed=7, series=True)
    Ks = K_rrw * math.pi / 180 / 3600 / 60
    t = (K - 1) * DT
    # 6000 samples -> standard error 1.8 %; tolerance 7 %
    assert np.var(sh.data["gyro_bias"][:, -1]) == pytest.approx(Ks**2 * t, rel=0.07)
    assert np.var(sh.data["accel_bias"][:, -1]) == pytest.approx(
        (100 * 9.80665e-6) ** 2 * t, rel=0.07
    )
    assert np.all(sh.data["gyro_bias"][:, 0] == 0)


def test_quantization_with_residual_carry_and_saturation():
    lsb = 1e-3  # rad/s
    g = grade(
        gyro={
            "quantization": {"value": lsb, "unit": "rad_per_s"},
            "range": {"value": 0.25, "unit": "rad_per_s"},
            "white_noise": WN,
        }
    )
    tr = moving_truth(K=3000)
    sh = S.simulate(tr, g, sequences=2, seed=8, outputs="both")
    inc = sh.data["dtheta"]
    q = lsb * DT
    np.testing.assert_allclose(inc / q, np.round(inc / q), atol=1e-6)
    # residual carry: the integrated output never drifts from the integrated input by >= 1 LSB
    ref = S.simulate(
        tr,
        grade(gyro={"white_noise": WN, "range": {"value": 0.25, "unit": "rad_per_s"}}),
        sequences=2,
        seed=8,
        outputs="both",
    )
    drift = np.cumsum(inc - ref.data["dtheta"], axis=1)
    assert np.max(np.abs(drift)) <= q / 2 * (1 + 1e-9)
    # saturation: z true rate 0.3 > 0.25 full scale
    assert np.max(sh.data["gyro"][..., 2]) <= 0.25 + 1e-12
    assert np.max(inc[..., 2]) <= 0.25 * DT + 1e-15


def test_temperature_profile_drives_bias_and_scale_factor():
    g = grade(
        accel={
            "temperature_bias": {"value": 10, "unit": "ug_per_K"},
            "temperature_scale_factor": {"value": 50, "unit": "ppm_per_K"},
        }
    )
    tr = moving_truth(K=1000)
    prof = {"kind": "warmup", "delta_K": 20.0, "tau_s": 3.0}
    sh = S.simulate(tr, g, sequences=2, seed=9, temperature=prof, series=True, outputs="both")
    dT = 20.0 * (1 - np.exp(-tr.time / 3.0))
    for j in range(2):
        np.testing.assert_allclose(
            sh.data["accel_bias"][j], np.outer(dT, sh.accel.tb[j]), rtol=1e-12, atol=1e-18
        )
        np.testing.assert_allclose(
            sh.data["accel_sf"][j], np.outer(dT, sh.accel.ts[j]), rtol=1e-12, atol=1e-18
        )
        exp_rate = tr.f * (1 + np.outer(dT, sh.accel.ts[j])) + np.outer(dT, sh.accel.tb[j])
        np.testing.assert_allclose(sh.data["accel"][j], exp_rate, rtol=1e-13)
    # no profile: the temperature terms have no effect
    sh0 = S.simulate(tr, g, sequences=2, seed=9, outputs="both")
    np.testing.assert_array_equal(sh0.data["accel"], np.broadcast_to(tr.f, (2, 1000, 3)))


def test_time_chunking_does_not_change_results(monkeypatch):
    g = grade(
        gyro={
            "bias_instability": {
                "value": 5,
                "unit": "deg_per_h",
                "kind": "allan_floor",
                "correlation_time": {"value": 1, "unit": "s"},
            },
            "white_noise": WN,
            "rate_random_walk": {"value": 1, "unit": "deg_per_h_per_sqrt_h"},
            "quantization": {"value": 1e-4, "unit": "rad_per_s"},
        },
        accel={"white_noise": {"value": 0.1, "unit": "m_per_s_per_sqrt_h"}},
    )
    tr = moving_truth(K=2500)
    a = S.simulate(tr, g, sequences=2, seed=10, outputs="both", series=True)
    monkeypatch.setattr(S, "CHUNK", 333)
    b = S.simulate(tr, g, sequences=2, seed=10, outputs="both", series=True)
    for k in a.data:
        np.testing.assert_array_equal(a.data[k], b.data[k])


@pytest.mark.parametrize("start", ["stationary", "zero"])
def test_increment_kernel_matches_the_general_kernel(monkeypatch, start):
    """Increments alone go through a one-pass kernel (``kernel_increments``); with ``series`` the
    general two-pass kernel computes the same increments: every term on, chunked in two ways,
    the two must agree bit for bit (saturation and quantization included)."""
    gm = {
        "value": 5,
        "unit": "deg_per_h",
        "kind": "allan_floor",
        "correlation_time": {"value": 1, "unit": "s"},
        "start": start,
    }
    full = {
        **({"turn_on_bias": TB} if start == "zero" else {}),
        "bias_instability": gm,
        "white_noise": WN,
        "rate_random_walk": {"value": 1, "unit": "deg_per_h_per_sqrt_h"},
        "scale_factor": {"value": 1000, "unit": "ppm"},
        "cross_coupling": {"value": 1, "unit": "mrad"},
        "g_sensitivity": {"value": 10, "unit": "deg_per_h_per_g"},
        "quantization": {"value": 1e-4, "unit": "rad_per_s"},
        "range": {"value": 0.25, "unit": "rad_per_s"},
    }
    acc = {
        "turn_on_bias": {"value": 1, "unit": "mg", "kind": "one_sigma"},
        "white_noise": {"value": 0.1, "unit": "m_per_s_per_sqrt_h"},
        "scale_factor": {"value": 300, "unit": "ppm"},
        "range": {"value": 9.81, "unit": "m_per_s2"},
    }
    g = grade(gyro=full, accel=acc)
    tr = moving_truth(K=2500)
    calls = {"inc": 0}
    real = sensors.kernel_increments

    def counted(*a):
        calls["inc"] += 1
        return real(*a)

    monkeypatch.setattr(sensors, "kernel_increments", counted)
    for chunk in (S.CHUNK, 333):
        monkeypatch.setattr(S, "CHUNK", chunk)
        fast = S.simulate(tr, g, sequences=3, seed=12)
        n_fast = calls["inc"]
        general = S.simulate(tr, g, sequences=3, seed=12, series=True)
        assert n_fast > 0 and calls["inc"] == n_fast  # each path was the one meant
        for k in ("dtheta", "dv"):
            np.testing.assert_array_equal(fast.data[k], general.data[k])
        # saturation was exercised: true z rate 0.3 > 0.25 rad/s (within one quantization step)
        assert np.mean(np.abs(general.data["dtheta"][:, 1:, 2] - 0.25 * DT) <= 1e-6) == 1.0
        assert np.any(general.data["dv"][..., 2] == 9.81 * DT)
        calls["inc"] = 0


def test_flicker_bias_instability_draws_components():
    g = grade(
        gyro={
            "bias_instability": {
                "value": 2,
                "unit": "deg_per_h",
                "kind": "allan_floor",
                "model": "flicker",
                "flicker_band": {"min": 1, "max": 1000, "unit": "s"},
                "components": 7,
            }
        }
    )
    sh = S.simulate(StaticTruth(1.0, 100.0), g, sequences=2, seed=1)
    assert sh.gyro.bi_sigma.shape == (2, 3, 7)
    np.testing.assert_allclose(sh.gyro.bi_tau[0], np.geomspace(1, 1000, 7))


@pytest.mark.parametrize("nominal", [False, True])
def test_draw_of_many_sequences_is_each_sequences_draw(nominal):
    """draw_sensors on 30 sequences' variates gives, row for row and bit for bit, what
    draw_sensor gives each sequence from its own stream (every preset, both sensors, all terms
    and every other term enabled)."""
    from imugen.sensors.grades import TERMS, presets
    from imugen.sensors.model import (
        N_NORMAL,
        N_SLOW_UNIFORM,
        N_UNIFORM,
        SensorParams,
        draw_sensor,
        draw_sensors,
    )

    slow = 0
    for grade in presets().values():
        for spec in (grade.gyro, grade.accel):
            slow += spec.slow_bias is not None
            for enabled in (frozenset(TERMS), frozenset(TERMS[::2])):
                one, u, z, us = [], [], [], []
                for i in range(30):
                    one.append(draw_sensor(spec, np.random.default_rng(i), enabled, nominal))
                    rng = np.random.default_rng(i)
                    u.append(rng.random(N_UNIFORM))
                    z.append(rng.standard_normal(N_NORMAL))
                    us.append(rng.random(N_SLOW_UNIFORM))  # unused without a slow_bias
                many = draw_sensors(spec, np.array(u), np.array(z), enabled, nominal,
                                    np.array(us))  # fmt: skip
                assert many.n_slow == one[0].n_slow
                for name in SensorParams.ARRAYS:
                    a = np.concatenate([getattr(p, name) for p in one])
                    np.testing.assert_array_equal(getattr(many, name), a, err_msg=name)
                    assert np.array_equal(np.signbit(getattr(many, name)), np.signbit(a))
                    assert np.array_equal(getattr(many.rows(3), name), getattr(one[3], name))
                assert (many.lsb, many.full_scale, many.q_round) == (one[0].lsb,
                        one[0].full_scale, one[0].q_round)  # fmt: skip
    assert slow  # a preset with the slow bias (adis16405) is among them
