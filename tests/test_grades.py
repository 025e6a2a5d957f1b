"""Grade presets and custom grades: loading, sources, immutability, validation."""

import dataclasses
import math

import numpy as np
import pytest

from imugen import grades
from imugen.errors import InputError

EXPECTED_IDS = {
    "consumer": 1,
    "industrial": 2,
    "tactical": 3,
    "navigation": 4,
    "paper_low_cost": 11,
    "paper_industrial": 12,
    "paper_tactical": 13,
}


def test_preset_ids_are_stable():
    p = grades.presets()
    assert {n: g.id for n, g in p.items()} == EXPECTED_IDS


def test_every_number_has_a_source_and_kind():
    for name, g in grades.presets().items():
        cfg = g.config
        for sensor in ("gyro", "accel"):
            for term, entry in (cfg.get(sensor) or {}).items():
                assert entry.get("source"), f"{name}.{sensor}.{term} has no source"
                if term in ("turn_on_bias", "bias_instability"):
                    assert entry["kind"] in ("one_sigma", "allan_floor", "gm_sigma")
                if (
                    term == "bias_instability"
                    and entry.get("model", "gauss_markov") == "gauss_markov"
                ):
                    assert entry["correlation_time"].get("source")


def test_presets_are_immutable():
    g = grades.presets()["consumer"]
    with pytest.raises(dataclasses.FrozenInstanceError):
        g.id = 7
    with pytest.raises(TypeError):
        grades.presets()["x"] = g
    c = g.config
    c["gyro"]["white_noise"]["value"] = 99.0
    assert g.config["gyro"]["white_noise"]["value"] == 0.3
    assert grades.presets()["consumer"] is g


def test_si_conversion_of_a_preset():
    g = grades.presets()["industrial"]
    np.testing.assert_allclose(g.gyro.white_noise.value, 0.2 * math.pi / 180 / 60)
    np.testing.assert_allclose(g.accel.bias_instability.level.value, 20 * 9.80665e-6)
    assert g.gyro.bias_instability.level.kind == "allan_floor"
    assert g.gyro.bias_instability.correlation_time.value[0] == 3600.0


def test_gm_allan_peak_matches_literature():
    # IEEE Std 952 / El-Sheimy 2008: a GM process' Allan deviation peaks at ~0.618 sigma
    # near tau ~ 1.89 T
    from scipy.optimize import minimize_scalar

    r = minimize_scalar(
        lambda lx: -grades.gm_avar(np.exp(lx), 1.0, 1.0),
        bounds=(-1.0, 2.0),
        method="bounded",
        options={"xatol": 1e-12},
    )
    assert grades.GM_PEAK == pytest.approx(np.sqrt(-r.fun), rel=1e-9)
    assert grades.GM_PEAK_X == pytest.approx(np.exp(r.x), rel=1e-6)
    # limits of the closed form: RRW for tau << T (K^2 = 2 sigma^2 / T), white for tau >> T
    s, T = 2.0, 50.0
    assert grades.gm_avar(1e-3, s, T) == pytest.approx(2 * s**2 / T * 1e-3 / 3, rel=1e-4)
    assert grades.gm_avar(1e7, s, T) == pytest.approx(2 * s**2 * T / 1e7, rel=1e-4)


def test_paper_grades_follow_the_code_coefficients():
    # seed-code-review.md §3: per-sample sigma = sqrt(A^2 + B^2) (gyro), accel x g0, z 10x
    p = grades.presets()
    for name, (A, B) in {
        "paper_low_cost": (1.75e-3, 4.85e-5),
        "paper_industrial": (4.85e-6, 1.745e-4),
        "paper_tactical": (4.85e-7, 1.745e-4),
    }.items():
        g = p[name]
        np.testing.assert_allclose(g.gyro.white_noise.value, math.hypot(A, B), rtol=1e-3)
        a = g.accel.white_noise.value
        assert a[2] == pytest.approx(10 * a[0]) and a[0] == a[1]
        assert g.gyro.configured() == ("white_noise",) == g.accel.configured()


def _cfg(**gyro):
    return {"id": 1000, "gyro": gyro}


@pytest.mark.parametrize(
    ("cfg", "match"),
    [
        (_cfg(white_noise={"value": 0.1, "unit": "deg_per_h"}), "not allowed"),
        (_cfg(turn_on_bias={"value": 1, "unit": "deg_per_h"}), "needs 'kind'"),
        (_cfg(turn_on_bias={"value": 1, "unit": "deg_per_h", "kind": "allan_floor"}), "kind"),
        (
            _cfg(white_noise={"value": 0.1, "range": [0.2, 0.3], "unit": "deg_per_sqrt_h"}),
            "lo <= value",
        ),
        (_cfg(white_noise={"value": -0.1, "unit": "deg_per_sqrt_h"}), ">= 0"),
        (_cfg(white_noise={"valeu": 0.1, "unit": "deg_per_sqrt_h"}), "unknown key"),
        (_cfg(wite_noise={"value": 0.1, "unit": "deg_per_sqrt_h"}), "unknown term"),
        (
            _cfg(quantization={"value": 1e-3, "range": [1e-4, 1e-2], "unit": "rad_per_s"}),
            "no range",
        ),
        (
            _cfg(bias_instability={"value": 1, "unit": "deg_per_h", "kind": "allan_floor"}),
            "correlation_time",
        ),
        ({"gyro": {}}, "integer 'id'"),
        ({"id": True}, "integer 'id'"),
        ({"id": 5, "colour": "red"}, "unknown key"),
    ],
)
def test_validation_errors(cfg, match):
    with pytest.raises(InputError, match=match):
        grades.grade_from_config("custom", cfg, "test.yaml")


def test_accel_has_no_g_sensitivity():
    with pytest.raises(InputError, match="unknown term"):
        grades.grade_from_config(
            "c", {"id": 9, "accel": {"g_sensitivity": {"value": 1, "unit": "deg_per_h_per_g"}}}
        )


def test_custom_file(tmp_path):
    f = tmp_path / "g.yaml"
    f.write_text(
        "grades:\n"
        "  mine:\n"
        "    id: 1001\n"
        "    gyro:\n"
        "      white_noise: {value: 0.1, unit: deg_per_sqrt_h, source: me}\n"
        "      bias_instability: {value: 1, unit: deg_per_h, kind: allan_floor, model: flicker,\n"
        "                         flicker_band: {min: 1, max: 1000, unit: s}}\n"
    )
    g = grades.get_grade(f"{f}:mine")
    assert g.id == 1001 and g.gyro.bias_instability.model == "flicker"
    assert g.gyro.bias_instability.components >= 5
    assert grades.get_grade("mine", grades_file=f) == g
    # collisions with presets are rejected
    f.write_text("grades:\n  mine:\n    id: 3\n")
    with pytest.raises(InputError, match="preset"):
        grades.load_grades(f)
    f.write_text("grades:\n  a:\n    id: 2000\n  b:\n    id: 2000\n")
    with pytest.raises(InputError, match="already used"):
        grades.load_grades(f)
    with pytest.raises(InputError, match="unknown grade"):
        grades.get_grade("no_such_grade")


def test_flicker_normalization_is_flat():
    taus = np.geomspace(10, 200, 20)
    adev = np.sqrt(grades.flicker_unit_avar(taus, (1.0, 1000.0), 7))
    assert np.all(np.abs(adev - 1) < 0.05)
