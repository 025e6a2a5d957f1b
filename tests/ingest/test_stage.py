"""Ingestion: path choice, validation, time rules, frames, outputs and the CLI contract."""

import json
from datetime import UTC, datetime, timedelta

import numpy as np
import pandas as pd
import pyarrow.parquet as pq
import pytest
from pyproj import Geod

from imugen.core.errors import InputError
from imugen.core.io import read_meta
from imugen.ingest.options import IngestOptions
from imugen.ingest.stage import ingest, run

GEOD = Geod(ellps="WGS84")


def gpx(points, name="t.gpx", tmp=None):
    pts = []
    for p in points:
        lat, lon = p[0], p[1]
        ele = f"<ele>{p[2]}</ele>" if len(p) > 2 and p[2] is not None else ""
        tm = f"<time>{p[3]}</time>" if len(p) > 3 and p[3] is not None else ""
        pts.append(f'<trkpt lat="{lat}" lon="{lon}">{ele}{tm}</trkpt>')
    f = tmp / name
    f.write_text(f"<gpx><trk><trkseg>{''.join(pts)}</trkseg></trk></gpx>")
    return f


def T(s):
    t = datetime(2024, 5, 1, 10, 0, 0, tzinfo=UTC) + timedelta(seconds=s)
    return t.isoformat().replace("+00:00", "Z")


def test_timed_gpx_table_and_metadata(tmp_path):
    f = gpx(
        [(31.63, -7.99, 450, T(0)), (31.6301, -7.99, 451, T(2)), (31.6302, -7.9899, 452, T(4))],
        tmp=tmp_path,
    )
    out = run(f, tmp_path / "o.parquet")
    df = pd.read_parquet(tmp_path / "o.parquet")
    assert list(df.columns) == ["time_s", "lat_deg", "lon_deg", "alt_m", "e_m", "n_m", "u_m"]
    np.testing.assert_allclose(df.time_s, [0, 2, 4])
    np.testing.assert_allclose(df.iloc[0][["e_m", "n_m", "u_m"]], 0, atol=1e-9)
    meta = read_meta(tmp_path / "o.parquet")
    assert meta["origin"] == {"lat_deg": 31.63, "lon_deg": -7.99, "alt_m": 450.0}
    assert meta["origin_from"] == "first point" and meta["timed"]
    assert meta["start_time_utc"] == "2024-05-01T10:00:00Z"
    assert meta["source"].endswith("t.gpx") and len(meta["source_sha256"]) == 64
    assert meta["units"]["e_m"] == "m" and "WGS-84" in meta["frame"]
    length = GEOD.line_length([-7.99, -7.99, -7.9899], [31.63, 31.6301, 31.6302])
    assert meta["length_horizontal_m"] == pytest.approx(length, rel=1e-4)
    assert out.meta == meta


def test_origin_option_and_utm(tmp_path):
    f = gpx([(31.63, -7.99, 450), (31.64, -7.99, 450)], tmp=tmp_path)
    ing = ingest(f, origin="31.63,-8.0,400", utm=True)
    assert ing.table.e_m.iloc[0] == pytest.approx(947.9, abs=1.0)  # 0.01 deg of longitude east
    assert ing.table.u_m.iloc[0] > 49.9  # 50 m above the origin (less curvature drop)
    assert ing.meta["utm"]["epsg"] == 32629
    assert {"utm_e_m", "utm_n_m"} <= set(ing.table.columns)


def test_enu_text_needs_origin_and_dt(tmp_path):
    f = tmp_path / "p.txt"
    f.write_text("1000\t2000\t480\n1003\t\t2004\t481\n1006\t2008\t481\n")
    with pytest.raises(InputError, match="--origin"):
        ingest(f)
    ing = ingest(f, origin="31.63,-7.99,480", dt=1.0)
    np.testing.assert_allclose(ing.table.time_s, [0, 1, 2])
    np.testing.assert_allclose(ing.table[["e_m", "n_m", "u_m"]].iloc[1], [3, 4, 1], atol=1e-6)
    assert ing.table.alt_m.iloc[0] == pytest.approx(480.0, abs=1e-6)
    assert ing.meta["time_source"].startswith("uniform dt")


def test_csv_stage_round_trip(tmp_path):
    f = gpx(
        [(31.63, -7.99, 450, T(0)), (31.6301, -7.9901, 455, T(1.5)), (31.6305, -7.99, 452, T(3))],
        tmp=tmp_path,
    )
    a = run(f, tmp_path / "r.csv", IngestOptions(origin="31.62,-7.98,440"))
    b = run(tmp_path / "r.csv", tmp_path / "r.parquet")
    assert b.meta["origin"] == a.meta["origin"] and "carried" in b.meta["origin_from"]
    assert b.meta["start_time_utc"] == a.meta["start_time_utc"]
    pd.testing.assert_frame_equal(a.table, b.table, check_exact=False, rtol=0, atol=1e-9)


def test_duplicates_and_clock_rules(tmp_path):
    f = gpx(
        [(1, 2, 0, T(0)), (1, 2, 0, T(0)), (1.001, 2, 0, T(1)), (1.002, 2, 0, T(2))], tmp=tmp_path
    )
    ing = ingest(f)
    assert len(ing.table) == 3 and any("exact duplicate" in w for w in ing.warnings)
    back = gpx(
        [(1, 2, 0, T(0)), (1.001, 2, 0, T(2)), (1.002, 2, 0, T(1)), (1.003, 2, 0, T(3))],
        "b.gpx",
        tmp_path,
    )
    with pytest.raises(InputError, match="goes backwards at point 3"):
        ingest(back)
    rep = gpx(
        [(1, 2, 0, T(0)), (1.001, 2, 0, T(1)), (1.002, 2, 0, T(1)), (1.003, 2, 0, T(3))],
        "r.gpx",
        tmp_path,
    )
    with pytest.raises(InputError, match="repeats at point 3"):
        ingest(rep)
    same = gpx([(1, 2, 0, T(5)), (1.001, 2, 0, T(5)), (1.002, 2, 0, T(5))], "s.gpx", tmp_path)
    ing = ingest(same)
    assert "time_s" not in ing.table.columns and any("same time" in w for w in ing.warnings)
    part = gpx([(1, 2, 0, T(0)), (1.001, 2, 0, None), (1.002, 2, 0, T(5))], "p.gpx", tmp_path)
    assert "time_s" not in ingest(part).table.columns
    stop = gpx([(1, 2, 0, T(0)), (1, 2, 0, T(30)), (1.001, 2, 0, T(100))], "stop.gpx", tmp_path)
    ing = ingest(stop, gap_warn_s=60, max_gap_s=120)  # a 70 s gap below the split limit
    assert (
        len(ing.table) == 3
        and ing.meta["gaps"]["max_s"] == 70
        and any("gaps" in w for w in ing.warnings)
    )
    untimed = gpx([(1, 2), (1, 2), (1.001, 2), (1.001, 2), (1.002, 2)], "u.gpx", tmp_path)
    ing = ingest(untimed)
    assert len(ing.table) == 3 and any("repeated consecutive" in w for w in ing.warnings)


@pytest.mark.parametrize(
    "points, message",
    [
        ([(1, -1230), (1, 2)], "point 1: longitude -1230 deg is outside"),
        ([(1, 2), (95, 2)], "point 2: latitude 95"),
        ([(1, 2), (float("nan"), 2)], "point 2: lat/lon .*not a finite number: .nan."),
        ([(1, 2, 1e7), (1.1, 2)], "height 1e\\+07 m"),
        ([(1, 2)], "at least two"),
        ([(1, 2), (1, 2), (1, 2)], "fewer than two distinct points"),
        ([(1, 2, 0, T(0)), (1, 2, 0, T(1))], "zero length"),
        (
            [(1, 2, 0, T(0)), (1.01, 2, 0, T(1)), (1.02, 2, 0, T(2))],
            "implied speed 3,9\\d\\d km/h between points [12] and [23]",
        ),
    ],
)
def test_validation_refusals(tmp_path, points, message):
    with pytest.raises(InputError, match=message):
        ingest(gpx(points, tmp=tmp_path))


def test_small_route_across_antimeridian_is_handled(tmp_path):
    f = gpx([(-16.8, 179.995, 0), (-16.8, -179.995, 0), (-16.79, -179.99, 0)], tmp=tmp_path)
    ing = ingest(f)
    seg = np.linalg.norm(np.diff(ing.table[["e_m", "n_m", "u_m"]].to_numpy(), axis=0), axis=1)
    geod = [
        GEOD.inv(179.995, -16.8, -179.995, -16.8)[2],
        GEOD.inv(-179.995, -16.8, -179.99, -16.79)[2],
    ]
    # untimed: each segment (> 500 m) is cut into 3 equal geodesic parts
    assert ing.meta["geodesic"]["points_added"] == 4
    np.testing.assert_allclose(seg.reshape(2, 3).sum(axis=1), geod, rtol=1e-5)
    assert any("antimeridian" in w for w in ing.warnings)


def test_long_route_across_antimeridian(tmp_path):
    """A 7,600 km timed route across 180 deg (airliner speed, 11 km): accepted, ENU continuous
    and exact (segment lengths = ECEF chords), geodesic horizontal length, limit only when set."""
    lon0, lat0, az = 139.78, 35.55, 55.0
    dist = np.linspace(0.0, 7.6e6, 761)  # 40 s apart at 250 m/s
    lon, lat, _ = GEOD.fwd(
        np.full_like(dist, lon0), np.full_like(dist, lat0), np.full_like(dist, az), dist
    )
    pts = [(la, lo, 11000.0, T(d / 250.0)) for la, lo, d in zip(lat, lon, dist, strict=True)]
    f = gpx(pts, tmp=tmp_path)
    ing = ingest(f)
    assert ing.meta["crosses_antimeridian"]
    # the route is one geodesic from its origin: its farthest point is 7,600 km away along it
    # (the horizontal part of the origin's ENU is R sin(d/R), 5.9e6 m, no distance)
    assert ing.meta["max_distance_from_origin_m"] == pytest.approx(7.6e6, rel=1e-9)
    assert np.hypot(ing.table.e_m, ing.table.n_m).max() < 6.5e6
    assert ing.meta["length_horizontal_m"] == pytest.approx(7.6e6, rel=1e-6)
    enu = ing.table[["e_m", "n_m", "u_m"]].to_numpy()
    from imugen.core.earth import ecef_from_geodetic

    r = ecef_from_geodetic(
        *np.radians(ing.table[["lat_deg", "lon_deg"]].to_numpy().T), ing.table["alt_m"].to_numpy()
    )
    np.testing.assert_allclose(
        np.linalg.norm(np.diff(enu, axis=0), axis=1),
        np.linalg.norm(np.diff(r, axis=0), axis=1),
        rtol=1e-9,
    )
    with pytest.raises(InputError, match="beyond --max-extent-km 1000"):
        ingest(f, max_extent_km=1000.0)
    with pytest.raises(InputError, match=r"reaches 7,600 km \(geodesic\) from its origin"):
        ingest(f, max_extent_km=7599.0)
    assert ingest(f, max_extent_km=7601.0).meta["points_out"] == 761


def test_path_selection(tmp_path):
    f = tmp_path / "m.gpx"
    f.write_text(
        '<gpx><trk><name>A</name><trkseg><trkpt lat="1" lon="2"/><trkpt lat="1.001" lon="2"/></trkseg></trk>'
        '<trk><name>B</name><trkseg><trkpt lat="1" lon="2"/><trkpt lat="1.002" lon="2"/>'
        '<trkpt lat="1.003" lon="2"/></trkseg></trk></gpx>'
    )
    with pytest.raises(
        InputError, match=r"2 candidate paths.*\[1\] 'A' \(trkseg, 2 points, 111 m\).*\[2\] 'B'"
    ):
        ingest(f)
    assert ingest(f, path="B").meta["path"] == "B"
    assert ingest(f, path="b").meta["path"] == "B"
    assert ingest(f, path=1).meta["path"] == "A"
    with pytest.raises(InputError, match="only 2 candidate"):
        ingest(f, path="3")
    with pytest.raises(InputError, match="no path named 'C'"):
        ingest(f, path="C")


def test_cli_error_contract(tmp_path, cli):
    bad = gpx([(1, -1230), (1, 2)], tmp=tmp_path)
    out = tmp_path / "out.parquet"
    proc = cli("ingest", bad, "-o", out)
    assert proc.returncode == 2
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and str(bad) in lines[0] and "longitude -1230" in lines[0]
    assert "Traceback" not in proc.stderr
    assert (
        not out.exists()
        and list(tmp_path.glob("*.tmp")) == []
        and list(tmp_path.glob(".out*")) == []
    )
    nul = tmp_path / "nul.kml"
    nul.write_bytes(b"<kml>\x00</kml>")
    proc = cli("ingest", nul, "-o", out)
    assert proc.returncode == 2 and "NUL" in proc.stderr and "Traceback" not in proc.stderr
    proc = cli("ingest", tmp_path / "missing.gpx", "-o", out)
    assert proc.returncode == 2 and "no such file" in proc.stderr
    proc = cli("ingest", bad, "-o", tmp_path / "out.txt")
    assert proc.returncode == 2
    proc = cli("ingest", bad, "--origin", "north", "-o", out)
    assert proc.returncode == 2 and "LAT,LON,H" in proc.stderr and not out.exists()


def test_cli_unwritable_output(tmp_path, cli):
    good = gpx([(1, 2), (1.001, 2)], tmp=tmp_path)
    blocker = tmp_path / "file"
    blocker.write_text("x")
    proc = cli("ingest", good, "-o", blocker / "sub" / "o.parquet")
    assert proc.returncode == 2 and "cannot write" in proc.stderr and "Traceback" not in proc.stderr


def test_cli_success_writes_parquet_and_csv(tmp_path, cli):
    good = gpx([(1, 2, 5, T(0)), (1.001, 2, 5, T(10))], tmp=tmp_path)
    cli("ingest", good, "-o", tmp_path / "o.csv", check=0)
    first = (tmp_path / "o.csv").read_text().splitlines()[0]
    assert first.startswith("# imugen: ") and json.loads(first[10:])["timed"]
    cli("ingest", tmp_path / "o.csv", "-o", tmp_path / "o.parquet", check=0)
    schema = pq.read_schema(tmp_path / "o.parquet")
    assert b"imugen" in schema.metadata


# every real file is either read correctly or refused with the documented message
REAL = {
    "a_sparkfun_rally_course_ge_pro.kml": dict(points=138, timed=False, path="path"),
    "b_kml23_track_no_gx_prefix.kml": dict(points=7, timed=True),
    # gaps up to 5 min: split, longest part taken (checked in test_segments.py)
    "b_mapfinity_hike_austin_gxtrack.kml": dict(timed=True, warn="bridged (9 as stops"),
    "c_limassol_tour_newline_coords.kml": dict(points=1812, timed=False),
    "e_cycling_central_park_1hz.gpx": dict(points=1812, timed=True),
    "f_hike_identical_1901_timestamps.gpx": dict(timed=False, warn="does not advance"),
}


@pytest.mark.parametrize("name", sorted(REAL))
def test_real_files_read(shared_file, name):
    f = shared_file(name)
    exp = REAL[name]
    ing = ingest(f)
    if "points" in exp:
        added = (ing.meta["geodesic"] or {}).get("points_added", 0)
        assert len(ing.table) - added <= exp["points"]
        assert ing.meta["points_in"] == exp["points"]
    assert ing.meta["timed"] == exp["timed"]
    if "warn" in exp:
        assert any(exp["warn"] in w for w in ing.warnings)
    enu = ing.table[["e_m", "n_m", "u_m"]].to_numpy()
    assert np.isfinite(enu).all()
    geod = GEOD.line_length(ing.table.lon_deg.to_numpy(), ing.table.lat_deg.to_numpy())
    assert ing.meta["length_horizontal_m"] == pytest.approx(geod, rel=1e-3)


def test_real_central_park_time_span(shared_file):
    ing = ingest(shared_file("e_cycling_central_park_1hz.gpx"))
    assert ing.meta["duration_s"] == pytest.approx(ing.table.time_s.iloc[-1])
    assert 1700 < ing.meta["duration_s"] < 1900 and 9.0e3 < ing.meta["length_horizontal_m"] < 1.05e4


def test_real_pacific_route_is_accepted(shared_file):
    """The trans-Pacific route (across the antimeridian, thousands of km) ingests whole; a limit
    of one's own still refuses it."""
    ing = ingest(shared_file("f_pacific_route_antimeridian.kml"))
    assert ing.meta["crosses_antimeridian"] and ing.meta["max_distance_from_origin_m"] > 1e6
    with pytest.raises(InputError, match=r"beyond --max-extent-km 100"):
        ingest(shared_file("f_pacific_route_antimeridian.kml"), max_extent_km=100.0)


def test_real_pacific_route_extent_limit_is_geodesic(shared_file, tmp_path, cli):
    """``--max-extent-km`` measures the geodesic from the origin: the Pacific route's farthest
    point is 7,544 km away by ``Geod.inv`` (5,908 km in the origin's tangent plane, which is no
    distance), so 7,000 km refuses it in one line and 8,000 km accepts it."""
    src = shared_file("f_pacific_route_antimeridian.kml")
    ing = ingest(src)
    o = ing.meta["origin"]
    lat, lon = ing.table.lat_deg.to_numpy(), ing.table.lon_deg.to_numpy()
    d = GEOD.inv(np.full_like(lon, o["lon_deg"]), np.full_like(lat, o["lat_deg"]), lon, lat)[2]
    assert ing.meta["max_distance_from_origin_m"] == pytest.approx(d.max(), rel=1e-12)
    assert 7.0e6 < d.max() < 8.0e6 and np.hypot(ing.table.e_m, ing.table.n_m).max() < 7.0e6
    out = tmp_path / "p.parquet"
    proc = cli("ingest", src, "-o", out, "--max-extent-km", "7000")
    assert proc.returncode == 2 and not out.exists()
    assert proc.stderr == (
        f"imugen: error: {src}: path 'Path' reaches {d.max() / 1e3:,.0f} km (geodesic) from its "
        "origin, beyond --max-extent-km 7000; raise or drop the limit (routes of any length are "
        "simulated in ECEF)\n"
    )
    cli("ingest", src, "-o", out, "--max-extent-km", "8000", check=0)
    assert out.exists()


def test_real_refusals(shared_file):
    with pytest.raises(InputError, match="6 candidate paths"):
        ingest(shared_file("c_google_kml_samples.kml"))
    # two track segments; the second's time gap bridged by a stop (gaps judged by motion), or
    # split into two parts by the fixed-time rule
    with pytest.raises(InputError, match=r"2 candidate paths.*'ACTIVE LOG #3' \(trkseg, 157"):
        ingest(shared_file("e_car_colorado_mountain_pass.gpx"))
    with pytest.raises(InputError, match=r"3 candidate paths.*#3 / part 2"):
        ingest(shared_file("e_car_colorado_mountain_pass.gpx"), gaps="split")
    car = ingest(shared_file("e_car_colorado_mountain_pass.gpx"), path=1)
    assert car.meta["points_in"] == 104 and car.meta["timed"]
    assert ingest(shared_file("c_google_kml_samples.kml"), path="Absolute").meta["altitude_trusted"]


def test_real_paper_trajectory(shared_file):
    ing = ingest(
        shared_file("seed_reference_trajectory_enu.txt"), origin="31.63,-7.99,480.6", dt=1.0
    )
    assert len(ing.table) == 620 and ing.meta["duration_s"] == 619
    raw = np.loadtxt(shared_file("seed_reference_trajectory_enu.txt"))
    np.testing.assert_allclose(ing.table[["e_m", "n_m", "u_m"]].to_numpy(), raw - raw[0], atol=1e-6)
    assert ing.meta["length_3d_m"] == pytest.approx(
        np.linalg.norm(np.diff(raw, axis=0), axis=1).sum()
    )


def test_long_candidate_lists_are_cut_with_a_count_and_a_hint(tmp_path):
    from imugen.ingest import stage as ing

    segs = "".join(
        f"<trkseg><trkpt lat='40' lon='{-105 + k * 1e-3}'/><trkpt lat='40.{k + 1:03d}' "
        f"lon='{-105 + k * 1e-3}'/></trkseg>"
        for k in range(40)
    )
    src = tmp_path / "many.gpx"
    src.write_text(f"<gpx version='1.1'><trk><name>t</name>{segs}</trk></gpx>")
    with pytest.raises(InputError) as e:
        ing.ingest(src, path="nonexistent")
    msg = str(e.value)
    assert "and 32 more" in msg and "--path longest" in msg and len(msg) < 2000
    assert msg.count("[") == ing.LIST_CANDIDATES


def test_the_reader_registry_names_every_reader():
    """imugen.ingest.formats (the help of `imugen ingest`) names every reader module, and only
    those; GPSBabel's suffixes are the babel reader's."""
    import pkgutil

    from imugen.ingest import formats, readers

    modules = {m.name for m in pkgutil.iter_modules(readers.__path__)}
    assert {f.reader for f in formats.FORMATS} == modules
    babel = next(f for f in formats.FORMATS if f.reader == "babel")
    assert set(babel.suffixes) == set(formats.GPSBABEL)
