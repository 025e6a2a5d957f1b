"""The truth's pre-write gate (imugen.truth.gate): an impossible motion is refused in one
line naming the file, the place and the limit, with nothing written; a plausible one (every
shared real track but one) is written. The audit's impossible cases as synthetic routes of
the same shape: a pedestrian diving from heights read as 0 m, a GPS spike of 325 m/s, a
truth below the input's heights."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest

from imugen import truth
from imugen.core.errors import InputError
from imugen.core.io import write_parquet
from imugen.truth import stage
from imugen.truth.gate import findings, refusal
from imugen.truth.options import TruthOptions

from helpers import SHARED_TRAJ

ORIGIN = (46.5, 7.5, 800.0)
SHARED = Path(os.environ.get("IMUGEN_SHARED_TRAJECTORIES", SHARED_TRAJ))


def _walk(n=600, seed=3):
    """A timed 1 Hz walk at 1.4 m/s along a gentle curve, 0.5 m noise (ENU, times)."""
    rng = np.random.default_rng(seed)
    t = np.arange(n, dtype=float)
    s = 1.4 * t
    enu = np.column_stack([s, 30.0 * np.sin(s / 200.0), np.zeros(n)])
    return t, enu + rng.normal(0.0, 0.5, (n, 3)) * [1.0, 1.0, 0.3]


def _enu_file(tmp_path, enu, t):
    df, meta = truth.enu_table(enu, t, ORIGIN)
    src = tmp_path / "walk_enu.parquet"
    write_parquet(df, meta, src)
    return src


def _refused(tmp_path, enu, t, vehicle="pedestrian"):
    src = _enu_file(tmp_path, enu, t)
    out = tmp_path / "truth.parquet"
    with pytest.raises(InputError) as exc:
        stage.run(src, out, TruthOptions(rate_hz=10, earth="wgs84", vehicle=vehicle))
    assert not out.exists()
    msg = str(exc.value)
    assert msg.startswith(str(src)) and "\n" not in msg
    assert "not a motion a pedestrian makes" in msg and "nothing written" in msg
    assert "t = " in msg and " N, " in msg and " E, " in msg and "km along the route" in msg
    return msg


def test_plausible_walk_is_written_without_findings(tmp_path):
    t, enu = _walk()
    src = _enu_file(tmp_path, enu, t)
    meta = stage.run(
        src, tmp_path / "ok.parquet", TruthOptions(rate_hz=10, earth="wgs84", vehicle="pedestrian")
    )
    assert meta["gate"] == [] and (tmp_path / "ok.parquet").exists()


def test_pedestrian_diving_from_missing_heights_is_refused(tmp_path):
    """60 fixes whose heights were read as 0 m on a walk 800 m up: the truth dives at ~100 m/s."""
    t, enu = _walk()
    enu[300:360, 2] -= ORIGIN[2]
    msg = _refused(tmp_path, enu, t)
    assert "speed" in msg and "beyond the pedestrian limit 12 m/s" in msg
    t_at = float(msg.split("at t = ")[1].split(" s")[0])
    assert 295.0 <= t_at <= 365.0  # at the dive's edges


def test_gps_spike_is_refused(tmp_path):
    """Five fixes 325 m off the walk (325 m/s between fixes)."""
    t, enu = _walk()
    enu[400:405, 0] += 325.0
    msg = _refused(tmp_path, enu, t)
    assert "speed" in msg or "acceleration" in msg


def test_allow_implausible_writes_with_a_warning(tmp_path, cli):
    t, enu = _walk()
    enu[400:405, 0] += 325.0
    src = _enu_file(tmp_path, enu, t)
    out = tmp_path / "t.parquet"
    bad = cli(
        "truth", src, f"--output={out}", "--rate-hz=10", "--earth=wgs84", "--vehicle=pedestrian"
    )
    assert bad.returncode == 2 and not out.exists()
    assert "Traceback" not in bad.stderr and "not a motion a pedestrian makes" in bad.stderr
    ok = cli(
        "truth", src, f"--output={out}", "--rate-hz=10", "--earth=wgs84", "--vehicle=pedestrian",
        "--allow-implausible",
    )  # fmt: skip
    assert ok.returncode == 0 and out.exists()
    assert "written anyway (--allow-implausible)" in ok.stderr


def test_truth_below_the_input_heights_is_found():
    """A truth 100 m under every input height (an untimed flight fitted underground)."""
    t, enu = _walk(120)
    df, meta = truth.enu_table(enu, t, ORIGIN)
    tr, tmeta = truth.build_truth(
        df, meta, rate_hz=10, earth="wgs84", vehicle="pedestrian", verbose=False
    )
    assert tmeta["gate"] == []
    from imugen.core import earth as ea

    frame = ea.OriginFrame.from_deg(*ORIGIN, "wgs84")
    h_in = frame.geodetic_from_n(enu)[2]
    vp = truth.VEHICLES["pedestrian"]
    found = findings(tr, vp, frame=frame, input_heights=h_in + 100.0)
    assert [f["limit"] for f in found] == ["height below the input's lowest"]
    assert found[0]["value"] == pytest.approx(100.0, abs=5.0)
    assert "height below the input's lowest by " in refusal(found, "pedestrian")


def test_car_on_its_suspension_is_gated_by_its_roll_and_pitch_limits():
    """A car on a 50 m circle at 15 m/s (4.5 m/s^2) with a stop: on its suspension it rolls ~2.3 deg and pitches on braking, within its limits; the same truth is
    refused when held to a rigid car's zero roll, or to a roll limit under the roll it has."""
    from dataclasses import replace

    from imugen.core import earth as ea

    t = np.arange(0.0, 60.0, 0.5)
    v = np.minimum(15.0, 3.0 * t)
    th = np.r_[0.0, np.cumsum(0.5 * (v[1:] + v[:-1]) * 0.5)] / 50.0
    enu = np.column_stack([50.0 * np.sin(th), 50.0 * (1 - np.cos(th)), 0 * t])
    df, meta = truth.enu_table(enu, t, ORIGIN)
    tr, tmeta = truth.build_truth(
        df, meta, rate_hz=10, earth="wgs84", vehicle="car", verbose=False,
        vehicle_params={"suspension": "damped"},
    )  # fmt: skip
    assert tmeta["gate"] == []
    roll = np.abs(tr["roll_rad"].to_numpy()).max()
    assert roll > np.radians(2.0)
    vp = replace(truth.VEHICLES["car"], suspension="damped")
    frame = ea.OriginFrame.from_deg(*ORIGIN, "wgs84")
    assert findings(tr, vp, frame=frame) == []
    rigid = [f["limit"] for f in findings(tr, replace(vp, suspension="rigid"), frame=frame)]
    assert "roll on the ground" in rigid
    low = findings(tr, replace(vp, max_roll_rad=0.5 * roll), frame=frame)
    assert [f["limit"] for f in low] == ["roll on the ground"]
    assert low[0]["value"] == pytest.approx(roll)


# ------------------------------------------------------------------------------------------
# real tracks
# ------------------------------------------------------------------------------------------
REFUSED = {
    # 1 Hz GGA fixes whose own speeds go 39 -> 28 -> 9.5 -> 9.6 -> 18 m/s in one-second
    # steps (t = 234-239 s): no car brakes and accelerates so (the fit, smoothed within 4
    # noise estimates, still needs 11.9 m/s^2); its fixes zigzag at every bend, so that the
    # body, its slip gated on timed routes too, slides sideways at 5.0 m/s (the worst finding)
    "g_nmea_gga_midnight_rollover.nmea": ("slip (body lateral speed)", "acceleration"),
}
REVERSALS = {
    # Untimed paths that double back (issue 27), timed leg by leg from rest to rest with a stop
    # and a turn at rest between (truth.reversals): the number of reversals found, and the
    # limits the gate finds. Jerk and acceleration hold (they were 30.01-33.3 m/s^3 and, the
    # hike's pedestrian, 12.5 m/s^2 when the joined legs were refitted with stop detection);
    # the body no longer slides sideways as it pulls away from a reversal's stop (slip 4.0,
    # 0.81, 4.97 and 4.99 m/s when the heading turned with the distance after the stop).
    ("c_limassol_tour_newline_coords.kml", 1): (1, set()),
    ("f_hike_identical_1901_timestamps.gpx", 1): (2, set()),
    ("g_segmented_tracks.geojson", 1): (None, set()),
    ("g_segmented_tracks.geojson", 2): (3, set()),
}


def _vehicle(name: str, index: int) -> str:
    n = name.lower()
    if "colorado" in n:
        return "car" if index == 1 else "pedestrian"
    for key, veh in (("cycl", "bicycle"), ("bike", "bicycle"), ("hike", "pedestrian"),
                     ("glider", "aircraft"), (".igc", "aircraft")):  # fmt: skip
        if key in n:
            return veh
    return "car"


def _paths():
    if not SHARED.is_dir():
        return []
    return sorted(p for p in SHARED.iterdir() if p.suffix.lower() not in (".md", ".txt"))


@pytest.mark.shared
@pytest.mark.skipif(not SHARED.is_dir(), reason="shared trajectories absent")
@pytest.mark.parametrize("path", _paths(), ids=lambda p: p.name)
def test_real_tracks_pass_the_gate(path):
    """Every path of every shared real track (ingested with defaults; ground paths up to
    500 km) passes the gate at 10 Hz as its class (per-class jerk limits), the untimed paths
    that double back included, but the one whose fixes are themselves impossible; cars on their
    suspension (roll and pitch within the suspension limits, turn about the yaw axis, the
    suspension's input capped at the tyre limit). The slip (body lateral speed) is gated on
    timed routes too (issue 27): the timed ground tracks' bends tighter than the class turns
    are refitted within its radius (:mod:`imugen.truth.timed_bends`; the mountain-pass drive
    3.3 -> 0.008 m/s; the bicycle computer's 2.9 -> 1.1 m/s, inside its declared turn at
    rest while creeping)."""
    from imugen.ingest.readers import read_route_file
    from imugen.ingest.stage import ingest

    try:
        n = len(read_route_file(path))
    except InputError as exc:
        pytest.skip(f"not readable here: {exc}")
    checked = 0
    for i in range(1, n + 1):
        try:
            ing = ingest(path, path=i)
        except InputError:
            continue
        enu = ing.table[["e_m", "n_m"]].to_numpy()
        if np.sum(np.linalg.norm(np.diff(enu, axis=0), axis=1)) > 500e3:
            continue
        veh = _vehicle(path.name, i)
        try:
            _, meta = truth.build_truth(
                ing.table, ing.meta, rate_hz=10, vehicle=veh, earth="wgs84", verbose=False,
                vehicle_params={"suspension": "damped"} if veh == "car" else None,
            )  # fmt: skip
        except InputError:  # too short to fit (two fixes)
            continue
        if path.name in REFUSED:
            worst, also = REFUSED[path.name]
            assert meta["gate"] and meta["gate"][0]["limit"] == worst, path.name
            assert also in {g["limit"] for g in meta["gate"]}, path.name
        elif (path.name, i) in REVERSALS:
            count, limits = REVERSALS[(path.name, i)]
            if count is not None:
                assert meta["timing"]["reversals"] == count, (path.name, i)
            assert {g["limit"] for g in meta["gate"]} == limits, (path.name, i, meta["gate"])
        else:
            assert meta["gate"] == [], (path.name, i, meta["gate"])
        checked += 1
    if not checked:
        pytest.skip("no path")


@pytest.mark.shared
@pytest.mark.skipif(not SHARED.is_dir(), reason="shared trajectories absent")
def test_mountain_pass_bends_are_driven_within_the_turning_radius():
    """The timed mountain-pass drive (4-6 s fixes): its two switchbacks (1.7 and 1.9 x the
    car's curvature limit where the fit slows at the apex) and a bend at 376 s (2.4 x) are
    refitted within the car's radius. Its U-turn at 293 s (legs 3 m apart) the fit follows
    through a near stop (0.3 m/s; the abrupt-stop join no longer rounds the stop at 346 s by
    12 m, which had let the local smoothing round the U-turn as far), too tight to refit
    (10 x): a reversal, turned at rest (159 deg, standing in for a multi-point turn), as is
    the creep into the stop at 463 s (-32 deg). Outside the turns at rest the body's lateral
    speed stays within 0.104 m/s (3.3 m/s unbounded), and the gate passes."""
    from imugen.core import rotations as rot
    from imugen.ingest.stage import ingest
    from imugen.tables import truth as col

    path = SHARED / "e_car_colorado_mountain_pass.gpx"
    if not path.exists():
        pytest.skip("no mountain pass")
    ing = ingest(path, path=1)
    df, m = truth.build_truth(
        ing.table, ing.meta, rate_hz=10, vehicle="car", earth="wgs84", verbose=False
    )
    bends = m["fit"]["curvature_bound"]
    assert bends["refitted"] == 3 and bends["left"] == 2
    turns = m["timing"]["turns_at_rest_s"]
    t = df[col.TIME].to_numpy()
    inside = np.zeros(len(t), bool)
    for a, b in turns:
        inside |= (t >= a) & (t <= b)
    assert inside[(t >= 292.0) & (t <= 296.0)].all()  # the U-turn
    C_nb = rot.quat_to_dcm(df[list(col.QUAT)].to_numpy())
    v_b = np.einsum("mji,mj->mi", C_nb, df[list(col.VEL)].to_numpy())
    assert np.abs(v_b[~inside, 1]).max() < 0.15
    assert m["gate"] == []


def _abrupt_stop(seed=0):
    """A 1 Hz car logger (0.5 m noise): 5.7 m/s, braking to rest within the last second
    before the fix at 60 s (5.7 m/s^2), 30 s still, then pulling away at 2 m/s^2."""
    rng = np.random.default_rng(seed)
    t = np.arange(0.0, 120.0)
    v0, u = 5.7, np.clip(t - 90.0, 0.0, None)
    s_stop = v0 * 59.0 + 0.5 * v0
    s = np.where(t <= 59.0, v0 * t, s_stop)
    s = s + np.where(u < v0 / 2.0, u * u, (v0 / 2.0) ** 2 + v0 * (u - v0 / 2.0))
    enu = np.column_stack([s, np.zeros_like(s), np.zeros_like(s)])
    return t, enu + rng.normal(0.0, 0.5, enu.shape) * [1.0, 1.0, 0.3]


def test_abrupt_stop_starts_at_the_first_still_fix(tmp_path):
    """Issue 27: at an abrupt stop of sparse fixes the timed fit's stop took in the last
    moving fix (2.85 m before the stop's position, at 59 s), so that the spline, held still
    from there, braked early and sped up before to make up the distance (5.7 -> 10.2 m/s).
    Now the stop starts at its first still fix (60 s), and the spline joins it at zero speed
    and acceleration, its penalty relaxed where it rounded the braking: no bounce (8.8 m/s
    with the C4 join of a simple knot; tests/truth/test_abrupt_stops.py)."""
    t, enu = _abrupt_stop(0)
    src = _enu_file(tmp_path, enu, t)
    meta = stage.run(
        src, tmp_path / "truth.parquet", TruthOptions(rate_hz=10, earth="wgs84", vehicle="car")
    )
    assert meta["gate"] == []
    ((a, b),) = meta["fit"]["stops"]
    assert a == 60.0 and 89.0 <= b <= 91.0
    from imugen.tables import truth as col

    tr = col.read(tmp_path / "truth.parquet").frame
    tt = tr[col.TIME].to_numpy()
    speed = np.linalg.norm(tr[list(col.VEL)].to_numpy()[:, :2], axis=1)
    # 10.2 m/s, then 8.8 before; now within two sigma of a fix-to-fix speed (0.5 m noise)
    assert speed[(tt > 45.0) & (tt < 60.0)].max() < 5.7 + 2.0 * np.sqrt(2.0) * 0.5
