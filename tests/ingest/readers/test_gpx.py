import re
from datetime import datetime

import numpy as np
import pytest

from imugen.core.errors import InputError
from imugen.ingest.readers.gpx import read_gpx

GPX11 = """<?xml version="1.0" encoding="UTF-8"?>
<gpx version="1.1" creator="test" xmlns="http://www.topografix.com/GPX/1/1">
  <wpt lat="1" lon="2"><name>not a path</name></wpt>
  <trk><name>Drive</name>
    <trkseg>
      <trkpt lat="31.6300" lon="-7.9900"><ele>450.5</ele><time>2024-05-01T10:00:00Z</time></trkpt>
      <trkpt lat="+031.6301" lon="-7.9899"><ele>451</ele><time>2024-05-01T10:00:01.5Z</time></trkpt>
    </trkseg>
    <trkseg>
      <trkpt lat="31.6302" lon="-7.9898"><time>2024-05-01T12:00:03+02:00</time></trkpt>
      <trkpt lat="31.6303" lon="-7.9897"><time>2024-05-01T12:00:04+02:00</time></trkpt>
    </trkseg>
  </trk>
  <rte><rtept lat="10" lon="20"/><rtept lat="10.001" lon="20.001"/></rte>
</gpx>"""

GPX10 = """<?xml version="1.0"?>
<gpx version="1.0" xmlns="http://www.topografix.com/GPX/1/0">
<trk><trkseg><trkpt lat="1.0" lon="2.0"><ele>5</ele></trkpt><trkpt lat="1.001" lon="2.0"><ele>6</ele></trkpt></trkseg></trk>
</gpx>"""


def _write(tmp_path, text, name="t.gpx"):
    p = tmp_path / name
    p.write_text(text, encoding="utf-8")
    return p


def test_gpx11_segments_routes_and_times(tmp_path):
    paths = read_gpx(_write(tmp_path, GPX11))
    assert [p.name for p in paths] == ["Drive / segment 1", "Drive / segment 2", "route 1"]
    seg1, seg2, rte = paths
    assert seg1.kind == "trkseg" and rte.kind == "rte"
    np.testing.assert_allclose(seg1.lat_deg, [31.63, 31.6301])
    np.testing.assert_allclose(seg1.alt_m, [450.5, 451.0])
    assert seg1.altitude_trusted
    np.testing.assert_allclose(np.diff(seg1.time_unix_s), [1.5])
    # +02:00 offset: 12:00:03+02:00 is 10:00:03Z, i.e. 3 s after the first point
    assert seg2.time_unix_s[0] - seg1.time_unix_s[0] == pytest.approx(3.0)
    assert not seg2.altitude_trusted and seg2.notes
    assert rte.time_unix_s is None


def test_gpx10(tmp_path):
    (p,) = read_gpx(_write(tmp_path, GPX10))
    assert p.n_points == 2 and p.time_unix_s is None and p.name == "track 1"


@pytest.mark.parametrize(
    "text, message",
    [
        ('<gpx><wpt lat="1" lon="2"/></gpx>', "no track or route"),
        ('<gpx><trk><trkseg><trkpt lat="x" lon="2"/></trkseg></trk></gpx>', "not numbers"),
        (
            '<gpx><trk><trkseg><trkpt lat="1" lon="2"><ele>high</ele></trkpt></trkseg></trk></gpx>',
            "<ele>",
        ),
        (
            '<gpx><trk><trkseg><trkpt lat="1" lon="2"><time>yesterday</time></trkpt></trkseg></trk></gpx>',
            "ISO-8601",
        ),
        ("<kml/>", "not GPX"),
        ("<gpx><trk>", "well-formed"),
    ],
)
def test_gpx_refusals(tmp_path, text, message):
    with pytest.raises(InputError, match=message) as exc:
        read_gpx(_write(tmp_path, text))
    assert "t.gpx" in str(exc.value) and "\n" not in str(exc.value)


def test_gpx_xxe_refused(tmp_path):
    secret = tmp_path / "secret.txt"
    secret.write_text("TOPSECRET")
    text = (
        f'<?xml version="1.0"?><!DOCTYPE gpx [<!ENTITY x SYSTEM "file://{secret}">]>'
        '<gpx><trk><name>&x;</name><trkseg><trkpt lat="1" lon="2"/><trkpt lat="1.1" lon="2"/>'
        "</trkseg></trk></gpx>"
    )
    with pytest.raises(InputError, match="DOCTYPE") as exc:
        read_gpx(_write(tmp_path, text))
    assert "TOPSECRET" not in str(exc.value)


def _iso(s):
    return datetime.fromisoformat(s).timestamp()


def test_real_central_park(shared_file):
    f = shared_file("e_cycling_central_park_1hz.gpx")
    raw = f.read_text()
    n = len(re.findall(r"<trkpt\b", raw))
    times = re.findall(r"<trkpt[^>]*>.*?<time>([^<]+)</time>", raw, flags=re.S)
    (p,) = read_gpx(f)
    assert p.n_points == n == 1812
    span = p.time_unix_s[-1] - p.time_unix_s[0]
    assert span == pytest.approx(_iso(times[-1]) - _iso(times[0]))


def test_real_colorado_two_segments(shared_file):
    f = shared_file("e_car_colorado_mountain_pass.gpx")
    raw = f.read_text()
    seg_counts = [len(re.findall(r"<trkpt\b", s)) for s in raw.split("<trkseg>")[1:]]
    paths = read_gpx(f)
    assert [p.n_points for p in paths] == seg_counts
    assert len(paths) == 2
    alt = paths[0].alt_m
    assert 2800 < alt.mean() < 3300


def test_real_identical_timestamps_read(shared_file):
    (p,) = read_gpx(shared_file("f_hike_identical_1901_timestamps.gpx"))
    assert p.time_unix_s is not None and np.ptp(p.time_unix_s) < 1e-3
