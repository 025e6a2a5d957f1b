"""Gaps split paths into candidate parts; --path longest; trivial candidates skipped."""

from __future__ import annotations

import itertools
import re
from datetime import datetime

import numpy as np
import pytest
from pyproj import Geod

from imugen.core.errors import InputError
from imugen.ingest.route import RoutePath
from imugen.ingest.segments import split_at_gaps
from imugen.ingest.stage import ingest, write

GEOD = Geod(ellps="WGS84")


def _path(t, name="p"):
    n = len(t)
    return RoutePath(
        name=name,
        kind="trkseg",
        lat_deg=40 + np.arange(n) * 1e-4,
        lon_deg=np.full(n, -105.0),
        alt_m=np.zeros(n),
        time_unix_s=np.asarray(t, float),
    )


def _gpx(tmp_path, tracks, name="g.gpx"):
    """tracks: list of (name, [seconds...]); points 11 m apart northwards, 1 track each."""
    body = ""
    for tname, times in tracks:
        pts = "".join(
            f'<trkpt lat="{40 + k * 1e-4!r}" lon="-105.0"><ele>1600</ele>'
            f"<time>{datetime.fromtimestamp(1.7e9 + s).isoformat()}Z</time></trkpt>"
            for k, s in enumerate(times)
        )
        body += f"<trk><name>{tname}</name><trkseg>{pts}</trkseg></trk>"
    f = tmp_path / name
    f.write_text(f"<gpx>{body}</gpx>")
    return f


def test_split_at_gaps():
    t = [0, 1, 2, 100, 101, 102, 103, 300, 500, 501]
    parts = split_at_gaps(_path(t), 60.0)
    assert [p.name for p in parts] == ["p / part 1", "p / part 2", "p / part 3"]
    assert [p.time_unix_s.tolist() for p in parts] == [[0, 1, 2], [100, 101, 102, 103], [500, 501]]
    assert [p.lat_deg[0] for p in parts] == [40, 40 + 3e-4, 40 + 8e-4]
    assert "single-point parts dropped" in parts[0].notes[-1]  # the fix at 300 s
    # only the 200 s gap is longer than 199 s: the fix at 300 s stays with the first part
    assert [p.n_points for p in split_at_gaps(_path(t), 199.0)] == [8, 2]
    whole = _path([0, 1, 2])
    untimed = _path([0, 100, 200])
    untimed.time_unix_s = None
    assert split_at_gaps(whole, 60.0) == [whole] and split_at_gaps(untimed, 1.0) == [untimed]


def test_split_takes_longest_part_with_warning(tmp_path):
    """``gaps="split"``, the fixed-time rule (the default judges gaps by motion)."""
    f = _gpx(tmp_path, [("drive", [*range(10), *range(200, 230), *range(400, 405)])])
    ing = ingest(f, gaps="split")
    assert ing.meta["path"] == "drive / part 2" and ing.meta["points_in"] == 30
    assert ing.meta["duration_s"] == 29.0
    seg = ing.meta["segments"]
    assert (seg["mode"], seg["parts"], seg["not_used"]) == (
        "split",
        3,
        ["drive / part 1", "drive / part 3"],
    )
    w = next(w for w in ing.warnings if "3 parts after splitting" in w)
    assert "'drive / part 1' (10 points" in w and "--gaps bridge" in w
    # the parts are candidates: by name, by index, longest, or the original's name
    assert ingest(f, gaps="split", path="drive / part 3").meta["points_in"] == 5
    assert ingest(f, gaps="split", path=1).meta["path"] == "drive / part 1"
    assert ingest(f, gaps="split", path="longest").meta["path"] == "drive / part 2"
    assert ingest(f, gaps="split", path="DRIVE").meta["path"] == "drive / part 2"
    assert ingest(f, gaps="split", max_gap_s=500).meta["points_in"] == 45


def test_bridge_only_when_asked(tmp_path):
    f = _gpx(tmp_path, [("drive", [*range(10), *range(200, 230)])])
    ing = ingest(f, gaps="bridge")
    assert ing.meta["points_in"] == 40 and ing.meta["segments"]["bridged_gaps"] == 1
    assert any("bridged 1 time gaps longer than 60 s" in w for w in ing.warnings)
    # the CSV stage keeps the decision (it would split again otherwise)
    again = ingest(write(ing, tmp_path / "route.csv"))
    assert len(again.table) == 40 and again.meta["segments"]["carried"]
    with pytest.raises(InputError, match="--max-gap-s"):
        ingest(f, max_gap_s=0)
    with pytest.raises(InputError, match="--gaps"):
        ingest(f, gaps="jump")


def test_several_tracks_still_need_a_choice(tmp_path):
    f = _gpx(tmp_path, [("a", range(20)), ("b", [*range(10), *range(100, 120)])])
    with pytest.raises(InputError, match=r"3 candidate paths.*\[2\] 'b / part 1'"):
        ingest(f, gaps="split")
    assert ingest(f, gaps="split", path="b").meta["path"] == "b / part 2"
    assert ingest(f, gaps="split", path="longest").meta["points_in"] == 20


def test_only_real_candidate_taken_with_note(tmp_path):
    line = "<Placemark><name>{}</name><LineString><coordinates>{}</coordinates></LineString></Placemark>"
    real = " ".join(f"-105.0,{40 + k * 1e-4!r},1600" for k in range(30))
    stub = "-105.0,40.0,1600 -105.0,40.00002,1600"
    few = " ".join(f"-105.0,{40 + k * 1e-3!r},1600" for k in range(3))
    f = tmp_path / "m.kml"
    f.write_text(
        "<kml><Document>"
        + line.format("stub", stub)
        + line.format("route", real)
        + line.format("few", few)
        + "</Document></kml>"
    )
    ing = ingest(f)
    assert ing.meta["path"] == "route"
    w = next(w for w in ing.warnings if "only real path" in w)
    assert "'stub' (2 points, 2 m)" in w and "'few' (3 points" in w
    f.write_text(
        "<kml><Document>" + line.format("a", real) + line.format("b", real) + "</Document></kml>"
    )
    with pytest.raises(InputError, match="2 candidate paths"):
        ingest(f)


def test_real_austin_hike_split_at_its_gaps(shared_file):
    path = shared_file("b_mapfinity_hike_austin_gxtrack.kml")
    text = re.search(r"<gx:Track>.*</gx:Track>", path.read_text(), re.S).group(0)
    whens = [datetime.fromisoformat(w).timestamp() for w in re.findall(r"<when>(.*?)</when>", text)]
    coords = np.array(
        [[float(v) for v in c.split()] for c in re.findall(r"<gx:coord>(.*?)</gx:coord>", text)]
    )
    t = np.array(whens)
    assert len(t) == len(coords) == 451
    cuts = [0, *(np.flatnonzero(np.diff(t) > 60) + 1).tolist(), len(t)]
    parts = [(a, b) for a, b in itertools.pairwise(cuts) if b - a >= 2]
    lengths = [GEOD.line_length(coords[a:b, 0], coords[a:b, 1]) for a, b in parts]
    a, b = parts[int(np.argmax(lengths))]
    ing = ingest(path, vehicle="pedestrian", gaps="split")  # the fixed-time rule
    assert ing.meta["segments"]["parts"] == len(parts) > 1
    assert ing.meta["points_in"] == b - a
    assert ing.meta["duration_s"] == pytest.approx(t[b - 1] - t[a])
    assert np.diff(ing.table.time_s).max() <= 60
    judged = ingest(path, vehicle="pedestrian")  # the default: gaps judged by motion
    seg = judged.meta["segments"]
    assert seg["mode"] == "auto" and len(seg["gaps"]) >= len(parts) - 1
    assert judged.meta["duration_s"] > ing.meta["duration_s"]


def test_cli_gap_options(tmp_path, cli):
    f = _gpx(tmp_path, [("drive", [*range(10), *range(100, 130)])])
    out = tmp_path / "o.csv"
    proc = cli("ingest", f, "-o", out, "--gaps=split", check=0)
    assert "took the longest" in proc.stderr and "30 points" in proc.stderr
    proc = cli("ingest", f, "-o", out, check=0)  # judged by motion: 11 m in 91 s is a stop
    assert "a stop of" in proc.stderr and "took the longest" not in proc.stderr
    proc = cli("ingest", f, "-o", out, "--max-gap-s", "100", "--gaps=split", check=0)
    assert "took the longest" not in proc.stderr and "40 points" in proc.stderr
    proc = cli("ingest", f, "-o", out, "--gaps", "bridge", check=0)
    assert "bridged 1 time gaps" in proc.stderr


def _gpx_segments(tmp_path, segs, name="segs.gpx"):
    """One track of several segments: segs = [(lat0, [seconds...]), ...], points 11 m apart."""
    body = ""
    for lat0, times in segs:
        pts = "".join(
            f'<trkpt lat="{lat0 + k * 1e-4!r}" lon="-105.0"><ele>1600</ele>'
            f"<time>{datetime.fromtimestamp(1.7e9 + s).isoformat()}Z</time></trkpt>"
            for k, s in enumerate(times)
        )
        body += f"<trkseg>{pts}</trkseg>"
    f = tmp_path / name
    f.write_text(f"<gpx><trk><name>drive</name>{body}</trk></gpx>")
    return f


def test_segments_of_one_track_that_continue_are_one_path(tmp_path):
    """Issue 27: a track whose segments continue each other in time and space reads whole."""
    f = _gpx_segments(tmp_path, [(40.0, range(0, 30)), (40.003, range(35, 60)),
                                 (40.0055, range(62, 90))])  # fmt: skip
    ing = ingest(f)
    assert ing.meta["points_out"] == 83
    assert any("joined the 3 paths" in w for w in ing.warnings)
    # a jump the pause cannot explain (30 km in 5 s): the refusal lists the candidates
    f = _gpx_segments(tmp_path, [(40.0, range(0, 30)), (40.3, range(35, 60))], "jump.gpx")
    with pytest.raises(InputError, match="holds 2 candidate paths"):
        ingest(f)


def test_path_all_writes_one_route_per_path(tmp_path, cli):
    f = _gpx(tmp_path, [("Morning walk", range(0, 20)), ("Evening run!", range(5000, 5030)),
                        ("x", [0])])  # fmt: skip
    out = tmp_path / "routes" / "walks.csv"
    r = cli("ingest", str(f), "-o", str(out), "--path=all")
    assert r.returncode == 0, r.stderr
    from imugen.ingest.stage import IngestOptions, read_all, route_ids

    files = sorted(p.name for p in (tmp_path / "routes" / "walks").iterdir())
    assert [n[: -len("-123456.csv")] for n in files] == ["evening-run", "morning-walk"]
    done, refused = read_all(f, IngestOptions(path="all"))
    ids = [rid for rid, _ in done]
    assert [f"{rid}.csv" for rid in ids] == sorted(files, reverse=True)
    assert done[1][1].meta["points_out"] == 30 and done[1][1].meta["route_id"] == ids[1]
    assert [rid[:2] for rid, _ in refused] == ["x-"]  # one point: refused, the others written
    assert f"path {refused[0][0]} not read" in r.stderr
    # one path of them by its id, as the workflow's paths: all reads it
    one = ingest(f, path=f"all:{ids[1]}")
    assert one.meta["points_out"] == 30 and one.meta["route_id"] == ids[1]
    with pytest.raises(InputError, match="no path has this id"):
        ingest(f, path="all:nope")
    # ids: name slug + hash of name and first point; twins are numbered
    from imugen.ingest import limits
    from imugen.ingest.readers import read_route_file

    cands = read_route_file(f, limits.read_input(f))
    twice = route_ids([cands[0], cands[0]])
    assert twice == [ids[0], f"{ids[0]}-2"]
    with pytest.raises(InputError, match="one route per path"):
        ingest(f, path="all")


def _hike(tmp_path, teleport=False):
    """A slow hike logged every ~24 s (0.7 m/s northwards) with gaps of 70-190 s at the same
    pace (issue 27's 6 h canyon hike, smaller); ``teleport``: one gap jumps 2 km in 100 s."""
    rng = np.random.default_rng(7)
    dts = rng.uniform(20, 28, 160)
    dts[10::15] = rng.uniform(70, 190, len(dts[10::15]))
    if teleport:
        dts[100] = 100.0
    t = np.concatenate([[0.0], np.cumsum(dts)])
    north = 0.7 * t + (2000.0 if teleport else 0.0) * (np.arange(len(t)) > 100)
    lat = 36.0 + north / 111_000.0
    pts = "".join(
        f'<trkpt lat="{float(la)!r}" lon="-112.0"><ele>{800 + 0.01 * n:.2f}</ele>'
        f"<time>{datetime.fromtimestamp(1.7e9 + s).isoformat()}Z</time></trkpt>"
        for la, n, s in zip(lat, north, t, strict=True)
    )
    f = tmp_path / "hike.gpx"
    f.write_text(f"<gpx><trk><name>hike</name><trkseg>{pts}</trkseg></trk></gpx>")
    return f, t, int((dts > 60).sum())


def test_sparse_hike_reads_whole_with_gaps_judged_by_motion(tmp_path):
    f, t, n_gaps = _hike(tmp_path)
    split = ingest(f, vehicle="pedestrian", gaps="split")  # fixed time: the longest part only
    assert split.meta["duration_s"] < 0.5 * t[-1]
    ing = ingest(f, vehicle="pedestrian")  # the default: gaps judged by motion
    assert ing.meta["duration_s"] == pytest.approx(t[-1])
    seg = ing.meta["segments"]
    assert len(seg["gaps"]) == n_gaps and all(g["bridge"] for g in seg["gaps"])
    assert all(g["kind"] == "leg" and g["leg_speed_mps"] > 0.5 for g in seg["gaps"])
    assert seg["invented_m"] == pytest.approx(sum(g["distance_m"] for g in seg["gaps"]))
    # the legs cover the gaps' share of the time (28 % here), at the pace around them
    assert seg["invented_m"] < 0.35 * ing.meta["length_3d_m"]
    assert any("judged by motion" in w for w in ing.warnings)
    # bridged by straight legs: the virtual fixes never leave the line between the fixes
    assert np.all(np.diff(ing.table["n_m"].to_numpy()) >= -1e-6)


def test_implausible_gap_is_split(tmp_path):
    f, _, _ = _hike(tmp_path, teleport=True)
    ing = ingest(f, vehicle="pedestrian", gaps="auto")
    seg = ing.meta["segments"]
    jumps = [g for g in seg["gaps"] if not g["bridge"]]
    assert len(jumps) == 1 and jumps[0]["distance_m"] > 2000
    assert seg["parts"] == 2


def _car_park(tmp_path):
    """Issue 27's car logger: 8 m/s northwards into an underground car park (1 Hz fixes, 3 m
    uphill over the route), 924 s without a fix, out again 36 m further on at 8 m/s."""
    rng = np.random.default_rng(3)
    t_in = np.arange(0.0, 61.0)
    t_out = t_in[-1] + 924.0 + np.arange(0.0, 61.0)
    north = np.concatenate([8.0 * t_in, 8.0 * t_in[-1] + 36.0 + 8.0 * (t_out - t_out[0])])
    east = np.concatenate([np.zeros(61), np.full(61, 5.0)])
    north += rng.normal(0.0, 0.3, north.size)
    up = 500.0 + 3.0 * north / north[-1]
    t = np.concatenate([t_in, t_out])
    pts = "".join(
        f'<trkpt lat="{46.0 + n / 111_132.0:.9f}" lon="{7.0 + e / 77_300.0:.9f}"><ele>{u:.2f}</ele>'
        f"<time>{datetime.fromtimestamp(1.7e9 + s).isoformat()}Z</time></trkpt>"
        for n, e, u, s in zip(north, east, up, t, strict=True)
    )
    f = tmp_path / "carpark.gpx"
    f.write_text(f"<gpx><trk><name>drive</name><trkseg>{pts}</trkseg></trk></gpx>")
    return f


def test_a_long_gap_between_close_fixes_is_a_stop_within_the_cars_limits(tmp_path):
    """Issue 27: a 924 s gap between fixes 36 m apart, entered and left at 8 m/s, is a stop
    (braking, waiting, accelerating within the car's acceleration), not a 1.46 km drive nor
    a 27 m/s^2 halt; the truth stays between the two fixes' heights. The truth's stop holds
    only the gap's held fixes, not its braking and accelerating ramps (it reached 6.3 m/s^2
    and overshot to 11.6 m/s before the gap when the stop took in the ramps' last fixes)."""
    from imugen import truth
    from imugen.tables import truth as col
    from imugen.truth import VEHICLES

    ing = ingest(_car_park(tmp_path))  # gaps judged by motion: the default
    seg = ing.meta["segments"]
    assert seg["mode"] == "auto" and len(seg["gaps"]) == 1
    g = seg["gaps"][0]
    assert g["bridge"] and g["kind"] == "stop" and g["stop_s"] > 900
    assert g["accel_mps2"] <= 4.0 and 30 < seg["invented_m"] < 45  # peak of the ramps
    assert any("a stop of" in w for w in ing.warnings)
    tr, m = truth.build_truth(ing.table, ing.meta, rate_hz=10.0, vehicle="car", verbose=False)
    t = tr[col.TIME].to_numpy()
    v = tr[list(col.VEL)].to_numpy()
    acc = np.linalg.norm(np.diff(v, axis=0), axis=1) / np.diff(t)
    assert acc.max() <= 0.5 * VEHICLES["car"].max_accel_mps2  # the ramps' 2.6 m/s^2, smoothed
    (stop,) = m["fit"]["stops"]
    ramp_s = np.pi / 2.0 * 8.0 / g["accel_mps2"]  # 8 m/s to rest at the ramps' peak acceleration
    assert stop[0] >= 60.0 + ramp_s - 0.5 and stop[1] <= 984.0 - ramp_s + 0.5
    speed_h = np.linalg.norm(v[:, :2], axis=1)
    assert speed_h[(t > 50.0) & (t < 70.0)].max() < 1.1 * 8.0  # braking, no surge before it
    assert speed_h[(t > 975.0) & (t < 995.0)].max() < 1.1 * 8.0
    pos = tr[list(col.POS)].to_numpy()
    travelled = np.linalg.norm(np.diff(pos[:, :2], axis=0), axis=1).sum()
    assert travelled < 1.05 * ing.meta["length_3d_m"]
    gap = (t > 61.0) & (t < 985.0)
    u_fixes = ing.table["u_m"].to_numpy()
    lo, hi = u_fixes[60], u_fixes[-61]
    assert pos[gap, 2].min() >= min(lo, hi) - 0.5 and pos[gap, 2].max() <= max(lo, hi) + 0.5
    speed = np.linalg.norm(v[:, :2], axis=1)
    assert (speed[gap] < 0.05).sum() * 0.1 > 800  # standing still, not creeping


def test_a_gap_of_years_is_split_not_bridged():
    """A logger's clock jumping by years between close fixes is no motion to invent: the gap
    is split (bridging it made ~3.4e8 virtual fixes and exhausted memory in the fuzz test)."""
    from imugen.ingest.segments import AUTO_MAX_BRIDGE_S, judge_gaps

    n = 12
    t = np.arange(n, dtype=float)
    t[6:] += 10 * 365 * 86400.0
    lat = 48.0 + 1e-5 * np.arange(n)
    p = RoutePath(
        name="gap",
        kind="trkseg",
        lat_deg=lat,
        lon_deg=np.full(n, 11.0),
        alt_m=np.zeros(n),
        time_unix_s=t,
    )
    (gap,) = judge_gaps(p, 60.0, "car")
    assert gap["length_s"] > AUTO_MAX_BRIDGE_S and not gap["bridge"]
    t2 = t.copy()
    t2[6:] -= 10 * 365 * 86400.0 - 600.0
    (short,) = judge_gaps(
        RoutePath(
            name="gap",
            kind="trkseg",
            lat_deg=lat,
            lon_deg=np.full(n, 11.0),
            alt_m=np.zeros(n),
            time_unix_s=t2,
        ),
        60.0,
        "car",
    )
    assert short["bridge"] and short["kind"] == "stop"
