"""Delimited text readers: CSV with a header, and the paper's headerless E N U rows.

CSV with a header
    Comma, semicolon or TAB separated (the first of ``,`` ``;`` TAB found in the header,
    outside quotes); fields may be quoted (``"Main St, 5"``, RFC 4180). With a semicolon or
    TAB separator a decimal comma (``40,1234``) is read as a decimal point (with a note).
    The header names the columns, case-insensitive:
    latitude (``lat``, ``latitude``, ``lat_deg``), longitude (``lon``, ``lng``, ``long``,
    ``longitude``, ``lon_deg``), height (``alt``, ``altitude``, ``alt_m``, ``ele``,
    ``elevation``, ``height``, ``h``; optional, 0 m and untrusted when absent) and time
    (``time``, ``time_s``, ``timestamp``, ``datetime``, ``t``; optional). Times are
    ISO-8601 date-times or plain seconds. A header with ``e_m``/``n_m``/``u_m`` (or
    ``east``/``north``/``up``) and no latitude/longitude is an ENU table.
    Lines starting with ``#`` are comments; a ``# imugen: {json}`` line written by
    ``imugen ingest`` carries the path name and altitude trust through the CSV stage (a
    malformed one is refused: delete the line to read the table without it).
Encodings
    UTF-8 (with or without a byte-order mark), UTF-16 and UTF-32 with a byte-order mark.
    Anything else is refused with the offset of the first undecodable byte.
E N U rows (the paper's format)
    No header; 3 numeric columns ``E N U`` (metres) or 4 columns ``t E N U`` (seconds),
    separated by any run of spaces/TABs (or commas). Placing them on the Earth needs an
    origin (``--origin``), see :mod:`imugen.ingest.stage`.
"""

from __future__ import annotations

import csv
import json
import math
import re
from pathlib import Path

import numpy as np

from imugen.core.errors import InputError
from imugen.ingest import limits
from imugen.ingest.route import RoutePath, parse_iso_time, parse_number

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
_ATTITUDE = ("q_w", "q_x", "q_y", "q_z")  # imugen.tables.enu.ATTITUDE
_SPLIT_WS = re.compile(r"[\s,]+")
_BOMS = (
    (b"\xef\xbb\xbf", "utf-8"),
    (b"\xff\xfe\x00\x00", "utf-32-le"),
    (b"\x00\x00\xfe\xff", "utf-32-be"),
    (b"\xff\xfe", "utf-16-le"),
    (b"\xfe\xff", "utf-16-be"),
)
_DECIMAL_COMMA = re.compile(r"[+-]?[0-9]+,[0-9]+", re.ASCII)


def _decode(data: bytes, path: Path) -> str:
    """Text of the file: UTF-8, or UTF-8/16/32 with a byte-order mark (which is removed)."""
    encoding = "utf-8"
    for bom, name in _BOMS:
        if data.startswith(bom):
            data, encoding = data[len(bom) :], name
            break
    if encoding == "utf-8" and b"\x00" in data:
        raise InputError(
            path, "contains NUL bytes: not a text route file (UTF-16 needs a byte-order mark)"
        )
    try:
        text = data.decode(encoding)
    except UnicodeDecodeError as exc:
        raise InputError(
            path,
            f"is not {encoding.upper()} text (byte 0x{data[exc.start]:02x} at offset "
            f"{exc.start}); save it as UTF-8",
        ) from None
    if "\x00" in text:
        raise InputError(path, "contains NUL characters: not a text route file")
    return text


def _is_number(tok: str) -> bool:
    try:
        parse_number(tok)
    except ValueError:
        return False
    return True


def _delimiter(line: str) -> str | None:
    """First of ``,`` ``;`` TAB that occurs outside double quotes."""
    unquoted = line.split('"')[::2]
    for d in (",", ";", "\t"):
        if any(d in part for part in unquoted):
            return d
    return None


def _no_nan(value) -> None:
    raise ValueError(f"{value} is not allowed")


def _carried(text: str, path: Path, lineno: int) -> dict:
    """The ``# imugen: {json}`` metadata, checked field by field (InputError if malformed)."""

    def bad(why: str) -> InputError:
        return InputError(
            path,
            f"line {lineno}: the '# imugen:' metadata comment is malformed ({why}); "
            "delete the line to read the table without it",
        )

    try:
        meta = json.loads(text, parse_constant=_no_nan)
    except (ValueError, RecursionError) as exc:
        raise bad(limits.shorten(str(exc).splitlines()[0] if str(exc) else "not JSON")) from None
    if not isinstance(meta, dict):
        raise bad("not a JSON object")
    for key in ("path", "source", "altitude_mode", "start_time_utc"):
        if meta.get(key) is not None and not isinstance(meta[key], str):
            raise bad(f"{key} is not a string")
    name = meta.get("path")
    if name is not None:
        limits.check(path, "name_chars", len(name), f"line {lineno}: path name")
    if not isinstance(meta.get("altitude_trusted", True), bool):
        raise bad("altitude_trusted is not true/false")
    notes = meta.get("notes", [])
    if not isinstance(notes, list) or not all(isinstance(n, str) for n in notes):
        raise bad("notes is not a list of strings")
    if meta.get("start_time_utc"):
        try:
            parse_iso_time(meta["start_time_utc"])
        except ValueError as exc:
            raise bad(f"start_time_utc: {exc}") from None
    origin = meta.get("origin")
    if origin is not None:
        keys = ("lat_deg", "lon_deg", "alt_m")
        if not isinstance(origin, dict) or not all(
            isinstance(origin.get(k), int | float)
            and not isinstance(origin.get(k), bool)
            and math.isfinite(origin[k])
            for k in keys
        ):
            raise bad("origin is not {lat_deg, lon_deg, alt_m} finite numbers")
    return meta


def read_text(path: str | Path, data: bytes | None = None) -> list[RoutePath]:
    """Read a CSV-with-header or E N U text file into one candidate path.

    ``data`` is the file's content when already read (:func:`imugen.ingest.limits.read_input`).
    """
    path = Path(path)
    text = _decode(limits.read_input(path) if data is None else data, path)
    max_rows = limits.current().points + 1  # the header
    meta: dict = {}
    rows: list[tuple[int, str]] = []
    for lineno, raw in enumerate(text.splitlines(), start=1):
        line = raw.strip()
        if not line:
            continue
        if line.startswith("#"):
            if line.startswith("# imugen:"):
                meta = _carried(line[len("# imugen:") :], path, lineno)
            continue
        rows.append((lineno, line))
        if len(rows) > max_rows:
            limits.check(path, "points", len(rows) - 1, f"line {lineno}")
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
        except ValueError as exc:
            raise InputError(path, f"line {lineno}: {exc}") from None
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


def _header_name(field: str) -> str:
    """Lower-case column name without a trailing unit in brackets (``height (m)`` -> height)."""
    name = field.strip().strip('"').strip().lower()
    if name.endswith((")", "]")):
        cut = [k for k in (name.find("("), name.find("[")) if k >= 0]
        if cut:
            name = name[: min(cut)].rstrip()
    return name


def _split_rows(rows, delim: str | None, path: Path) -> list[list[str]]:
    """Fields of each row: RFC 4180 quoting with ``delim``, or whitespace runs when None."""
    if delim is None:
        return [line.split() for _, line in rows]
    reader = csv.reader((line for _, line in rows), delimiter=delim, strict=True)
    out = []
    try:
        for fields in reader:
            out.append([f.strip() for f in fields])
    except csv.Error as exc:
        lineno = rows[min(reader.line_num, len(rows)) - 1][0]
        raise InputError(path, f"line {lineno}: bad CSV quoting ({exc})") from None
    if len(out) != len(rows):  # a quoted field spanning lines
        raise InputError(path, "a quoted field spans several lines: not supported")
    return out


def _read_csv(rows, path: Path, meta: dict) -> RoutePath:
    header_line = rows[0][1]
    delim = _delimiter(header_line)
    fields = _split_rows(rows, delim, path)
    for field in fields[0]:
        limits.check(path, "name_chars", len(field), f"line {rows[0][0]}: a header field")
    names = [_header_name(h) for h in fields[0]]
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
            f"header {limits.shorten(header_line, 80)!r} names no latitude/longitude columns "
            "(expected e.g. lat,lon[,alt][,time]) and no E/N/U columns",
        )
    body = rows[1:]
    if not body:
        raise InputError(path, "has a header but no data rows")
    n = len(body)
    cells = fields[1:]
    for (lineno, _), parts in zip(body, cells, strict=True):
        if len(parts) != len(names):
            hint = ""
            if delim == "," and len(parts) > len(names):
                hint = " (decimal commas? separate the fields with ';' or quote them)"
            raise InputError(
                path,
                f"line {lineno}: {len(parts)} fields where the header has {len(names)}{hint}",
            )
    notes = list(meta.get("notes", []))
    decimal_commas = 0

    def number(tok: str) -> float:
        nonlocal decimal_commas
        if delim != "," and _DECIMAL_COMMA.fullmatch(tok):
            decimal_commas += 1
            tok = tok.replace(",", ".")
        return parse_number(tok)

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
                out[i] = number(tok)
            except ValueError as exc:
                shown = limits.shorten(tok, 30)
                raise InputError(
                    path, f"line {body[i][0]}: {names[j]} {shown!r} is not a number ({exc})"
                ) from None
        return out

    time = None
    absolute = True
    if "time" in col:
        j = col["time"]
        toks = [parts[j] for parts in cells]
        seconds = [np.nan if tok == "" else _seconds(tok, delim) for tok in toks]
        if all(v is not None for v in seconds):
            time = np.array(seconds, dtype=float)
            absolute = False
        else:
            time = np.full(n, np.nan)
            for i, tok in enumerate(toks):
                if tok:
                    try:
                        time[i] = parse_iso_time(tok)
                    except ValueError as exc:
                        raise InputError(
                            path,
                            f"line {body[i][0]}: time is neither ISO-8601 nor seconds ({exc})",
                        ) from None
        if not np.isfinite(time).any():
            time = None
        elif not absolute and meta.get("start_time_utc"):
            time = time + parse_iso_time(meta["start_time_utc"])
            absolute = True
    name = str(meta.get("path", path.stem))
    attitude = None
    if all(c in names for c in _ATTITUDE):  # a pose trajectory's CSV stage
        col.update({c: names.index(c) for c in _ATTITUDE})
        attitude = np.column_stack([numeric(c, required=True) for c in _ATTITUDE])
    if geodetic:
        alt = numeric("alt", required=False)
        trusted = bool(meta.get("altitude_trusted", True))
        lat = numeric("lat", required=True)
        lon = numeric("lon", required=True)
        if alt is None:
            alt = np.zeros(n)
            trusted = False
            notes.append("no height column: heights set to 0 m")
        if decimal_commas:
            notes.append(f"read {decimal_commas} values with a decimal comma")
        return RoutePath(
            name=name,
            kind="csv",
            lat_deg=lat,
            lon_deg=lon,
            alt_m=alt,
            time_unix_s=time,
            altitude_mode=meta.get("altitude_mode"),
            altitude_trusted=trusted,
            time_is_absolute=absolute,
            notes=notes,
            carried=meta,
            attitude=attitude,
            attitude_frame=None if attitude is None else "level",
        )
    enu_m = np.column_stack([numeric(k, required=True) for k in ("e", "n", "u")])
    if decimal_commas:
        notes.append(f"read {decimal_commas} values with a decimal comma")
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
        attitude=attitude,
        attitude_frame=None if attitude is None else "origin",
    )


def _seconds(tok: str, delim: str | None) -> float | None:
    """A time in plain seconds (decimal comma allowed with a non-comma separator), else None."""
    if delim != "," and _DECIMAL_COMMA.fullmatch(tok):
        tok = tok.replace(",", ".")
    try:
        return parse_number(tok)
    except ValueError:
        return None
