"""Read candidate paths from KML and KMZ files.

Every path geometry of every Placemark is returned, in document order, as a
:class:`imugen.ingest.route.RoutePath`; choosing among candidates and validating numbers
(ranges, NaN, speeds, time order) is done later, not here. This module only refuses
files whose *structure* is wrong: not XML, not KML, no path at all, coordinate
tuples or ``<when>`` times that cannot be parsed, ``<when>``/``<coord>`` count
mismatches, bad KMZ archives.

What is a path
    ``LineString``; ``gx:Track`` and the OGC KML 2.3 ``Track`` (``<when>`` and
    ``<coord>`` either interleaved or grouped, paired by order); every ``Track`` of a
    ``gx:MultiTrack`` and every ``LineString``/``Track`` of a ``MultiGeometry``
    (recursively) is its own candidate. ``Point``, ``Polygon`` (and the
    ``LinearRing`` boundaries inside it, or on their own), ``Model`` and overlays are
    never paths. Elements are matched by local name, so KML 2.0, 2.1, 2.2, 2.3, the
    ``gx:`` extension namespace and un-namespaced files are all read alike.
    Geometries outside a Placemark are ignored (KML allows them only there).

Names
    The Placemark's ``<name>`` (stripped), else ``"Placemark k"`` (k counts every
    Placemark of the file from 1). When one Placemark yields several candidates they
    get the suffixes ``" [1]"``, ``" [2]"``, ...

altitudeMode policy (``altitudeMode`` or ``gx:altitudeMode`` of the geometry, or of
the enclosing ``gx:MultiTrack``/``MultiGeometry`` when the geometry has none; kept
as written in ``RoutePath.altitude_mode``)
    ``absolute``
        Heights above the WGS-84 ellipsoid/sea level as given: used and trusted.
    ``relativeToGround``, ``relativeToSeaFloor``
        Heights above a terrain we do not know: kept as written but
        ``altitude_trusted=False``, with a note.
    no altitudeMode (KML default ``clampToGround``)
        Google Earth would ignore the altitudes, but a track saved without a mode (an
        airliner's climb) still carries real heights: kept as written,
        ``altitude_trusted=False``, with a note (ingestion warns).
    ``clampToGround``, ``clampToSeaFloor``, or an unknown value
        Google Earth ignores the altitudes, so do we: ``alt_m`` is set to 0,
        ``altitude_trusted=False``, with a note.
    A path of 2-D tuples only (``lon,lat``) gets altitude 0 and ``altitude_trusted=False``
    whatever the mode; a path mixing 3-D and 2-D tuples marks the 2-D ones' heights missing
    (``alt_missing``: ingestion interpolates them from their neighbours, never reads 0 m).

Times
    ``<when>`` of a Track -> POSIX seconds (:func:`imugen.ingest.route.parse_iso_time`); an
    empty ``<when>`` gives NaN (noted). A Track without any ``<when>`` is untimed
    (``time_unix_s`` None, noted). A ``<coord>`` that is empty is skipped together
    with its ``<when>`` (noted). LineStrings are untimed; a Placemark
    ``<TimeStamp>``/``<TimeSpan>`` is not per point and is ignored (noted).

KMZ
    A zip archive read in memory (nothing is extracted to disk). The main document is
    ``doc.kml`` at the archive root, else the first ``*.kml`` at the root in archive
    order. The chosen member is refused if its name is absolute or has ``..`` parts,
    or if it decompresses to more than the input bound of :mod:`imugen.ingest.limits` (at most
    :data:`KMZ_MAX_MEMBER_BYTES`; checked on the header and again while reading, so a
    lying header cannot bypass the bound).
XML safety
    Parsing goes through :func:`imugen.ingest.xmlsafe.parse_xml`: DTDs, entities (XXE,
    billion laughs) and NUL bytes are refused, element count and depth are bounded.
    Coordinates are tokenized with string methods (no regular expression runs on them), so
    reading is linear in the size of the file.
"""

from __future__ import annotations

import io
import posixpath
import re
import zipfile
import zlib
from pathlib import Path
from xml.etree.ElementTree import Element

import numpy as np

from imugen.core.errors import InputError
from imugen.ingest import limits
from imugen.ingest.route import RoutePath, parse_iso_time, parse_number
from imugen.ingest.xmlsafe import local, parse_xml

__all__ = ["KMZ_MAX_MEMBER_BYTES", "read_kml", "read_kmz"]

#: Hard ceiling (bytes) on the decompressed KML document of a KMZ archive; the input bound of
#: :mod:`imugen.ingest.limits` applies below it.
KMZ_MAX_MEMBER_BYTES = 256 * 1024 * 1024

_CHUNK_BYTES = 1024 * 1024

_ABSOLUTE = "absolute"
_RELATIVE = {"relativeToGround", "relativeToSeaFloor"}
_CLAMPED = {"clampToGround", "clampToSeaFloor"}

_NOT_PATHS = {
    "Point": "Points",
    "Polygon": "Polygons",
    "LinearRing": "LinearRings",
    "Model": "Models",
}
_OVERLAYS = {"GroundOverlay", "ScreenOverlay", "PhotoOverlay"}


def _tuples(text: str, sep: str) -> list[str]:
    """Split coordinate text into tuples, components joined by ``sep``.

    Whitespace runs separate tuples; whitespace around a comma ("lon, lat, alt") belongs to
    the tuple. Linear: one split, fixed-width replaces and one more split.
    """
    flat = " ".join(text.split()).replace(" ,", ",").replace(", ", ",")
    return flat.split() if sep == "," else [" ".join(flat.replace(",", " ").split())]


class _Ctx:
    """Per-file state: the source name and counters of non-path geometries."""

    def __init__(self, source: str | Path):
        self.source = source
        self.counts = {v: 0 for v in _NOT_PATHS.values()}
        self.counts["overlays"] = 0

    def error(self, message: str) -> InputError:
        return InputError(self.source, message)


def _text(elem: Element) -> str:
    """All text inside ``elem`` (comments dropped), concatenated."""
    return "".join(elem.itertext())


def _children(elem: Element, name: str) -> list[Element]:
    return [c for c in elem if isinstance(c.tag, str) and local(c.tag) == name]


def _altitude_mode(geom: Element, inherited: str | None) -> str | None:
    for child in geom:
        if isinstance(child.tag, str) and local(child.tag) == "altitudeMode":
            return _text(child).strip()
    return inherited


def _apply_altitude_mode(
    mode: str | None, alt_m: np.ndarray, notes: list[str]
) -> tuple[np.ndarray, bool]:
    """Apply the altitudeMode policy; return the altitudes and whether they are trusted."""
    if mode == _ABSOLUTE:
        return alt_m, True
    if mode in _RELATIVE:
        notes.append(
            f"altitudes are {mode} (heights above unknown terrain): kept as written, not trusted"
        )
        return alt_m, False
    if mode is None:
        notes.append(
            "no altitudeMode (KML default clampToGround): altitudes kept as written, not trusted"
        )
        return alt_m, False
    if mode in _CLAMPED:
        why = f"altitudeMode {mode}"
    else:
        why = f"unknown altitudeMode {limits.shorten(mode)!r}, treated as clampToGround"
    notes.append(f"altitudes ignored ({why}): set to 0 m")
    return np.zeros_like(alt_m), False


def _tuple_error(ctx: _Ctx, where: str, k: int, tup: str, what: str) -> InputError:
    shown = tup if len(tup) <= 80 else tup[:77] + "..."
    return ctx.error(f"{where}: coordinate tuple {k} {shown!r} {what}")


def _parse_tuples(
    tuples: list[str],
    sep: str | None,
    ctx: _Ctx,
    where: str,
    numbers: list[int] | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, int]:
    """Parse ``lon<sep>lat[<sep>alt]`` tuples.

    ``numbers`` are the 1-based positions used in error messages (default 1..n).
    Returns lat_deg, lon_deg, alt_m (shape (n,)) and the mask of 2-D tuples (shape (n,),
    altitude 0 there).
    """
    n = len(tuples)
    lon = np.empty(n)
    lat = np.empty(n)
    alt = np.zeros(n)
    two_d = np.zeros(n, bool)
    for k, tup in enumerate(tuples):
        parts = tup.split(sep)
        number = k + 1 if numbers is None else numbers[k]
        if len(parts) not in (2, 3):
            raise _tuple_error(
                ctx, where, number, tup, f"has {len(parts)} components, expected lon,lat[,alt]"
            )
        try:
            values = [parse_number(p) for p in parts]
        except ValueError as exc:
            raise _tuple_error(ctx, where, number, tup, f"is not numeric ({exc})") from None
        lon[k] = values[0]
        lat[k] = values[1]
        if len(values) == 3:
            alt[k] = values[2]
        else:
            two_d[k] = True
    return lat, lon, alt, two_d


def _finish(
    name: str,
    kind: str,
    lat: np.ndarray,
    lon: np.ndarray,
    alt: np.ndarray,
    two_d: np.ndarray,
    mode: str | None,
    times: np.ndarray | None,
    notes: list[str],
) -> RoutePath:
    alt, trusted = _apply_altitude_mode(mode, alt, notes)
    n_2d = int(two_d.sum())
    missing = None
    if 0 < n_2d < len(lat) and np.any(alt[~two_d] != 0.0):  # heights kept: 2-D ones missing
        notes.append(
            f"{n_2d} of {len(lat)} coordinate tuples are 2-D (lon,lat): their heights are missing"
        )
        missing = two_d
    elif n_2d:
        notes.append(
            f"{n_2d} of {len(lat)} coordinate tuples are 2-D (lon,lat): altitude set to 0 m"
        )
        trusted = False
    return RoutePath(
        name=name,
        kind=kind,
        lat_deg=lat,
        lon_deg=lon,
        alt_m=alt,
        time_unix_s=times,
        altitude_mode=mode,
        altitude_trusted=trusted,
        notes=notes,
        alt_missing=missing,
    )


def _read_linestring(geom: Element, mode: str | None, ctx: _Ctx, where: str) -> RoutePath:
    coords = _children(geom, "coordinates")
    text = " ".join(_text(c) for c in coords)
    tuples = _tuples(text, ",")
    lat, lon, alt, two_d = _parse_tuples(tuples, ",", ctx, where)
    notes: list[str] = []
    if not tuples:
        notes.append("LineString has no coordinates")
    return _finish(where, "LineString", lat, lon, alt, two_d, mode, None, notes)


def _read_track(geom: Element, mode: str | None, ctx: _Ctx, where: str) -> RoutePath:
    whens: list[str] = []
    coords: list[str] = []
    for child in geom:
        if not isinstance(child.tag, str):
            continue
        tag = local(child.tag)
        if tag == "when":
            whens.append(_text(child).strip())
        elif tag == "coord":
            coords.append(_text(child).strip())
    notes: list[str] = []
    if whens and len(whens) != len(coords):
        raise ctx.error(
            f"{where}: Track has {len(whens)} <when> but {len(coords)} <coord> elements"
        )
    keep = [k for k, c in enumerate(coords) if c]
    n_skipped = len(coords) - len(keep)
    if n_skipped:
        notes.append(
            f"skipped {n_skipped} empty <coord> element(s)"
            + (" with their <when>" if whens else "")
        )
    # gx:coord is "lon lat alt"; tolerate commas too.
    tuples = [_tuples(coords[k], " ")[0] for k in keep]
    lat, lon, alt, two_d = _parse_tuples(
        tuples, None, ctx, f"{where}, <coord>", [k + 1 for k in keep]
    )
    times: np.ndarray | None = None
    if whens:
        times = np.empty(len(keep))
        n_empty = 0
        for i, k in enumerate(keep):
            w = whens[k]
            if not w:
                times[i] = np.nan
                n_empty += 1
                continue
            try:
                times[i] = parse_iso_time(w)
            except ValueError as exc:
                raise ctx.error(f"{where}: <when> {k + 1}: {exc}") from None
        if n_empty:
            notes.append(f"{n_empty} empty <when> element(s): time unknown (NaN)")
    elif coords:
        notes.append("Track has no <when> elements: untimed")
    return _finish(where, "Track", lat, lon, alt, two_d, mode, times, notes)


def _collect(
    geom: Element, inherited_mode: str | None, ctx: _Ctx, where: str, out: list[RoutePath]
) -> None:
    """Append the path candidates of one geometry element (recursing into collections)."""
    tag = local(geom.tag)
    if tag == "LineString":
        out.append(_read_linestring(geom, _altitude_mode(geom, inherited_mode), ctx, where))
    elif tag == "Track":
        out.append(_read_track(geom, _altitude_mode(geom, inherited_mode), ctx, where))
    elif tag in ("MultiTrack", "MultiGeometry"):
        mode = _altitude_mode(geom, inherited_mode)
        for child in geom:
            if isinstance(child.tag, str):
                _collect(child, mode, ctx, where, out)
    elif tag in _NOT_PATHS:
        ctx.counts[_NOT_PATHS[tag]] += 1


def _paths_from_root(root: Element, ctx: _Ctx) -> list[RoutePath]:
    if local(root.tag) != "kml":
        raise ctx.error(f"is not a KML file (root element <{local(root.tag)}>, expected <kml>)")
    paths: list[RoutePath] = []
    k = 0
    for elem in root.iter():
        if not isinstance(elem.tag, str):
            continue
        tag = local(elem.tag)
        if tag in _OVERLAYS:
            ctx.counts["overlays"] += 1
            continue
        if tag != "Placemark":
            continue
        k += 1
        names = _children(elem, "name")
        name = _text(names[0]).strip() if names else ""
        name = name or f"Placemark {k}"
        limits.check(ctx.source, "name_chars", len(name), f"Placemark {k} <name>")
        found: list[RoutePath] = []
        for child in elem:
            if isinstance(child.tag, str):
                _collect(child, None, ctx, f"Placemark {name!r}", found)
        timed_placemark = any(
            local(c.tag) in ("TimeStamp", "TimeSpan") for c in elem if isinstance(c.tag, str)
        )
        for i, path in enumerate(found):
            path.name = f"{name} [{i + 1}]" if len(found) > 1 else name
            if timed_placemark and path.kind == "LineString":
                path.notes.append("Placemark TimeStamp/TimeSpan is not per point: ignored")
        paths.extend(found)
    if not paths:
        c = ctx.counts
        extra = ", ".join(
            f"{c[key]} {key}" for key in ("LinearRings", "Models", "overlays") if c[key]
        )
        raise ctx.error(
            f"no path (LineString, Track) found; the file holds {c['Points']} Points, "
            f"{c['Polygons']} Polygons" + (f", {extra}" if extra else "")
        )
    return paths


def _parse_kml_bytes(data: bytes, source: str | Path) -> list[RoutePath]:
    return _paths_from_root(parse_xml(data, source), _Ctx(source))


def read_kml(path: Path, data: bytes | None = None) -> list[RoutePath]:
    """Read every candidate path of a KML file.

    Parameters
    ----------
    path : Path
        The ``.kml`` file.
    data : bytes, optional
        Its content, when already read (:func:`imugen.ingest.limits.read_input`).

    Returns
    -------
    list of RoutePath
        All path candidates in document order (at least one).

    Raises
    ------
    InputError
        Unreadable file, not XML, not KML, DTD/entities present, no path, or a
        coordinate tuple / ``<when>`` that cannot be parsed.
    """
    path = Path(path)
    if data is None:
        data = limits.read_input(path)
    return _parse_kml_bytes(data, path)


def _root_name(name: str) -> str | None:
    """Base name of a member at the archive root, else None.

    A drive letter, leading ``/`` and ``.``/``..`` parts are disregarded here, so that a
    member such as ``../doc.kml`` is chosen and then refused with a clear message.
    """
    norm = re.sub(r"^[A-Za-z]:", "", name.replace("\\", "/"))
    parts = [p for p in posixpath.normpath("/" + norm).split("/") if p not in ("", ".", "..")]
    if len(parts) != 1 or name.endswith(("/", "\\")):
        return None
    return parts[0]


def _unsafe_member(name: str) -> bool:
    norm = name.replace("\\", "/")
    return (
        norm.startswith("/") or re.match(r"^[A-Za-z]:", norm) is not None or ".." in norm.split("/")
    )


def _choose_member(infos: list[zipfile.ZipInfo]) -> zipfile.ZipInfo | None:
    root_kml = []
    for info in infos:
        base = _root_name(info.filename)
        if base is not None and base.lower().endswith(".kml"):
            if base.lower() == "doc.kml":
                return info
            root_kml.append(info)
    return root_kml[0] if root_kml else None


def read_kmz(path: Path, data: bytes | None = None) -> list[RoutePath]:
    """Read every candidate path of the main KML document of a KMZ archive.

    Parameters
    ----------
    path : Path
        The ``.kmz`` file (a zip archive).
    data : bytes, optional
        Its content, when already read (:func:`imugen.ingest.limits.read_input`).

    Returns
    -------
    list of RoutePath
        All path candidates of the main document, in document order.

    Raises
    ------
    InputError
        Not a zip archive, no ``.kml`` at the archive root, unsafe member name,
        member too large, or any :func:`read_kml` problem in the member.
    """
    path = Path(path)
    if data is None:
        data = limits.read_input(path)
    try:
        zf = zipfile.ZipFile(io.BytesIO(data))
    except (zipfile.BadZipFile, ValueError, EOFError, OSError):
        raise InputError(path, "is not a KMZ (zip) archive") from None
    with zf:
        info = _choose_member(zf.infolist())
        if info is None:
            raise InputError(path, "KMZ archive holds no .kml document at its root")
        member = info.filename
        shown = limits.shorten(member)
        if _unsafe_member(member):
            raise InputError(path, f"KMZ member {shown!r} has an absolute or '..' path: refused")
        limit = min(KMZ_MAX_MEMBER_BYTES, limits.current().input_bytes)
        too_big = f"KMZ member {shown!r} decompresses to more than {limit} bytes: refused"
        if info.file_size > limit:
            raise InputError(path, too_big)
        chunks: list[bytes] = []
        total = 0
        try:
            with zf.open(info) as fh:
                while True:
                    chunk = fh.read(_CHUNK_BYTES)
                    if not chunk:
                        break
                    total += len(chunk)
                    if total > limit:
                        raise InputError(path, too_big)
                    chunks.append(chunk)
        except InputError:
            raise
        # zipfile raises NotImplementedError for compression methods it lacks (e.g. deflate64)
        # and RuntimeError for encrypted members: both are a user's file, not a bug
        except (zipfile.BadZipFile, RuntimeError, NotImplementedError, EOFError, OSError) as exc:
            raise InputError(path, f"KMZ member {shown!r} cannot be read ({exc})") from None
        except zlib.error as exc:
            raise InputError(path, f"KMZ member {shown!r} cannot be decompressed ({exc})") from None
    data = b"".join(chunks)
    try:
        return _parse_kml_bytes(data, path)
    except InputError as exc:
        raise InputError(path, f"(member {shown}) {exc.message}") from None
