"""Allan deviation (allantools) of simulated static data recovers the configured terms.

Tolerance 10 % (the issue's). The term scales are chosen so that white noise dominates below
0.5 s, the flicker floor between 0.5 and 5 s and the rate random walk above 10 s; with
600 s x (4-6 sequences x 3 axes) the long-tau Allan variance averages ~200 independent 30 s
intervals, and repeated seeds scatter by <= 6 % (measured: 16 seeds x 3 rates).
"""

import json
import math

import numpy as np
import pytest

from imugen.allan import stage as allan
from imugen.sensors.grades import grade_from_config
from imugen.simulate import stage as S

from helpers import simulate_shard

DEG_H = math.pi / 180 / 3600
GYRO = {
    "white_noise": {"value": 0.0118, "unit": "deg_per_sqrt_h"},
    "bias_instability": {
        "value": 1.0,
        "unit": "deg_per_h",
        "kind": "allan_floor",
        "model": "flicker",
        "flicker_band": {"min": 0.1, "max": 10, "unit": "s"},
    },
    "rate_random_walk": {"value": 36.7, "unit": "deg_per_h_per_sqrt_h"},
}


def grade(gyro=None, accel=None):
    return grade_from_config("a", {"id": 9001, "gyro": gyro or {}, "accel": accel or {}})


@pytest.mark.parametrize(("rate", "M"), [(10.0, 6), (100.0, 6), (1000.0, 4)])
def test_allan_recovers_terms_at_every_rate(rate, M):
    sh = S.simulate(
        None, grade(GYRO), sequences=M, seed=1, static_s=600.0, rate_hz=rate, draw="nominal"
    )
    cv = allan.allan_curves(sh, max_sequences=M, sensors=("gyro",))
    rep = allan.allan_report(sh, curves=cv)
    assert set(rep) == {"arw", "gyro_bias_instability", "gyro_rrw"}
    assert rep["arw"]["configured"] == pytest.approx(0.0118)
    assert rep["gyro_rrw"]["configured"] == pytest.approx(36.7)
    assert rep["gyro_bias_instability"]["configured"] == pytest.approx(1.0)
    for k, e in rep.items():
        assert e["measured"] == pytest.approx(e["configured"], rel=0.10), k


def test_arw_read_at_one_second():
    N = 0.3  # deg/sqrt(h)
    sh = S.simulate(
        None,
        grade({"white_noise": {"value": N, "unit": "deg_per_sqrt_h"}}),
        sequences=4,
        seed=2,
        static_s=200.0,
        rate_hz=100.0,
    )
    cv = allan.allan_curves(sh, sensors=("gyro",), taus=np.array([1.0]))
    # adev(1 s) of white rate noise is the density itself; 12 curves x 200 s -> ~1.5 % error
    assert math.sqrt(cv["gyro"][0]) == pytest.approx(N * math.pi / 180 / 60, rel=0.05)


def test_flicker_floor_and_rrw_slope():
    sh = S.simulate(
        None,
        grade({"bias_instability": GYRO["bias_instability"]}),
        sequences=6,
        seed=3,
        static_s=300.0,
        rate_hz=20.0,
    )
    taus = np.geomspace(0.6, 4.0, 6)
    cv = allan.allan_curves(sh, sensors=("gyro",), taus=taus)
    floor = np.sqrt(cv["gyro"]) / DEG_H
    assert np.all(np.abs(floor - 1.0) < 0.10), floor
    K = 36.7 * DEG_H / 60
    sh = S.simulate(
        None,
        grade({"rate_random_walk": GYRO["rate_random_walk"]}),
        sequences=6,
        seed=4,
        static_s=600.0,
        rate_hz=20.0,
    )
    taus = np.geomspace(5.0, 60.0, 6)
    adev = np.sqrt(allan.allan_curves(sh, sensors=("gyro",), taus=taus)["gyro"])
    slope = np.polyfit(np.log(taus), np.log(adev), 1)[0]
    assert slope == pytest.approx(0.5, abs=0.05)
    np.testing.assert_allclose(adev, K * np.sqrt(taus / 3), rtol=0.10)


def test_gauss_markov_allan_floor_reading():
    # kind allan_floor + gauss_markov: the Allan peak (at ~1.89 T) is the configured figure
    g = grade(
        accel={
            "bias_instability": {
                "value": 50,
                "unit": "ug",
                "kind": "allan_floor",
                "correlation_time": {"value": 2.0, "unit": "s"},
            }
        }
    )
    sh = S.simulate(None, g, sequences=6, seed=5, static_s=300.0, rate_hz=20.0)
    cv = allan.allan_curves(sh, sensors=("accel",), taus=np.array([3.78]))
    assert math.sqrt(cv["accel"][0]) / (50 * 9.80665e-6) == pytest.approx(1.0, rel=0.10)


def test_report_from_file_and_plot(tmp_path):
    g = grade(
        GYRO,
        {
            "white_noise": {"value": 0.05, "unit": "m_per_s_per_sqrt_h"},
            "bias_instability": {
                "value": 20,
                "unit": "ug",
                "kind": "gm_sigma",
                "correlation_time": {"value": 5, "unit": "s"},
            },
        },
    )
    out = tmp_path / "static.parquet"
    simulate_shard(None, out, g, sequences=6, seed=6, static_s=600.0, rate_hz=20.0, draw="nominal")
    rep = allan.run(out, plot=tmp_path / "allan.png")
    json.dumps(rep)
    assert set(rep) == {"arw", "vrw", "gyro_bias_instability", "accel_bias_instability", "gyro_rrw"}
    assert (
        rep["vrw"]["unit"] == "m_per_s_per_sqrt_h"
        and rep["accel_bias_instability"]["kind"] == "gm_sigma"
    )
    for k, e in rep.items():
        assert e["measured"] == pytest.approx(e["configured"], rel=0.10), k
    assert (tmp_path / "allan.png").stat().st_size > 10_000


def test_bias_instability_check_uses_the_records_confidence_interval():
    """Issue 24: the industrial gyro bias instability read 1.14 x its configured value with
    4 x 2 h at seed 7; over 60 seeds the ratio is 0.94 +- 0.13 (95 % range 0.68-1.18):
    estimator scatter. The report's interval is that wide (not a fixed 10 %), holds the
    value, and still rejects a wrong configuration (the labels claim 1.5 x less)."""
    sh = S.simulate(None, "industrial", sequences=4, seed=7, static_s=7200.0, rate_hz=10.0,
                    terms=["white_noise", "bias_instability"])  # fmt: skip
    cv = allan.allan_curves(sh, max_sequences=4, sensors=("gyro",))
    e = allan.allan_report(sh, curves=cv)["gyro_bias_instability"]
    lo, hi = e["ci95"]
    assert 0.1 < e["sigma_rel"] < 0.2 and 0.6 < lo < 0.8 and 1.2 < hi < 1.4
    assert e["within"]
    wrong = sh.labels.copy()
    for c in wrong.columns:
        if c.startswith("gyro_bias_instability_") and not c.endswith("_s"):
            wrong[c] /= 1.5
    cv_wrong = {**cv, "labels": wrong}
    e2 = allan.allan_report(sh, curves=cv_wrong)["gyro_bias_instability"]
    assert e2["ratio"] == pytest.approx(1.5 * e["ratio"], rel=1e-6)
    assert not e2["within"]


def test_check_of_a_grade_with_output_bandwidth_and_rounding():
    """A filtered part reads below the N^2 / tau line at short tau (0.82x at 10 ms for the
    ADIS16405's filter) and rounds its rate register: the check's bases are the filtered
    white noise's and white rounding, so the configured density is read back (the plain
    N^2 / tau basis read 0.90x of it)."""
    g = grade(
        {
            "white_noise": {"value": 2.3, "unit": "deg_per_sqrt_h"},
            "quantization": {"value": 0.05, "unit": "deg_per_s", "mode": "round"},
            "bandwidth": {"filter": "moving_average", "taps": 10,
                          "internal_rate": {"value": 819.2, "unit": "hz"}},
        }
    )  # fmt: skip
    sh = S.simulate(None, g, sequences=4, seed=3, static_s=300.0, rate_hz=100.0, outputs="rates")
    e = allan.allan_report(sh, curves=allan.allan_curves(sh, 4, sensors=("gyro",)))["arw"]
    assert e["ratio"] == pytest.approx(1.0, abs=0.02) and e["within"], e


def test_a_slow_bias_is_its_own_basis_not_read_as_another_term():
    """A grade with a slow_bias (a second GM, T 60 s, twice the flicker floor): the Allan
    check reads the white noise, the flicker floor and the rate random walk as it does for
    the grade without it (same seed), because the slow process has its own basis; without
    that basis the rate random walk would read 1.27x and leave its interval."""
    import copy

    slow = {"value": 2.0, "unit": "deg_per_h", "kind": "allan_floor",
            "correlation_time": {"value": 60, "unit": "s"}}  # fmt: skip
    reps = []
    for g in (GYRO, {**GYRO, "slow_bias": slow}):
        sh = S.simulate(None, grade(g), sequences=6, seed=1, static_s=1200.0, rate_hz=10.0,
                        draw="nominal")  # fmt: skip
        cv = allan.allan_curves(sh, max_sequences=6, sensors=("gyro",))
        reps.append(allan.allan_report(sh, curves=cv))
    assert set(reps[1]) == {"arw", "gyro_bias_instability", "gyro_rrw"}
    for k in reps[0]:
        assert reps[1][k]["ratio"] == pytest.approx(reps[0][k]["ratio"], abs=0.02), k
    assert reps[1]["gyro_rrw"]["within"]
    blind = copy.deepcopy(cv)
    blind["meta"]["terms"]["gyro"] = [t for t in blind["meta"]["terms"]["gyro"] if t != "slow_bias"]
    e = allan.allan_report(sh, curves=blind)["gyro_rrw"]
    assert e["ratio"] > 1.15 and not e["within"]
