"""grade fit: recovers known models from simulated logs; the real-data oracle on the ADIS16405."""

import numpy as np
import pytest

from imugen.sensors import bandwidth as bw
from imugen.sensors import fit as F
from imugen.sensors.noise_terms import AxisModel

from helpers import SHARED

ADIS = SHARED / "data" / "imu" / "adis16405_static"


def simulate_triad(models, K, seed):
    rng = np.random.default_rng(seed)
    return np.column_stack([m.simulate(K, rng) for m in models])


def test_detect_lsb():
    rng = np.random.default_rng(0)
    y = 0.05 * np.round(rng.standard_normal(10000) * 3 / 0.05) + 0.0123
    assert F.detect_lsb(y.astype(np.float32).astype(float)) == pytest.approx(0.05, rel=1e-5)
    assert F.detect_lsb(rng.standard_normal(1000)) == 0.0


def test_recovers_flicker_model_filter_and_quantization():
    filt = bw.moving_average(10, 819.2, 100.0)
    truth = [
        AxisModel(rate_hz=100.0, white=w, filt=filt, lsb=0.002, bi_model="flicker",
                  bi_floor=6e-4, bi_band=(1.0, 3000.0), bi_components=8, offset=0.3)
        for w in (0.0015, 0.002, 0.0012)
    ]  # fmt: skip
    K = 300_000
    Y = simulate_triad(truth, K, 1)
    sf = F.fit_sensor(Y, 100.0, "accel", internal_rate_hz=819.2)
    assert np.allclose(sf.lsb, 0.002, rtol=1e-6)
    assert sf.bi_kind == "flicker", sf.choice
    assert sf.filt.adev_ratio_tau0() == pytest.approx(filt.adev_ratio_tau0(), rel=0.03)
    for am, tr in zip(sf.models, truth, strict=True):
        # the output's white line is what the log determines
        assert sf.filt.output_density(am.white) == pytest.approx(
            filt.output_density(tr.white), rel=0.03
        )
        assert am.bi_floor == pytest.approx(tr.bi_floor, rel=0.3)
    assert all(u["white_noise"] < 0.01 for u in sf.uncertainty)


def test_narrow_floor_chooses_gauss_markov():
    truth = [
        AxisModel(rate_hz=100.0, white=0.002, bi_model="gauss_markov", bi_floor=2e-3, bi_T=20.0)
        for _ in range(3)
    ]
    Y = simulate_triad(truth, 200_000, 2)
    sf = F.fit_sensor(Y, 100.0, "gyro", internal_rate_hz=100.0, slow_gm=False)
    assert sf.bi_kind == "gauss_markov", sf.choice
    assert 8.0 < sf.bi_par < 50.0
    for am in sf.models:
        assert am.bi_floor == pytest.approx(2e-3, rel=0.25)


def test_gravity_frame_z_down():
    fr = F.gravity_frame(np.array([-0.04, -0.02, -9.96]))
    assert fr["axis"] == "z" and fr["sign"] < 0
    assert np.allclose(fr["R_body_sensor"] @ [0, 0, -9.96], [0, 0, 9.96])


@pytest.mark.skipif(not ADIS.exists(), reason="needs ../shared/data/imu")
def test_adis16405_fitted_grade_simulated_by_imugen_reproduces_the_real_allan_curve():
    """The issue's oracle, end to end: fit the gyro of a real ADIS16405 (2.78 h still), write
    the grade, simulate it with imugen's simulator for the same length (8 sequences, their
    Allan variances averaged: one replica scatters +-5-8 % at 41-82 s, so a
    single one fails a 10 % test now and then for a perfect model), and compare the
    overlapping Allan deviation with the real one at every octave from 0.02 s to 82 s.

    Gyro x and y only, and only the gyro (to keep the test near 30 s): the z gyro carries a
    20 Hz line and the accelerometers a 0.56 Hz line (environment, in the grade's notes, not
    simulated); their fitted models are held to the real curves by the test below."""
    pd = pytest.importorskip("pandas")
    from imugen.sensors.grades import grade_from_config
    from imugen.simulate.stage import simulate

    df = pd.read_parquet(ADIS / "adis16405_static_imu1.parquet")
    Y = df.iloc[:, :3].to_numpy(np.float64)
    K = len(Y)
    sf = F.fit_sensor(Y, 100.0, "gyro", internal_rate_hz=819.2, slow_gm=False)
    cfg = {"id": 5100, "gyro": F.sensor_config(sf, "adis16405 unit 1"), "accel": {}}
    g = grade_from_config("adis_fit_test", cfg)
    assert g.gyro.bandwidth.filter != "ideal" and g.gyro.quantization_mode == "round"
    sh = simulate(None, g, sequences=8, seed=24, static_s=(K - 1) / 100.0, rate_hz=100.0,
                  outputs="rates")  # fmt: skip
    mo = F.octaves(K, 0.01)
    t = mo / 100.0
    band = (t >= 0.02) & (t <= 82)
    assert t[band][0] == pytest.approx(0.02) and t[band][-1] > 80
    for a in (0, 1):
        meas = F.oavar(Y[:, a], mo)
        sim = np.mean([F.oavar(sh.data["gyro"][j, :, a], mo) for j in range(8)], axis=0)
        ratio = np.sqrt(sim / meas)[band]
        assert np.all(np.abs(ratio - 1) < 0.10), (a, np.round(ratio, 3))


@pytest.mark.skipif(not ADIS.exists(), reason="needs ../shared/data/imu")
def test_adis16405_accelerometer_fit_holds_the_real_curve():
    """The accelerometer fit (lines included) on the first 300,000 samples (50 min, to keep
    the test short): the fitted model's expected Allan deviation within 10 % of the real one
    at every octave from 0.02 s to 82 s, and the LSB (3.33 mg) and the output filter found."""
    pd = pytest.importorskip("pandas")
    df = pd.read_parquet(ADIS / "adis16405_static_imu1.parquet")
    Y = df.iloc[:300_000, 3:6].to_numpy(np.float64)
    sf = F.fit_sensor(Y, 100.0, "accel", internal_rate_hz=819.2, slow_gm=False)
    cfg = F.sensor_config(sf, "adis16405 unit 1")
    assert cfg["quantization"]["value"] == pytest.approx(3.33, rel=1e-3)
    assert 0.7 < sf.filt.adev_ratio_tau0() < 0.9  # the part filters its output
    mo = F.octaves(len(Y), 0.05)
    t = mo / 100.0
    band = (t >= 0.02) & (t <= 82)
    for a, am in enumerate(sf.models):
        meas = F.oavar(Y[:, a], mo)
        ratio = np.sqrt(am.avar(mo, len(Y)) / meas)[band]
        assert np.all(np.abs(ratio - 1) < 0.10), (a, np.round(ratio, 3))


@pytest.mark.skipif(not ADIS.exists(), reason="needs ../shared/data/imu")
@pytest.mark.parametrize("sensor", ["gyro", "accel"])
def test_adis16405_long_tau_inside_the_real_curves_confidence(sensor):
    """Out to 655 s (unit 1, the whole 2.78 h record: the longest octaves need it). The fit's
    model, with the slow second Gauss-Markov hump (T 100-150 s) it finds, holds every axis
    within 10 % at every octave 0.02-82 s and inside the real curve's own 95 % interval
    (chi-square of Greenhall's EDF: about [0.86, 1.20] at 164 s, [0.81, 1.31] at 328 s,
    [0.75, 1.52] at 655 s) beyond. The grade document holds no second hump (one bias process
    per sensor plus rate random walk): without it, gyro y/z and accelerometer x/z still stay
    inside the interval, gyro x (0.75 at 328 s) and accelerometer y (0.76 at 164 s) do not
    (docs/how-to/fit-a-grade.md). Expected (closed-form) Allan variances: the simulator is
    held to them by test_noise_terms."""
    pd = pytest.importorskip("pandas")
    df = pd.read_parquet(ADIS / "adis16405_static_imu1.parquet")
    Y = df.iloc[:, :3] if sensor == "gyro" else df.iloc[:, 3:6]
    Y = Y.to_numpy(np.float64)
    K = len(Y)
    mo = F.octaves(K, 0.1)
    t = mo / 100.0
    short, long_ = (t >= 0.02) & (t <= 82), t > 82
    assert t[long_][-1] > 650
    meas = [F.oavar(Y[:, a], mo) for a in range(3)]
    ci = [F.adev_ci(np.ones(len(mo)), F.edf(mo, K, F.noise_alpha(mo, v))) for v in meas]
    inside = {}
    for slow in (True, False):
        sf = F.fit_sensor(Y, 100.0, sensor, internal_rate_hz=819.2, slow_gm=slow)
        for a, am in enumerate(sf.models):
            r = np.sqrt(am.avar(mo, K) / meas[a])
            lo, hi = ci[a]
            ok = bool(np.all((r[long_] >= lo[long_]) & (r[long_] <= hi[long_])))
            if slow:
                assert np.all(np.abs(r[short] - 1) < 0.10), (a, np.round(r[short], 3))
                assert ok, (a, np.round(r[long_], 3), np.round(lo[long_], 3))
            else:
                inside[a] = ok
    # the grade's own model (no hump): the axes it holds
    assert all(inside[a] for a in ((1, 2) if sensor == "gyro" else (0, 2))), inside
