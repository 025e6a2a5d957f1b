"""Grade import (Kalibr/EuRoC, VINS, i2Nav) and export to Kalibr: mappings and round trips."""

from __future__ import annotations

import math

import numpy as np
import pytest
import yaml

from imugen import grade_io
from imugen.errors import InputError
from imugen.grades import get_grade, grade_from_config, load_grades

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
    from imugen.simulate import simulate

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


def test_cli_round_trip(tmp_path, cli):
    p = tmp_path / "sensor.yaml"
    p.write_text(EUROC)
    out = tmp_path / "g.yaml"
    r = cli("grade", "import", str(p), "--name", "adis16448", "--id", "5000", "-o", str(out))
    assert r.returncode == 0, r.stderr
    r = cli("grade", "export", f"{out}:adis16448", "--rate-hz", "200")
    assert r.returncode == 0 and "gyroscope_noise_density: 0.00016968" in r.stdout
    r = cli("grade", "import", str(tmp_path / "missing.yaml"))
    assert r.returncode == 2 and r.stderr.count("\n") == 1
