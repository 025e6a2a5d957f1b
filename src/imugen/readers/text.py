"""Delimited text readers: CSV with a header, and the paper's headerless E N U rows.

CSV with a header
    Comma, semicolon or TAB separated; the header names the columns, case-insensitive:
    latitude (``lat``, ``latitude``, ``lat_deg``), longitude (``lon``, ``lng``, ``long``,
    ``longitude``, ``lon_deg``), height (``alt``, ``altitude``, ``alt_m``, ``ele``,
    ``elevation``, ``height``, ``h``; optional, 0 m and untrusted when absent) and time
    (``time``, ``time_s``, ``timestamp``, ``datetime``, ``t``; optional). Times are
    ISO-8601 date-times or plain seconds. A header with ``e_m``/``n_m``/``u_m`` (or
    ``east``/``north``/``up``) and no latitude/longitude is an ENU table.
    Lines starting with ``#`` are comments; a ``# imugen: {json}`` line written by
    ``imugen ingest`` carries the path name and altitude trust through the CSV stage.
E N U rows (the paper's format)
    No header; 3 numeric columns ``E N U`` (metres) or 4 columns ``t E N U`` (seconds),
    separated by any run of spaces/TABs (or commas). Placing them on the Earth needs an
    origin (``--origin``), see :mod:`imugen.ingest`.
"""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np

from imugen.errors import InputError
from imugen.route import RoutePath, parse_iso_time, parse_number

_ALIASES = {
    "lat": {"lat", "latitude", "lat_deg", "latitude_deg"},
    "lon": {"lon", "lng", "long", "longitude", "lon_deg", "longitude_deg"},
    "alt": {
        "alt",
        "altitude",
        "alt_m",
        "altitude_m",
        "ele",
        "elevation",
        "height",
        "h",
        "height_m",
    },
    "time": {"time", "time_s", "timestamp", "datetime", "date_time", "t", "time_utc", "utc"},
    "e": {"e", "e_m", "east", "east_m"},
    "n": {"n", "n_m", "north", "north_m"},
    "u": {"u", "u_m", "up", "up_m"},
}
_SPLIT_WS = re.compile(r"[\s,]+")


def _decode(data: bytes, path: Path) -> str:
    if b"\x00" in data:
        raise InputError(path, "contains NUL bytes: not a text route file")
    try:
        return data.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        raise InputError(
            path, f"is not UTF-8 text (byte 0x{data[exc.start]:02x} at offset {exc.start})"
        ) from None


def _is_number(tok: str) -> bool:
    try:
        float(tok)
    except ValueError:
        return False
    return True


def _delimiter(line: str) -> str | None:
    for d in (",", ";", "\t"):
        if d in line:
            return d
    return None


def read_text(path: str | Path) -> list[RoutePath]:
    """Read a CSV-with-header or E N U text file into one candidate path."""
    path = Path(path)
    text = _decode(path.read_bytes(), path)
    meta: dict = {}
    rows: list[tuple[int, str]] = []
    for lineno, raw in enumerate(text.splitlines(), start=1):
        line = raw.strip()
        if not line:
            continue
        if line.startswith("#"):
            if line.startswith("# imugen:"):
                try:
                    meta = json.loads(line[len("# imugen:") :])
                except json.JSONDecodeError:
                    meta = {}
            continue
        rows.append((lineno, line))
    if not rows:
        raise InputError(path, "has no data rows")
    first = rows[0][1]
    tokens = [t for t in _SPLIT_WS.split(first) if t]
    if all(_is_number(t) for t in tokens):
        return [_read_enu_rows(rows, path)]
    return [_read_csv(rows, path, meta)]


def _read_enu_rows(rows, path: Path) -> RoutePath:
    ncol = None
    data = []
    for lineno, line in rows:
        toks = [t for t in _SPLIT_WS.split(line) if t]
        if ncol is None:
            ncol = len(toks)
            if ncol not in (3, 4):
                raise InputError(
                    path,
                    f"line {lineno}: expected 3 numeric columns (E N U) or 4 (t E N U), found {ncol}",
                )
        if len(toks) != ncol:
            raise InputError(path, f"line {lineno}: {len(toks)} columns where the file has {ncol}")
        try:
            data.append([parse_number(t) for t in toks])
        except ValueError:
            raise InputError(path, f"line {lineno}: not a number in {line[:60]!r}") from None
    arr = np.asarray(data, dtype=float)
    enu = arr[:, -3:]
    t = arr[:, 0] if ncol == 4 else None
    return RoutePath(
        name=path.stem,
        kind="enu",
        lat_deg=np.empty(0),
        lon_deg=np.empty(0),
        alt_m=np.empty(0),
        enu_m=enu,
        time_unix_s=t,
        time_is_absolute=False,
    )


def _read_csv(rows, path: Path, meta: dict) -> RoutePath:
    header_line = rows[0][1]
    delim = _delimiter(header_line)
    names = [
        h.strip().strip('"').strip().lower()
        for h in (header_line.split(delim) if delim else header_line.split())
    ]
    names = [re.sub(r"\s*[\(\[].*[\)\]]$", "", n) for n in names]
    col = {}
    for key, aliases in _ALIASES.items():
        hits = [i for i, n in enumerate(names) if n in aliases]
        if len(hits) > 1:
            raise InputError(path, f"header names {key!r} twice: {[names[i] for i in hits]}")
        if hits:
            col[key] = hits[0]
    geodetic = "lat" in col and "lon" in col
    enu = all(k in col for k in ("e", "n", "u"))
    if not geodetic and not enu:
        raise InputError(
            path,
            f"header {header_line[:80]!r} names no latitude/longitude columns "
            "(expected e.g. lat,lon[,alt][,time]) and no E/N/U columns",
        )
    body = rows[1:]
    if not body:
        raise InputError(path, "has a header but no data rows")
    n = len(body)
    cells: list[list[str]] = []
    for lineno, line in body:
        parts = [p.strip().strip('"') for p in (line.split(delim) if delim else line.split())]
        if len(parts) != len(names):
            raise InputError(
                path, f"line {lineno}: {len(parts)} fields where the header has {len(names)}"
            )
        cells.append(parts)

    def numeric(key: str, required: bool) -> np.ndarray | None:
        if key not in col:
            return None
        out = np.empty(n)
        j = col[key]
        for i, parts in enumerate(cells):
            tok = parts[j]
            if tok == "" and not required:
                out[i] = np.nan
                continue
            try:
                out[i] = parse_number(tok)
            except ValueError:
                raise InputError(
                    path, f"line {body[i][0]}: {names[j]} {tok!r} is not a number"
                ) from None
        return out

    time = None
    absolute = True
    if "time" in col:
        j = col["time"]
        toks = [parts[j] for parts in cells]
        if all(tok == "" or _is_number(tok) for tok in toks):
            time = np.array([float(tok) if tok else np.nan for tok in toks])
            absolute = False
        else:
            time = np.full(n, np.nan)
            for i, tok in enumerate(toks):
                if tok:
                    try:
                        time[i] = parse_iso_time(tok)
                    except ValueError:
                        raise InputError(
                            path, f"line {body[i][0]}: time {tok!r} is neither ISO-8601 nor seconds"
                        ) from None
        if not np.isfinite(time).any():
            time = None
        elif not absolute and meta.get("start_time_utc"):
            time = time + parse_iso_time(meta["start_time_utc"])
            absolute = True
    notes = list(meta.get("notes", []))
    name = str(meta.get("path", path.stem))
    if geodetic:
        alt = numeric("alt", required=False)
        trusted = bool(meta.get("altitude_trusted", True))
        if alt is None:
            alt = np.zeros(n)
            trusted = False
            notes.append("no height column: heights set to 0 m")
        return RoutePath(
            name=name,
            kind="csv",
            lat_deg=numeric("lat", required=True),
            lon_deg=numeric("lon", required=True),
            alt_m=alt,
            time_unix_s=time,
            altitude_mode=meta.get("altitude_mode"),
            altitude_trusted=trusted,
            time_is_absolute=absolute,
            notes=notes,
            carried=meta,
        )
    enu_m = np.column_stack([numeric(k, required=True) for k in ("e", "n", "u")])
    return RoutePath(
        name=name,
        kind="enu",
        lat_deg=np.empty(0),
        lon_deg=np.empty(0),
        alt_m=np.empty(0),
        enu_m=enu_m,
        time_unix_s=time,
        time_is_absolute=False,
        notes=notes,
        carried=meta,
    )
