"""GNSS logs the held-out audit found refused (issue 27), on synthetic files of the same form:
a ROS NavSatFix dump whose every row has status -1, a NUL-padded Columbus V-900 CSV, a 70mai
dashcam GPS log."""

from __future__ import annotations

import datetime as dt

import numpy as np
import pytest

from imugen.core.errors import InputError
from imugen.ingest.readers import read_route_file
from imugen.ingest.stage import ingest

T0 = 1_700_000_000  # 2023-11-14T22:13:20Z
NAVSAT = (
    "%time,field.header.seq,field.header.stamp,field.header.frame_id,field.status.status,"
    "field.status.service,field.latitude,field.longitude,field.altitude,"
    + ",".join(f"field.position_covariance{i}" for i in range(9))
    + ",field.position_covariance_type"
)


def navsatfix(path, n=40, status=-1, cov="4.0,0,0,0,4.0,0,0,0,9.0"):
    rows = [
        f"{(T0 + k) * 10**9 + 5000},{k},{(T0 + k) * 10**9},gps,{status},1,"
        f"{48.1371 + 1e-4 * k:.9f},{11.575:.9f},{520 + 0.01 * k:.3f},{cov},2"
        for k in range(n)
    ]
    path.write_text(NAVSAT + "\n" + "\n".join(rows) + "\n")
    return path


def test_navsatfix_every_row_status_minus_one_reads_with_one_warning(tmp_path):
    f = navsatfix(tmp_path / "fix.csv")
    ing = ingest(f)
    assert ing.meta["points_out"] == 40
    said = [w for w in ing.warnings if "status" in w]
    assert len(said) == 1 and "-1" in said[0] and "strict" in said[0]
    with pytest.raises(InputError, match=r"no data row with a fix.*status = -1"):
        ingest(f, navsatfix_status="strict")


def test_navsatfix_status_minus_one_refused_when_not_usable(tmp_path):
    # a non-finite covariance: not a driver's default but a receiver without a fix
    f = navsatfix(tmp_path / "nan.csv", cov="nan,0,0,0,nan,0,0,0,nan")
    with pytest.raises(InputError, match="no data row with a fix"):
        read_route_file(f)
    # mixed statuses: the rows without a fix are skipped, as before
    f = tmp_path / "mixed.csv"
    navsatfix(f, status=0)
    lines = f.read_text().splitlines()
    lines[3] = lines[3].replace(",gps,0,", ",gps,-1,")
    f.write_text("\n".join(lines) + "\n")
    (p,) = read_route_file(f)
    assert p.n_points == 39 and any("skipped 1 rows" in w for w in p.warnings)


def columbus(path, header_lat="LATITUDE N/S", header_lon="LONGITUDE E/W", n=30, south=False):
    """A Columbus V-900 CSV: fields NUL-padded to fixed width, CRLF."""

    def pad(s, w):
        return s + "\0" * (w - len(s))

    head = f"INDEX,TAG,DATE,TIME,{header_lat},{header_lon},HEIGHT,SPEED,HEADING,VOX"
    rows = []
    for k in range(n):
        lat = f"{48.1371 + 1e-4 * k:.6f}" + ("S" if south else "N")
        lon = f"{11.575:.6f}" + ("W" if south else "E")
        cells = [pad(str(k + 1), 6), "T", "231114", f"2213{20 + k:02d}", lat, pad(lon, 11),
                 pad("520", 5), pad("43", 4), pad("4", 3), pad("", 9)]  # fmt: skip
        rows.append(",".join(cells))
    path.write_bytes(("\r\n".join([head, *rows]) + "\r\n").encode())
    return path


@pytest.mark.parametrize(
    ("lat", "lon"),
    [
        ("LATITUDE N/S", "LONGITUDE E/W"),
        ("LATITUDE N", "LONGITUDE E"),
        ("LATITUDEN/S", "LONGITUDEE/W"),
    ],
)
def test_columbus_nul_padded_csv_reads_with_utc_times(tmp_path, lat, lon):
    f = columbus(tmp_path / "GPS001.CSV", lat, lon)
    (p,) = read_route_file(f)
    start = dt.datetime(2023, 11, 14, 22, 13, 20, tzinfo=dt.UTC).timestamp()
    np.testing.assert_array_equal(p.time_unix_s, start + np.arange(30))
    assert p.time_is_absolute
    assert p.lat_deg[0] == 48.1371 and p.lon_deg[0] == 11.575 and p.alt_m[0] == 520.0
    assert any("NUL bytes" in w for w in p.warnings)
    ing = ingest(f)
    assert ing.meta["points_out"] == 30 and ing.meta["timed"]


def test_columbus_hemispheres_and_bad_dates(tmp_path):
    (p,) = read_route_file(columbus(tmp_path / "s.csv", south=True))
    assert p.lat_deg[0] == -48.1371 and p.lon_deg[0] == -11.575
    f = tmp_path / "bad.csv"
    f.write_bytes(columbus(tmp_path / "b.csv").read_bytes().replace(b"231114", b"231314", 1))
    with pytest.raises(InputError, match="line 2: date/time '231314'"):
        read_route_file(f)


def dashcam(path, sessions):
    """A 70mai GPSData*.txt: ``sessions`` of (t0, lat0, n); repeated epochs and no-fix rows."""
    lines = []
    for t0, lat0, n in sessions:
        lines.append("$V02")
        lines.append(f"{t0 - 1},V,0.000000,0.000000,0,0,-85,3,47,NO.MP4,0,0,0")
        for k in range(n):
            row = f"{t0 + k},A,{lat0 + 1e-4 * k:.6f},11.575010,35911,1200,-85,3,47,NO.MP4,0,0,0"
            lines.append(row)
            if k == 3:
                lines.append(row.replace("-85,3,47", "-80,12,40"))  # the same epoch again
    path.write_text("\n".join(lines) + "\n")
    return path


def test_70mai_dashcam_log_reads_sessions_with_their_times(tmp_path):
    # two sessions that continue each other (3 s pause, 33 m): one path
    f = dashcam(tmp_path / "GPSData000001.txt", [(T0, 48.1371, 40), (T0 + 42, 48.1413, 30)])
    (p,) = read_route_file(f)
    assert p.kind == "70mai" and p.n_points == 70
    np.testing.assert_array_equal(p.time_unix_s[:3], [T0, T0 + 1, T0 + 2])
    assert p.time_unix_s[-1] == T0 + 42 + 29
    assert not p.altitude_trusted
    assert any("joined 2 recording sessions" in n for n in p.notes)
    assert any("2 rows without a fix" in w and "2 rows repeating" in w for w in p.warnings)
    ing = ingest(f)
    assert ing.meta["points_out"] == 70 and ing.meta["timed"]


def test_70mai_separate_drives_are_candidates(tmp_path):
    f = dashcam(tmp_path / "GPSData000002.txt", [(T0, 48.1371, 20), (T0 + 7200, 48.3, 25)])
    cands = read_route_file(f)
    assert [c.name for c in cands] == ["session 1", "session 2"]
    assert [c.n_points for c in cands] == [20, 25]
    assert ingest(f, path=2).meta["points_out"] == 25
