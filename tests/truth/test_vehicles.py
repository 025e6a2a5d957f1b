"""Vehicle motion models of the truth and its plausibility report.

Oracles: the stated limits of each vehicle class (curvature-bounded yaw rate, roll zero or a
coordinated lean, pitch = atan(grade), bounded), continuity (no attitude step beyond what
the rates allow), an independent 4th-order quadrature of the gyro columns against the
increments, and, on every real timed track and untimed ground path in ../shared, the
plausibility figures.
"""

from __future__ import annotations

import functools
import math
import os
from pathlib import Path

import numpy as np
import pytest

from imugen import truth
from imugen.core.errors import InputError
from imugen.core.io import write_parquet
from imugen.tables import enu as tenu
from imugen.tables import truth as col
from imugen.truth.report import _integral
from imugen.truth.vehicles import has_suspension, vehicle_params

from helpers import SHARED_TRAJ

ORIGIN = (45.0, 7.0, 300.0)
SHARED = Path(
    os.environ.get(
        "IMUGEN_SHARED_TRAJECTORIES",
        SHARED_TRAJ,
    )
)


def _build(enu, t, **kw):
    df, meta = truth.enu_table(enu, t, ORIGIN)
    kw.setdefault("verbose", False)
    return truth.build_truth(df, meta, **kw)


def _arr(tr, cols):
    return tr[list(cols)].to_numpy()


def _rate_increment_error(tr):
    """max |dtheta_k - 4th-order integral of the gyro| / dt [rad/s] (interior intervals)."""
    t = tr[col.TIME].to_numpy()
    i4, _ = _integral(_arr(tr, col.GYRO), np.diff(t))
    e = np.linalg.norm(_arr(tr, col.DTHETA)[1:] - i4, axis=1) / np.diff(t)
    return float(e[1:-1].max())


def _smooth(u):
    """Smoothstep 3u^2 - 2u^3 on [0, 1] (0 before, 1 after): from rest to rest."""
    u = np.clip(u, 0.0, 1.0)
    return u * u * (3.0 - 2.0 * u)


def _reversal_route(angle_deg, noise_m=0.05, seed=0):
    """From rest East for 60 m (smooth, at most 3.75 m/s and 0.63 m/s^2), a 10 s stop with
    GNSS jitter, then 60 m away at ``angle_deg`` from East (180: straight back); 1 Hz."""
    rng = np.random.default_rng(seed)
    t = np.arange(0.0, 71.0, 1.0)
    a = math.radians(angle_deg)
    leg1 = 60.0 * _smooth(t / 24.0)[:, None] * np.array([1.0, 0.0, 0.0])
    leg2 = 60.0 * _smooth((t - 34.0) / 24.0)[:, None] * np.array([math.cos(a), math.sin(a), 0.0])
    return t, leg1 + leg2 + rng.normal(scale=noise_m, size=(len(t), 3)) * [1, 1, 2]


@pytest.mark.parametrize("suspension", ["rigid", "damped"])
@pytest.mark.parametrize("angle", [90.0, 170.0, 179.0, 180.0, 181.0, 190.0, 270.0])
def test_reversal_through_a_stop_is_continuous(angle, suspension):
    """The old hold/target blend flipped its Log branch when the velocity reversed through a
    stop (a 2.5 rad attitude jump in 10 ms that dtheta carried and the gyro did not). Since
    session 33 (issue 27) the car turns at rest inside the stop from the direction it
    arrived in to the one it leaves in (a declared turn at rest, standing in for a
    multi-point turn, as at an untimed reversal): it pulls away facing its velocity, with no
    slide sideways (before, it swung round at the least turning radius while pulling away,
    its body sliding sideways)."""
    t, enu = _reversal_route(angle)
    rate = 20.0
    tr, meta = _build(
        enu, t, rate_hz=rate, earth="flat", vehicle="car",
        vehicle_params={"suspension": suspension},
    )  # fmt: skip
    vp = truth.VEHICLES["car"]
    rep = meta["plausibility"]
    assert rep["warnings"] == []
    # no attitude step beyond what the rates allow; dtheta agrees with the gyro columns
    # (the old blend: a 2.5 rad step in 10 ms, 43.6 rad/s between dtheta and the gyro)
    assert rep["max_attitude_step_excess_rad"] < 1e-4
    # on a suspension the body pitches with the acceleration, whose jerk steps where the
    # spline joins a stop (zero speed and acceleration, a C2 join: issue 27's abrupt stops):
    # a kink in the gyro, which the 4th-order integral of 20 Hz samples leaves at 1.3e-4 rad/s
    # at the stop's edges (2.7e-5 with the C4 join before)
    assert _rate_increment_error(tr) < (1e-4 if suspension == "rigid" else 2e-4)
    # a real stop, with the turn at rest inside it
    stops = meta["fit"]["stops"]
    assert any(a <= 25 and b >= 33 for a, b in stops), stops
    a0, b0 = max((a, b) for a, b in stops if a <= 25 and b >= 33)
    ((c0, c1),) = meta["timing"]["turns_at_rest_s"]
    assert a0 < c0 < c1 < b0
    tt = tr[col.TIME].to_numpy()
    turning = (tt >= c0) & (tt <= c1)
    # heading: per sample never more than speed x max curvature x dt but in the turn at rest
    # (no turning on the spot at speed)
    yaw = np.unwrap(tr["yaw_rad"].to_numpy())
    v_h = np.linalg.norm(_arr(tr, col.VEL)[:, :2], axis=1)
    allowed = vp.max_curvature_1pm * np.maximum(v_h[1:], v_h[:-1]) / rate
    # (on a suspension the body still rocks for a moment after it stops: its Euler yaw moves
    # by a few 1e-8 rad with the settling roll and pitch, the heading does not)
    tol = 1e-12 if suspension == "rigid" else 1e-6
    ok = np.abs(np.diff(yaw)) <= allowed * (1 + 1e-6) + tol
    assert np.all(ok | turning[1:] | turning[:-1])
    # the body settles on its suspension (a damped second order, pitch envelope
    # exp(-zeta omega_n t), 1/e in 0.33 s): its roll and pitch are then constant, turning or not
    if suspension == "rigid":  # attitude exactly constant at rest but in the turn
        for m in ((tt > a0) & (tt < c0), (tt > c1) & (tt < b0)):
            q = _arr(tr, col.QUAT)[m]
            assert np.abs(q - q[0]).max() < 1e-12
    rp = _arr(tr, col.EULER[:2])
    settled = (tt > a0 + 2.0) & (tt < b0)
    assert np.abs(rp[settled] - rp[settled][-1]).max() < 1e-5
    late = (tt > a0 + 5.0) & (tt < b0)
    assert np.abs(rp[late] - rp[late][-1]).max() < 1e-7
    # before: facing East; once the U-turn (radius >= 1 / max curvature) is done, facing the
    # direction of motion again, whichever way round it went
    assert abs(yaw[(tt > 3) & (tt < 18)]).max() < 0.05
    late = (tt > 46) & (tt < 54)
    v = _arr(tr, col.VEL)[late]
    err = (yaw[late] - np.arctan2(v[:, 1], v[:, 0]) + math.pi) % (2 * math.pi) - math.pi
    assert np.abs(err).max() < 0.02
    # the body rolls on its suspension within the car's roll limit (no U-turn at speed now:
    # a fraction of a degree, from the fit's jitter)
    roll = tr["roll_rad"].to_numpy()
    if suspension == "rigid":
        np.testing.assert_allclose(roll, 0.0, atol=1e-12)
    else:
        assert np.abs(roll).max() <= min(vp.max_roll_rad, math.radians(0.5))


def test_ground_rates_match_increments_wgs84():
    """Euler rates + transport rate of the ground model against the increments built from
    the quaternions (independent 4th-order quadrature), a climbing, leaning S-curve."""
    t = np.arange(0.0, 120.0, 0.5)
    x = 6.0 * t
    # curvature up to 0.1 /m: a 20 deg lean at 6 m/s
    enu = np.column_stack([x, 40.0 * np.sin(x / 20.0), 30.0 * np.sin(x / 200.0)])
    lateral = {}
    SUSPENSION = {"suspension": "damped"}  # the car on its suspension; the bicycle leans
    for vehicle in ("car", "bicycle"):
        # heading smoothing short against the 10 m turns: lean = atan(v^2 kappa / g) holds
        tr, meta = _build(
            enu,
            t,
            rate_hz=100,
            earth="wgs84",
            vehicle=vehicle,
            vehicle_params={"heading_smooth_m": 0.5, "heading_smooth_s": 0.05, **SUSPENSION},
        )
        assert _rate_increment_error(tr) < 1e-5  # the 4th-order rule's own error at 100 Hz
        assert meta["plausibility"]["max_attitude_step_excess_rad"] < 1e-6
        roll = tr["roll_rad"].to_numpy()
        mid = slice(len(roll) // 4, 3 * len(roll) // 4)
        lateral[vehicle] = np.abs(_arr(tr, col.ACCEL)[mid, 1]).max()
        if vehicle == "car":  # on its suspension: outwards, the roll gradient x a_lat
            vp = vehicle_params("car", SUSPENSION)
            v = _arr(tr, col.VEL)
            yaw = np.unwrap(tr["yaw_rad"].to_numpy())
            a_lat = np.hypot(v[:, 0], v[:, 1]) * np.gradient(yaw, tr[col.TIME].to_numpy())
            assert 0.0 < np.abs(roll).max() <= vp.max_roll_rad
            assert np.corrcoef(roll[mid], a_lat[mid])[0, 1] > 0.9
            assert np.ptp(roll[mid]) == pytest.approx(
                vp.roll_gradient_radpmps2 * np.ptp(a_lat[mid]), rel=0.3
            )
        else:
            assert np.abs(roll).max() > 0.3
    # a car feels the centripetal force sideways; a leaning bicycle almost none
    assert lateral["car"] > 3.0 and lateral["bicycle"] < 0.03 * lateral["car"]


@pytest.mark.parametrize("lat_deg", [0.0, 60.0])
def test_bicycle_leans_with_its_turn_relative_to_the_earth(lat_deg):
    """One eastward S-curve at 8 m/s built in ``flat`` and ``geodetic``: the lean agrees to
    1e-7 rad. Off ``flat`` the heading is measured from a local North that turns about the
    vertical along the path (``v_E tan(lat) / R``, 2.2e-6 rad/s at 60 deg): taken as the
    vehicle's turn it would lean the bicycle ``v^2 tan(lat) / (R g)`` = 1.8e-6 rad more."""
    t = np.arange(0.0, 100.0, 1.0)
    x = 8.0 * t
    enu = np.column_stack([x, 40.0 * np.sin(x / 50.0), 2.0 * np.sin(x / 300.0)])
    roll = {}
    for earth in ("flat", "geodetic"):
        df, meta = truth.enu_table(enu, t, (lat_deg, 10.0, 100.0))
        tr, _ = truth.build_truth(
            df, meta, rate_hz=10, earth=earth, vehicle="bicycle", verbose=False
        )
        roll[earth] = tr["roll_rad"].to_numpy()
    assert np.abs(roll["flat"]).max() > 0.05  # a lean of ~6 deg in the bends
    assert np.abs(roll["geodetic"] - roll["flat"]).max() < 1e-7


def test_pitch_is_the_grade_not_the_height_noise_at_a_stop():
    """A 5 % climb, a stop with a 1.2 m GNSS height step and 0.5 m height noise: pitch is
    atan(0.05) on the climb and the car does not tip over at the stop."""
    rng = np.random.default_rng(4)
    t = np.arange(0.0, 201.0, 1.0)
    s = 800.0 * (_smooth(t / 80.0) + _smooth((t - 120.0) / 80.0))
    up = 0.05 * s + np.where((t >= 100) & (t < 120), 1.2, 0.0)
    enu = np.column_stack([s, 0 * s, up]) + rng.normal(scale=[0.1, 0.1, 0.5], size=(len(t), 3))
    tr, meta = _build(enu, t, rate_hz=20, earth="flat", vehicle="car")
    tt = tr[col.TIME].to_numpy()
    pitch = tr["pitch_rad"].to_numpy()
    climb = ((tt > 20) & (tt < 60)) | ((tt > 140) & (tt < 180))
    np.testing.assert_allclose(pitch[climb], math.atan(0.05), atol=0.01)
    assert np.abs(pitch).max() < math.atan(0.05) + 0.03
    assert any(a <= 82 and b >= 118 for a, b in meta["fit"]["stops"])
    assert meta["plausibility"]["warnings"] == []


def test_grade_is_bounded_and_small_grades_exact():
    v = truth.VEHICLES["car"].max_pitch_rad
    y, dy = truth.attitude.soft_bound(np.array([0.0, 0.1, 0.7 * v, 2.0 * v, 50.0]), v)
    np.testing.assert_allclose(y[:3], [0.0, 0.1, 0.7 * v], rtol=0, atol=0)
    assert np.all(np.abs(y) <= v) and np.all(np.diff(y) >= 0) and np.all(dy >= 0)
    assert y[3] < v and dy[3] > 0


def test_aircraft_taxi_takeoff_and_turn():
    """Taxi at 5 m/s with GNSS height noise (pitch within the ground bound, roll 0), take-off
    roll, climbing coordinated turn (bank, no lateral force), continuous throughout."""
    rng = np.random.default_rng(2)
    dt = 0.5
    t = np.arange(0.0, 200.0, dt)
    spd = np.interp(t, [0, 60, 61, 90, 200], [5, 5, 5, 60, 60])
    turn = np.clip(t - 120, 0, None) * 0.1  # 0.1 rad/s turn from 120 s
    head = np.r_[0.0, np.cumsum(np.diff(turn))]
    e = np.cumsum(spd * np.cos(head)) * dt
    n = np.cumsum(spd * np.sin(head)) * dt
    u = np.where(t > 90, 3.0 * (t - 90), 0.0) + rng.normal(scale=0.5, size=len(t))
    tr, meta = _build(np.column_stack([e, n, u]), t, rate_hz=50, earth="wgs84", vehicle="aircraft")
    vp = truth.VEHICLES["aircraft"]
    rep = meta["plausibility"]
    assert rep["time_airborne_s"] > 80 and rep["max_abs_pitch_deg"] <= math.degrees(
        vp.max_pitch_rad
    )
    tt = tr[col.TIME].to_numpy()
    taxi = tt < 55
    assert np.abs(tr["roll_rad"].to_numpy()[taxi]).max() < 1e-6
    assert rep["max_attitude_step_excess_rad"] < 1e-6
    assert _rate_increment_error(tr) < 1e-3
    steady = (tt > 140) & (tt < 190)
    bank = np.arctan(60.0 * 0.1 / 9.8)
    np.testing.assert_allclose(np.abs(tr["roll_rad"].to_numpy()[steady]), bank, atol=0.03)
    assert np.abs(_arr(tr, col.ACCEL)[steady, 1]).max() < 0.05


def test_slow_glider_circling_high_is_flying():
    """A glider thermalling at 20 m/s (below the take-off speed) but high above the route's
    lowest point flies coordinated turns: bank atan(v^2 / (R g))."""
    V, R = 20.0, 100.0
    t = np.arange(0.0, 120.0, 1.0)
    w = V / R
    enu = np.column_stack([R * np.sin(w * t), R * (1 - np.cos(w * t)), 2.0 * t])
    tr, meta = _build(enu, t, rate_hz=20, earth="flat", vehicle="aircraft")
    tt = tr[col.TIME].to_numpy()
    high = (tt > 40) & (tt < 110)
    bank = math.atan(V * V / (R * 9.80665))
    np.testing.assert_allclose(np.abs(tr["roll_rad"].to_numpy()[high]), bank, atol=0.01)
    assert meta["plausibility"]["time_airborne_s"] > 90
    assert meta["plausibility"]["max_attitude_step_excess_rad"] < 1e-6


def test_vehicle_params_override_and_refusals():
    t, enu = _reversal_route(180.0)
    tr, meta = _build(enu, t, rate_hz=10, vehicle="car", vehicle_params={"max_curvature_1pm": 0.05})
    assert meta["vehicle_params"]["max_curvature_1pm"] == 0.05
    yaw_rate = np.abs(np.diff(np.unwrap(tr["yaw_rad"].to_numpy()))) * 10
    v_h = np.linalg.norm(_arr(tr, col.VEL)[1:, :2], axis=1)
    # the override holds at speed; the reversal's stop turns at rest (issue 27, session 33)
    tt = tr[col.TIME].to_numpy()[1:]
    rest = np.zeros(len(tt), bool)
    for c0, c1 in meta["timing"]["turns_at_rest_s"]:
        rest |= (tt >= c0) & (tt <= c1 + 0.1)
    assert rest.any() and np.all((yaw_rate <= 0.05 * (v_h + 0.5) + 1e-9) | rest)
    with pytest.raises(InputError, match="unknown vehicle parameter"):
        _build(enu, t, vehicle="car", vehicle_params={"wings": 2})
    with pytest.raises(InputError, match="invalid value"):
        _build(enu, t, vehicle="car", vehicle_params={"max_curvature_1pm": -1})


def test_report_flags_an_attitude_jump_and_turning_on_the_spot():
    """The report itself is an oracle only if it fails on a bad truth: a pi flip of the
    quaternion that the gyro does not see, with its increment, and a turn on the spot at walking
    pace in the gyro (the turn rate is the gyro's about the local vertical)."""
    t, enu = _reversal_route(90.0)
    tr, _ = _build(enu, t, rate_hz=10, vehicle="car")
    bad = tr.copy()
    k = len(bad) // 2
    q = _arr(bad, col.QUAT).copy()
    q[k:] = truth.attitude.rot.quat_mul(q[k:], np.array([0.0, 0.0, 0.0, 1.0]))
    bad[list(col.QUAT)] = q
    dth = _arr(bad, col.DTHETA).copy()
    dth[k, 2] += 2.5
    bad[list(col.DTHETA)] = dth
    w = _arr(bad, col.GYRO).copy()
    w[k, 2] += 2.5  # rad/s
    bad[list(col.GYRO)] = w
    rep = truth.report.plausibility(bad, truth.VEHICLES["car"])
    text = " ".join(rep["warnings"])
    assert "beyond what the rates allow" in text
    assert "disagree" in text and "turning on the spot" in text


def test_cli_prints_the_report_after_writing_and_stores_it(tmp_path, cli):
    from imugen.core.io import read_meta

    t, enu = _reversal_route(90.0)
    df, meta = truth.enu_table(enu, t, ORIGIN)
    src = tmp_path / "enu.parquet"
    write_parquet(df, meta, src)
    out = tmp_path / "truth.parquet"
    proc = cli(
        "truth", src, "-o", out, "--rate-hz", 10, "--vehicle", "bicycle",
        "--vehicle-param", "max_roll_rad=0.5", check=0,
    )  # fmt: skip
    assert "truth plausibility:" in proc.stderr
    m = read_meta(out)
    assert m["vehicle"] == "bicycle" and m["vehicle_params"]["max_roll_rad"] == 0.5
    assert m["plausibility"]["warnings"] == [] and m["plausibility"]["time_moving_s"] > 30
    bad = cli("truth", src, "-o", tmp_path / "x.parquet", "--vehicle-param", "lean=maybe")
    assert bad.returncode == 2 and not (tmp_path / "x.parquet").exists()


# ------------------------------------------------------------------------------------------
# real tracks
# ------------------------------------------------------------------------------------------
def _vehicle(name: str, index: int) -> str:
    """Vehicle of a shared track from its name (the data README says what each is)."""
    n = name.lower()
    if "colorado" in n:  # a car on a mountain pass, then a walk (README of the data)
        return "car" if index == 1 else "pedestrian"
    for key, veh in (
        ("cycl", "bicycle"),
        ("bike", "bicycle"),
        ("hike", "pedestrian"),
        ("walk", "pedestrian"),
        ("glider", "aircraft"),
        ("flight", "aircraft"),
        (".igc", "aircraft"),
    ):
        if key in n:
            return veh
    return "car"


MAX_GROUND_PATH_M = 500e3  # longer "ground" paths (an ocean crossing) take minutes at 10 Hz


def _real_tracks():
    if not SHARED.is_dir():
        return []
    return sorted(p for p in SHARED.iterdir() if p.suffix.lower() not in (".md", ".txt"))


def _ingested(path, index):
    """(ingestion, vehicle, its params) of path ``index`` of a shared file."""
    from imugen.ingest.stage import ingest

    vehicle = _vehicle(path.name, index)
    return ingest(path, path=index), vehicle, truth.VEHICLES[vehicle]


@functools.cache
def _shared_path_kinds() -> tuple:
    """``(file, path index, kind)`` of every path of the shared files that ingests (kind:
    ``timed`` with at least 5 points out, ``untimed ground``: a ground vehicle's, at most
    :data:`MAX_GROUND_PATH_M` long, or None), and ``(file, 0, InputError)`` of a file not
    readable here. Ingesting them all takes about 1 CPU-s."""
    from imugen.ingest.readers import read_route_file

    out = []
    for path in _real_tracks():
        try:
            n = len(read_route_file(path))
        except InputError as exc:
            out.append((path, 0, exc))
            continue
        for i in range(1, n + 1):
            try:
                ing, _, vp = _ingested(path, i)
            except InputError:
                continue
            enu = ing.table[list(tenu.ENU)].to_numpy()
            length = np.sum(np.linalg.norm(np.diff(enu[:, :2], axis=0), axis=1))
            kind = None
            if ing.meta["timed"] and ing.meta["points_out"] >= 5:
                kind = "timed"
            elif not ing.meta["timed"] and vp.attitude == "ground" and length <= MAX_GROUND_PATH_M:
                kind = "untimed ground"
            out.append((path, i, kind))
    return tuple(out)


def _shared_paths(kind):
    """Test cases ``(file, path index)`` of the shared paths of ``kind``: no case exists
    without such a path; a file not readable here is one skipped case saying why."""
    return [
        pytest.param(p, i, id=p.name, marks=pytest.mark.skip(reason=str(k)))
        if isinstance(k, InputError)
        else pytest.param(p, i, id=f"{p.name}#{i}")
        for p, i, k in _shared_path_kinds()
        if k == kind or isinstance(k, InputError)
    ]


def _plausibility_at_10hz(ing, vehicle, vp, label):
    """Build the truth at 10 Hz (wgs84) and assert the limits every class shares; returns
    the truth's metadata."""
    _, meta = truth.build_truth(
        ing.table, ing.meta, rate_hz=10, vehicle=vehicle, earth="wgs84", verbose=False
    )
    rep = meta["plausibility"]
    # on a suspension the body pitches beyond the grade by the pitch gradient x acceleration
    dive = 1.3 * vp.pitch_gradient_radpmps2 * vp.max_accel_mps2 if has_suspension(vp) else 0.0
    assert rep["max_abs_pitch_deg"] <= math.degrees(vp.max_pitch_rad + dive) + 1e-6, label
    if vehicle == "car":
        assert rep["max_abs_pitch_deg"] < 20.0, label  # well under 30 deg
    if has_suspension(vp):  # rolls on its suspension, within the car's limit
        assert rep["max_abs_roll_deg"] <= math.degrees(vp.max_roll_rad), label
    elif vehicle in ("car", "pedestrian"):
        assert rep["max_abs_roll_deg"] < 1e-6, label
    if vehicle == "aircraft":  # bank <= its limit; on the ground (and blending) small
        assert rep["max_abs_roll_airborne_deg"] <= math.degrees(vp.max_roll_rad), label
        assert rep["max_abs_roll_deg"] < 5.0, label
    assert rep["max_yaw_rate_excess_dps"] < 0.06, label
    assert rep["max_attitude_step_excess_rad"] < 1e-3, label
    # dtheta against the gyro: on every truth the gate lets through (the NMEA log whose fixes
    # the gate refuses, turning at rest at its 1 Hz zigzags, reaches 0.016 rad/s at 10 Hz)
    if not meta["gate"]:
        assert rep["max_rate_increment_radps"] < 1e-3, label
    return meta


@pytest.mark.shared
@pytest.mark.skipif(not SHARED.is_dir(), reason="shared trajectories absent")
@pytest.mark.parametrize(("path", "index"), _shared_paths("timed"))
def test_real_timed_tracks_are_plausible(path, index):
    """Every timed path of every shared real track, at a low IMU rate (10 Hz): the limits of
    its vehicle hold and nothing is invented (where no gap is bridged)."""
    ing, vehicle, vp = _ingested(path, index)
    label = f"{path.name} #{index} ({vehicle})"
    rep = _plausibility_at_10hz(ing, vehicle, vp, label)["plausibility"]
    gaps = np.diff(ing.table[col.TIME].to_numpy())
    bridged = (ing.meta.get("segments") or {}).get("bridged_gaps", 0)
    if gaps.max() <= 60.0 and not bridged:  # gaps judged by motion may be bridged
        assert rep["invented_fraction"] < 0.01, label


@pytest.mark.shared
@pytest.mark.skipif(not SHARED.is_dir(), reason="shared trajectories absent")
@pytest.mark.parametrize(("path", "index"), _shared_paths("untimed ground"))
def test_real_untimed_ground_paths_are_plausible(path, index):
    """Every untimed path of every shared real file driven by a ground vehicle, at 10 Hz: its
    vertical is the road profile of its heights (no pitch blend between two verticals, so no
    rate bumps), the vehicle's limits hold and its heights stay within the profile's residual
    of the input heights."""
    ing, vehicle, vp = _ingested(path, index)
    label = f"{path.name} #{index} ({vehicle})"
    meta = _plausibility_at_10hz(ing, vehicle, vp, label)
    vert = meta["fit"]["vertical"]
    # a path that doubles back is timed leg by leg and fitted as a timed route, whose
    # vertical is that of timed routes (imugen.truth.reversals): the limits above hold
    if "max_departure_m" in vert and not meta["timing"].get("reversals"):
        assert vert["max_departure_m"] < 1e-3, label
        res = vert["grade"]["rms_residual_m"]
        assert vert["rms_vertical_distance_m"] <= 1.02 * res + 1e-3, label
