"""imugen.stream with output bandwidths, rounding quantization, vibration and mounting.

Exact mode against the written shard (bit for bit); window mode against closed forms of
filtered white noise (:mod:`imugen.sensors.bandwidth`)."""

import copy

import numpy as np
import pytest
import yaml

from imugen.sensors.grades import preset_text, presets
from imugen.stream import Stream
from imugen.tables import shard as tshard

from helpers import simulate_shard

SEED, ROUTE, W = 11, "oracle", 50

BANDS = {  # grade name -> gyro/accel bandwidth entry (quantization mode)
    "bw_ideal": ({"filter": "ideal"}, "carry"),
    "bw_ma": ({"filter": "moving_average", "taps": 10, "internal_rate": {"value": 819.2,
                                                                          "unit": "hz"}}, "carry"),
    "bw_bartlett": ({"filter": "bartlett", "taps": 4, "internal_rate": {"value": 400,
                                                                         "unit": "hz"}}, "round"),
    "bw_butter": ({"filter": "butterworth", "order": 2, "internal_rate": {"value": 1000,
                   "unit": "hz"}, "cutoff": {"value": 30, "unit": "hz"}}, "carry"),
    "bw_dlpf": ({"filter": "mpu6050_dlpf", "setting": 3}, "carry"),
    "round_only": (None, "round"),
}  # fmt: skip


@pytest.fixture(scope="module")
def grades_file(tmp_path_factory):
    """consumer with each bandwidth / quantization mode of :data:`BANDS` (ids 90..)."""
    base = yaml.safe_load(preset_text())["grades"]["consumer"]
    doc = {"grades": {}}
    for i, (name, (band, mode)) in enumerate(BANDS.items()):
        g = copy.deepcopy(base)
        g["id"] = 90 + i
        for s in ("gyro", "accel"):
            g[s]["quantization"] = {**g[s]["quantization"], "mode": mode}
            if band is not None:
                g[s]["bandwidth"] = band
        doc["grades"][name] = g
    p = tmp_path_factory.mktemp("grades") / "grades.yaml"
    p.write_text(yaml.safe_dump(doc))
    return str(p)


def moving_truth(K, dt=0.01):
    """A body turning and accelerating (sinusoids), as arrays of a truth table."""
    t = np.arange(K) * dt
    w = np.column_stack([0.3 * np.sin(0.7 * t), 0.2 * np.cos(0.5 * t), 0.4 + 0 * t])
    f = np.column_stack([1.5 * np.sin(0.3 * t), 0.8 * np.cos(0.9 * t), 9.8 + 0.5 * np.sin(t)])
    dth = np.vstack([np.zeros(3), 0.5 * (w[1:] + w[:-1]) * dt])
    dv = np.vstack([np.zeros(3), 0.5 * (f[1:] + f[:-1]) * dt])
    return {"time_s": t, "omega_ib_b": w, "f_b": f, "dtheta": dth, "dv": dv}


@pytest.fixture(scope="module")
def truth():
    return moving_truth(K=400)


def _compare_exact(tmp_path, truth, grade, grades_file=None, outputs="increments", **opts):
    out = tmp_path / "shard-002.parquet"
    simulate_shard(truth, str(out), grade, sequences=2, seed=SEED, shard=2, route=ROUTE,
                   outputs=outputs, series=True, grades_file=grades_file, **opts)  # fmt: skip
    cols = list(tshard.INCREMENTS if outputs == "increments" else tshard.RATES)
    err = list(tshard.EFFECTIVE_ERROR[outputs])
    t = tshard.read(out, [*cols, *err, *tshard.BIAS])
    K = len(truth["time_s"])
    s = Stream({ROUTE: truth}, grade, window=W, batch_size=4, windows_per_sequence=2, seed=SEED,
               inputs=outputs, targets=["effective_error", "bias"], exact=True,
               grades_file=grades_file, **opts)  # fmt: skip
    j = np.array([0, 1, 1, 0])
    k0 = np.array([1, 1, K - W, 213])
    b = s.generate(s.keys(ROUTE, grade, 2, j, k0))
    for name, c in (("x", cols), ("effective_error", err), ("bias", list(tshard.BIAS))):
        a = np.column_stack([t.column(n).to_numpy() for n in c])
        want = np.stack([a[jj * K + kk : jj * K + kk + W] for jj, kk in zip(j, k0, strict=True)])
        np.testing.assert_array_equal(b[name], want, err_msg=f"{grade} {name}")


@pytest.mark.parametrize("grade", list(BANDS))
def test_exact_mode_with_bandwidth_and_rounding_is_the_shard(tmp_path, truth, grades_file, grade):
    _compare_exact(tmp_path, truth, grade, grades_file)


@pytest.mark.parametrize("grade", ["adis16405", "phone", "phone_calibrated"])
@pytest.mark.parametrize("outputs", ["increments", "rates"])
def test_measured_presets_stream_exactly(tmp_path, truth, grade, outputs):
    assert grade in presets()
    _compare_exact(tmp_path, truth, grade, outputs=outputs)


def test_exact_mode_with_vibration_and_mounting_is_the_shard(tmp_path, truth):
    _compare_exact(tmp_path, truth, "consumer", vibration="car",
                   mounting={"misalignment_sd_deg": 1.0, "lever_arm_m": [0.3, 0.1, -0.2]})  # fmt: skip


def _window_stream(truth, grade, grades_file, **kw):
    kw = {"window": W, "batch_size": 8, "windows_per_sequence": 4, "seed": SEED,
          "grades_file": grades_file, **kw}  # fmt: skip
    return Stream({ROUTE: truth}, grade, **kw)


@pytest.mark.parametrize("grade", ["bw_bartlett", "bw_butter", "bw_dlpf", "bw_ideal"])
@pytest.mark.parametrize("inputs", ["increments", "rates"])
def test_window_mode_filter_is_warmed_up_as_the_whole_sequence(truth, grades_file, grade, inputs):
    """Deterministic terms only: the window's filtered error (filter started a warm-up before
    the window) is the whole sequence's, up to the IIR's truncated tail."""
    terms = "turn_on_bias scale_factor cross_coupling g_sensitivity"
    s = _window_stream(truth, grade, grades_file, terms=terms, inputs=inputs,
                       targets=["effective_error"])  # fmt: skip
    K = len(truth["time_s"])
    keys = s.keys(ROUTE, grade, 5, [0, 0, 1, 1], [1, 40, 170, K - W])
    win = s.generate(keys, exact=False)["effective_error"]
    ex = s.generate(keys, exact=True)["effective_error"]
    scale = np.abs(ex).max(axis=1, keepdims=True)
    np.testing.assert_allclose(win[1:], ex[1:], rtol=0, atol=2e-6 * scale.max())
    # the first window starts at the route's start: the filters start in steady state on it
    np.testing.assert_allclose(win[0, 5:], ex[0, 5:], rtol=0, atol=2e-3 * scale.max())


@pytest.mark.parametrize("grade", ["bw_ma", "bw_butter", "bw_dlpf"])
def test_window_mode_noise_has_the_filters_closed_forms(grades_file, grade):
    """White noise only: variance and lag-1 covariance of the output noise are those of
    filtered white noise read at the output rate (OutputFilter.variance / output_autocov)."""
    from imugen.sensors.grades import get_grade

    tr = moving_truth(K=300)
    s = _window_stream(tr, grade, grades_file, terms="white_noise", inputs="rates",
                       targets=["effective_error"], draw="nominal", batch_size=512,
                       windows_per_sequence=8)  # fmt: skip
    b = s.batch(0)
    rows = b["keys"]["k0"][:, None] + np.arange(W)
    true = np.concatenate([tr["omega_ib_b"][rows], tr["f_b"][rows]], axis=2)
    n = b["x"].astype(float) - true - b["effective_error"]  # (B, W, 6)
    g = get_grade(grade, grades_file)
    for i, sensor in enumerate(("gyro", "accel")):
        f = s.bands[0][i]
        N = g.sensor(sensor).white_noise.value[0]
        r = f.output_autocov(N, 2)
        x = n[..., 3 * i : 3 * i + 3]
        var = np.mean(x**2)
        lag1 = np.mean(x[:, 1:] * x[:, :-1])
        assert var == pytest.approx(r[0], rel=0.06), sensor
        assert lag1 / var == pytest.approx(r[1] / r[0], abs=0.04), sensor


def test_window_mode_rounding_quantizes_each_sample(truth, grades_file):
    s = _window_stream(truth, "round_only", grades_file, inputs="rates")
    b = s.batch(0)
    from imugen.sensors.grades import get_grade

    g = get_grade("round_only", grades_file)
    for i, sensor in enumerate(("gyro", "accel")):
        q = g.sensor(sensor).quantization.value[0]
        k = b["x"][..., 3 * i : 3 * i + 3].astype(float) / q
        np.testing.assert_allclose(k, np.round(k), atol=1e-3)


@pytest.mark.parametrize("mounted", [False, True])
def test_gnss_target_is_the_aid_stages_table(tmp_path, mounted):
    """The gnss target of written keys: the aid stage's GNSS table (fixes, sigmas, scenario
    states, receiver labels) on the window's rows, with drawn outages and a spoofing ramp;
    with mounting, the antenna's lever arm from the mounted IMU (the shard's draws)."""
    from imugen.aid import stage as aid
    from imugen.aid.options import AidOptions
    from imugen.core.io import write_parquet
    from imugen.tables import gnss as tgnss
    from imugen.truth import build_truth, enu_table

    t = np.arange(0.0, 181.0, 1.0)
    enu = np.column_stack([400 * np.sin(t / 50.0), 250 * (1 - np.cos(t / 35.0)), 0.1 * t])
    df, meta = enu_table(enu, t, origin=(45.2, 7.6, 300.0))
    tdf, tmeta = build_truth(df, meta, rate_hz=50.0, earth="flat", verbose=False)
    truth = write_parquet(tdf, tmeta, tmp_path / "drive" / "truth.parquet")
    shard = tmp_path / "drive" / "imu" / "consumer" / "shard-001.parquet"
    mount = {"misalignment_sd_deg": 3.0, "lever_arm_m": [0.5, -0.3, 0.8]} if mounted else None
    simulate_shard(truth, shard, "consumer", sequences=3, seed=SEED, shard=1, mounting=mount)
    opts = {"draw_kinds": ("outage", "spoof_ramp"), "settle_s": 20.0, "lever_arm_sd_m": 0.1,
            "lever_arm_b_m": (0.2, 0.0, 1.2)}  # fmt: skip
    g = tmp_path / "g.parquet"
    aid.run(truth, shard, g, tmp_path / "a.parquet", AidOptions(**opts))
    s = Stream([str(truth)], "consumer", window=400, batch_size=2, windows_per_sequence=1,
               seed=SEED, targets=["gnss"], gnss=opts, shard_size=3, mounting=mount)  # fmt: skip
    route = s.route_names[0]
    k0 = np.array([1, 4000, 7500])
    b = s.generate(s.keys(route, "consumer", 1, [0, 2, 1], k0))
    tab = tgnss.read(g)
    lab = tgnss.read_labels(g)
    ids = np.sort(tab["sequence"].unique())
    dt = 1 / 50.0
    for i, (j, k) in enumerate(zip([0, 2, 1], k0, strict=True)):
        rows = tab[tab["sequence"] == ids[j]]
        kk = np.round(rows["time_s"].to_numpy() / dt).astype(int)
        sel = (kk >= k) & (kk < k + 400)
        r = kk[sel] - k
        assert len(r) >= 8
        for name, cols in (("gnss_p_n", tgnss.P), ("gnss_v_n", tgnss.V),
                           ("gnss_sigma_p_n", tgnss.SIGMA_P)):  # fmt: skip
            want = rows[list(cols)].to_numpy()[sel].astype(np.float32)
            np.testing.assert_array_equal(b[name][i, r], want, err_msg=name)
            assert np.isnan(b[name][i, np.setdiff1d(np.arange(400), r)]).all()
        np.testing.assert_array_equal(b["gnss_state"][i, r], rows["state"].to_numpy()[sel])
        want = lab[lab["sequence"] == ids[j]][s.gnss_label_names].to_numpy()[0]
        np.testing.assert_array_equal(b["gnss_labels"][i], want.astype(np.float32))
    assert (tab["state"] != 0).any()  # the scenarios act on the table
    if mounted:  # the mounting moves the antenna: not the unmounted IMU's fixes
        plain = Stream([str(truth)], "consumer", window=400, batch_size=2,
                       windows_per_sequence=1, seed=SEED, targets=["gnss"], gnss=opts,
                       shard_size=3).generate(b["keys"])  # fmt: skip
        d = np.nanmax(np.abs(plain["gnss_p_n"] - b["gnss_p_n"]))
        assert d > 1e-3


@pytest.mark.parametrize("grade", ["adis16405", "phone", "phone_calibrated"])
def test_measured_presets_stream_in_window_mode(truth, grade):
    """Window mode on the measured presets: finite rows, rates on the LSB grid (rounding)."""
    from imugen.sensors.grades import get_grade

    s = Stream({ROUTE: truth}, grade, window=W, batch_size=4, windows_per_sequence=2,
               seed=SEED, inputs="rates", targets=["effective_error", "bias"])  # fmt: skip
    b = s.batch(3)
    assert b["x"].shape == (4, W, 6) and np.isfinite(b["x"]).all()
    assert np.isfinite(b["effective_error"]).all() and np.isfinite(b["bias"]).all()
    g = get_grade(grade)
    for i, sensor in enumerate(("gyro", "accel")):
        q = g.sensor(sensor).quantization.value[0]
        k = b["x"][..., 3 * i : 3 * i + 3].astype(float) / q
        np.testing.assert_allclose(k, np.round(k), atol=1e-3 * np.abs(k).max())


def test_gnss_target_needs_truth_files(truth):
    from imugen.core.errors import InputError

    with pytest.raises(InputError, match="truth files"):
        Stream({ROUTE: truth}, "consumer", window=W, batch_size=4, windows_per_sequence=2,
               targets=["gnss"])  # fmt: skip


MOUNT = {"misalignment_sd_deg": 1.0, "lever_arm_m": [0.3, 0.1, -0.2]}


@pytest.mark.parametrize("grade", ["bw_ideal", "bw_butter", "round_only"])
@pytest.mark.parametrize("inputs", ["increments", "rates"])
def test_window_mode_with_vibration_and_mounting_is_the_sequences_motion(truth, grades_file,
                                                                         grade, inputs):  # fmt: skip
    """Mounting and vibration have no state: window mode applies the sequence's draws (the
    shard's streams) to the window's rows, so with the deterministic terms only its measured
    rows and effective error are exact mode's (up to the output filter's truncated tail)."""
    terms = "turn_on_bias scale_factor cross_coupling g_sensitivity"
    kw = {"terms": terms, "inputs": inputs, "targets": ["effective_error"]}
    s = _window_stream(truth, grade, grades_file, vibration="car", mounting=MOUNT, **kw)
    K = len(truth["time_s"])
    keys = s.keys(ROUTE, grade, 5, [0, 0, 1, 1], [40, 97, 170, K - W])
    win = s.generate(keys, exact=False)
    ex = s.generate(keys, exact=True)
    for name in ("x", "effective_error"):
        scale = np.abs(ex[name]).max()
        np.testing.assert_allclose(win[name], ex[name], rtol=0, atol=2e-6 * scale, err_msg=name)
    # the motion is the mounted, vibrating case's: not the vehicle's
    still = _window_stream(truth, grade, grades_file, **kw).generate(keys, exact=False)["x"]
    assert np.abs(win["x"] - still).max() > 100 * 2e-6 * np.abs(still).max()
