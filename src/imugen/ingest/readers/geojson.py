"""GeoJSON reader (RFC 7946): every line of the file is a candidate path.

A ``LineString`` is one candidate, each line of a ``MultiLineString`` is its own candidate
(named ``"<name> [k]"``); ``Feature``, ``FeatureCollection`` and ``GeometryCollection`` are
walked in document order. Points and polygons are never paths. Positions are
``[lon, lat]`` or ``[lon, lat, height]`` (RFC 7946: WGS-84, height in metres above the
ellipsoid); a line where only some positions have a height marks the others missing (filled
by ingestion), one where none has gets 0 m, untrusted. Per-point times are read from the
``coordTimes`` (or ``times``) property when it holds one ISO-8601 time per position (the
convention of togeojson and GPSBabel); otherwise the line is untimed. Names: the Feature's
``name`` property, else ``"feature k"``.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from imugen.core.errors import InputError
from imugen.ingest.route import RoutePath, parse_iso_time


def _is_num(x) -> bool:
    return isinstance(x, int | float) and not isinstance(x, bool)


def _line(coords, times, name: str, source: Path) -> RoutePath:
    if not isinstance(coords, list):
        raise InputError(source, f"{name!r}: coordinates are not an array")
    n = len(coords)
    lat, lon, alt = np.empty(n), np.empty(n), np.zeros(n)
    have = np.zeros(n, dtype=bool)
    for i, c in enumerate(coords):
        if not (isinstance(c, list) and 2 <= len(c) <= 4 and all(_is_num(v) for v in c)):
            shown = json.dumps(c)[:60]
            raise InputError(source, f"{name!r}: position {i + 1} {shown} is not [lon, lat[, h]]")
        try:
            lon[i], lat[i] = c[0], c[1]
            if len(c) >= 3:
                alt[i], have[i] = c[2], True
        except OverflowError:
            raise InputError(source, f"{name!r}: position {i + 1} is out of range") from None
    t = None
    notes: list[str] = []
    if isinstance(times, list) and len(times) == n and n:
        t = np.empty(n)
        for i, s in enumerate(times):
            try:
                t[i] = parse_iso_time(s) if isinstance(s, str) else float("nan")
            except (ValueError, OverflowError):
                raise InputError(source, f"{name!r}: time {i + 1} {s!r} is not ISO-8601") from None
    elif times is not None:
        notes.append("coordTimes does not give one time per position: untimed")
    if not have.any():
        notes.append("2-D positions: heights set to 0 m")
    return RoutePath(
        name=name,
        kind="geojson",
        lat_deg=lat,
        lon_deg=lon,
        alt_m=alt,
        time_unix_s=t,
        altitude_trusted=bool(have.any()),
        notes=notes,
        alt_missing=~have if have.any() and not have.all() else None,
    )


def _walk(obj, name: str | None, times, out: list, counts: dict, source: Path) -> None:
    if not isinstance(obj, dict):
        return
    kind = obj.get("type")
    if kind == "FeatureCollection":
        for f in obj.get("features") or []:
            counts["features"] += 1
            _walk(f, None, None, out, counts, source)
    elif kind == "Feature":
        props = obj.get("properties") if isinstance(obj.get("properties"), dict) else {}
        label = props.get("name")
        label = str(label).strip() if label is not None and str(label).strip() else None
        label = label or f"feature {max(counts['features'], 1)}"
        times = props.get("coordTimes", props.get("times"))
        _walk(obj.get("geometry"), label, times, out, counts, source)
    elif kind == "GeometryCollection":
        for g in obj.get("geometries") or []:
            _walk(g, name, None, out, counts, source)
    elif kind == "LineString":
        out.append(_line(obj.get("coordinates"), times, name or f"line {len(out) + 1}", source))
    elif kind == "MultiLineString":
        lines = obj.get("coordinates")
        if not isinstance(lines, list):
            raise InputError(source, f"{name!r}: MultiLineString coordinates are not an array")
        base = name or f"line {len(out) + 1}"
        for k, coords in enumerate(lines, start=1):
            tk = times[k - 1] if isinstance(times, list) and len(times) == len(lines) else None
            label = f"{base} [{k}]" if len(lines) > 1 else base
            out.append(_line(coords, tk, label, source))
    else:
        counts["other"] += 1


def read_geojson(path: str | Path, data: bytes | None = None) -> list[RoutePath]:
    """Read every LineString (and line of a MultiLineString) of a GeoJSON file."""
    path = Path(path)
    try:
        doc = json.loads(path.read_bytes() if data is None else data)
    except (ValueError, RecursionError) as exc:
        raise InputError(path, f"is not valid GeoJSON ({type(exc).__name__}: {exc})") from None
    out: list[RoutePath] = []
    counts = {"features": 0, "other": 0}
    try:
        _walk(doc, None, None, out, counts, path)
    except RecursionError:
        raise InputError(path, "GeoJSON geometries are nested too deeply") from None
    out = [p for p in out if p.n_points]
    if not out:
        raise InputError(
            path,
            f"GeoJSON holds no LineString or MultiLineString ({counts['other']} other geometries)",
        )
    return out
