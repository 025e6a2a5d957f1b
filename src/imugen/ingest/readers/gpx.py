"""GPX 1.0 / 1.1 reader: tracks (trk/trkseg/trkpt) and routes (rte/rtept).

Each track segment and each route is one candidate path. A segment is named after its
track (``"<trk name> / segment k"`` when the track has several segments); unnamed tracks
and routes are called ``"track k"`` and ``"route k"``. ``<ele>`` gives the height (GPX
defines it as metres above mean sea level, WGS-84 geoid: taken as trusted); a point without
``<ele>`` is marked missing (ingestion interpolates it); a path without any ``<ele>`` gets
0 m and is flagged untrusted. ``<time>`` gives the clock; a path
where no point has a time is untimed, a path where only some points do keeps NaN for the
others (ingestion then decides, see :mod:`imugen.ingest.stage`).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from imugen.core.errors import InputError
from imugen.ingest import limits
from imugen.ingest.route import RoutePath, parse_iso_time, parse_number
from imugen.ingest.xmlsafe import local, parse_xml


def _child(el, name):
    for c in el:
        if local(c.tag) == name:
            return c
    return None


def _children(el, name):
    return [c for c in el if local(c.tag) == name]


def _text(el, name) -> str | None:
    c = _child(el, name)
    return None if c is None or c.text is None else c.text.strip()


def _points(pts, where: str, source: Path, name: str, kind: str) -> RoutePath:
    n = len(pts)
    lat = np.empty(n)
    lon = np.empty(n)
    alt = np.zeros(n)
    t = np.full(n, np.nan)
    have_ele = 0
    missing = np.ones(n, dtype=bool)
    for i, p in enumerate(pts):
        try:
            lat[i] = parse_number(p.get("lat", ""))
            lon[i] = parse_number(p.get("lon", ""))
        except ValueError as exc:
            raise InputError(
                source,
                f"{where} point {i + 1}: lat/lon attributes are missing or not numbers ({exc})",
            ) from None
        ele = _text(p, "ele")
        if ele:
            try:
                alt[i] = parse_number(ele)
                have_ele += 1
                missing[i] = False
            except ValueError as exc:
                raise InputError(source, f"{where} point {i + 1}: <ele>: {exc}") from None
        when = _text(p, "time")
        if when:
            try:
                t[i] = parse_iso_time(when)
            except ValueError as exc:
                raise InputError(source, f"{where} point {i + 1}: <time>: {exc}") from None
    notes = []
    trusted = have_ele > 0
    if have_ele == 0:
        notes.append("no point has <ele>: heights set to 0 m")
    elif have_ele < n:
        notes.append(f"{n - have_ele} of {n} points have no <ele>: heights interpolated")
    timed = bool(np.isfinite(t).any())
    return RoutePath(
        name=name,
        kind=kind,
        lat_deg=lat,
        lon_deg=lon,
        alt_m=alt,
        time_unix_s=t if timed else None,
        altitude_trusted=trusted,
        notes=notes,
        alt_missing=missing if 0 < have_ele < n else None,
    )


def read_gpx(path: str | Path, data: bytes | None = None) -> list[RoutePath]:
    """Read all track segments and routes of a GPX file (``data``: its bytes, if already read).

    Returns
    -------
    list of RoutePath
        One per non-empty ``trkseg`` and per non-empty ``rte``, in document order.
    """
    path = Path(path)
    root = parse_xml(limits.read_input(path) if data is None else data, path)
    if local(root.tag) != "gpx":
        raise InputError(path, f"is not GPX: the root element is <{local(root.tag)}>, not <gpx>")
    out: list[RoutePath] = []
    n_wpt = len(_children(root, "wpt"))
    for ti, trk in enumerate(_children(root, "trk"), start=1):
        tname = _text(trk, "name") or f"track {ti}"
        limits.check(path, "name_chars", len(tname), f"track {ti} <name>")
        segs = [s for s in _children(trk, "trkseg") if _children(s, "trkpt")]
        for si, seg in enumerate(segs, start=1):
            name = tname if len(segs) == 1 else f"{tname} / segment {si}"
            out.append(_points(_children(seg, "trkpt"), f"track {name!r}", path, name, "trkseg"))
    for ri, rte in enumerate(_children(root, "rte"), start=1):
        pts = _children(rte, "rtept")
        if pts:
            name = _text(rte, "name") or f"route {ri}"
            limits.check(path, "name_chars", len(name), f"route {ri} <name>")
            out.append(_points(pts, f"route {name!r}", path, name, "rte"))
    if not out:
        extra = f" (it holds {n_wpt} waypoints, which are not a path)" if n_wpt else ""
        raise InputError(path, f"has no track or route with points{extra}")
    return out
