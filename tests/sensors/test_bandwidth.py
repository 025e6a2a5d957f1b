"""Closed forms of the output-bandwidth model against simulation (each a few seconds)."""

import math

import numpy as np
import pytest
from scipy import signal

from imugen.sensors import bandwidth as bw
from imugen.sensors.fit import oavar

N = 0.01  # density, any unit


def sim(f, K, seed):
    return f.white(N, K, np.random.default_rng(seed))


@pytest.mark.parametrize(
    "filt",
    [
        bw.ideal(100.0),
        bw.moving_average(10, 819.2, 100.0),  # asynchronous read
        bw.bartlett(8, 800.0, 100.0),
        bw.butterworth(2, 30.0, 1000.0, 100.0),
        bw.butterworth(1, 20.0, 1600.0, 200.0),
        bw.mpu6050_dlpf(3, "accel", 100.0),
        bw.adis16405(3, 1, 100.0),
    ],
    ids=lambda f: f.kind + f"-{f.taps or f.cutoff_hz:g}-{f.ratio:g}",
)
def test_variance_autocov_and_allan_match_simulation(filt):
    K = 400_000
    y = sim(filt, K, 1)
    r = filt.output_autocov(N, 4)
    # variance and lag-1/2 autocovariance: standard errors ~ sqrt(2/K) r0
    se = r[0] * math.sqrt(2.0 / K) * 3
    assert np.var(y) == pytest.approx(r[0], abs=4 * se)
    for lag in (1, 2):
        assert np.mean(y[:-lag] * y[lag:]) == pytest.approx(r[lag], abs=4 * se)
    # Allan variance at tau = m / f_o, closed form vs overlapping estimate
    m = np.array([1, 2, 4, 16, 64])
    a_sim = oavar(y, m)
    a_cf = filt.avar(m, N)
    assert np.allclose(a_sim, a_cf, rtol=4 * np.sqrt(2 * m / K * 3) + 0.01)
    # long tau: the white line g N^2 / tau (g the aliasing gain)
    mm = np.array([1000, 4000])
    g = filt.alias_gain()
    assert np.allclose(filt.avar(mm, N), g * N**2 / (mm / filt.output_rate_hz), rtol=0.02)
    assert np.var(np.add.reduceat(y, np.arange(0, K, 1000))[:-1] / 1000) == pytest.approx(
        g * N**2 * filt.output_rate_hz / 1000, rel=0.15
    )


def test_ideal_is_the_white_line_and_ma_of_the_ratio_is_ideal():
    m = np.array([1, 2, 3, 10, 100])
    f = bw.ideal(100.0)
    assert np.allclose(f.avar(m, N), N**2 / (m / 100.0), rtol=1e-12)
    assert f.adev_ratio_tau0() == pytest.approx(1.0)
    # averaging D internal samples and reading every D-th = integrate-and-dump at f_o
    g = bw.moving_average(8, 800.0, 100.0)
    assert np.allclose(g.avar(m, N), f.avar(m, N), rtol=1e-12)
    assert g.variance(N) == pytest.approx(f.variance(N))


def test_fir_variance_closed_forms():
    for L in (1, 4, 10):
        f = bw.moving_average(L, 1000.0, 100.0)
        assert f.variance(N) == pytest.approx(N**2 * 1000.0 / L)
        b = bw.bartlett(L, 1000.0, 100.0)
        assert b.variance(N) == pytest.approx(N**2 * 1000.0 * (2 * L * L + 1) / (3 * L**3))
    # the aliasing gain: 1 for MA(D) read synchronously; 1 + 2 c(lD)/c(0)... for async reads
    assert bw.moving_average(10, 1000.0, 100.0).alias_gain() == pytest.approx(1.0)
    g = bw.moving_average(10, 819.2, 100.0).alias_gain()
    assert g == pytest.approx(819.2 * (0.1 + 2 * (0.808 * 0.02 + 0.192 * 0.01)) / 100, rel=1e-9)


def test_first_order_variance_closed_form():
    # bilinear first-order low-pass: sum h^2 from its pole and zero
    fi, fc = 1000.0, 50.0
    f = bw.butterworth(1, fc, fi, fi)
    b, a = np.asarray(f.b), np.asarray(f.a)
    p = -a[1]  # pole
    # H = b0 (1 + z^-1) / (1 - p z^-1): h0 = b0, h_n = b0 (1 + p) p^(n-1)
    b0 = b[0]
    s2 = b0**2 + b0**2 * (1 + p) ** 2 / (1 - p * p)
    assert f.variance(N) == pytest.approx(N**2 * fi * s2, rel=1e-5)
    assert f.alias_gain() == pytest.approx(1.0, rel=1e-5)  # read at the internal rate


def test_psd_closed_form_matches_welch():
    filt = bw.butterworth(2, 30.0, 800.0, 100.0)
    y = sim(filt, 1_000_000, 2)
    f, P1 = signal.welch(y, fs=100.0, nperseg=1024)
    sel = (f > 1) & (f < 49)
    S2 = filt.psd(f[sel], N)
    ratio = (P1[sel] / 2) / S2
    # 1950 averaged segments: ~2 % per bin; allow 8 %
    assert np.all(np.abs(ratio - 1) < 0.08), ratio
    # integrated PSD = variance; PSD at 0 = g N^2
    assert filt.psd(np.array([0.0]), N)[0] == pytest.approx(filt.alias_gain() * N**2)
    ff = np.linspace(-50, 50, 20001)
    assert np.trapezoid(filt.psd(ff, N), ff) == pytest.approx(filt.variance(N), rel=1e-3)


def test_named_parts():
    # MPU-6050: bandwidth reproduced, equivalent noise bandwidth of a Butterworth-2
    for s in range(7):
        g = bw.mpu6050_dlpf(s, "gyro", 100.0)
        bwg = bw.MPU6050_DLPF[s][2]
        assert g.cutoff_3db_hz() == pytest.approx(min(bwg, 0.45 * g.internal_rate_hz), rel=0.02)
        if g.cutoff_3db_hz() < g.internal_rate_hz / 20:  # bilinear warp small
            assert g.enbw_hz() / g.cutoff_3db_hz() == pytest.approx(1.11, abs=0.01)
        # documented delay honoured where the Butterworth's own is shorter (settings 0-2)
        if s <= 2:
            assert g.group_delay_s() * 1e3 == pytest.approx(bw.MPU6050_DLPF[s][3], abs=0.05)
    # ADIS16405: -3 dB of the Bartlett window vs the IIO driver's sps / divisor table
    for n in (1, 2, 3, 4, 5):
        f = bw.adis16405(n, 1, 819.2)
        assert f.cutoff_3db_hz() == pytest.approx(819.2 / bw.ADIS16400_3DB_DIVISORS[n], rel=0.12), n


def test_rejects_bad_input():
    with pytest.raises(ValueError):
        bw.OutputFilter(50.0, 100.0)
    with pytest.raises(ValueError):
        bw.butterworth(2, 600.0, 1000.0, 100.0)
    with pytest.raises(ValueError):
        bw.mpu6050_dlpf(7, "gyro", 100.0)


# --- the grade key and the simulator ------------------------------------------------------
def _grade(bandwidth, quantization=None, gid=4242):
    from imugen.sensors.grades import grade_from_config

    gyro = {"white_noise": {"value": 0.6, "unit": "deg_per_sqrt_h"}, "bandwidth": bandwidth}
    if quantization is not None:
        gyro["quantization"] = quantization
    return grade_from_config("bw_test", {"id": gid, "gyro": gyro, "accel": {}})


def test_grade_key_validation():
    from imugen.core.errors import InputError

    g = _grade(
        {"filter": "moving_average", "taps": 10, "internal_rate": {"value": 819.2, "unit": "hz"}}
    )
    assert g.gyro.bandwidth.output_filter("gyro", 100.0).ratio == pytest.approx(8.192)
    assert g.accel.bandwidth is None
    bad = [
        {"filter": "moving_average", "taps": 10},  # no internal rate
        {"filter": "boxcar"},
        {"filter": "butterworth", "order": 2, "cutoff": {"value": 500, "unit": "hz"},
         "internal_rate": {"value": 800, "unit": "hz"}},  # cut-off above Nyquist
        {"filter": "mpu6050_dlpf", "setting": 9},
        {"filter": "ideal", "taps": 3},
        {"filter": "bartlett", "taps": 4, "internal_rate": {"value": 800, "unit": "deg"}},
    ]  # fmt: skip
    for b in bad:
        with pytest.raises(InputError):
            _grade(b)
    with pytest.raises(InputError, match="above the gyro's internal rate"):
        g.gyro.bandwidth.output_filter("gyro", 1000.0)
    with pytest.raises(InputError, match="mode"):
        _grade({"filter": "ideal"}, {"value": 0.01, "unit": "deg_per_s", "mode": "floor"})


def _still(grade, seconds, rate, outputs="both", seed=3):
    from imugen.simulate.stage import simulate

    return simulate(None, grade, sequences=1, seed=seed, static_s=seconds, rate_hz=rate,
                    outputs=outputs, terms="white_noise,quantization")  # fmt: skip


@pytest.mark.parametrize(
    "band",
    [
        {"filter": "moving_average", "taps": 10, "internal_rate": {"value": 819.2, "unit": "hz"}},
        {"filter": "butterworth", "order": 2, "cutoff": {"value": 30, "unit": "hz"},
         "internal_rate": {"value": 1000, "unit": "hz"}},
        {"filter": "mpu6050_dlpf", "setting": 3},
    ],
    ids=["ma10-async", "butter2-30", "mpu6050-3"],
)  # fmt: skip
def test_simulated_noise_matches_the_filter_closed_forms(band):
    """The simulator's gyro noise (rate and increments) has the variance, lag-1 covariance and
    Allan variance of the filtered white noise, not N^2 / dt."""
    g = _grade(band)
    rate = 100.0
    sh = _still(g, 3000.0, rate)
    filt = g.gyro.bandwidth.output_filter("gyro", rate)
    N = g.gyro.white_noise.value[0]
    y = sh.data["gyro"][0, :, 0]
    y = y - y.mean()
    K = len(y)
    r = filt.output_autocov(N, 3)
    se = r[0] * math.sqrt(2.0 / K) * 4
    assert np.var(y) == pytest.approx(r[0], abs=4 * se)
    assert np.mean(y[:-1] * y[1:]) == pytest.approx(r[1], abs=4 * se)
    assert r[1] > 0.1 * r[0]  # samples correlated: not the ideal sensor's white sequence
    m = np.array([1, 2, 8, 32])
    assert np.allclose(oavar(y, m), filt.avar(m, N), rtol=0.05)
    # increments are the same output integrated by the host: dtheta / dt = rate sample
    inc = sh.data["dtheta"][0, 1:, 0] / (1 / rate)
    assert np.allclose(inc, sh.data["gyro"][0, 1:, 0], atol=1e-12)


def test_filter_acts_on_motion_with_its_frequency_response():
    """A sinusoidal rate through the stream comes out scaled by |H| and delayed by the
    filter's phase (below the output Nyquist, up to the linear interpolation)."""
    f = bw.butterworth(2, 10.0, 1000.0, 100.0)
    st = bw.Stream(f, np.zeros((1, 3)), [np.random.default_rng(0)])
    fo, K, f0 = 100.0, 4000, 3.0
    t = np.arange(K) / fo
    x = np.sin(2 * np.pi * f0 * t)
    y = np.concatenate([st.motion("rate", k0, np.repeat(x[k0:k0 + 500, None], 3, 1)[None])
                        for k0 in range(0, K, 500)], axis=1)[0, :, 0]  # fmt: skip
    H = f.response(np.array([f0]))[0]
    expect = np.abs(H) * np.sin(2 * np.pi * f0 * t + np.angle(H))
    assert np.max(np.abs(y[1000:] - expect[1000:])) < 0.01


def test_stream_is_independent_of_chunking():
    f = bw.moving_average(10, 819.2, 100.0)
    a = bw.Stream(f, np.full((1, 3), 0.01), [np.random.default_rng(5)])
    b = bw.Stream(f, np.full((1, 3), 0.01), [np.random.default_rng(5)])
    whole = a.noise(0, 1000)
    parts = np.concatenate([b.noise(0, 333), b.noise(333, 667)], axis=1)
    assert np.allclose(whole, parts, rtol=0, atol=1e-15)  # same draws; sums may round apart


def test_round_quantization_adds_white_lsb2_over_12():
    q = 0.05  # deg/s
    g = _grade({"filter": "ideal"}, {"value": q, "unit": "deg_per_s", "mode": "round"}, 4243)
    sh = _still(g, 2000.0, 100.0, outputs="rates")
    y = sh.data["gyro"][0, :, 0]
    qs = math.radians(q)
    assert np.allclose(y / qs, np.round(y / qs), atol=1e-9)  # on the grid
    N = g.gyro.white_noise.value[0]
    assert np.var(y) == pytest.approx(N**2 * 100.0 + qs**2 / 12, rel=0.03)


def test_datasheet_import_and_kalibr_export_carry_the_bandwidth(tmp_path):
    from imugen.sensors import grade_io
    from imugen.sensors.grades import grade_from_config

    ds = tmp_path / "ds.yaml"
    ds.write_text(
        "datasheet:\n  part: Test IMU\n  rate_hz: 1000\n  bandwidth_hz: 98\n"
        "  gyro:\n    noise_density_deg_per_s_per_sqrt_hz: 0.005\n"
        "  accel:\n    noise_density_ug_per_sqrt_hz: 400\n"
    )
    with pytest.warns(UserWarning, match="Butterworth"):
        name, cfg = grade_io.import_grade(ds, grade_id=3001)
    g = grade_from_config(name, cfg)
    f = g.gyro.bandwidth.output_filter("gyro", 200.0)
    assert (f.kind, f.order, f.internal_rate_hz) == ("butterworth", 2, 1000.0)
    assert f.cutoff_3db_hz() == pytest.approx(98.0, rel=0.02)
    # a named part's filter
    ds.write_text(
        "datasheet:\n  part: MPU\n  filter: {filter: mpu6050_dlpf, setting: 3}\n"
        "  gyro:\n    noise_density_deg_per_s_per_sqrt_hz: 0.005\n"
    )
    name, cfg = grade_io.import_grade(ds, grade_id=3002)
    g2 = grade_from_config(name, cfg)
    assert g2.gyro.bandwidth.filter == "mpu6050_dlpf"
    # Kalibr: the output's white line at the export rate, and the filter said
    text = grade_io.to_kalibr(g, rate_hz=200.0)
    N = g.gyro.white_noise.value[0]
    assert "gyro output bandwidth: Butterworth order 2" in text
    k = grade_io.kalibr_figures(g, 200.0)["gyroscope_noise_density"]
    assert k == pytest.approx(N * math.sqrt(f.alias_gain()))
    assert k != pytest.approx(N, rel=1e-3)


# --- many windows at once (the stream's window mode) ----------------------------------------
WINDOW_FILTERS = {
    "ideal": lambda: bw.ideal(100.0),
    "ma_async": lambda: bw.moving_average(10, 819.2, 100.0),
    "bartlett_sync": lambda: bw.bartlett(4, 400.0, 100.0),
    "butter_sync": lambda: bw.butterworth(2, 30.0, 1000.0, 100.0),
    "butter_async": lambda: bw.butterworth(2, 52.0, 832.0, 104.0 * 0.97),
}


@pytest.mark.parametrize("name", list(WINDOW_FILTERS))
def test_filter_windows_is_the_streams_motion_filter(name):
    """filter_windows (one compiled call over many windows) gives what Stream.motion gives
    each window run on its own from its first sample, with the same read phase."""
    f = WINDOW_FILTERS[name]()
    rng = np.random.default_rng(3)
    B, L = 5, 40
    y = np.cumsum(rng.standard_normal((B, L, 6)), axis=1)
    ph = rng.random(B)
    got = bw.filter_windows(f, y, ph)
    for b in range(B):
        st = bw.Stream(f, np.ones((1, 3)), [np.random.default_rng(0)])
        st.phase[:] = 0.0 if f.synchronous else ph[b]
        want = np.concatenate([st.motion("a", 1, y[b : b + 1, :, :3])[0],
                               st.motion("b", 1, y[b : b + 1, :, 3:])[0]], axis=1)  # fmt: skip
        np.testing.assert_allclose(got[b], want, rtol=0, atol=1e-12 * np.abs(y).max())


@pytest.mark.parametrize("name", list(WINDOW_FILTERS))
def test_noise_windows_has_the_filtered_noises_law(name):
    """noise_windows (the reads' exact Gaussian law, one normal per read) against the closed
    forms: per read phase, the covariance N^2 f_i c(j_k - j_l) of the reads (the sample
    covariance of 6,000 windows x 3 axes); over uniform phases, OutputFilter.output_autocov."""
    f = WINDOW_FILTERS[name]()
    rng = np.random.default_rng(7)
    B, L, N = 6000, 12, 0.3
    scale = np.full((B, 3), N * np.sqrt(f.internal_rate_hz))
    c = np.concatenate([f.internal_autocorr(), np.zeros(L * 200)])
    for ph in (0.0, 0.73):  # one phase for every window: the covariance given the phase
        y = bw.noise_windows(f, rng.standard_normal((B, L, 3)), scale, np.full(B, ph))
        x = y.transpose(0, 2, 1).reshape(-1, L)
        j = np.floor(np.arange(1, L + 1) * f.ratio + (0.0 if f.synchronous else ph))
        j = j.astype(int)
        want = N**2 * f.internal_rate_hz * c[np.abs(j[:, None] - j[None, :])]
        got = x.T @ x / len(x)
        tol = 4 * want[0, 0] * np.sqrt(2 / len(x))  # ~4 sigma of a sample covariance
        np.testing.assert_allclose(got, want, rtol=0, atol=tol)
    y = bw.noise_windows(f, rng.standard_normal((B, L, 3)), scale, rng.random(B))
    r = f.output_autocov(N, 3)
    for lag in range(3):
        got = np.mean(y[:, lag:] * y[:, : L - lag])
        assert got == pytest.approx(r[lag], abs=4 * r[0] * np.sqrt(2 / (B * 3 * (L - lag))))
