"""IGC flight-log reader (FAI IGC technical specification, appendix A).

B records
    ``B HHMMSS DDMMmmm{N|S} DDDMMmmm{E|W} {A|V} PPPPP GGGGG ...``: UTC time of day, latitude and
    longitude in degrees and thousandths of minutes, fix validity (``A`` 3-D, ``V`` 2-D or no
    GNSS height), pressure altitude (ICAO standard atmosphere, m) and GNSS altitude (m above
    the WGS-84 ellipsoid). Extensions after column 35 are ignored. Malformed B records are
    skipped and counted (warning).
Heights
    GNSS altitude is preferred: it is used when at least half of the fixes have one (``A`` and
    non-zero), and fixes without it get a missing height (interpolated by ingestion). Otherwise
    the pressure altitude is used for every fix, flagged as untrusted (it is a standard
    atmosphere height, not a geometric one).
Date
    ``HFDTE`` (``HFDTEddmmyy`` or ``HFDTEDATE:ddmmyy,nn``) is the UTC date of the first fix; a
    time of day that falls back by more than 12 h is a midnight rollover. Without a date the
    clock is relative.
"""

from __future__ import annotations

from datetime import UTC, datetime
from pathlib import Path

import numpy as np

from imugen.core.errors import InputError
from imugen.ingest.readers.nmea import elapsed_from_time_of_day, parse_time_of_day
from imugen.ingest.route import RoutePath


def _date(line: str) -> float | None:
    digits = line[5:].removeprefix("DATE:").strip()[:6]
    if len(digits) != 6 or not digits.isdigit():
        return None
    yy = int(digits[4:])
    try:
        dt = datetime(2000 + yy if yy < 80 else 1900 + yy, int(digits[2:4]), int(digits[:2]))
    except ValueError:
        return None
    return dt.replace(tzinfo=UTC).timestamp()


def _b_record(line: str) -> tuple[float, float, float, bool, float, float]:
    if len(line) < 35:
        raise ValueError("short B record")
    tod = parse_time_of_day(line[1:7])
    lat_s, lon_s = line[7:14], line[15:23]
    if not (lat_s.isdigit() and lon_s.isdigit()) or line[14] not in "NS" or line[23] not in "EW":
        raise ValueError("bad position")
    lat = int(lat_s[:2]) + int(lat_s[2:]) / 60000.0
    lon = int(lon_s[:3]) + int(lon_s[3:]) / 60000.0
    if line[24] not in "AV":
        raise ValueError("bad validity")
    p_alt, g_alt = int(line[25:30]), int(line[30:35])
    return (
        tod,
        -lat if line[14] == "S" else lat,
        -lon if line[23] == "W" else lon,
        line[24] == "A",
        float(p_alt),
        float(g_alt),
    )


def read_igc(path: str | Path, data: bytes | None = None) -> list[RoutePath]:
    """Read the B records of an IGC file as one candidate path."""
    path = Path(path)
    text = (path.read_bytes() if data is None else data).decode("ascii", errors="replace")
    date = None
    recs = []
    bad = 0
    for raw in text.splitlines():
        line = raw.strip()
        if line.startswith("HFDTE") or line.startswith("HPDTE"):
            date = _date(line)
        elif line.startswith("B"):
            try:
                recs.append(_b_record(line))
            except ValueError:
                bad += 1
    if not recs:
        raise InputError(path, f"IGC file holds no valid B record ({bad} malformed)")
    tod, lat, lon, valid, p_alt, g_alt = (np.array(c) for c in zip(*recs, strict=True))
    t, rollovers = elapsed_from_time_of_day(tod.astype(float))
    notes, warnings = [], []
    has_gnss = valid.astype(bool) & (g_alt != 0)
    missing = None
    trusted = True
    if has_gnss.mean() >= 0.5:
        alt = np.where(has_gnss, g_alt, 0.0)
        if not has_gnss.all():
            missing = ~has_gnss
        notes.append("heights: GNSS altitude")
    else:
        alt = p_alt.astype(float)
        trusted = False
        notes.append("heights: pressure altitude (ICAO standard atmosphere), not trusted")
    if date is not None:
        t = t + date
    else:
        notes.append("no HFDTE date: relative clock")
    if rollovers:
        notes.append(f"{rollovers} midnight (UTC) rollover(s)")
    if bad:
        warnings.append(f"skipped {bad} malformed IGC B records")
    return [
        RoutePath(
            name=path.stem,
            kind="igc",
            lat_deg=lat.astype(float),
            lon_deg=lon.astype(float),
            alt_m=alt.astype(float),
            time_unix_s=t,
            altitude_trusted=trusted,
            time_is_absolute=date is not None,
            notes=notes,
            alt_missing=missing,
            warnings=warnings,
        )
    ]
