"""Dashcam GPS logs: the 70mai ``GPSData*.txt`` (format as GPSBabel's reference sample and
public converters document it).

A ``$V02`` line (``$V`` and a version) starts each recording session, also mid-file; then one
row per second without a header: ``epoch_s,A|V,lat,lon,heading*100,speed*100,ax,ay,az,
video.MP4,0,0,0``. ``A`` is a fix, ``V`` (or ``0.000000,0.000000``) none; the same epoch may
repeat (one row per video frame group). No heights: 0 m, untrusted. The epoch is the camera's
clock (set by the phone app; converters read it as local wall time): the times are kept as
written, relative seconds are exact.

Rows without a fix and repeated epochs are dropped with one warning. Consecutive sessions
that continue each other (the next starts within :data:`JOIN_GAP_S` of the previous end, at a
speed below :data:`JOIN_SPEED_MPS`) are joined into one path (a note says so); otherwise each
session is a candidate path (``session k``).
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
from pyproj import Geod

from imugen.core.errors import InputError
from imugen.ingest.route import RoutePath, parse_number

JOIN_GAP_S = 60.0
"""Longest pause between sessions joined into one path (s)."""
JOIN_SPEED_MPS = 70.0
"""Fastest straight-line speed across a pause between sessions joined into one path (m/s)."""
_ROW = re.compile(r"^\s*\d+\s*,\s*[AV]\s*,\s*-?[\d.]+\s*,\s*-?[\d.]+\s*,")
_GEOD = Geod(ellps="WGS84")


def claims(text_head: str) -> bool:
    """True when a file starts with a ``$V0`` session line followed by a 70mai row."""
    lines = [ln.strip() for ln in text_head.splitlines() if ln.strip()]
    return len(lines) >= 2 and lines[0].startswith("$V0") and bool(_ROW.match(lines[1]))


def read_70mai(path: str | Path, data: bytes) -> list[RoutePath]:
    """Read a 70mai dashcam GPS log: one path per run of continuing sessions."""
    path = Path(path)
    try:
        text = data.decode("utf-8-sig")
    except UnicodeDecodeError:
        raise InputError(path, "is a 70mai dashcam log but not UTF-8 text") from None
    sessions: list[list[tuple[float, float, float]]] = []
    no_fix = repeated = 0
    for lineno, line in enumerate(text.splitlines(), start=1):
        s = line.strip()
        if not s:
            continue
        if s.startswith("$V"):
            sessions.append([])
            continue
        cells = [c.strip() for c in s.split(",")]
        if len(cells) < 4:
            raise InputError(path, f"line {lineno}: {len(cells)} fields, a 70mai row has 13")
        if not sessions:
            sessions.append([])
        try:
            t, lat, lon = parse_number(cells[0]), parse_number(cells[2]), parse_number(cells[3])
        except ValueError as exc:
            raise InputError(path, f"line {lineno}: {exc}") from None
        if cells[1] != "A" or (lat == 0.0 and lon == 0.0):
            no_fix += 1
            continue
        if not (-90.0 <= lat <= 90.0 and -180.0 <= lon <= 180.0):
            raise InputError(path, f"line {lineno}: latitude/longitude {lat}, {lon} out of range")
        cur = sessions[-1]
        if cur and t <= cur[-1][0]:
            repeated += 1
            continue
        cur.append((t, lat, lon))
    sessions = [np.array(x) for x in sessions if x]
    if not sessions:
        raise InputError(path, "has no data row with a fix (70mai rows with status A)")
    runs = [[sessions[0]]]
    for sess in sessions[1:]:
        prev = runs[-1][-1]
        gap = sess[0, 0] - prev[-1, 0]
        _, _, d = _GEOD.inv(prev[-1, 2], prev[-1, 1], sess[0, 2], sess[0, 1])
        if 0.0 < gap <= JOIN_GAP_S and d <= JOIN_SPEED_MPS * gap:
            runs[-1].append(sess)
        else:
            runs.append([sess])
    warnings = []
    if no_fix or repeated:
        warnings.append(
            f"skipped {no_fix} rows without a fix (status V or 0,0) and {repeated} rows "
            "repeating an epoch"
        )
    out = []
    k = 0
    for run in runs:
        a = np.concatenate(run)
        first = k + 1
        k += len(run)
        name = f"session {first}" if len(run) == 1 else f"sessions {first}-{k}"
        notes = [
            "70mai dashcam log: no heights (0 m, untrusted); times are the camera clock's "
            "epoch seconds (its time zone as set in the app)"
        ]
        if len(run) > 1:
            notes.append(f"joined {len(run)} recording sessions that continue each other")
        out.append(
            RoutePath(
                name=name if len(runs) > 1 else path.stem,
                kind="70mai",
                lat_deg=a[:, 1],
                lon_deg=a[:, 2],
                alt_m=np.zeros(len(a)),
                time_unix_s=a[:, 0].astype(float),
                altitude_trusted=False,
                time_is_absolute=True,
                notes=notes,
                warnings=list(warnings),
            )
        )
    return out
