"""The fitted vibration model (imugen.sensors.vibration_model) against closed forms."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest
from scipy import signal

from imugen.sensors.vibration import PROFILES, Vibration
from imugen.sensors.vibration_model import (
    Harmonic,
    VibrationModel,
    alias,
    fit_vibration,
    preset,
    simulate,
)


@pytest.mark.parametrize("rate_hz", [1000.0, 410.0])
def test_simulated_variance_and_lines_match_the_closed_forms(rate_hz):
    m = preset("quadrotor")
    n = int(60 * rate_hz)
    gyro, accel = simulate(m, rate_hz, n, np.random.default_rng(3))
    for x, s in ((gyro, "gyro"), (accel, "accel")):
        np.testing.assert_allclose(x.var(axis=0), m.variance(s), rtol=0.03)
    f, P = signal.welch(accel, fs=rate_hz, nperseg=4096, axis=0)
    df = f[1] - f[0]
    f_true, f_seen = m.line_frequencies(rate_hz)
    for h, fa in zip(m.harmonics, f_seen, strict=True):
        k = round(fa / df)
        assert np.argmax(P[k - 5 : k + 6, 2]) in (4, 5, 6)  # the line at its (aliased) bin
        power = P[k - 3 : k + 4, 2].sum() * df
        assert power == pytest.approx(0.5 * h.accel_mps2[2] ** 2, rel=0.1)
    if rate_hz == 410.0:
        assert f_true[-1] > rate_hz / 2 > f_seen[-1]  # the 4P line is seen as an alias


@pytest.mark.parametrize(("name", "speed"), [("car", 20.0), ("car", 8.0), ("aircraft", 60.0)])
def test_presets_are_the_kernels_spectra(name, speed):
    """The car and aircraft presets have the variance of what `simulate.vibration` runs."""
    dt = 1e-3
    K = 60_000
    vib = Vibration(PROFILES[name], np.full(K, speed), dt)
    p = PROFILES[name]
    rng = np.random.default_rng(5)
    seq = type(vib.draw(rng))(
        vib, np.ones(2), rng.integers(0, 2, size=(len(p.orders) + p.lines, 3)),
        rng.uniform(0, 2 * math.pi, size=(len(p.orders), 3)),
        rng.uniform(p.band_hz[0], p.band_hz[1], size=(p.lines, 3)),
    )  # fmt: skip
    z = np.zeros((K, 3))
    w, a, _, _ = seq.apply(0, z, z, z, z)  # the case's rate and specific force, still body
    m = preset(name, speed)
    assert m.rotation_hz * 60.0 == pytest.approx(vib.shaft_radps[-1] * 60 / (2 * math.pi))
    np.testing.assert_allclose(a.var(axis=0), m.variance("accel"), rtol=0.03)
    g = m.variance("gyro")
    ok = g > 0
    np.testing.assert_allclose(w.var(axis=0)[ok], g[ok], rtol=0.03)


def test_fit_recovers_the_model():
    rng = np.random.default_rng(7)
    m = preset("quadrotor")
    fs, n = 1000.0, 40_000
    gyro, accel = simulate(m, fs, n, rng)
    noise = {"gyro": 5e-4, "accel": 5e-3}  # white sensor noise [unit / sqrt(Hz)]
    gyro += noise["gyro"] * math.sqrt(fs) * rng.standard_normal(gyro.shape)
    accel += noise["accel"] * math.sqrt(fs) * rng.standard_normal(accel.shape)
    fit, rep = fit_vibration({"gyro": gyro, "accel": accel}, fs)
    assert fit.rotation_hz == pytest.approx(m.rotation_hz, rel=1e-3)
    assert [h.order for h in fit.harmonics] == [h.order for h in m.harmonics]
    for h, h0 in zip(fit.harmonics, m.harmonics, strict=True):
        np.testing.assert_allclose(h.accel_mps2, h0.accel_mps2, rtol=0.08)
        np.testing.assert_allclose(h.gyro_radps, h0.gyro_radps, rtol=0.08)
    np.testing.assert_allclose(fit.accel_rms_mps2, m.accel_rms_mps2, rtol=0.1)
    dens = rep["floor_density"]["accel_mps2_per_sqrt_hz"]
    np.testing.assert_allclose(dens, noise["accel"], rtol=0.1)
    back = VibrationModel.from_dict(fit.as_dict())
    np.testing.assert_allclose(back.variance("gyro"), fit.variance("gyro"))


def test_white_noise_has_no_vibration():
    rng = np.random.default_rng(2)
    x = rng.standard_normal((30_000, 6))
    fit, _ = fit_vibration(x, 500.0)
    assert not fit.harmonics and not fit.lines
    assert not any(fit.accel_rms_mps2) and not any(fit.gyro_rms_radps)


def test_alias():
    assert alias(367.0, 410.0) == pytest.approx(43.0)
    assert alias(100.0, 410.0) == pytest.approx(100.0)


def test_cli_fits_a_recording_against_its_truth(tmp_path):
    """`imugen vibration fit`: a hovering multirotor's record = truth + vibration + noise."""
    import pandas as pd
    import yaml

    from imugen.cli import main
    from imugen.tables import truth as ttable
    from imugen.truth.build import build_truth, enu_table

    t = np.arange(0.0, 40.0, 0.5)
    p = np.column_stack([0.05 * np.sin(0.2 * t), 0 * t, 1.0 + 0 * t])
    df, meta = enu_table(p, t, (47.4, 8.5, 400.0))
    tr, tm = build_truth(df, meta, rate_hz=500.0, earth="flat", vehicle="multirotor", verbose=False)
    ttable.write(tr, tm, tmp_path / "truth.parquet")
    rng = np.random.default_rng(11)
    m = preset("quadrotor")
    gyro, accel = simulate(m, 500.0, len(tr), rng)
    rec = pd.DataFrame({"time_s": tr[ttable.TIME]})
    for i, ax in enumerate("xyz"):
        rec[f"gyro_{ax}_radps"] = (
            tr[ttable.GYRO[i]] + gyro[:, i] + 1e-2 * rng.standard_normal(len(tr))
        )
        rec[f"accel_{ax}_mps2"] = (
            tr[ttable.ACCEL[i]] + accel[:, i] + 0.05 * rng.standard_normal(len(tr))
        )
    rec.to_csv(tmp_path / "rec.csv", index=False)
    out = tmp_path / "vib.yaml"
    main(["vibration", "fit", str(tmp_path / "rec.csv"), f"--truth={tmp_path / 'truth.parquet'}",
          f"--rotation-hz={m.rotation_hz}", f"--output={out}"])  # fmt: skip
    fit = VibrationModel.from_dict(yaml.safe_load(out.read_text())["vibration"])
    assert [h.order for h in fit.harmonics] == [1.0, 2.0, 4.0]
    np.testing.assert_allclose(fit.variance("accel"), m.variance("accel"), rtol=0.1)


def test_multirotor_vibration_is_locked_to_the_truths_rotors(tmp_path):
    """`simulate.vibration: vehicle` on a multirotor truth: the quadrotor preset, its
    harmonics at the truth's rotor speed; a fitted model's YAML runs through the same kernel."""
    import yaml

    from imugen.sensors.ideal import ArrayTruth
    from imugen.sensors.vibration import setup_vibration
    from imugen.sensors.vibration_model import kernel_profile
    from imugen.tables import truth as ttable
    from imugen.truth.build import build_truth, enu_table

    t = np.arange(0.0, 12.0, 0.5)
    df, meta = enu_table(np.tile([0.0, 0.0, 1.0], (len(t), 1)), t, (47.4, 8.5, 400.0))
    tr, tm = build_truth(
        df, meta, rate_hz=1000.0, earth="flat", vehicle="multirotor", verbose=False
    )
    ttable.write(tr, tm, tmp_path / "truth.parquet")
    truth = ArrayTruth.read(tmp_path / "truth.parquet")
    rpm = tr[list(ttable.ROTORS[:4])].to_numpy().mean(axis=1)
    np.testing.assert_allclose(truth.rotor_rpm, rpm)
    vib = setup_vibration(truth, "vehicle")
    assert vib.profile.name == "quadrotor" and vib.profile.rotation == "rotor"
    np.testing.assert_allclose(vib.shaft_radps, 2 * math.pi * rpm / 60.0)
    seq = vib.draw(np.random.default_rng(1))
    z = np.zeros((truth.K, 3))
    _, f_c, _, _ = seq.apply(0, z, z, z, z)
    f, P = signal.welch(f_c[:, 2], fs=1000.0, nperseg=4096)
    blade_pass = 2 * rpm.mean() / 60.0  # two-blade props
    assert abs(f[np.argmax(P)] - blade_pass) < 2 * (f[1] - f[0])
    # a fitted model's YAML, as `imugen vibration fit` writes it
    m = preset("quadrotor")
    (tmp_path / "vib.yaml").write_text(yaml.safe_dump({"vibration": _plain(m.as_dict())}))
    prof = kernel_profile(str(tmp_path / "vib.yaml"))
    assert prof.orders == (1.0, 2.0, 4.0)
    assert prof.gyro_noise_radps == m.gyro_rms_radps and prof.gyro_lines == 360  # 180 Hz / 0.5
    np.testing.assert_allclose(
        np.asarray(prof.accel_g) * 9.80665, [h.accel_mps2 for h in m.harmonics]
    )


def _plain(x):
    from imugen.sensors.vibration_fit import _plain as plain

    return plain(x)


# --- the model's gyro broadband and fixed lines in the simulate stage's kernel --------------
def _model_yaml(tmp_path, model):
    import yaml

    path = tmp_path / "vib.yaml"
    path.write_text(yaml.safe_dump({"vibration": _plain(model.as_dict())}))
    return str(path)


def _simulate_rates(vibration, truth=None, rate_hz=400.0, seconds=60.0, sequences=2):
    """Rate samples (M, K, 3) of an ideal IMU (no sensor errors) on a vibrating case."""
    from imugen.sensors.grades import grade_from_config
    from imugen.simulate import stage as S

    clean = grade_from_config("clean", {"id": 5000})
    where = {"static_s": seconds, "rate_hz": rate_hz} if truth is None else {}
    sh = S.simulate(
        truth, clean, sequences=sequences, seed=3, vibration=vibration, outputs="rates", **where
    )
    return sh.data["gyro"], sh.data["accel"]


def test_gyro_broadband_has_the_models_variance_and_a_flat_band(tmp_path):
    """Gyro broadband only: the simulated rate has variance sigma^2 per axis (the closed form)
    and a flat PSD sigma^2 / (f_hi - f_lo) in the band, nothing outside it."""
    band = (20.0, 150.0)
    rms = np.array([0.02, 0.015, 0.01])  # rad/s
    m = VibrationModel(band_hz=band, gyro_rms_radps=tuple(rms))
    fs = 400.0
    gyro, accel = _simulate_rates(_model_yaml(tmp_path, m), rate_hz=fs)
    # the case tilts by its angle (rate / omega, summed over the lines: ~1e-4 rad) only
    assert np.max(np.abs(accel - accel[:, :1])) < 1e-3 * 9.81
    for x in gyro:
        np.testing.assert_allclose(x.var(axis=0), rms**2, rtol=0.03)
        f, P = signal.welch(x, fs=fs, nperseg=4096, axis=0)
        df = f[1] - f[0]
        edges = np.arange(band[0], band[1] + 1e-9, 10.0)  # 10 Hz slices of the band
        for a, b in itertools.pairwise(edges):
            inside = (f >= a + 1) & (f < b - 1)  # (lines near a slice edge leak across it)
            density = P[inside].mean(axis=0)
            np.testing.assert_allclose(density, rms**2 / (band[1] - band[0]), rtol=0.15)
        out = (f < band[0] - 2) | (f > band[1] + 2)
        assert np.all(P[out].sum(axis=0) * df < 0.01 * rms**2)


def test_fixed_lines_appear_at_their_frequency_with_their_amplitude(tmp_path):
    """A fixed gyro line (y, 37 Hz) and accelerometer line (z, 55 Hz): power A^2 / 2 at
    their frequency, on their axis; the gyro line's angle ``A / omega`` tilts gravity into
    the accelerometer's x axis (``g A / omega``), nothing else."""
    from imugen.sensors.vibration_model import Line

    g_amp, a_amp = 0.01, 0.2
    m = VibrationModel(
        lines=[Line(37.0, (0.0, g_amp, 0.0)), Line(55.0, accel_mps2=(0.0, 0.0, a_amp))]
    )
    fs = 400.0
    gyro, accel = _simulate_rates(_model_yaml(tmp_path, m), rate_hz=fs, seconds=30.0)
    g = float(np.mean(accel[0, :, 2]))
    tilt = g * g_amp / (2 * math.pi * 37.0)
    for gy, ac in zip(gyro, accel, strict=True):
        for x, axis, f0, amp in ((gy, 1, 37.0, g_amp), (ac, 2, 55.0, a_amp)):
            f, P = signal.welch(x, fs=fs, nperseg=4000, axis=0)
            df = f[1] - f[0]
            k = round(f0 / df)
            assert np.argmax(P[:, axis]) == k
            assert P[k - 3 : k + 4, axis].sum() * df == pytest.approx(0.5 * amp**2, rel=0.02)
            assert x.var(axis=0)[axis] == pytest.approx(0.5 * amp**2, rel=0.02)
        assert np.all(gy.var(axis=0)[[0, 2]] < 1e-9 * g_amp**2)
        assert ac.var(axis=0)[0] == pytest.approx(0.5 * tilt**2, rel=0.02)
        assert ac.var(axis=0)[1] < 1e-9 * tilt**2


def test_fit_recovers_a_simulated_records_gyro_broadband(tmp_path):
    """Round trip: a model with gyro broadband and a harmonic, simulated
    by the simulate stage on a hovering multirotor's truth plus sensor noise; `imugen
    vibration fit` recovers the broadband RMS per axis."""
    import pandas as pd
    import yaml

    from imugen.cli import main
    from imugen.tables import truth as ttable
    from imugen.truth.build import build_truth, enu_table

    fs = 500.0
    t = np.arange(0.0, 40.0, 0.5)
    p = np.column_stack([0.05 * np.sin(0.2 * t), 0 * t, 1.0 + 0 * t])
    df, meta = enu_table(p, t, (47.4, 8.5, 400.0))
    tr, tm = build_truth(df, meta, rate_hz=fs, earth="flat", vehicle="multirotor", verbose=False)
    ttable.write(tr, tm, tmp_path / "truth.parquet")
    rpm = tr[list(ttable.ROTORS[:4])].to_numpy().mean()
    d = math.radians(1.0)
    m = VibrationModel(
        rotation_hz=rpm / 60.0,
        harmonics=[Harmonic(2.0, (0.8 * d, 0.8 * d, 0.4 * d), (0.1, 0.1, 0.2))],
        band_hz=(20.0, 150.0),
        gyro_rms_radps=(1.0 * d, 0.8 * d, 0.5 * d),
    )  # (no accelerometer broadband: its 24 lines per axis are resolved as lines by the fit)
    gyro, accel = _simulate_rates(_model_yaml(tmp_path, m), tmp_path / "truth.parquet", sequences=1)
    rng = np.random.default_rng(4)
    rec = pd.DataFrame({"time_s": tr[ttable.TIME]})
    for i, ax in enumerate("xyz"):
        rec[f"gyro_{ax}_radps"] = gyro[0, :, i] + 2e-3 * rng.standard_normal(len(tr))
        rec[f"accel_{ax}_mps2"] = accel[0, :, i] + 0.02 * rng.standard_normal(len(tr))
    rec.to_csv(tmp_path / "rec.csv", index=False)
    out = tmp_path / "fit.yaml"
    main(["vibration", "fit", str(tmp_path / "rec.csv"), f"--truth={tmp_path / 'truth.parquet'}",
          f"--rotation-hz={m.rotation_hz}", f"--output={out}"])  # fmt: skip
    fit = VibrationModel.from_dict(yaml.safe_load(out.read_text())["vibration"])
    np.testing.assert_allclose(fit.gyro_rms_radps, m.gyro_rms_radps, rtol=0.15)
    assert [h.order for h in fit.harmonics] == [2.0] and not fit.lines
    np.testing.assert_allclose(fit.harmonics[0].gyro_radps, m.harmonics[0].gyro_radps, rtol=0.1)


def test_angular_lines_do_not_depend_on_the_chunks():
    """The broadband's sin/cos step by rotations between resyncs at fixed sample indices: the
    same numbers whatever the chunks, and on the phase's closed form to 1e-12."""
    from imugen.core.rotations import exp_quat, log_quat, quat_mul
    from imugen.sensors.vibration import Vibration, profile_for

    K, dt = 3000, 1 / 400
    vib = Vibration(profile_for("quadrotor"), np.zeros(K), dt)
    seq = vib.draw(np.random.default_rng(2))
    w = np.column_stack([0.3 * np.sin(np.arange(K) * dt), np.full(K, 0.1), np.zeros(K)])
    f = np.tile([0.0, 0.0, 9.8], (K, 1))
    for raw in (False, True):
        whole = seq.apply(0, w, f, w * dt, f * dt, raw=raw)
        cuts = [0, 1, 100, 1337, 2999, K]
        parts = [seq.apply(a, w[a:b], f[a:b], w[a:b] * dt, f[a:b] * dt, raw=raw)
                 for a, b in itertools.pairwise(cuts)]  # fmt: skip
        for i in range(4):
            np.testing.assert_array_equal(np.concatenate([p[i] for p in parts]), whole[i])
    # the case's angle against its closed form (the phases evaluated at every sample)
    ks = np.arange(K)
    th = seq.angle(ks)
    _, _, comp, _ = seq.apply(0, np.zeros((K, 3)), f, np.zeros((K, 3)), f * dt)
    q = np.array([1.0, 0.0, 0.0, 0.0])
    for k in range(1, K):
        q = quat_mul(q, exp_quat(comp[k]))
    np.testing.assert_allclose(log_quat(q), th[-1], atol=1e-12)
