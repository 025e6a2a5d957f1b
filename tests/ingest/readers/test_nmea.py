"""NMEA 0183 reader: checksums, GGA/RMC merging, dates, midnight rollover, decimals."""

from __future__ import annotations

import re
from datetime import UTC, datetime
from functools import reduce

import numpy as np
import pytest

from imugen.core.errors import InputError
from imugen.ingest.readers import read_route_file
from imugen.ingest.readers.nmea import read_nmea
from imugen.ingest.stage import ingest


def _sentence(body: str, good: bool = True) -> str:
    x = reduce(lambda a, c: a ^ ord(c), body, 0) ^ (0 if good else 1)
    return f"${body}*{x:02X}"


def _write(tmp_path, lines, name="log.nmea"):
    p = tmp_path / name
    p.write_text("\r\n".join(lines) + "\r\n")
    return p


def test_real_gga_only_log_rolls_over_midnight(shared_file):
    path = shared_file("g_nmea_gga_midnight_rollover.nmea")
    text = path.read_text()
    gga = re.findall(
        r"^\$GPGGA,(\d{6})\.\d+,(\d{2})(\d{2}\.\d+),N,(\d{3})(\d{2}\.\d+),E", text, re.M
    )
    assert len(gga) == 500
    (p,) = read_route_file(path)
    assert p.kind == "nmea" and p.n_points == 500 and not p.time_is_absolute
    lat = [int(d) + float(m) / 60 for _, d, m, _, _ in gga]
    lon = [int(d) + float(m) / 60 for _, _, _, d, m in gga]
    np.testing.assert_allclose(p.lat_deg, lat, atol=1e-12)
    np.testing.assert_allclose(p.lon_deg, lon, atol=1e-12)
    # 23:56:00 .. 00:04:19 at 1 Hz: continuous through midnight
    np.testing.assert_array_equal(np.diff(p.time_unix_s), np.ones(499))
    i = next(k for k, g in enumerate(gga) if g[0] == "000000")
    assert gga[i - 1][0] == "235959" and p.time_unix_s[i] == 86400.0
    assert any("1 midnight rollover" in n for n in p.notes)
    ing = ingest(path)
    assert ing.meta["duration_s"] == 499.0 and ing.meta["start_time_utc"] is None


def test_real_rmc_gga_log_with_dates_and_decimals(shared_file):
    path = shared_file("g_nmea_rmc_gga_southern.nmea")
    lines = path.read_text().splitlines()
    times = [ln.split(",")[1] for ln in lines if ln.startswith("$GPRMC")]
    good = [t for t in times if re.fullmatch(r"\s*\d{6}(\.\d*)?\s*", t)]
    assert len(times) == 19 and len(good) == 16  # 222515.x, 222523.0x and .1 are malformed
    (p,) = read_route_file(path)
    assert p.n_points == 16 and p.time_is_absolute
    start = datetime(2019, 10, 23, 22, 25, 7, tzinfo=UTC).timestamp()
    assert p.time_unix_s[0] == start
    expect = [float(t.strip()[:6][4:]) + float("0" + (t.strip()[6:] or ".")) for t in good]
    got = (p.time_unix_s - start + 7) % 60
    np.testing.assert_allclose(got, expect, atol=1e-6)
    assert np.all(p.lat_deg < -42.8) and np.all(p.lon_deg > 147.4)
    np.testing.assert_allclose(p.alt_m[0], 30.0 - 8.8)  # MSL + geoid separation
    assert p.warnings == [
        "skipped 6 NMEA sentences: 0 with a wrong checksum, 6 unparsable, 0 without a fix"
    ]


def test_checksums_fixes_and_rmc_only_epochs(tmp_path):
    lines = [
        _sentence("GPRMC,120000.00,A,4000.000,N,10500.000,W,0.0,,010224,,,A"),
        _sentence("GPGGA,120000.00,4000.000,N,10500.000,W,1,08,1.0,1600.0,M,-20.0,M,,"),
        _sentence("GPGGA,120001.00,4000.010,N,10500.000,W,1,08,1.0,1601.0,M,-20.0,M,,", False),
        _sentence("GPGGA,120002.00,4000.020,N,10500.000,W,0,00,,,M,,M,,"),  # no fix
        _sentence("GPRMC,120003.00,V,4000.030,N,10500.000,W,0.0,,010224,,,A"),  # void
        _sentence("GNRMC,120004.00,A,4000.040,N,10500.000,W,0.0,,010224,,,A"),  # RMC only
        _sentence("GNGGA,120005.00,4000.050,N,10500.000,W,2,08,1.0,1605.0,M,-20.0,M,,"),
        _sentence("GPGSV,3,1,11,03,03,111,00"),
        "$GPGGA,120006.00,4000.060,N,10500.000,W,1,08,1.0,1606.0,M,-20.0,M,,",  # no checksum
    ]
    (p,) = read_nmea(_write(tmp_path, lines))
    assert p.n_points == 4
    t0 = datetime(2024, 2, 1, 12, tzinfo=UTC).timestamp()
    np.testing.assert_array_equal(p.time_unix_s - t0, [0, 4, 5, 6])
    np.testing.assert_allclose(p.lat_deg, 40 + np.array([0, 0.04, 0.05, 0.06]) / 60)
    np.testing.assert_allclose(p.lon_deg, -105.0)
    np.testing.assert_array_equal(p.alt_missing, [False, True, False, False])
    np.testing.assert_allclose(p.alt_m[[0, 2, 3]], [1580.0, 1585.0, 1586.0])
    assert "1 with a wrong checksum, 0 unparsable, 2 without a fix" in p.warnings[0]


def test_refusal_without_fixes(tmp_path):
    with pytest.raises(InputError, match=r"no valid NMEA GGA or RMC fix.*1 bad checksums"):
        read_nmea(_write(tmp_path, [_sentence("GPGGA,1,2", False)]))


def test_dated_log_across_midnight_and_new_year(tmp_path):
    lines = []
    for tod, date in (("235958.5", "311223"), ("235959.5", "311223"), ("000000.5", "010124")):
        lines.append(_sentence(f"GPRMC,{tod},A,4000.000,N,10500.000,W,0.0,,{date},,,A"))
        lines.append(_sentence(f"GPGGA,{tod},4000.000,N,10500.000,W,1,08,1.0,1600.0,M,0,M,,"))
    (p,) = read_nmea(_write(tmp_path, lines))
    t0 = datetime(2023, 12, 31, 23, 59, 58, 500000, tzinfo=UTC).timestamp()
    np.testing.assert_array_equal(p.time_unix_s - t0, [0.0, 1.0, 2.0])
