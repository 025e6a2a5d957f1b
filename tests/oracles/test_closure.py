"""Zero-error closure: route -> ingest -> truth -> mechanization of the exact increments.

Targets (issue 3): final 3-D position error <= 1e-6 m (never worse than 1e-3 m) and attitude
<= 1e-9 rad on the paper trajectory at 100 Hz, flat and wgs84; also a timed GPX track and an
untimed KML path. Stability matrix: each case closes (finite, bounded) or is refused with a
clear InputError.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from imugen.closure import attitude_angle, closure
from imugen.core.errors import InputError

ORIGIN = "45.0,7.0,300"
TARGET_M = 1e-6
NEVER_M = 1e-3
ATT_RAD = 1e-9


def check(res: dict, pos=TARGET_M, att=ATT_RAD, label=""):
    print(
        f"{label}: final {res['final_position_error_m']:.2e} m, max "
        f"{res['max_position_error_m']:.2e} m, attitude max {res['max_attitude_error_rad']:.2e}"
        f" rad, {res['samples']} samples, {res['seconds']:.2f} s ({res['earth']})"
    )
    for k in (
        "final_position_error_m",
        "max_position_error_m",
        "max_attitude_error_rad",
        "max_velocity_error_mps",
    ):
        assert math.isfinite(res[k]), k
    assert res["final_position_error_m"] <= pos
    assert res["max_position_error_m"] <= NEVER_M
    assert res["max_attitude_error_rad"] <= att


def write_enu(path: Path, t, p, timed=True):
    rows = np.column_stack([t, p]) if timed else np.asarray(p)
    np.savetxt(path, rows, fmt="%.6f", delimiter="\t")
    return path


# --- shared real routes --------------------------------------------------------------------------
@pytest.mark.parametrize("earth", ["flat", "wgs84"])
def test_paper_trajectory_100hz(shared_file, earth):
    src = shared_file("seed_reference_trajectory_enu.txt")
    res = closure(src, rate_hz=100, earth=earth, dt=1.0, origin="31.6295,-7.9811,466")
    check(res, label=f"paper {earth}")
    assert res["samples"] == 61901
    assert res["earth"] == earth


def test_timed_gpx_track(shared_file):
    res = closure(shared_file("e_cycling_central_park_1hz.gpx"), earth="wgs84")
    # 30 min with stops: the truth's angle increments during stops must be exact to ~1e-16
    # relative (see rotations.relative_rotation_vector) for the 1e-6 m target
    check(res, pos=1e-6, label="gpx cycling wgs84")


def test_untimed_kml_path(shared_file):
    res = closure(shared_file("a_sparkfun_rally_course_ge_pro.kml"), earth="flat")
    check(res, label="kml rally flat")
    res = closure(shared_file("a_sparkfun_rally_course_ge_pro.kml"), earth="wgs84")
    check(res, label="kml rally wgs84")


# --- stability matrix (synthetic routes) ---------------------------------------------------------
def test_vertical_climb_and_loop_aircraft(tmp_path):
    # level run, vertical loop (pitch through +-90 deg) of radius 300 m at ~60 m/s, level run,
    # then a vertical climb
    V, R = 60.0, 300.0
    w = V / R
    t1 = np.arange(0, 20.0)
    p1 = np.column_stack([V * t1, 0 * t1, 1000 + 0 * t1])
    tl = np.arange(0, 2 * math.pi / w, 1.0)
    pl = np.column_stack([V * 20 + R * np.sin(w * tl), 0 * tl, 1000 + R * (1 - np.cos(w * tl))])
    t2 = np.arange(0, 15.0)
    x2 = V * 20 + V * t2
    p2 = np.column_stack([x2, 0 * t2, 1000 + 0 * t2])
    t = np.concatenate([t1, 20 + tl, 20 + tl[-1] + 1 + t2])
    p = np.vstack([p1, pl, p2])
    src = write_enu(tmp_path / "loop.txt", t, p)
    res = closure(src, earth="wgs84", vehicle="aircraft", origin=ORIGIN)
    check(res, label="vertical loop aircraft")
    # straight up: a rocket-like climb at 40 m/s after a level run
    t = np.arange(0, 60.0)
    p = np.column_stack([np.minimum(t, 20) * 50.0, 0 * t, 500 + np.maximum(t - 20, 0) * 40.0])
    src = write_enu(tmp_path / "climb.txt", t, p)
    try:
        res = closure(src, earth="flat", vehicle="aircraft", origin=ORIGIN)
    except InputError as exc:  # a refusal must say why
        assert str(exc)
    else:
        check(res, label="vertical climb aircraft")


def test_stationary_start_and_stops(tmp_path):
    rng = np.random.default_rng(1)
    t = np.arange(0, 400.0)
    # 30 s still, drive, 10 s stop, drive, 200 s long stop, drive
    speed = np.where((t < 30) | ((t >= 100) & (t < 110)) | ((t >= 180) & (t < 380)), 0.0, 10.0)
    s = np.cumsum(speed)
    p = np.column_stack([s * np.cos(s / 400), s * np.sin(s / 400), 0 * s])
    p[:, :2] += rng.normal(size=(len(t), 2)) * 0.3  # GPS-like jitter, also during stops
    src = write_enu(tmp_path / "stops.txt", t, p)
    for earth in ("flat", "wgs84"):
        res = closure(src, earth=earth, origin=ORIGIN)
        check(res, pos=1e-6, label=f"stops {earth}")


def test_hairpins_and_polyline_corners(tmp_path):
    # untimed polyline: right-angle corners, a hairpin (180 deg, 6 m apart), a zig-zag
    p = np.array(
        [
            [0, 0, 0],
            [200, 0, 0],
            [200, 150, 0],
            [0, 150, 0],
            [0, 156, 0],
            [250, 156, 0],
            [260, 170, 0],
            [270, 156, 0],
            [280, 170, 0],
            [290, 156, 1],
        ],
        dtype=float,
    )
    src = write_enu(tmp_path / "corners.txt", None, p, timed=False)
    for earth in ("flat", "wgs84"):
        res = closure(src, earth=earth, origin=ORIGIN)
        check(res, label=f"corners {earth}")


def test_untimed_path_with_stepped_noisy_heights(tmp_path):
    # a polyline whose heights step (2 m altimeter rounding) and jitter (0.5 m): its vertical
    # becomes the road profile (heights against horizontal distance) before the speed profile
    rng = np.random.default_rng(1)
    s = np.arange(0.0, 3000.0, 10.0)
    h = np.round((0.04 * s + 3.0 * np.sin(s / 300.0)) / 2.0) * 2.0
    p = np.column_stack([s, 80.0 * np.sin(s / 400.0), h + rng.normal(scale=0.5, size=len(s))])
    src = write_enu(tmp_path / "stepped.txt", None, p, timed=False)
    for earth in ("flat", "wgs84"):
        res = closure(src, earth=earth, origin=ORIGIN)
        check(res, label=f"stepped heights untimed {earth}")


def test_sparse_points_10s_apart(tmp_path):
    t = np.arange(0, 600.0, 10.0)
    p = np.column_stack([400 * np.sin(t / 120), 300 * np.sin(t / 90), 5 * np.sin(t / 200)])
    src = write_enu(tmp_path / "sparse.txt", t, p)
    res = closure(src, earth="wgs84", origin=ORIGIN)
    check(res, label="sparse 10 s")


def test_dense_jittery_points(tmp_path):
    rng = np.random.default_rng(2)
    t = np.arange(0, 120.0, 0.1)
    p = np.column_stack([8 * t, 50 * np.sin(t / 15), 0 * t]) + rng.normal(size=(len(t), 3))
    src = write_enu(tmp_path / "dense.txt", t, p)
    res = closure(src, earth="flat", origin=ORIGIN)
    check(res, label="dense jittery 10 Hz")


def test_one_hour_at_1khz(tmp_path):
    t = np.arange(0, 3601.0, 5.0)
    p = np.column_stack([1500 * np.sin(t / 600), 1000 * np.sin(t / 450), 10 * np.sin(t / 900)])
    src = write_enu(tmp_path / "hour.txt", t, p)
    res = closure(src, rate_hz=1000, earth="flat", origin=ORIGIN)
    assert res["samples"] == 3_600_001
    check(res, pos=1e-5, label="1 kHz for 1 h")


@pytest.mark.parametrize(("speed", "vehicle"), [(0.05, "pedestrian"), (250.0, "aircraft")])
def test_very_slow_and_very_fast(tmp_path, speed, vehicle):
    T = 200.0
    t = np.arange(0, T + 1, 1.0)
    R = speed * T / 3  # a third of a... curved path
    s = speed * t
    p = np.column_stack([R * np.sin(s / R), R * (1 - np.cos(s / R)), 0 * s])
    if vehicle == "aircraft":
        p[:, 2] = 3000 + 0.1 * s
    src = write_enu(tmp_path / f"v{speed}.txt", t, p)
    res = closure(src, earth="wgs84", vehicle=vehicle, origin=ORIGIN)
    check(res, label=f"speed {speed} m/s {vehicle}")


def test_refusals_are_clear(tmp_path):
    # two points only / all identical points: ingestion or truth refuses with a message
    src = write_enu(tmp_path / "same.txt", np.arange(5.0), np.zeros((5, 3)))
    try:
        res = closure(src, origin=ORIGIN)
    except InputError as exc:
        assert "same.txt" in str(exc) or str(exc)
    else:  # a still route is fine too: it must then close exactly
        check(res, label="all points identical")


def test_attitude_angle_oracle():
    # rotation by a known angle about a random axis; sign of the quaternion is irrelevant
    rng = np.random.default_rng(3)
    ax = rng.normal(size=(100, 3))
    ax /= np.linalg.norm(ax, axis=1, keepdims=True)
    ang = rng.uniform(1e-12, 3.0, 100)
    q = np.column_stack([np.cos(ang / 2), np.sin(ang / 2)[:, None] * ax])
    ident = np.tile([1.0, 0, 0, 0], (100, 1))
    np.testing.assert_allclose(attitude_angle(ident, q), ang, rtol=1e-12)
    np.testing.assert_allclose(attitude_angle(ident, -q), ang, rtol=1e-12)


def test_closure_reports_horizontal_vertical_and_the_free_growth(tmp_path):
    """`imugen closure` (issue 27): horizontal and vertical closure separately, the vertical
    channel used and why, and the free channel's expected growth."""
    t = np.arange(0, 300.0)
    s = 12.0 * t
    p = np.column_stack([s * np.cos(s / 900), s * np.sin(s / 900), 20 * np.sin(t / 60)])
    src = write_enu(tmp_path / "drive.txt", t, p)
    auto = closure(src, earth="wgs84", origin=ORIGIN, rate_hz=20)
    damped = closure(src, earth="wgs84", origin=ORIGIN, rate_hz=20, vertical="damped")
    assert auto["vertical_channel"]["mode"] == "free"  # 300 s < 3 x 570 s
    assert damped["vertical_channel"]["mode"] == "damped"
    assert damped["vertical_channel"]["gains"] == pytest.approx([0.03, 3.03e-4, 1e-6], rel=0.01)
    for res in (auto, damped):
        check(res, label=res["vertical_channel"]["mode"])
        assert res["final_position_error_m"] == pytest.approx(
            math.hypot(res["horizontal_final_m"], res["vertical_final_m"]), rel=1e-6
        )
        assert res["horizontal_max_m"] <= res["max_position_error_m"] * (1 + 1e-12)
        free = res["free"]
        assert free["growth_time_s"] == pytest.approx(569.5, abs=1.5)
        assert free["growth_factor"] == pytest.approx(math.cosh(299.0 / free["growth_time_s"]))
    # free: the whole run is its own seed, the expected growth is the run itself
    assert auto["free"]["expected_vertical_m"] == pytest.approx(auto["vertical_final_m"])
