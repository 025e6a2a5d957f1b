"""GNSS-logger CSV dialects: ROS NavSatFix dumps, hemisphere letters, NUL-padded fields."""

from __future__ import annotations

import numpy as np
import pytest

from imugen.core.errors import InputError
from imugen.ingest.readers import read_route_file
from imugen.ingest.readers.gnsscsv import parse_degrees
from imugen.ingest.stage import ingest

ROS_HEADER = (
    "%time,field.header.seq,field.header.stamp,field.header.frame_id,field.status.status,"
    "field.status.service,field.latitude,field.longitude,field.altitude,"
    "field.position_covariance0,field.position_covariance_type"
)


def _ros_row(k, rec_ns, stamp_ns, lat, lon, alt, status=0):
    return f"{rec_ns},{k},{stamp_ns},gps,{status},1,{lat!r},{lon!r},{alt},1.0,2"


def test_ros_navsatfix_dump(tmp_path):
    t0 = 1_700_000_000_000_000_000
    rows = [
        _ros_row(0, t0 + 5_000_000, t0, 30.2, -97.6, 150.0),
        _ros_row(1, t0 + 105_000_000, t0 + 100_000_000, 30.20001, -97.6, 150.5),
        _ros_row(2, t0 + 205_000_000, t0 + 200_000_000, 30.20002, -97.6, 151.0, status=-1),
        _ros_row(3, t0 + 305_000_000, t0 + 300_000_000, 30.20003, -97.6, "nan"),
        _ros_row(4, t0 + 405_000_000, t0 + 400_000_000, 30.20004, -97.6, 152.0),
    ]
    f = tmp_path / "fix.csv"
    f.write_text(ROS_HEADER + "\n" + "\n".join(rows) + "\n")
    (p,) = read_route_file(f)
    assert p.kind == "navsatfix" and p.n_points == 4
    # the header stamp (sensor time), not %time (recording time)
    np.testing.assert_allclose(p.time_unix_s - 1.7e9, [0.0, 0.1, 0.3, 0.4], atol=1e-6)
    np.testing.assert_array_equal(p.lat_deg, [30.2, 30.20001, 30.20003, 30.20004])
    np.testing.assert_array_equal(p.alt_missing, [False, False, True, False])
    assert p.warnings == ["skipped 1 rows without a fix (field.status.status < 0)"]
    # without field.header.stamp, %time is used
    g = tmp_path / "rec.csv"
    g.write_text(
        "%time,field.latitude,field.longitude,field.altitude\n"
        f"{t0},1.0,2.0,3\n{t0 + 10**9},1.0001,2.0,3\n"
    )
    (q,) = read_route_file(g)
    np.testing.assert_allclose(q.time_unix_s - 1.7e9, [0.0, 1.0], atol=1e-6)


@pytest.mark.parametrize(
    "token, value",
    [("30.2N", 30.2), ("097.6W", -97.6), ("S42.8", -42.8), ("147.4e", 147.4), ("12.5", 12.5)],
)
def test_hemisphere_letters(token, value):
    assert parse_degrees(token) == value


def test_hemisphere_csv_and_bad_sign(tmp_path):
    f = tmp_path / "h.csv"
    f.write_text(
        "time,lat,lon,alt\n"
        "2024-01-01T00:00:00Z,30.2000N,097.6000W,150\n"
        "2024-01-01T00:00:01Z,30.2001N,097.6000W,150\n"
    )
    (p,) = read_route_file(f)
    np.testing.assert_array_equal(p.lat_deg, [30.2, 30.2001])
    np.testing.assert_array_equal(p.lon_deg, [-97.6, -97.6])
    assert p.time_is_absolute and np.diff(p.time_unix_s)[0] == 1.0
    u16 = tmp_path / "u16.csv"
    u16.write_bytes(f.read_text().encode("utf-16"))
    (q,) = read_route_file(u16)
    np.testing.assert_array_equal(q.lon_deg, p.lon_deg)
    g = tmp_path / "bad.csv"
    g.write_text("lat,lon\n30.2N,-097.6W\n30.3N,097.6W\n")
    with pytest.raises(InputError, match="line 2: negative value with hemisphere"):
        read_route_file(g)


def test_nul_padded_fixed_width_fields(tmp_path):
    pad = lambda s, w: s.encode() + b"\x00" * (w - len(s))  # noqa: E731
    rows = [
        b",".join([pad("time", 12), pad("lat", 12), pad("lon", 12), pad("alt", 8)]),
        b",".join([pad("0", 12), pad("30.2000N", 12), pad("097.6000W", 12), pad("150.0", 8)]),
        b",".join([pad("1", 12), pad("30.2001N", 12), pad("097.6000W", 12), pad("150.5", 8)]),
    ]
    f = tmp_path / "fixed.csv"
    data = b"\n".join(rows) + b"\n"
    f.write_bytes(data)
    (p,) = read_route_file(f)
    assert p.n_points == 2 and p.lat_deg[1] == 30.2001 and p.alt_m[1] == 150.5
    assert p.warnings == [f"removed {data.count(0)} NUL bytes (NUL-padded fixed-width fields)"]
    ing = ingest(f)
    assert any("NUL" in w for w in ing.warnings)


def test_binary_file_refused_naming_gpsbabel(tmp_path):
    f = tmp_path / "blob.bin"
    f.write_bytes(bytes(range(256)) * 4)
    with pytest.raises(InputError, match="GPSBabel"):
        read_route_file(f)
