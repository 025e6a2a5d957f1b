"""Reader inputs that ended in a traceback or a confusing line (issue 22) now get one clear line."""

from __future__ import annotations

import shutil

import numpy as np
import pytest

from imugen.core.errors import InputError
from imugen.ingest.route import RoutePath
from imugen.ingest.stage import _clock, ingest

NAVSAT_HEADER = (
    "%time,field.header.stamp,field.status.status,field.latitude,field.longitude,field.altitude\n"
)


def _one_line_refusal(cli, tmp_path, name: str, data: bytes, needle: str) -> None:
    src = tmp_path / name
    src.write_bytes(data)
    out = tmp_path / "out" / "route.csv"
    out.parent.mkdir()
    proc = cli("ingest", src, "-o", out, check=2)
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("imugen: error: "), proc.stderr
    assert needle in lines[0], lines[0]
    assert not any(out.parent.iterdir())


def test_nmea_sentence_without_fields(cli, tmp_path):
    _one_line_refusal(cli, tmp_path, "f.nmea", b"$GPRMC", "holds no valid NMEA GGA or RMC fix")


def test_navsatfix_stamp_beyond_the_calendar(cli, tmp_path):
    rows = "".join(
        f"{k},{10**25 + 2 * k * 10**9},0,{30.2 + k * 1e-4},-97.6,150\n" for k in range(10)
    )
    data = (NAVSAT_HEADER + rows).encode()
    _one_line_refusal(cli, tmp_path, "fix.csv", data, "outside the years 1 to 9999")


def test_absolute_clock_outside_the_calendar_is_refused_by_ingestion():
    """Whatever a reader lets through: an absolute time beyond year 9999 is one line."""
    t = 1e16 + 2.0 * np.arange(5)
    p = RoutePath("p", "x", np.full(5, 40.0), np.full(5, -105.0), np.zeros(5), time_unix_s=t)
    pos = np.column_stack([np.linspace(40, 40.01, 5), np.full(5, -105.0), np.zeros(5)])
    with pytest.raises(InputError, match=r"point 1: time 1e\+16 s \(POSIX\) is outside the years"):
        _clock(p, pos, None, [], "f.x")
    p.time_is_absolute = False  # relative seconds: any span is a clock
    assert _clock(p, pos, None, [], "f.x")[0][-1] == 8.0


def test_every_part_a_single_point_after_splitting_at_gaps(tmp_path):
    """Three fixes an hour apart: no part of two points is left (was: 'holds 0 candidate
    paths; choose one with --path ...')."""
    f = tmp_path / "hourly.csv"
    f.write_text(
        "time,lat,lon\n2024-01-01T00:00:00Z,40,-105\n2024-01-01T01:00:00Z,40.01,-105\n"
        "2024-01-01T02:00:00Z,40.02,-105\n"
    )
    with pytest.raises(InputError, match="no path is left after splitting at time gaps"):
        ingest(f, gaps="split")
    assert ingest(f, gaps="bridge").meta["points_out"] >= 3


@pytest.mark.skipif(not shutil.which("gpsbabel"), reason="GPSBabel is not installed")
def test_tcx_is_converted_by_the_real_gpsbabel(tmp_path):
    """``.tcx`` names GPSBabel's ``gtrnctr`` format (it named ``gtrcrs``, which GPSBabel does
    not know: every TCX file was refused)."""
    pts = "".join(
        f"<Trackpoint><Time>2024-01-01T00:00:{k:02d}Z</Time><Position><LatitudeDegrees>"
        f"{40 + k * 1e-4}</LatitudeDegrees><LongitudeDegrees>-105</LongitudeDegrees></Position>"
        "<AltitudeMeters>1600</AltitudeMeters></Trackpoint>"
        for k in range(5)
    )
    f = tmp_path / "ride.tcx"
    f.write_text(
        '<?xml version="1.0" encoding="UTF-8"?><TrainingCenterDatabase xmlns="http://www.garmin'
        '.com/xmlschemas/TrainingCenterDatabase/v2"><Activities><Activity Sport="Biking"><Id>'
        '2024-01-01T00:00:00Z</Id><Lap StartTime="2024-01-01T00:00:00Z"><Track>'
        f"{pts}</Track></Lap></Activity></Activities></TrainingCenterDatabase>"
    )
    ing = ingest(f, vehicle="bicycle")
    assert ing.meta["points_out"] == 5 and ing.meta["timed"]
