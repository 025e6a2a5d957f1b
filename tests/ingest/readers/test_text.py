import numpy as np
import pytest

from imugen.core.errors import InputError
from imugen.ingest.readers import read_route_file
from imugen.ingest.readers.text import read_text


def _w(tmp_path, text, name="r.csv", encoding="utf-8"):
    p = tmp_path / name
    p.write_bytes(text.encode(encoding) if isinstance(text, str) else text)
    return p


@pytest.mark.parametrize(
    "text",
    [
        "lat,lon,alt\n31.63,-7.99,450\n31.631,-7.991,451\n",
        "Latitude;Longitude;Elevation\n31.63;-7.99;450\n31.631;-7.991;451\n",
        "lat_deg\tlon_deg\talt_m\n31.63\t-7.99\t450\n31.631\t-7.991\t451\n",
        "\ufefflatitude (deg),longitude [deg],height (m)\n31.63,-7.99,450\n31.631,-7.991,451\n",
    ],
)
def test_csv_header_variants(tmp_path, text):
    (p,) = read_text(_w(tmp_path, text))
    np.testing.assert_allclose(p.lat_deg, [31.63, 31.631])
    np.testing.assert_allclose(p.lon_deg, [-7.99, -7.991])
    np.testing.assert_allclose(p.alt_m, [450, 451])
    assert p.time_unix_s is None and p.kind == "csv"


def test_csv_times_iso_and_seconds(tmp_path):
    (p,) = read_text(
        _w(tmp_path, "time,lat,lon\n2024-01-01T00:00:00Z,1,2\n2024-01-01T00:00:02.5Z,1.001,2\n")
    )
    np.testing.assert_allclose(np.diff(p.time_unix_s), [2.5])
    assert p.time_is_absolute and not p.altitude_trusted
    (q,) = read_text(_w(tmp_path, "t,lat,lon,alt\n0,1,2,3\n0.5,1.001,2,3\n", "s.csv"))
    np.testing.assert_allclose(q.time_unix_s, [0, 0.5])
    assert not q.time_is_absolute


def test_enu_rows_tabs_double_tabs(tmp_path):
    text = "345474.2\t9119349.1\t480.6\n345475.0\t\t9119350.0\t480.7\n  345476.0 9119351.0 480.8 \n"
    (p,) = read_text(_w(tmp_path, text, "e.txt"))
    assert p.kind == "enu" and p.time_unix_s is None
    np.testing.assert_allclose(p.enu_m[1], [345475.0, 9119350.0, 480.7])


def test_enu_rows_with_time(tmp_path):
    (p,) = read_text(_w(tmp_path, "0 1 2 3\n1 2 3 4\n", "e.txt"))
    np.testing.assert_allclose(p.time_unix_s, [0, 1])
    np.testing.assert_allclose(p.enu_m[:, 0], [1, 2])


@pytest.mark.parametrize(
    "text, message",
    [
        ("1 2\n3 4\n", "expected 3 numeric columns"),
        ("1 2 3\n4 5 6 7\n", "4 columns where the file has 3"),
        ("1 2 3\n4 x 6\n", "not a number"),
        ("name,value\na,1\n", "no latitude/longitude"),
        ("lat,lon\n1,2,3\n", "3 fields where the header has 2"),
        ("lat,lon\n1,north\n", "'north' is not a number"),
        ("lat,lon,time\n1,2,noon\n1,2.1,later\n", "neither ISO-8601 nor seconds"),
        ("lat,lon,latitude\n1,2,3\n", "twice"),
        ("# only a comment\n\n", "no data rows"),
        ("lat,lon\n", "no data rows"),
    ],
)
def test_text_refusals(tmp_path, text, message):
    with pytest.raises(InputError, match=message):
        read_text(_w(tmp_path, text))


def test_wrong_encoding_and_nul(tmp_path):
    with pytest.raises(InputError, match="not UTF-8"):
        read_text(_w(tmp_path, "lat,lon,name\n1,2,Sa\xefd\n".encode("latin-1")))
    (p,) = read_route_file(_w(tmp_path, b"lat,lon\n1,2\x00\n", "n.csv"))  # NUL padding
    assert p.lon_deg[0] == 2.0 and p.warnings == [
        "removed 1 NUL bytes (NUL-padded fixed-width fields)"
    ]


def test_dispatch_by_content(tmp_path):
    gpx = _w(
        tmp_path,
        '<gpx><rte><rtept lat="1" lon="2"/><rtept lat="1.1" lon="2"/></rte></gpx>',
        "x.dat",
    )
    assert read_route_file(gpx)[0].kind == "rte"
    with pytest.raises(InputError, match="neither KML"):
        read_route_file(_w(tmp_path, "<html></html>", "y.xml"))
    with pytest.raises(InputError, match="no such file"):
        read_route_file(tmp_path / "missing.kml")
    with pytest.raises(InputError, match="is empty"):
        read_route_file(_w(tmp_path, "", "z.csv"))


def test_real_paper_file(shared_file):
    f = shared_file("seed_reference_trajectory_enu.txt")
    rows = [ln.split() for ln in f.read_text().splitlines() if ln.strip()]
    (p,) = read_text(f)
    assert p.n_points == len(rows) == 620
    np.testing.assert_allclose(p.enu_m[0], [float(x) for x in rows[0]])
    np.testing.assert_allclose(p.enu_m[-1], [float(x) for x in rows[-1]])


def test_strict_numbers():
    from imugen.ingest.route import parse_number

    assert parse_number("+008.5") == 8.5 and parse_number(" -1e-3 ") == -1e-3
    assert parse_number(".5") == 0.5 and parse_number("7.") == 7.0
    for bad in ("1_000", "0x10", "", "1,5", "--1", "nan", "-inf", "1e999", "\u0661", "1e"):
        with pytest.raises(ValueError):
            parse_number(bad)


def test_utf16_kml_with_bom(tmp_path):
    kml = (
        '<?xml version="1.0" encoding="UTF-16"?><kml xmlns="http://www.opengis.net/kml/2.2">'
        "<Placemark><name>Ünïcode</name><LineString><altitudeMode>absolute</altitudeMode>"
        "<coordinates>2,1,10 2.001,1,11</coordinates></LineString></Placemark></kml>"
    )
    f = tmp_path / "u16.kml"
    f.write_bytes(kml.encode("utf-16"))
    (p,) = read_route_file(f)
    assert p.name == "Ünïcode" and p.n_points == 2
