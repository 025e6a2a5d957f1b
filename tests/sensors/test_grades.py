"""Grade presets and custom grades: loading, sources, immutability, validation."""

import dataclasses
import functools
import math

import numpy as np
import pytest

from imugen.core.errors import InputError
from imugen.sensors import grades
from imugen.simulate.sources import StaticTruth

EXPECTED_IDS = {
    "consumer": 1,
    "industrial": 2,
    "tactical": 3,
    "navigation": 4,
    "consumer_calibrated": 5,
    "industrial_calibrated": 6,
    "tactical_calibrated": 7,
    "navigation_calibrated": 8,
    "paper_low_cost": 11,
    "paper_industrial": 12,
    "paper_tactical": 13,
    "adis16405": 14,
    "phone": 15,
    "phone_calibrated": 16,
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
                if term in ("turn_on_bias", "bias_instability", "slow_bias"):
                    assert entry["kind"] in ("one_sigma", "allan_floor", "gm_sigma")
                if (
                    term in ("bias_instability", "slow_bias")
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
    np.testing.assert_allclose(g.gyro.white_noise.value, 0.15 * math.pi / 180 / 60)
    np.testing.assert_allclose(g.accel.bias_instability.level.value, 50 * 9.80665e-6)
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


# --- one bias model per source ----------------------------------------------------------------
_TB = {"value": 1, "unit": "deg_per_h", "kind": "one_sigma"}
_GM = {
    "value": 1,
    "unit": "deg_per_h",
    "kind": "gm_sigma",
    "correlation_time": {"value": 3600, "unit": "s"},
}


def test_turn_on_beside_a_stationary_process_is_refused():
    with pytest.raises(InputError, match="counts the initial bias twice"):
        grades.grade_from_config(
            "c", _cfg(turn_on_bias=_TB, bias_instability={**_GM, "start": "stationary"})
        )
    with pytest.raises(InputError, match="start must be"):
        grades.grade_from_config("c", _cfg(bias_instability={**_GM, "start": "later"}))


def test_default_start_is_unambiguous():
    both = grades.grade_from_config("c", _cfg(turn_on_bias=_TB, bias_instability=_GM))
    assert both.gyro.bias_instability.start == "zero"
    alone = grades.grade_from_config("c", _cfg(bias_instability=_GM))
    assert alone.gyro.bias_instability.start == "stationary"


def test_calibrated_grade_needs_its_calibration():
    with pytest.raises(InputError, match="calibration"):
        grades.grade_from_config("c", {"id": 1000, "variant": "calibrated"})
    with pytest.raises(InputError, match="variant"):
        grades.grade_from_config("c", {"id": 1000, "variant": "factory"})


def test_every_datasheet_grade_has_a_calibrated_twin_of_the_same_part():
    p = grades.presets()
    for name in ("consumer", "industrial", "tactical", "navigation"):
        u, c = p[name], p[f"{name}_calibrated"]
        assert u.variant == "uncalibrated" and c.variant == "calibrated" and c.calibration
        assert u.description.split("part: ")[1].split(" (")[0] in c.description
        for s in grades.SENSORS:
            us, cs = u.sensor(s), c.sensor(s)
            # noise and factory figures are the part's; only the bias differs
            for t in ("white_noise", "scale_factor", "cross_coupling", "g_sensitivity"):
                assert getattr(us, t) == getattr(cs, t)
            # the calibrated residual is the part's Allan floor (the GM peak for a GM state)
            bi = us.bias_instability
            floor = bi.allan_floor_from_level(bi.level.value[0])
            assert cs.turn_on_bias.value[0] == pytest.approx(floor, rel=2e-3)
            assert cs.bias_instability.start == "zero"
            ub = (
                us.turn_on_bias.value[0]
                if us.turn_on_bias
                else bi.sigma_from_level(bi.level.value[0])
            )
            assert cs.turn_on_bias.value[0] < ub


def _population_rms(p):
    """RMS of a level log-uniform in [lo, hi] (closed form), per axis."""
    lo, hi = np.asarray(p.lo), np.asarray(p.hi)
    return np.sqrt((hi**2 - lo**2) / (2.0 * np.log(hi / lo)))


def _ranged(g):
    for s in grades.SENSORS:
        spec = g.sensor(s)
        for t in spec.configured():
            p = getattr(spec, t)
            p = p.level if t in ("bias_instability", "slow_bias") else p
            if p.randomized:
                yield f"{g.name}.{s}.{t}", p


MEASURED = ("adis16405", "phone", "phone_calibrated")
"""Presets whose ranges are measured spreads (min..max over units and axes) or brackets of
several parts, with the value the median or the named part's figure: not the datasheet
presets' [value / 1.5, value * 1.5] around one part's figure."""


def test_preset_ranges_are_centred_on_the_part():
    for name, g in grades.presets().items():
        if name.startswith("paper_") or name in MEASURED:
            continue
        for where, p in _ranged(g):
            centre = np.sqrt(np.asarray(p.lo) * np.asarray(p.hi))
            np.testing.assert_allclose(centre, p.value, rtol=0.01, err_msg=where)
            assert np.all(np.asarray(p.hi) / np.asarray(p.lo) <= 2.26), where
            # the population's RMS level stays within 6 % of the part's figure
            np.testing.assert_array_less(_population_rms(p), 1.06 * np.asarray(p.value))


@functools.cache
def _start_bias(name, M=1000):
    """Slow bias at t = 0 and at the last sample, and the turn-on labels, of M sequences."""
    from imugen.simulate import stage as S

    sh = S.simulate(
        None,
        name,
        sequences=M,
        seed=4,
        static_s=620.0,
        rate_hz=0.2,
        series=True,
        terms=["turn_on_bias", "bias_instability"],
    )
    return sh.data["gyro_bias"], sh.data["accel_bias"], sh.gyro.b_on, sh.accel.b_on


@pytest.mark.parametrize(
    ("name", "gyro_deg_h", "accel_mps2"),
    [
        # one GM state: the population starts at the part's sigma, not sqrt(2) x (1.41)
        ("tactical", 1.0, 1e-3 * 9.80665),
        # turn-on draw + in-run from zero: starts at the turn-on figure alone
        ("industrial", 7.07, 0.75e-3 * 9.80665),
        ("tactical_calibrated", 0.618, 0.618e-3 * 9.80665),
    ],
)
def test_population_starts_at_the_parts_figure(name, gyro_deg_h, accel_mps2):
    gb, ab, g_on, a_on = _start_bias(name)
    g = grades.presets()[name]
    for bias, on, fig, spec in ((gb, g_on, gyro_deg_h, g.gyro), (ab, a_on, accel_mps2, g.accel)):
        p = spec.turn_on_bias or spec.bias_instability.level
        fig_si = fig * (math.pi / 180 / 3600 if spec is g.gyro else 1.0)
        expect = fig_si * _population_rms(p)[0] / p.value[0]
        rms0 = float(np.sqrt(np.mean(bias[:, 0] ** 2)))
        # 3000 values, level-mixed normal: standard error of the RMS about 1.6 %
        assert rms0 == pytest.approx(expect, rel=0.06)
        if spec.bias_instability.start == "zero":
            # the in-run process starts at zero: the bias at t = 0 is the turn-on draw exactly
            np.testing.assert_allclose(bias[:, 0], on, rtol=0, atol=1e-15)
        else:
            assert np.all(on == 0.0)


def test_calibrated_in_run_wander_grows_as_the_gm_law():
    # tactical_calibrated gyro: x(0) = 0, Var x(T) = sigma^2 (1 - exp(-2 T / tau)) at T = 620 s
    gb, _, g_on, _ = _start_bias("tactical_calibrated")
    g = grades.presets()["tactical_calibrated"].gyro
    bi = g.bias_instability
    sig = _population_rms(bi.level)[0]
    T, tau = 620.0, bi.correlation_time.value[0]
    wander = gb[:, -1] - g_on
    expect = sig * math.sqrt(-math.expm1(-2 * T / tau))
    assert float(np.sqrt(np.mean(wander**2))) == pytest.approx(expect, rel=0.06)


def test_calibration_at_rest_removes_the_static_g_sensitivity():
    from imugen.simulate import stage as S

    kw = {"sequences": 3, "seed": 2, "static_s": 1.0, "rate_hz": 10.0, "outputs": "rates"}
    for name, removed in (("consumer", False), ("consumer_calibrated", True)):
        assert grades.presets()[name].gyro.static_g_removed is removed
        sh = S.simulate(None, name, terms=["gyro.g_sensitivity"], **kw)
        G = sh.gyro.gs
        # still and level: f = (0, 0, g), so the gyro reads G (0, 0, g), less G (0, 0, g0)
        # (standard gravity) when calibrated at rest: what is left is G (0, 0, g - g0)
        g = StaticTruth(1.0, 10.0).f_b[2]
        expect = G[:, :, 2] * (g - (9.80665 if removed else 0.0))
        np.testing.assert_allclose(sh.data["gyro"][:, -1], expect, rtol=1e-9, atol=1e-20)
        if removed:
            assert np.max(np.abs(expect)) < 3e-3 * np.max(np.abs(G[:, :, 2] * g))
        assert np.all(np.abs(G[:, :, 2]) > 0)
    # accelerometers: scale factor and cross-coupling on gravity, E (0, 0, g), likewise
    for name, removed in (("industrial", False), ("industrial_calibrated", True)):
        sh = S.simulate(None, name, terms=["accel.scale_factor", "accel.cross_coupling"], **kw)
        p = sh.accel
        E = p.cc + p.sf[:, :, None] * np.eye(3)[None]
        g = StaticTruth(1.0, 10.0).f_b[2]
        expect = E[:, :, 2] * (g - (9.80665 if removed else 0.0))
        expect[:, 2] += g
        np.testing.assert_allclose(sh.data["accel"][:, -1], expect, rtol=1e-9, atol=1e-20)
    with pytest.raises(InputError, match="calibrated_at_rest"):
        grades.grade_from_config("c", {"id": 1000, "calibrated_at_rest": True})
