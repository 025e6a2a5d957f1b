"""A grade's second, slow Gauss-Markov bias process (``slow_bias``): parsing, closed forms in
the simulator, the torch model and the stream, and the other terms' draws left unchanged."""

import math

import numpy as np
import pytest
import yaml

from imugen.core.errors import InputError
from imugen.core.seeding import SENSOR_STREAMS
from imugen.sensors import fit as F
from imugen.sensors.grades import GM_PEAK, grade_from_config
from imugen.sensors.model import SensorModel, draw_sensor
from imugen.sensors.noise_terms import AxisModel
from imugen.simulate.stage import simulate

DEG_H = math.pi / 180 / 3600
UG = 9.80665e-6


def cfg(gyro_slow=None, accel_slow=None, start=None):
    """A grade with white noise, one fast GM (T 2 s) and, optionally, slow biases."""
    g = {
        "white_noise": {"value": 0.5, "unit": "deg_per_sqrt_h"},
        "bias_instability": {"value": 20, "unit": "deg_per_h", "kind": "gm_sigma",
                             "correlation_time": {"value": 2, "unit": "s"}},
    }  # fmt: skip
    a = {"white_noise": {"value": 0.05, "unit": "m_per_s_per_sqrt_h"}}
    if start is not None:
        g["bias_instability"]["start"] = start
    if gyro_slow is not None:
        g["slow_bias"] = gyro_slow
    if accel_slow is not None:
        a["slow_bias"] = accel_slow
    return {"id": 5300, "gyro": g, "accel": a}


SLOW_G = {"value": 40, "unit": "deg_per_h", "kind": "gm_sigma",
          "correlation_time": {"value": 20, "unit": "s"}}  # fmt: skip
SLOW_A = {"value": 300, "range": [200, 450], "unit": "ug", "kind": "allan_floor",
          "correlation_time": {"value": 15, "range": [10, 30], "unit": "s"}}  # fmt: skip


def test_parsing_and_refusals():
    g = grade_from_config("s", cfg(SLOW_G, SLOW_A))
    sb = g.gyro.slow_bias
    assert sb.model == "gauss_markov" and sb.components == 1 and sb.start == "stationary"
    assert sb.sigma_from_level(sb.level.value[0]) == pytest.approx(40 * DEG_H)
    sa = g.accel.slow_bias
    assert sa.sigma_from_level(300 * UG) == pytest.approx(300 * UG / GM_PEAK)
    assert "slow_bias" in g.gyro.configured()
    assert len(set(SENSOR_STREAMS.values())) == len(SENSOR_STREAMS)
    bad = [
        {**SLOW_G, "model": "flicker"},  # one GM only
        {k: v for k, v in SLOW_G.items() if k != "correlation_time"},
        {k: v for k, v in SLOW_G.items() if k != "kind"},
        {**SLOW_G, "unit": "ug"},
    ]
    for b in bad:
        with pytest.raises(InputError, match="slow_bias"):
            grade_from_config("s", cfg(b))
    c = cfg({**SLOW_G, "start": "stationary"})
    c["gyro"]["turn_on_bias"] = {"value": 1, "unit": "deg_per_h", "kind": "one_sigma"}
    with pytest.raises(InputError, match="twice"):
        grade_from_config("s", c)


def test_adding_it_leaves_every_other_draw_unchanged():
    """An accelerometer slow bias: the gyro's outputs are the same bits, the accelerometer's
    differ by the slow process alone (its turn-on, white noise draws unchanged)."""
    kw = dict(sequences=2, seed=5, static_s=20.0, rate_hz=100.0, outputs="rates", series=True)
    a = simulate(None, grade_from_config("s", cfg()), **kw)
    b = simulate(None, grade_from_config("s", cfg(accel_slow=SLOW_A)), **kw)
    for k in ("gyro", "gyro_bias", "dtheta"):
        if k in a.data:
            np.testing.assert_array_equal(a.data[k], b.data[k])
    d = b.data["accel"] - a.data["accel"]
    np.testing.assert_allclose(d, b.data["accel_bias"] - a.data["accel_bias"], atol=1e-12)
    assert np.all(np.abs(d).max(axis=1) > 0)
    # switching the term off (terms) gives back the grade without it, bit for bit
    c = simulate(None, grade_from_config("s", cfg(accel_slow=SLOW_A)),
                 terms=["gyro", "accel.white_noise"], **kw)  # fmt: skip
    np.testing.assert_array_equal(c.data["accel"], a.data["accel"])


RATE = 20.0  # Hz: the closed-form checks (T 2 s and 20 s) need no more, and memory stays small


def _series(c, S=24, T_s=600.0):
    return simulate(None, grade_from_config("s", c), sequences=S, seed=11, static_s=T_s,
                    rate_hz=RATE, outputs="rates", series=True)  # fmt: skip


@pytest.fixture(scope="module")
def stationary():
    return _series(cfg({**SLOW_G, "start": "stationary"}, start="stationary"))


def test_simulated_variance_and_autocorrelation_are_the_gm_sums(stationary):
    """Both processes from their stationary laws: the slow bias series has variance
    ``s1^2 + s2^2`` and autocovariance ``s1^2 e^(-l dt/T1) + s2^2 e^(-l dt/T2)`` at every lag."""
    b = stationary.data["gyro_bias"]  # (S, K, 3), turn-on 0
    s1, s2, T1, T2 = 20 * DEG_H, 40 * DEG_H, 2.0, 20.0
    x = b.reshape(-1, 3)
    v = np.mean(x**2)
    n_eff = b.shape[0] * 3 * b.shape[1] / RATE / (2 * T2)
    assert v == pytest.approx(s1**2 + s2**2, rel=5 / math.sqrt(n_eff))
    for lag_s in (2.0, 20.0):
        lag = int(lag_s * RATE)
        c = np.mean(b[:, lag:] * b[:, :-lag])
        want = s1**2 * math.exp(-lag_s / T1) + s2**2 * math.exp(-lag_s / T2)
        assert c == pytest.approx(want, abs=5 * (s1**2 + s2**2) / math.sqrt(n_eff))
    # the exact discrete recursion of the slow component: labels hold sigma and T
    lab = stationary.labels
    assert np.allclose(lab["gyro_slow_bias_sigma_x_radps"], s2)
    assert np.allclose(lab["gyro_slow_bias_tau_s"], T2)


def test_simulated_allan_is_the_closed_form_of_the_gm_sum():
    """Zero start (the in-run wander beside a turn-on bias, the ADIS preset's law): the mean
    overlapping Allan variance of the rate output over 24 sequences of 600 s equals the closed
    form of white + GM(2 s) + GM(20 s), zero-start corrections included, within its scatter."""
    sh = _series(cfg({**SLOW_G, "start": "zero"}, start="zero"), T_s=600.0)
    y = sh.data["gyro"]
    S, K, _ = y.shape
    am = AxisModel(rate_hz=RATE, white=0.5 * math.pi / 180 / 60, bi_model="gauss_markov",
                   bi_floor=20 * DEG_H * GM_PEAK, bi_T=2.0, bi_start="zero",
                   slow_peak=40 * DEG_H * GM_PEAK, slow_T=20.0)  # fmt: skip
    m = np.array([1, 2, 20, 80, 200, 400, 800, 1600])
    sim = np.mean([F.oavar(y[j, :, a], m) for j in range(S) for a in range(3)], axis=0)
    want = am.avar(m, K)
    e = F.edf(m, K, F.noise_alpha(m, want))
    tol = 4 * np.sqrt(2 / e / (3 * S)) + 0.01
    assert np.all(np.abs(sim / want - 1) < tol), np.round(sim / want, 3)
    # and without the slow process the same taus would miss by far (the test can fail)
    am.slow_peak = 0.0
    assert np.abs(sim[-1] / am.avar(m, K)[-1] - 1) > 5 * tol[-1]


def test_stream_exact_mode_is_the_shard_and_window_mode_draws_the_law(tmp_path):
    """Exact mode: the shard path's numbers bit for bit (the new streams included); window
    mode: the bias at a window's first row minus the turn-on value is normal with variance
    ``sum_c sigma_c^2 (1 - phi_c^(2 k0))`` (both processes started at zero)."""
    from imugen.stream import Stream
    from imugen.tables import shard as tshard

    from helpers import simulate_shard

    gy = tmp_path / "g.yaml"
    c = cfg(SLOW_G, SLOW_A)
    c["gyro"]["turn_on_bias"] = {"value": 30, "unit": "deg_per_h", "kind": "one_sigma"}
    gy.write_text(yaml.safe_dump({"grades": {"slowtest": c}}))
    K, W = 300, 40
    t = np.arange(K) * 0.01
    truth = {"time_s": t, "omega_ib_b": np.zeros((K, 3)), "f_b": np.tile([0, 0, 9.8], (K, 1)),
             "dtheta": np.zeros((K, 3)), "dv": np.vstack([np.zeros(3), np.tile([0, 0, 0.098],
                                                                               (K - 1, 1))])}  # fmt: skip
    out = tmp_path / "shard-001.parquet"
    simulate_shard(truth, str(out), "slowtest", sequences=2, seed=3, shard=1, route="r",
                   grades_file=str(gy), outputs="rates", series=True)  # fmt: skip
    tab = tshard.read(out, [*tshard.RATES, *tshard.BIAS])
    s = Stream({"r": truth}, "slowtest", window=W, batch_size=4, windows_per_sequence=2,
               seed=3, grades_file=str(gy), inputs="rates", targets=["bias"], exact=True)  # fmt: skip
    j, k0 = np.array([0, 1, 1]), np.array([1, 7, K - W])
    bt = s.generate(s.keys("r", "slowtest", 1, j, k0))
    for name, cols in (("x", tshard.RATES), ("bias", tshard.BIAS)):
        a = np.column_stack([tab.column(n).to_numpy() for n in cols])
        want = np.stack([a[jj * K + kk : jj * K + kk + W] for jj, kk in zip(j, k0, strict=True)])
        np.testing.assert_array_equal(bt[name], want, err_msg=name)
    ws = Stream({"r": truth}, "slowtest", window=W, batch_size=256, windows_per_sequence=2,
                seed=3, grades_file=str(gy), targets=["bias", "labels"])  # fmt: skip
    names = ws.label_names
    z = []
    for n in range(3):
        b = ws.batch(n)
        kk = b["keys"]["k0"].astype(float)
        lab_rows = b["labels"].astype(float)

        def lab(x, rows=lab_rows):
            return rows[:, names.index(x)]

        for i, ax in enumerate("xyz"):
            var = 0.0
            for sig, tau in ((f"gyro_bias_instability_sigma0_{ax}_radps",
                              "gyro_bias_instability_tau0_s"),
                             (f"gyro_slow_bias_sigma_{ax}_radps", "gyro_slow_bias_tau_s")):  # fmt: skip
                var = var + lab(sig) ** 2 * -np.expm1(-2 * 0.01 * kk / lab(tau))
            on = lab(f"gyro_turn_on_bias_{ax}_radps")
            z.append((b["bias"][:, 0, i] - on) / np.sqrt(var))
    z = np.concatenate(z)
    assert abs(np.mean(z**2) - 1) < 4 * np.sqrt(2 / len(z)), np.mean(z**2)
    assert abs(np.mean(z)) < 4 / np.sqrt(len(z))


def test_torch_model_slow_bias_closed_forms():
    """The torch model runs the slow process as one more GM component: at a window start
    ``k0`` the state's variance is ``sigma^2 (1 - phi^(2 (k0 - 1)))`` (zero start), and the
    stationary sum's autocovariance at a lag is that of the GM sum."""
    torch = pytest.importorskip("torch")
    from imugen.sensors.torch_model import TorchSensor

    g = grade_from_config("s", cfg({**SLOW_G, "start": "stationary"}, start="stationary"))
    enabled = frozenset(g.gyro.configured())
    p = draw_sensor(g.gyro, np.random.default_rng(0), enabled, nominal=True)
    assert p.components == 2 and p.n_slow == 1
    from imugen.sensors.model import SensorParams

    S = 512
    P = SensorParams.stack([p] * S)
    ts = TorchSensor(P, 0.01)
    gen = torch.Generator().manual_seed(3)
    L = 801
    s = ts.slow(L, k0=1, generator=gen).numpy()  # (S, L + 1, 3)
    s1, s2, T1, T2 = 20 * DEG_H, 40 * DEG_H, 2.0, 20.0
    var = np.mean(s**2, axis=(0, 2))
    n = S * 3
    assert np.all(np.abs(var / (s1**2 + s2**2) - 1) < 6 * math.sqrt(2 / n))
    lag = 500  # 5 s
    c = np.mean(s[:, lag:] * s[:, :-lag]) / np.mean(s**2)
    want = (s1**2 * math.exp(-5 / T1) + s2**2 * math.exp(-5 / T2)) / (s1**2 + s2**2)
    assert c == pytest.approx(want, abs=0.02)
    # zero start: the law at a window's start
    gz = grade_from_config("s", cfg({**SLOW_G, "start": "zero"}, start="zero"))
    pz = SensorParams.stack([draw_sensor(gz.gyro, np.random.default_rng(0), enabled, True)] * S)
    k0 = 1501  # 15 s after turn-on
    x = TorchSensor(pz, 0.01).slow(1, k0=k0, generator=gen).numpy()[:, 0]
    want = s1**2 * -math.expm1(-2 * 15 / T1) + s2**2 * -math.expm1(-2 * 15 / T2)
    assert np.mean(x**2) == pytest.approx(want, rel=6 * math.sqrt(2 / n))
    # the numpy model agrees on what it runs
    assert SensorModel(pz, 0.01).normals_per_sample == 3 + 3 + 3


def test_datasheet_import_and_kalibr_export(tmp_path):
    """A datasheet's ``slow_bias_<unit>`` with ``slow_bias_correlation_time_<unit>`` imports as
    the grade's slow_bias (Allan peak); alone it is refused; the Kalibr export counts its
    driving noise ``2 sigma^2 / T`` in ``random_walk``."""
    from imugen.sensors.grade_io import import_grade, kalibr_figures

    f = tmp_path / "ds.yaml"
    ds = {"part": "X", "gyro": {"arw_deg_per_sqrt_h": 2.0, "bias_instability_deg_per_h": 20,
                                "bias_instability_flicker_band_s": [1, 200],
                                "slow_bias_deg_per_h": 25, "slow_bias_correlation_time_s": 150}}  # fmt: skip
    f.write_text(yaml.safe_dump({"datasheet": ds}))
    name, c = import_grade(f, grade_id=5400)
    sb = c["gyro"]["slow_bias"]
    assert sb["kind"] == "allan_floor" and sb["value"] == 25
    assert sb["correlation_time"] == {"value": 150.0, "unit": "s"}
    g = grade_from_config(name, c)
    without = {k: v for k, v in c["gyro"].items() if k != "slow_bias"}
    g0 = grade_from_config(name, {**c, "gyro": without})
    k, k0 = (kalibr_figures(x)["gyroscope_random_walk"] for x in (g, g0))
    s = 25 * DEG_H / GM_PEAK
    assert k**2 - k0**2 == pytest.approx(2 * s * s / 150, rel=1e-9)
    del ds["gyro"]["slow_bias_correlation_time_s"]
    f.write_text(yaml.safe_dump({"datasheet": ds}))
    with pytest.raises(InputError, match="go together"):
        import_grade(f, grade_id=5400)


def test_filter_tuning_counts_the_slow_process():
    """The aided filter's bias state: initial sigma and driving noise add the slow process's
    ``sigma^2`` and ``2 sigma^2 / T``; switched off (``terms``), the grade without it."""
    from imugen.aid.filter.tuning import Tuning

    g = grade_from_config("s", cfg(SLOW_G, start="stationary"))
    g0 = grade_from_config("s", cfg(start="stationary"))
    t, t0 = Tuning.from_grade(g), Tuning.from_grade(g0)
    s = 40 * DEG_H
    np.testing.assert_allclose(t.gyro_bias_sd**2 - t0.gyro_bias_sd**2, s * s, rtol=1e-9)
    np.testing.assert_allclose(t.gyro_bias_q - t0.gyro_bias_q, 2 * s * s / 20.0, rtol=1e-9)
    off = Tuning.from_grade(g, terms=[x for x in g.gyro.configured() if x != "slow_bias"])
    np.testing.assert_allclose(off.gyro_bias_sd, t0.gyro_bias_sd)
    np.testing.assert_allclose(off.gyro_bias_q, t0.gyro_bias_q)
