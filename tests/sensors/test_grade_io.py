"""Grade import (Kalibr/EuRoC, VINS, i2Nav) and export to Kalibr: mappings and round trips."""

from __future__ import annotations

import math

import numpy as np
import pytest
import yaml

from imugen.core.errors import InputError
from imugen.sensors import grade_io
from imugen.sensors.grades import get_grade, grade_from_config, load_grades

EUROC = """%YAML:1.0
sensor_type: imu
rate_hz: 200
gyroscope_noise_density: 1.6968e-04
gyroscope_random_walk: 1.9393e-05
accelerometer_noise_density: 2.0000e-3
accelerometer_random_walk: 3.0000e-3
"""
I2NAV = """imunoise:
  arw: 0.24      # deg/sqrt(h)
  vrw: 0.24      # m/s/sqrt(h)
  gbstd: 50.0    # deg/h
  abstd: 250.0   # mGal
  gsstd: 1000.0  # ppm
  asstd: 1000.0
  corrtime: 1.0  # h
"""


def test_kalibr_import_is_lossless_and_exports_back(tmp_path):
    p = tmp_path / "sensor.yaml"
    p.write_text(EUROC)
    name, cfg = grade_io.import_grade(p, grade_id=4242)
    g = grade_from_config(name, cfg)
    assert math.isclose(g.gyro.white_noise.value[0], 1.6968e-4)
    assert math.isclose(g.accel.rate_random_walk.value[0], 3.0e-3)
    back = yaml.safe_load(grade_io.to_kalibr(g, rate_hz=200))
    for k in grade_io.KALIBR_KEYS:
        assert math.isclose(back[k], yaml.safe_load(EUROC.split("\n", 1)[1])[k], rel_tol=1e-6)
    assert back["update_rate"] == 200.0


def test_vins_keys_map_like_kalibr(tmp_path):
    p = tmp_path / "vins.yaml"
    p.write_text("acc_n: 0.08\ngyr_n: 0.004\nacc_w: 0.00004\ngyr_w: 2.0e-6\n")
    _, cfg = grade_io.import_grade(p)
    assert cfg["accel"]["white_noise"]["value"] == 0.08
    assert cfg["gyro"]["rate_random_walk"]["value"] == 2.0e-6


def test_i2nav_imunoise_block_becomes_one_gauss_markov_state(tmp_path):
    p = tmp_path / "kf-gins.yaml"
    p.write_text("imupath: x.txt\n" + I2NAV)
    name, cfg = grade_io.import_grade(p, name="adis")
    g = grade_from_config(name, cfg)
    bi = g.gyro.bias_instability
    assert bi.level.kind == "gm_sigma" and bi.model == "gauss_markov"
    assert math.isclose(bi.level.value[0], 50.0 * math.pi / 180 / 3600)
    assert math.isclose(g.accel.bias_instability.level.value[0], 250e-5)
    assert math.isclose(bi.correlation_time.value[0], 3600.0)
    assert g.gyro.turn_on_bias is None  # the GM state's stationary law is the turn-on value
    assert math.isclose(g.gyro.white_noise.value[0], 0.24 * math.pi / 180 / 60)
    # exported random walk = driving noise of the GM: sigma sqrt(2 / T)
    k = grade_io.kalibr_figures(g)["gyroscope_random_walk"]
    assert math.isclose(k, 50.0 * math.pi / 180 / 3600 * math.sqrt(2 / 3600.0), rel_tol=1e-9)


def test_imported_grade_runs_through_simulate(tmp_path):
    from imugen.simulate.stage import simulate

    p = tmp_path / "kf.yaml"
    p.write_text(I2NAV)
    out = tmp_path / "grades.yaml"
    name, cfg = grade_io.import_grade(p, name="adis", grade_id=777)
    grade_io.write_text(out, grade_io.grades_document(name, cfg))
    g = load_grades(out)["adis"]
    sh = simulate(None, g, sequences=2, seed=1, static_s=20.0, rate_hz=50.0)
    assert np.all(np.isfinite(sh.data["dtheta"])) and np.std(sh.data["dtheta"][:, 1:]) > 0


def test_presets_export_with_dropped_terms_named():
    text = grade_io.to_kalibr("consumer")
    assert "SIMPLIFICATION" in text and "turn_on_bias" in text
    fig = yaml.safe_load(text)
    g = get_grade("consumer")
    assert math.isclose(
        fig["gyroscope_noise_density"], float(np.mean(g.gyro.white_noise.value)), rel_tol=1e-6
    )


@pytest.mark.parametrize(
    "text, msg",
    [
        ("foo: 1\n", "not a known IMU description"),
        ("gyroscope_noise_density: -1\n", ">= 0"),
        ("gyroscope_noise_density: .nan\n", "finite"),
        ("imunoise: {gbstd: 3}\n", "corrtime"),
        ("a: [\n", "not valid YAML"),
    ],
)
def test_bad_descriptions_are_refused_in_one_line(tmp_path, text, msg):
    p = tmp_path / "bad.yaml"
    p.write_text(text)
    with pytest.raises(InputError, match=msg):
        grade_io.import_grade(p)


def test_cli_round_trip(tmp_path, cli, capsys):
    from imugen.cli import main

    p = tmp_path / "sensor.yaml"
    p.write_text(EUROC)
    out = tmp_path / "g.yaml"
    assert (
        main(["grade", "import", str(p), "--name", "adis16448", "--id", "5000", "-o", str(out)])
        == 0
    )
    capsys.readouterr()
    assert main(["grade", "export", f"{out}:adis16448", "--rate-hz", "200"]) == 0
    assert "gyroscope_noise_density: 0.00016968" in capsys.readouterr().out
    r = cli("grade", "import", str(tmp_path / "missing.yaml"))  # the real entry point
    assert r.returncode == 2 and r.stderr.count("\n") == 1


# --- datasheet figures -----------------------------------------------------------------------
# The figures of the MPU-6050 as its datasheet and the Allan analysis the consumer preset cites
# give them (PS-MPU-6000A-00 sec 6.1-6.2; AirSim/Greenheck), in the datasheet's own units.
MPU6050 = """datasheet:
  part: InvenSense MPU-6050
  source: PS-MPU-6000A-00 rev 3.4
  spread: 1.5
  gyro:
    noise_density_deg_per_s_per_sqrt_hz: 0.005
    bias_instability_deg_per_h: 4.6
    bias_instability_correlation_time_s: 500
    turn_on_bias_deg_per_h: 200
    scale_factor_percent: {limit: 3}
    cross_axis_percent: {limit: 2}
    g_sensitivity_deg_per_s_per_g: 0.1
    quantization_rad_per_s: 2.0e-3
    range_deg_per_s: 2000
  accel:
    noise_density_ug_per_sqrt_hz: 400
    bias_instability_ug: 36
    bias_instability_correlation_time_s: 800
    turn_on_bias_mg: 10
    scale_factor_percent: {limit: 3}
    cross_axis_percent: {limit: 2}
    quantization_m_per_s2: 0.1
    range_g: 16
"""
STIM300 = """datasheet:
  part: Safran Sensonor STIM300
  gyro:
    arw_deg_per_sqrt_h: 0.15
    bias_instability_deg_per_h: 0.5
    bias_instability_correlation_time_h: 1
    turn_on_bias_deg_per_h: 7.07
    scale_factor_ppm: 500
    misalignment_mrad: 1
    g_sensitivity_deg_per_h_per_g: 1
  accel:
    vrw_m_per_s_per_sqrt_h: 0.06
    bias_instability_ug: 50
    bias_instability_correlation_time_s: 3600
    bias_repeatability_mg: 0.75
    scale_factor_ppm: 300
    misalignment_mrad: 1
    range_g: 10
"""


def _same_terms(got, want, ranges: bool):
    # the preset rounds its hand conversions to 3-4 digits (0.235 m/s/sqrt(h) for 400 ug/sqrt(Hz))
    tol = dict(rtol=3e-3, atol=0)
    for s in ("gyro", "accel"):
        a, b = got.sensor(s), want.sensor(s)
        assert a.configured() == b.configured(), s
        for t in a.configured():
            pa, pb = getattr(a, t), getattr(b, t)
            if t in ("bias_instability", "slow_bias"):
                assert (pa.model, pa.start, pa.level.kind) == (pb.model, pb.start, pb.level.kind)
                np.testing.assert_allclose(pa.correlation_time.value, pb.correlation_time.value)
                pa, pb = pa.level, pb.level
            assert pa.kind == pb.kind, (s, t)
            np.testing.assert_allclose(pa.value, pb.value, **tol, err_msg=f"{s}.{t}")
            if ranges:
                assert pa.randomized == pb.randomized, (s, t)
                if pa.randomized:
                    np.testing.assert_allclose(pa.lo, pb.lo, **tol, err_msg=f"{s}.{t} lo")
                    np.testing.assert_allclose(pa.hi, pb.hi, **tol, err_msg=f"{s}.{t} hi")


@pytest.mark.parametrize(
    "text, preset, ranges", [(MPU6050, "consumer", True), (STIM300, "industrial", False)]
)
def test_datasheet_figures_of_a_preset_give_the_preset_back(tmp_path, text, preset, ranges):
    p = tmp_path / "part.yaml"
    p.write_text(text)
    name, cfg = grade_io.import_grade(p, grade_id=3001)
    assert (
        name == {"consumer": "invensense_mpu_6050", "industrial": "safran_sensonor_stim300"}[preset]
    )
    _same_terms(grade_from_config(name, cfg), get_grade(preset), ranges)


def _white_and_gm(tmp_path, text):
    p = tmp_path / "ds.yaml"
    p.write_text(text)
    return grade_from_config(*grade_io.import_grade(p, grade_id=3002))


def test_datasheet_densities_and_floor_against_allan_deviation(tmp_path):
    # oracles independent of the mapping: a white rate noise of Kalibr/IEEE density N has Allan
    # deviation N at tau = 1 s, and a one-sided ASD (welch) of sqrt(2) N; a Gauss-Markov bias
    # read from an Allan floor B peaks at B (tau = 1.89 T)
    from scipy.signal import welch

    from imugen.allan import stage as allan
    from imugen.simulate.stage import simulate

    nd = 0.005  # deg/s/sqrt(Hz), stated as a one-sided ASD
    g = _white_and_gm(
        tmp_path,
        "datasheet:\n  density_sides: 1\n  gyro: {noise_density_deg_per_s_per_sqrt_hz: 0.005}\n"
        "  accel:\n    bias_instability_ug: 50\n    bias_instability_correlation_time_s: 2\n",
    )
    sh = simulate(None, g, sequences=6, seed=3, static_s=300.0, rate_hz=20.0, draw="nominal")
    cv = allan.allan_curves(sh, sensors=("gyro", "accel"), taus=np.array([1.0, 1.8926 * 2]))
    N = nd * math.pi / 180 / math.sqrt(2)
    # tolerances: 12 seeds scatter by 0.6 %, 0.2 % and 2.2 % (1 sigma)
    assert math.sqrt(cv["gyro"][0]) == pytest.approx(N, rel=0.03)
    rate = sh.data["dtheta"][:, 1:, :] * 20.0
    _, pxx = welch(rate, fs=20.0, nperseg=256, axis=1)  # one-sided by default
    assert math.sqrt(np.mean(pxx[:, 1:-1, :])) == pytest.approx(nd * math.pi / 180, rel=0.02)
    assert math.sqrt(cv["accel"][1]) == pytest.approx(50e-6 * 9.80665, rel=0.10)
    assert grade_io.kalibr_figures(g)["gyroscope_noise_density"] == pytest.approx(N)


def test_datasheet_assumptions_are_warned_and_limits_are_three_sigma(tmp_path):
    p = tmp_path / "x.yaml"
    p.write_text(
        "datasheet:\n  rate_hz: 200\n  bandwidth_hz: 50\n  gyro:\n"
        "    arw_deg_per_sqrt_h: 0.2\n    bias_instability_deg_per_h: 3\n"
        "    turn_on_bias_deg_per_s: {limit: 0.3, source: table 1}\n"
    )
    with pytest.warns(UserWarning) as rec:
        name, cfg = grade_io.import_grade(p)
    msgs = " ".join(str(w.message) for w in rec)
    assert "T = 3600 s assumed" in msgs and "bandwidth 50 Hz" in msgs
    g = grade_from_config(name, cfg)
    assert name == "x" and g.id == 1000
    assert g.gyro.bias_instability.correlation_time.value[0] == 3600.0
    assert g.gyro.turn_on_bias.value[0] == pytest.approx(0.1 * math.pi / 180)
    assert "table 1" in g.gyro.turn_on_bias.source


def test_density_sides_apply_to_densities_only_and_flicker_band(tmp_path):
    p = tmp_path / "x.yaml"
    p.write_text(
        "datasheet:\n  density_sides: 1\n  gyro:\n    arw_deg_per_sqrt_h: 0.2\n"
        "    in_run_bias_stability_deg_per_h: 3\n"
        "    bias_instability_flicker_band_s: [1, 1000]\n"
        "  accel: {noise_density_mg_per_sqrt_hz: [0.1, 0.1, 0.2]}\n"
    )
    g = grade_from_config(*grade_io.import_grade(p))
    # an ARW is an Allan figure (N itself); a one-sided ASD is sqrt(2) N
    assert g.gyro.white_noise.value[0] == pytest.approx(0.2 * math.pi / 180 / 60)
    np.testing.assert_allclose(
        g.accel.white_noise.value, np.array([0.1, 0.1, 0.2]) * 9.80665e-3 / math.sqrt(2)
    )
    bi = g.gyro.bias_instability
    assert (bi.model, bi.level.kind, bi.flicker_band) == ("flicker", "allan_floor", (1.0, 1000.0))


@pytest.mark.parametrize(
    "body, msg",
    [
        ("gyro: {arw_deg_per_h: 0.2}", "unit 'deg_per_h'"),
        ("gyro: {noise_deg_per_sqrt_h: 0.2}", "not a datasheet figure"),
        ("gyro: {arw_deg_per_sqrt_h: {limit: 0.2}}", "typical value"),
        ("gyro: {bias_instability_correlation_time_s: 9}", "needs a bias_instability"),
        ("gyro: {arw_deg_per_sqrt_h: 0.2, noise_density_deg_per_s_per_sqrt_hz: 0.01}", "twice"),
        ("accel: {vrw_m_per_s_per_sqrt_h: -1}", ">= 0"),
        ("density_sides: 3\n  gyro: {arw_deg_per_sqrt_h: 0.2}", "density_sides"),
        ("gyros: {arw_deg_per_sqrt_h: 0.2}", "unknown key"),
        ("part: x", "no gyro or accel"),
    ],
)
def test_bad_datasheets_are_refused_in_one_line(tmp_path, body, msg):
    p = tmp_path / "bad.yaml"
    p.write_text("datasheet:\n  " + body + "\n")
    with pytest.raises(InputError, match=msg):
        grade_io.import_grade(p)


# --- imugen grades documents ---------------------------------------------------------------
def test_grades_document_keeps_its_name_and_id_unless_overridden(tmp_path, capsys):
    from imugen.cli import main

    src = tmp_path / "ds.yaml"
    gcfg = {"id": 3000, "gyro": {"white_noise": {"value": 0.66, "unit": "deg_per_sqrt_h"}}}
    src.write_text(yaml.safe_dump({"grades": {"adis16448_ds": gcfg}}))
    name, cfg = grade_io.import_grade(src)
    assert (name, cfg["id"]) == ("adis16448_ds", 3000)
    name, cfg = grade_io.import_grade(src, name="mine", grade_id=4000)
    assert (name, cfg["id"]) == ("mine", 4000)
    out = tmp_path / "g.yaml"
    assert main(["grade", "import", str(src), "--id", "4000", "-o", str(out)]) == 0
    g = load_grades(out)["adis16448_ds"]
    assert g.id == 4000 and g.gyro.white_noise.value[0] == pytest.approx(0.66 * math.pi / 10800)
    src.write_text(yaml.safe_dump({"grades": {"low": {**gcfg, "id": 7}}}))
    with pytest.raises(InputError, match="give --id"):
        grade_io.import_grade(src)


# --- grade -> Kalibr -> grade --------------------------------------------------------------
@pytest.mark.parametrize("preset", ["consumer", "industrial", "tactical", "paper_low_cost"])
def test_round_trip_through_kalibr_keeps_what_kalibr_holds(tmp_path, preset):
    K_G, K_A = 2.0e-5, 3.0e-4  # rate random walks, rad/s^2/sqrt(Hz), m/s^3/sqrt(Hz)
    cfg = get_grade(preset).config
    cfg["gyro"]["rate_random_walk"] = {"value": K_G, "unit": "rad_per_s_per_sqrt_s"}
    cfg["accel"]["rate_random_walk"] = {"value": K_A, "unit": "m_per_s2_per_sqrt_s"}
    g = grade_from_config("g", cfg)
    text = grade_io.to_kalibr(g, rate_hz=200.0)
    p = tmp_path / "imu.yaml"
    p.write_text(text)
    back = grade_from_config(*grade_io.import_grade(p, grade_id=3003))
    for s in ("gyro", "accel"):
        orig, new = g.sensor(s), back.sensor(s)
        assert new.configured() == ("white_noise", "rate_random_walk")
        # white noise comes back (axis mean when per-axis values differ, as the file says)
        assert new.white_noise.value[0] == pytest.approx(np.mean(orig.white_noise.value), rel=1e-6)
        # the walk: the RRW, plus the in-run GM bias's driving noise 2 sigma^2 / T
        k2 = orig.rate_random_walk.value[0] ** 2
        bi = orig.bias_instability
        if bi is not None:
            sig = bi.level.value[0] / (0.6173642831444415 if bi.level.kind == "allan_floor" else 1)
            k2 += 2 * sig**2 / bi.correlation_time.value[0]
        assert new.rate_random_walk.value[0] == pytest.approx(math.sqrt(k2), rel=1e-6)
        if bi is None:
            assert new.rate_random_walk.value[0] == pytest.approx(orig.rate_random_walk.value[0])
    dropped = {t for s in (g.gyro, g.accel) for t in s.configured()} - {
        "white_noise",
        "rate_random_walk",
        "bias_instability",
    }
    line = next(ln for ln in text.splitlines() if ln.startswith("# Dropped terms"))
    named = set(line.split(":", 1)[1].strip(" .").split(", ")) - {"none"}
    assert named == dropped
    assert "SIMPLIFICATION" in text and ("Per-axis values averaged" in text) == (
        preset == "paper_low_cost"
    )
    # the projection is idempotent: exporting the imported grade gives the same numbers
    assert yaml.safe_load(grade_io.to_kalibr(back, rate_hz=200.0)) == yaml.safe_load(text)


def test_cli_prints_import_warnings_in_one_line_each(tmp_path, capsys):
    from imugen.cli import main

    p = tmp_path / "ds.yaml"
    p.write_text("datasheet:\n  accel: {vrw_m_per_s_per_sqrt_h: 0.1, bias_instability_mg: 0.1}\n")
    assert main(["grade", "import", str(p)]) == 0
    out, err = capsys.readouterr()
    assert err.startswith(f"imugen: warning: {p}: accel bias instability") and err.count("\n") == 1
    assert load_grades_text(out)["ds"].accel.bias_instability.level.kind == "allan_floor"


def load_grades_text(text):
    from imugen.sensors.grades import grades_from_document

    return grades_from_document(yaml.safe_load(text), "<stdout>")
