"""Robust cleaning: chord deviations, noise estimates, outliers, heights, refusal, metadata."""

from __future__ import annotations

import numpy as np
import pytest

from imugen.core.errors import InputError
from imugen.core.frames import LocalFrame, Origin
from imugen.ingest.clean import (
    VEHICLE_LIMITS,
    chord_deviation,
    find_outliers,
    noise_sigma,
)
from imugen.ingest.stage import ingest, write

ORIGIN = Origin(40.0, -105.0, 1600.0)
T0 = np.datetime64("2024-01-01T00:00:00")


def _gpx(tmp_path, enu, t=None, missing=(), name="t.gpx"):
    """GPX of ENU points (m) about ORIGIN, times in s from 2024-01-01, <ele> left out at `missing`."""
    lat, lon, alt = LocalFrame(ORIGIN).to_geodetic(np.asarray(enu, float))
    pts = []
    for i in range(len(lat)):
        ele = "" if i in missing else f"<ele>{float(alt[i])!r}</ele>"
        when = "" if t is None else f"<time>{T0 + np.timedelta64(round(t[i] * 1000), 'ms')}Z</time>"
        pts.append(f'<trkpt lat="{float(lat[i])!r}" lon="{float(lon[i])!r}">{ele}{when}</trkpt>')
    f = tmp_path / name
    f.write_text("<gpx><trk><trkseg>" + "".join(pts) + "</trkseg></trk></gpx>")
    return f


def _straight(n, v=15.0, dt=1.0, up=0.0):
    t = np.arange(n) * dt
    return t, np.column_stack([v * t, np.zeros(n), up * t])


def test_chord_deviation_is_the_constant_acceleration_closed_form():
    rng = np.random.default_rng(1)
    t = np.cumsum(rng.uniform(0.2, 3.0, 50))
    a = np.array([2.0, -1.5])
    x = 0.5 * t[:, None] ** 2 * a + 3.0 * t[:, None]
    d, w = chord_deviation(t, x)
    dt = np.diff(t)
    np.testing.assert_allclose(w[1:-1], dt[:-1] * dt[1:] / 2)
    np.testing.assert_allclose(w[0], dt[0] * (dt[0] + dt[1]) / 2)
    np.testing.assert_allclose(w[-1], dt[-1] * (dt[-1] + dt[-2]) / 2)
    np.testing.assert_allclose(d, np.linalg.norm(a) * w, rtol=1e-9)


@pytest.mark.parametrize("dims, sigma", [(2, 2.0), (1, 0.5)])
def test_noise_sigma_recovers_white_noise(dims, sigma):
    rng = np.random.default_rng(2)
    t, x = _straight(20000)
    x = x[:, :dims] + rng.normal(0, sigma, (len(t), dims))
    d, _ = chord_deviation(t, x)
    assert noise_sigma(d, dims) == pytest.approx(sigma, rel=0.03)


def test_spikes_found_and_manoeuvres_kept():
    rng = np.random.default_rng(3)
    n = 2000
    t = np.arange(n, dtype=float)
    # a car at 15 m/s with a 8 m/s^2 turn (below the 10 m/s^2 bound) half way
    heading = np.where(t < 1000, 0.0, np.minimum((t - 1000) * 8.0 / 15.0, np.pi / 2))
    v = 15.0 * np.column_stack([np.cos(heading), np.sin(heading)])
    x = np.cumsum(v, axis=0) + rng.normal(0, 1.0, (n, 2))
    assert len(find_outliers(t, x, VEHICLE_LIMITS["car"].max_accel_mps2)) == 0
    y = x.copy()
    y[300] += [2000.0, 0.0]  # 7,200 km/h jump
    y[700] += [0.0, 40.0]  # lateral 40 m
    y[1500:1502] += [0.0, -60.0]  # two-epoch excursion
    assert find_outliers(t, y, 10.0).tolist() == [300, 700, 1500, 1501]


def test_the_vehicle_decides():
    t, x = _straight(60)
    x = x[:, :2].copy()
    x[30, 1] += 12.0  # implied 24 m/s^2: impossible for a car, possible for an aircraft
    assert find_outliers(t, x, VEHICLE_LIMITS["car"].max_accel_mps2).tolist() == [30]
    assert find_outliers(t, x, VEHICLE_LIMITS["aircraft"].max_accel_mps2).tolist() == []


def test_spike_no_longer_refuses_the_file(tmp_path):
    rng = np.random.default_rng(4)
    t, x = _straight(200, v=1.4)  # a walk
    x += rng.normal(0, [1.0, 1.0, 0.0], x.shape)
    x[120, 0] += 2009.0  # 7,231 km/h against its neighbours
    ing = ingest(_gpx(tmp_path, x, t), vehicle="pedestrian")
    c = ing.meta["cleaning"]
    assert (c["outliers_removed"], c["outlier_points"]) == (1, [121])
    assert ing.meta["points_out"] == 199
    assert any("removed 1 fixes no pedestrian could reach" in w for w in ing.warnings)
    assert c["noise_horizontal_m"] == pytest.approx(1.0, rel=0.25)


def test_missing_heights_interpolated_not_zero(tmp_path):
    t, x = _straight(100, v=10.0, up=0.65)  # steady climb of 65 m
    missing = set(range(40, 46))  # six points without <ele> inside a track at ~1,630 m
    ing = ingest(_gpx(tmp_path, x, t, missing=missing))
    c = ing.meta["cleaning"]
    assert c["heights_filled"] == 6 and c["height_filled_points"] == list(range(41, 47))
    assert c["outliers_removed"] == 0
    np.testing.assert_allclose(ing.table.u_m, x[:, 2] - x[0, 2], atol=0.01)  # on the line
    assert any("6 points have no height" in w for w in ing.warnings)


def test_multipath_heights_rejected_and_refilled(tmp_path):
    rng = np.random.default_rng(5)
    t, x = _straight(300, v=12.0, up=0.2)
    x[:, 2] += rng.normal(0, 0.5, 300)
    truth_u = x[:, 2].copy()
    x[150:153, 2] += 60.0  # multipath for three epochs
    ing = ingest(_gpx(tmp_path, x, t))
    c = ing.meta["cleaning"]
    assert c["outliers_removed"] == 0 and c["heights_rejected"] == 3
    u = ing.table.u_m.to_numpy() + x[0, 2]
    assert np.abs(u[150:153] - truth_u[150:153]).max() < 3 * 0.5 + 0.5
    assert c["noise_vertical_m"] == pytest.approx(0.5, rel=0.3)
    assert c["noise_horizontal_m"] < 0.2  # horizontal and vertical estimated separately


def test_refused_when_too_little_survives(tmp_path):
    rng = np.random.default_rng(6)
    t, x = _straight(100, v=10.0)
    x[::2, :2] += rng.uniform(-300, 300, (50, 2))  # every other fix is garbage
    x[1::4, :2] += rng.uniform(-300, 300, (25, 2))
    with pytest.raises(InputError, match=r"of 100 points are outliers for a car.*less than 50%"):
        ingest(_gpx(tmp_path, x, t))


def test_kml_default_altitude_mode_heights_kept(tmp_path):
    lat, lon, alt = LocalFrame(ORIGIN).to_geodetic(_straight(30, v=120.0, up=230.0)[1])
    coords = " ".join(
        f"{lo:.9f},{la:.9f},{h + 100:.1f}" for la, lo, h in zip(lat, lon, alt, strict=True)
    )
    f = tmp_path / "climb.kml"
    f.write_text(
        f"<kml><Placemark><LineString><coordinates>{coords}</coordinates></LineString></Placemark></kml>"
    )
    ing = ingest(f)
    assert ing.table.alt_m.max() == pytest.approx(alt.max() + 100, abs=0.1) and alt.max() > 6000
    assert ing.meta["altitude_mode"] is None and ing.meta["altitude_trusted"] is False
    assert any("no altitudeMode" in w for w in ing.warnings)


def test_cleaning_carried_through_the_csv_stage(tmp_path):
    t, x = _straight(50)
    x[20, 1] += 500.0
    first = ingest(_gpx(tmp_path, x, t))
    csv = write(first, tmp_path / "route.csv")
    second = ingest(csv)
    assert second.meta["cleaning"]["outliers_removed"] == 1
    assert second.meta["cleaning"]["carried"] is True and len(second.table) == 49


def test_cli_vehicle_option(tmp_path, cli):
    t, x = _straight(60, v=1.4)
    x[30, 1] += 12.0  # 24 m/s^2 for one fix
    f = _gpx(tmp_path, x, t)
    out = tmp_path / "o.csv"
    proc = cli("ingest", f, "-o", out, "--vehicle", "pedestrian", check=0)
    assert "removed 1 horizontal outliers" in proc.stderr
    proc = cli("ingest", f, "-o", out, "--vehicle", "aircraft", check=0)
    assert "outliers" not in proc.stderr
    assert cli("ingest", f, "-o", out, "--vehicle", "boat").returncode == 2


def test_speed_gate_removes_cold_start_plateau_and_excursion():
    """Issue 27 (an urban walk from an MTK logger): the first fixes 325 m off (cold start), a
    30-epoch plateau 320 m away and a smooth 20 s excursion of 323 m; the acceleration
    criterion alone keeps most of them. The speed gate removes exactly the 55 injected fixes."""
    from imugen.ingest.clean import speed_outliers

    rng = np.random.default_rng(3)
    t = np.arange(600.0)
    x = np.column_stack([1.3 * t, 20 * np.sin(t / 60)]) + rng.normal(0, 2.0, (600, 2))
    bad = np.zeros(600, bool)
    x[:5] += [250.0, 207.0]
    bad[:5] = True
    x[200:230] = [-100.0, 300.0]
    bad[200:230] = True
    k = np.arange(400, 420)
    x[k, 1] += 323.0 * np.sin(np.pi * (k - 399) / 21)
    bad[k] = True
    got = speed_outliers(t, x, VEHICLE_LIMITS["pedestrian"].max_speed_mps, 2.0)
    np.testing.assert_array_equal(got, np.flatnonzero(bad))
    # a clean walk, a fast car: nothing removed
    assert len(speed_outliers(t[~bad][:300], x[~bad][:300], 15.0, 2.0)) == 0
    car = np.column_stack([40.0 * t, np.zeros(600)]) + rng.normal(0, 3.0, (600, 2))
    assert len(speed_outliers(t, car, VEHICLE_LIMITS["car"].max_speed_mps, 3.0)) == 0
