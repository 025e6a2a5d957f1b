"""CSV written by GNSS loggers and robot middleware, which the plain CSV reader refuses.

It reads the three dialects below (any mix of them); every other CSV goes to
:mod:`imugen.ingest.readers.text`. One header row (comma, semicolon, TAB or spaces), ``#`` comments.

ROS ``sensor_msgs/NavSatFix`` dumps (``rostopic echo -p``, ``rosbag`` to CSV)
    Columns ``field.latitude``, ``field.longitude``, ``field.altitude`` (height above the
    WGS-84 ellipsoid); time from ``field.header.stamp`` (nanoseconds, the sensor time), else
    ``%time`` (nanoseconds, the recording time). Rows with ``field.status.status`` below 0 (no
    fix) are skipped and counted; NaN fields (no height) are missing heights. When *every* row
    says -1 (``STATUS_NO_FIX``, the default of drivers that never set it) but every position
    and covariance is finite, the rows are read as fixes with one warning
    (``navsatfix_status="strict"``, ``imugen ingest --navsatfix-status=strict``, refuses them).
Hemisphere letters
    ``30.2N``, ``097.6W``, ``S42.8``: decimal degrees with a hemisphere letter before or after,
    ``S`` and ``W`` negative.
NUL-padded fixed-width fields
    Loggers that pre-allocate fixed-width records pad fields with NUL bytes. NULs are removed
    (a warning gives their count); a file that is not text once they are removed (a binary
    format) is refused, naming GPSBabel. The Columbus/Visiontac V-900/V-990 loggers write such
    files: header ``INDEX,TAG,DATE,TIME,LATITUDE N/S,LONGITUDE E/W,HEIGHT,...`` (the V-1000:
    ``LATITUDEN/S``; some firmware ``LATITUDE N``), DATE ``yymmdd`` and TIME ``hhmmss`` in UTC.
Header names
    A hemisphere suffix of the latitude/longitude names (``LATITUDE N/S``, ``Longitude E``,
    ``LATITUDEN/S``) is dropped; names are matched without case. Separate ``date`` (``yymmdd``,
    ``yyyymmdd`` or ISO) and ``time`` (``hhmmss`` or ``hh:mm:ss``) columns are one UTC time.
Other columns follow the plain CSV names: ``lat``/``latitude``, ``lon``/``lng``/``longitude``,
``alt``/``altitude``/``height``/``ele``, ``time``/``timestamp`` (ISO-8601 or seconds).
"""

from __future__ import annotations

import datetime as _dt
import re
from pathlib import Path

import numpy as np

from imugen.core.errors import InputError
from imugen.ingest.route import TIME_RANGE_S, RoutePath, parse_iso_time, parse_number

_LAT = ("field.latitude", "latitude", "lat", "lat_deg")
_LON = ("field.longitude", "longitude", "lon", "lng", "long", "lon_deg")
_ALT = ("field.altitude", "altitude", "alt", "alt_m", "height", "ele", "elevation", "h")
_TIME_NS = ("field.header.stamp", "%time")
_TIME = ("time", "timestamp", "time_s", "datetime", "utc", "t")
_STATUS = "field.status.status"
_COV = "field.position_covariance"
NAVSATFIX_STATUS = ("lenient", "strict")
"""What to do with a NavSatFix dump whose every row has status -1 (module docstring)."""
_HEMI = {"N": 1.0, "E": 1.0, "S": -1.0, "W": -1.0}
_CONTROL = bytes(c for c in range(32) if c not in (9, 10, 13)) + b"\x7f"
_BABEL_HINT = (
    "a binary file: imugen reads it through GPSBabel when `gpsbabel` is installed and the file "
    "name ends in a suffix it knows (.fit, .tcx, .gdb, ...); or convert it to GPX: "
    "gpsbabel -i FORMAT -f FILE -o gpx -F FILE.gpx"
)


def _split(line: str, delim: str | None) -> list[str]:
    return [c.strip().strip('"').strip() for c in (line.split(delim) if delim else line.split())]


def _delimiter(line: str) -> str | None:
    for d in (",", ";", "\t"):
        if d in line:
            return d
    return None


def parse_degrees(token: str) -> float:
    """Decimal degrees with an optional hemisphere letter: ``097.6W`` -> -97.6."""
    s = token.strip()
    sign = 1.0
    if s and s[-1].upper() in _HEMI:
        sign, s = _HEMI[s[-1].upper()], s[:-1]
    elif s and s[0].upper() in _HEMI:
        sign, s = _HEMI[s[0].upper()], s[1:]
    value = parse_number(s)
    if sign < 0 and value < 0:
        raise ValueError(f"negative value with hemisphere S/W: {token!r}")
    return sign * value


def norm_header(name: str) -> str:
    """A header name, lower case, with a latitude/longitude hemisphere suffix dropped:
    ``LATITUDE N/S``, ``LATITUDEN/S``, ``Latitude N`` -> ``latitude``."""
    s = name.strip().lower()
    if re.match(r"^(lat|latitude|lon|lng|long|longitude)\b|^(latitude|longitude)", s):
        s = re.sub(r"(?:[\s_]+(?:n/s|e/w|n|s|e|w)|(?:n/s|e/w))$", "", s)
    return s


def _header(text: str) -> tuple[list[str], str | None]:
    for line in text.splitlines():
        s = line.strip()
        if s and not s.startswith("#"):
            d = _delimiter(s)
            return [norm_header(h) for h in _split(s, d)], d
    return [], None


def claims(head: bytes) -> bool:
    """True when the start of a text file is a dialect this module reads (see module doc)."""
    try:
        text = head.decode("utf-8-sig", errors="replace")
    except LookupError:  # pragma: no cover - utf-8 always exists
        return False
    names, delim = _header(text)
    if "field.latitude" in names:
        return True
    ilat = next((names.index(a) for a in _LAT if a in names), None)
    if ilat is None:
        return False
    rows = [r.strip() for r in text.splitlines() if r.strip() and not r.strip().startswith("#")]
    for row in rows[1:3]:
        cells = _split(row, delim)
        if ilat < len(cells) and _lettered(cells[ilat]):
            return True
    return False


def _lettered(cell: str) -> bool:
    for letter, rest in ((cell[-1:], cell[:-1]), (cell[:1], cell[1:])):
        if letter.upper() in _HEMI:
            try:
                parse_number(rest)
            except ValueError:
                continue
            return True
    return False


def _col(names: list[str], aliases: tuple[str, ...]) -> int | None:
    for a in aliases:
        if a in names:
            return names.index(a)
    return None


def read_gnss_csv(
    path: str | Path, data: bytes | None = None, navsatfix_status: str = "lenient"
) -> list[RoutePath]:
    """Read a NavSatFix dump, hemisphere-lettered or NUL-padded CSV as one candidate path
    (``navsatfix_status``: :data:`NAVSATFIX_STATUS`, module docstring)."""
    if navsatfix_status not in NAVSATFIX_STATUS:
        raise InputError("--navsatfix-status", f"must be one of {', '.join(NAVSATFIX_STATUS)}")
    path = Path(path)
    data = path.read_bytes() if data is None else data
    warnings: list[str] = []
    if data.startswith((b"\xff\xfe", b"\xfe\xff")):  # UTF-16 with a byte-order mark
        try:
            data = data.decode("utf-16").encode("utf-8")
        except UnicodeDecodeError:
            raise InputError(path, "is not valid UTF-16 text") from None
    n_nul = data.count(b"\x00")
    if n_nul:
        data = data.replace(b"\x00", b"")
    try:
        text = data.decode("utf-8-sig")
    except UnicodeDecodeError:
        raise InputError(path, f"contains NUL bytes and is not text: {_BABEL_HINT}") from None
    if n_nul:
        n_ctrl = len(data) - len(data.translate(None, _CONTROL))
        if n_ctrl > 0.01 * max(len(data), 1):
            raise InputError(path, f"contains NUL bytes and control characters: {_BABEL_HINT}")
        warnings.append(f"removed {n_nul} NUL bytes (NUL-padded fixed-width fields)")
    names, delim = _header(text)
    ilat, ilon = _col(names, _LAT), _col(names, _LON)
    if (ilat is None or ilon is None) and n_nul:
        raise InputError(
            path, f"contains NUL bytes and no CSV header naming latitude/longitude: {_BABEL_HINT}"
        )
    if ilat is None or ilon is None:
        raise InputError(
            path,
            f"header names no latitude/longitude column (found {', '.join(names[:12])})",
        )
    ialt, its_ns, its = _col(names, _ALT), _col(names, _TIME_NS), _col(names, _TIME)
    idate = names.index("date") if "date" in names and its is not None else None
    ist = names.index(_STATUS) if _STATUS in names else None
    rows = [
        (k, r.strip())
        for k, r in enumerate(text.splitlines(), start=1)
        if r.strip() and not r.strip().startswith("#")
    ][1:]
    read_no_fix = ist is not None and _all_no_fix(rows, names, delim, ist, ilat, ilon)
    if read_no_fix and navsatfix_status == "strict":
        raise InputError(
            path,
            f"has no data row with a fix: every one of the {len(rows)} rows has "
            "field.status.status = -1 (--navsatfix-status=lenient reads their finite positions)",
        )
    if read_no_fix:
        warnings.append(
            f"every one of the {len(rows)} rows has field.status.status = -1 (STATUS_NO_FIX) but "
            "finite positions and covariances: read as fixes (a driver that never sets the "
            "status); --navsatfix-status=strict refuses such files"
        )
    lat, lon, alt, t = [], [], [], []
    no_fix = 0
    for lineno, row in rows:
        cells = _split(row, delim)
        if len(cells) != len(names):
            raise InputError(
                path, f"line {lineno}: {len(cells)} fields where the header has {len(names)}"
            )
        try:
            if not read_no_fix and ist is not None and cells[ist] and parse_number(cells[ist]) < 0:
                no_fix += 1
                continue
            lat.append(parse_degrees(cells[ilat]))
            lon.append(parse_degrees(cells[ilon]))
            a = cells[ialt] if ialt is not None else ""
            # ROS writes an unknown altitude as NaN: a missing height, not a bad number
            alt.append(
                parse_number(a) if a and a.strip().lower() not in ("nan", "-nan") else np.nan
            )
            if its_ns is not None:
                t.append(_stamp_s(cells[its_ns]))
            elif idate is not None:
                t.append(_date_time_s(cells[idate], cells[its]))
            elif its is not None:
                tok = cells[its]
                try:
                    t.append(parse_number(tok))
                except ValueError:
                    t.append(parse_iso_time(tok))
        except (ValueError, OverflowError) as exc:
            raise InputError(path, f"line {lineno}: {exc}") from None
    if no_fix:
        warnings.append(f"skipped {no_fix} rows without a fix (field.status.status < 0)")
    if not lat:
        raise InputError(path, "has no data row with a fix")
    alt_a = np.asarray(alt, dtype=float)
    missing = ~np.isfinite(alt_a)
    notes = []
    if missing.all():
        notes.append("no height: heights set to 0 m")
    absolute = (
        its_ns is not None
        or idate is not None
        or (its is not None and not _numeric_time(rows, its, delim))
    )
    return [
        RoutePath(
            name=path.stem,
            kind="navsatfix" if "field.latitude" in names else "csv",
            lat_deg=np.asarray(lat, dtype=float),
            lon_deg=np.asarray(lon, dtype=float),
            alt_m=np.where(missing, 0.0, alt_a),
            time_unix_s=np.asarray(t, dtype=float) if t else None,
            altitude_trusted=not missing.all(),
            time_is_absolute=absolute,
            notes=notes,
            alt_missing=missing if missing.any() and not missing.all() else None,
            warnings=warnings,
        )
    ]


def _all_no_fix(rows, names, delim, ist, ilat, ilon) -> bool:
    """True when every row's status is below 0 and every position and covariance is finite:
    a driver that never sets the status (module docstring)."""
    icov = [i for i, n in enumerate(names) if n.startswith(_COV) and n[len(_COV) :].isdigit()]
    if not rows:
        return False
    for _, row in rows:
        cells = _split(row, delim)
        if len(cells) != len(names):
            return False
        try:
            if not cells[ist] or parse_number(cells[ist]) >= 0:
                return False
            values = [parse_number(cells[i]) for i in (ilat, ilon, *icov)]
        except ValueError:
            return False
        if not np.all(np.isfinite(values)):
            return False
    return True


def _date_time_s(date: str, time: str) -> float:
    """Separate UTC date (``yymmdd``, ``yyyymmdd``, ``yyyy-mm-dd``) and time (``hhmmss[.f]``,
    ``hh:mm:ss[.f]``) cells -> POSIX seconds; ValueError when not one of these."""
    d = date.strip().replace("-", "").replace("/", "")
    tm = time.strip().replace(":", "")
    if not (d.isdigit() and len(d) in (6, 8)):
        raise ValueError(f"date {date.strip()!r} is not yymmdd, yyyymmdd or yyyy-mm-dd")
    whole, _, frac = tm.partition(".")
    if not (whole.isdigit() and len(whole) == 6 and (frac == "" or frac.isdigit())):
        raise ValueError(f"time {time.strip()!r} is not hhmmss or hh:mm:ss")
    year = 2000 + int(d[:2]) if len(d) == 6 else int(d[:4])
    md = d[2:] if len(d) == 6 else d[4:]
    try:
        stamp = _dt.datetime(year, int(md[:2]), int(md[2:4]), int(whole[:2]), int(whole[2:4]),
                             int(whole[4:6]), tzinfo=_dt.UTC)  # fmt: skip
    except ValueError as exc:
        raise ValueError(f"date/time {date.strip()!r} {time.strip()!r}: {exc}") from None
    return stamp.timestamp() + (float("0." + frac) if frac else 0.0)


def _stamp_s(cell: str) -> float:
    """A ROS stamp in nanoseconds -> POSIX seconds; ValueError outside years 1 to 9999."""
    t = parse_number(cell) * 1e-9
    if not TIME_RANGE_S[0] <= t <= TIME_RANGE_S[1]:
        raise ValueError(f"stamp {cell.strip()!r} ns is outside the years 1 to 9999")
    return t


def _numeric_time(rows, its: int, delim: str | None) -> bool:
    cell = _split(rows[0][1], delim)[its] if rows else ""
    try:
        parse_number(cell)
    except ValueError:
        return False
    return True
