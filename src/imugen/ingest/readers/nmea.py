"""NMEA 0183 reader: GGA and RMC sentences of any talker (GP, GN, GL, GA, BD, ...).

Sentences
    ``$--GGA`` gives time of day, latitude, longitude, fix quality and height; ``$--RMC`` gives
    time of day, status, latitude, longitude and the date. Sentences with the same time of day
    that follow each other are one epoch (GGA position preferred, RMC date). Other sentence
    types are ignored (counted in a note).
Checksum
    ``*HH`` (XOR of the characters between ``$`` and ``*``) is verified; a sentence whose
    checksum is wrong, whose fields cannot be parsed (time ``222515.x``, empty position) or
    that has no fix (GGA quality 0, RMC status ``V``) is skipped and counted (warning).
Times
    ``hhmmss`` with any number of decimals (``.00``, ``.0``, ``.``, none). The date comes from
    RMC; GGA-only logs have no date: their clock is relative (seconds from the first fix). A
    time of day that falls back by more than 12 h is a midnight rollover (+1 day).
Heights
    GGA height above mean sea level plus the geoid separation (field 11) = height above the
    WGS-84 ellipsoid. An epoch with RMC only has no height (interpolated by ingestion).
"""

from __future__ import annotations

from datetime import UTC, datetime
from pathlib import Path

import numpy as np

from imugen.core.errors import InputError
from imugen.ingest.route import RoutePath

_DAY_S = 86400.0


def checksum_ok(body: str, given: str) -> bool:
    """True when ``given`` (two hex digits) is the XOR of the characters of ``body``."""
    x = 0
    for ch in body:
        x ^= ord(ch)
    try:
        return int(given, 16) == x and len(given) == 2
    except ValueError:
        return False


def parse_time_of_day(field: str) -> float:
    """``hhmmss[.fff]`` -> seconds of the day; ValueError when malformed or out of range."""
    s = field.strip()
    head, _, frac = s.partition(".")
    if len(head) != 6 or not head.isdigit() or (frac and not frac.isdigit()):
        raise ValueError(f"bad time of day {field!r}")
    hh, mm, ss = int(head[:2]), int(head[2:4]), int(head[4:])
    if hh > 23 or mm > 59 or ss > 60:
        raise ValueError(f"time of day out of range {field!r}")
    return hh * 3600.0 + mm * 60.0 + ss + (float("0." + frac) if frac else 0.0)


def _angle(value: str, hemi: str, deg_digits: int, pos: str, neg: str) -> float:
    v = value.strip()
    head = v.partition(".")[0]
    if len(head) != deg_digits + 2 or not head.isdigit() or not v.replace(".", "", 1).isdigit():
        raise ValueError(f"bad angle {value!r}")
    deg = int(v[:deg_digits]) + float(v[deg_digits:]) / 60.0
    h = hemi.strip().upper()
    if h == neg:
        return -deg
    if h != pos:
        raise ValueError(f"bad hemisphere {hemi!r}")
    return deg


def elapsed_from_time_of_day(tod: np.ndarray) -> tuple[np.ndarray, int]:
    """Seconds of day -> continuous seconds, adding a day where the clock falls back > 12 h.

    Returns the continuous times (shape (n,)) and the number of rollovers.
    """
    back = np.diff(tod) < -_DAY_S / 2
    days = np.concatenate([[0], np.cumsum(back)])
    return tod + _DAY_S * days, int(back.sum())


def _date_unix(field: str) -> float:
    s = field.strip()
    if len(s) != 6 or not s.isdigit():
        raise ValueError(f"bad date {field!r}")
    yy = int(s[4:])
    dt = datetime(1900 + yy if yy >= 80 else 2000 + yy, int(s[2:4]), int(s[:2]), tzinfo=UTC)
    return dt.timestamp()


def read_nmea(path: str | Path, data: bytes | None = None) -> list[RoutePath]:
    """Read the GGA/RMC fixes of an NMEA 0183 log as one candidate path."""
    path = Path(path)
    text = (path.read_bytes() if data is None else data).decode("ascii", errors="replace")
    bad_sum = unparsable = no_fix = other = 0
    epochs: list[dict] = []
    for raw in text.splitlines():
        line = raw.strip()
        if not line.startswith("$"):
            continue
        body, star, given = line[1:].partition("*")
        if star and not checksum_ok(body, given.strip()):
            bad_sum += 1
            continue
        f = body.split(",")
        kind = f[0][2:] if len(f[0]) == 5 else ""
        if kind not in ("GGA", "RMC"):
            other += 1
            continue
        try:
            tod = parse_time_of_day(f[1])
            if kind == "GGA":
                if len(f) < 12:
                    raise ValueError("short GGA")
                if f[6].strip() in ("", "0"):
                    no_fix += 1
                    continue
                lat = _angle(f[2], f[3], 2, "N", "S")
                lon = _angle(f[4], f[5], 3, "E", "W")
                alt = float(f[9]) + (float(f[11]) if f[11].strip() else 0.0) if f[9] else None
                rec = {"lat": lat, "lon": lon, "alt": alt}
            else:
                if len(f) < 10:
                    raise ValueError("short RMC")
                if f[2].strip().upper() != "A":
                    no_fix += 1
                    continue
                rec = {
                    "rlat": _angle(f[3], f[4], 2, "N", "S"),
                    "rlon": _angle(f[5], f[6], 3, "E", "W"),
                    "date": _date_unix(f[9]),
                }
        except (ValueError, IndexError):  # IndexError: a sentence without its fields
            unparsable += 1
            continue
        last = epochs[-1] if epochs else None
        if last is not None and last["tod"] == tod and kind not in last["kinds"]:
            last.update(rec)
            last["kinds"].add(kind)
        else:
            epochs.append({"tod": tod, "kinds": {kind}, **rec})
    if not epochs:
        raise InputError(
            path,
            f"holds no valid NMEA GGA or RMC fix ({bad_sum} bad checksums, {unparsable} "
            f"unparsable, {no_fix} without a fix, {other} other sentences)",
        )
    lat = np.array([e.get("lat", e.get("rlat")) for e in epochs], dtype=float)
    lon = np.array([e.get("lon", e.get("rlon")) for e in epochs], dtype=float)
    alt_raw = [e.get("alt") for e in epochs]
    missing = np.array([a is None for a in alt_raw])
    alt = np.array([0.0 if a is None else a for a in alt_raw])
    t, rollovers = elapsed_from_time_of_day(np.array([e["tod"] for e in epochs]))
    dated = [i for i, e in enumerate(epochs) if "date" in e]
    notes, warnings = [], []
    if dated:
        i = dated[0]
        t = t + (epochs[i]["date"] + epochs[i]["tod"] - t[i])
    else:
        notes.append(
            "no RMC date: times are seconds of day (relative clock)"
            + (f", {rollovers} midnight rollover(s)" if rollovers else "")
        )
    skipped = bad_sum + unparsable + no_fix
    if skipped:
        warnings.append(
            f"skipped {skipped} NMEA sentences: {bad_sum} with a wrong checksum, {unparsable} "
            f"unparsable, {no_fix} without a fix"
        )
    if other:
        notes.append(f"ignored {other} sentences other than GGA/RMC")
    trusted = not missing.all()
    if missing.all():
        notes.append("no GGA height: heights set to 0 m")
    return [
        RoutePath(
            name=path.stem,
            kind="nmea",
            lat_deg=lat,
            lon_deg=lon,
            alt_m=alt,
            time_unix_s=t,
            altitude_trusted=trusted,
            time_is_absolute=bool(dated),
            notes=notes,
            alt_missing=missing if missing.any() and not missing.all() else None,
            warnings=warnings,
        )
    ]
