"""IGC reader: B records, GNSS altitude preferred over pressure altitude, HFDTE date."""

from __future__ import annotations

import re
from datetime import UTC, datetime

import numpy as np
import pytest

from imugen.core.errors import InputError
from imugen.ingest.readers import read_route_file
from imugen.ingest.readers.igc import read_igc
from imugen.ingest.stage import ingest


def _b(hms, lat, lon, valid="A", p=100, g=120):
    def dm(x, w):
        d = int(abs(x))
        return f"{d:0{w}d}{round((abs(x) - d) * 60000):05d}"

    return (
        f"B{hms}{dm(lat, 2)}{'N' if lat >= 0 else 'S'}{dm(lon, 3)}{'E' if lon >= 0 else 'W'}"
        f"{valid}{p:05d}{g:05d}"
    )


def test_real_glider_flight(shared_file):
    path = shared_file("g_glider_ls4_flight.igc")
    text = path.read_text(errors="replace")
    recs = re.findall(
        r"^B(\d\d)(\d\d)(\d\d)(\d\d)(\d{5})([NS])(\d{3})(\d{5})([EW])([AV])(-?\d{4,5})(\d{5})",
        text,
        re.M,
    )
    assert len(recs) == 1070
    (p,) = read_route_file(path)
    assert p.kind == "igc" and p.n_points == 1070 and p.time_is_absolute
    lat = np.array([int(r[3]) + int(r[4]) / 60000 for r in recs])
    lon = -np.array([int(r[6]) + int(r[7]) / 60000 for r in recs])  # all W
    np.testing.assert_allclose(p.lat_deg, lat, atol=1e-12)
    np.testing.assert_allclose(p.lon_deg, lon, atol=1e-12)
    gnss = np.array([float(r[11]) for r in recs])
    np.testing.assert_array_equal(p.alt_m, gnss)  # GNSS altitude, not the pressure one
    assert not np.array_equal(gnss, [float(r[10]) for r in recs])
    h, m, s = (int(x) for x in recs[0][:3])
    assert p.time_unix_s[0] == datetime(2022, 7, 16, h, m, s, tzinfo=UTC).timestamp()
    assert np.all(np.diff(p.time_unix_s) > 0)
    ing = ingest(path)
    assert ing.meta["start_time_utc"] == "2022-07-16T19:41:31Z"


def test_pressure_fallback_rollover_and_bad_records(tmp_path):
    lines = [
        "AXXX001",
        "HFDTEDATE:311223,01",
        _b("235958", 46.5, 7.25, "V", 1500, 0),
        _b("235959", 46.5001, 7.25, "V", 1502, 0),
        "B000000garbage",
        _b("000000", 46.5002, 7.25, "A", 1504, 1560),
        _b("000001", -46.5003, -7.25, "V", 1506, 0)[:-3],  # short: skipped
        _b("000002", 46.5004, 7.25, "V", 1508, 0),
    ]
    f = tmp_path / "f.igc"
    f.write_text("\r\n".join(lines) + "\r\n")
    (p,) = read_igc(f)
    assert p.n_points == 4 and not p.altitude_trusted and p.alt_missing is None
    np.testing.assert_array_equal(p.alt_m, [1500, 1502, 1504, 1508])  # pressure for all
    t0 = datetime(2023, 12, 31, 23, 59, 58, tzinfo=UTC).timestamp()
    np.testing.assert_array_equal(p.time_unix_s - t0, [0, 1, 2, 4])
    assert p.warnings == ["skipped 2 malformed IGC B records"]
    # GNSS altitude on most fixes: used, the others missing
    g = tmp_path / "g.igc"
    g.write_text(
        "\n".join(
            ["HFDTE010122"]
            + [_b(f"1200{k:02d}", 46.5 + k * 1e-4, 7.25, "A", 1500, 1550 + k) for k in range(3)]
            + [_b("120003", 46.5003, 7.25, "V", 1503, 0)]
        )
    )
    (q,) = read_igc(g)
    assert q.altitude_trusted
    np.testing.assert_array_equal(q.alt_missing, [False, False, False, True])
    np.testing.assert_array_equal(q.alt_m[:3], [1550, 1551, 1552])


def test_refusal_without_b_records(tmp_path):
    f = tmp_path / "e.igc"
    f.write_text("AXXX\nHFDTE010122\nBnonsense\n")
    with pytest.raises(InputError, match="no valid B record \\(1 malformed\\)"):
        read_route_file(f)
