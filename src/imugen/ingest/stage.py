"""Ingestion stage: route file -> one validated path -> geodetic table + exact local ENU.

Rules (documented once here and in the README)
----------------------------------------------
Path choice
    A file may hold several candidate paths (Placemarks, tracks, segments, routes). The only
    one is taken; otherwise ``--path`` names one (exact name) or indexes it (1-based, in
    file order); otherwise ingestion refuses and lists the candidates with their name,
    point count and length.
Validation (each failure: one line naming the file, exit status 2, no output)
    At least two points; no NaN/inf; latitude in [-90, 90], longitude in [-180, 180],
    height in [-11 km, 100 km]; a non-zero path length; no point farther than
    ``max_extent_km`` from the origin (geodesic distance on the WGS-84 ellipsoid between the
    origin and the point, heights ignored) when that limit is given (a sanity check of one's own;
    by default routes of any length are accepted, and E N U rows only within
    :data:`ENU_SPAN_M` of the first row, the farthest two points near the Earth can be: a
    larger value is a unit error); for timed
    paths, no implied speed above ``max_speed_kmh`` (default 1,200 km/h) between
    consecutive points once outliers are removed.
Cleaning
    Outliers beyond the vehicle's limits are removed, missing heights interpolated and the
    noise estimated (:mod:`imugen.ingest.clean`); more than half of the points as outliers is refused.
Time
    ISO-8601 times become seconds from the first point (``time_s``); a time without an offset
    is UTC. Exact duplicates (same time and same position) are dropped with a warning. A time
    that does not increase at a point whose position differs is refused (the order of the
    points is ambiguous). When every point has the same time, or only some points have a time,
    the clock cannot be used: the path falls back to untimed with a warning. Gaps longer than
    ``max_gap_s`` split the path into candidate parts, or are bridged on request
    (:mod:`imugen.ingest.segments`); shorter ones are kept (the truth stage interpolates through them)
    and reported when longer than ``gap_warn_s`` (default 60 s). ``dt`` gives an untimed path a uniform clock (the paper's trajectory is
    1 point per second); it is ignored (with a warning) when the file has a usable clock.
Untimed paths
    Consecutive repeated positions are dropped (a path without a clock has no stops); the truth
    stage later gives it a clock from a speed profile. Geodetic vertices farther apart than
    500 m are joined by the WGS-84 geodesic (points added every <= 500 m, height linear in
    distance; :mod:`imugen.core.geodesic`), not by the chord; meta ``geodesic``.
Origin
    ``origin`` if given, else the origin recorded by an earlier ``imugen ingest`` (CSV stage),
    else the first point. E N U rows are placed on the Earth by putting their first row at the
    origin, which must then be given.
"""

from __future__ import annotations

import hashlib
import json
import re
import sys
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd
from pyproj import Geod

from imugen import __version__
from imugen.core.errors import InputError, printable
from imugen.core.frames import LocalFrame, Origin, to_utm, utm_crs
from imugen.core.geodesic import GEODESIC_STEP_M, densify, sagitta_m
from imugen.core.io import atomic_output
from imugen.ingest import limits
from imugen.ingest import pose as ipose
from imugen.ingest.clean import clean_path
from imugen.ingest.options import IngestOptions
from imugen.ingest.readers import read_route_file
from imugen.ingest.route import TIME_RANGE_S, RoutePath, iso_utc
from imugen.ingest.segments import choose_path
from imugen.tables import enu as tenu

UNITS = {
    tenu.TIME: "s",
    tenu.LAT: "deg (WGS-84)",
    tenu.LON: "deg (WGS-84)",
    tenu.ALT: "m (ellipsoidal height as given by the file)",
    **dict.fromkeys((*tenu.ENU, *tenu.UTM), "m"),
    **dict.fromkeys(tenu.ATTITUDE, "1 (quaternion, pose body -> local ENU at the point)"),
}
_GEOD = Geod(ellps="WGS84")
ENU_SPAN_M = 2.0 * 6378137.0 + 200e3
"""Largest distance [m] between two points within 100 km of the Earth's surface (E N U rows
farther from the first row are a unit error)."""


@dataclass
class Ingested:
    """Result of ingestion: the table (one row per kept input point) and its metadata."""

    table: pd.DataFrame
    meta: dict
    warnings: list[str] = field(default_factory=list)


def parse_origin(text: str | None) -> Origin | None:
    """Parse ``"LAT,LON,H"`` (degrees, degrees, metres); None passes through."""
    if text is None:
        return None
    parts = [p.strip() for p in str(text).split(",")]
    try:
        if len(parts) != 3:
            raise ValueError
        lat, lon, h = (float(p) for p in parts)
    except ValueError:
        raise InputError(
            "--origin", f"{text!r} is not LAT,LON,H (degrees, degrees, metres)"
        ) from None
    _check_geodetic(np.array([lat]), np.array([lon]), np.array([h]), "--origin", what="origin")
    return Origin(lat, lon, h)


def _path_length_m(p: RoutePath) -> float:
    if p.enu_m is not None:
        d = np.diff(p.enu_m, axis=0)
        return float(np.nansum(np.linalg.norm(d, axis=1)))
    ok = np.isfinite(p.lat_deg) & np.isfinite(p.lon_deg)
    ok &= (np.abs(p.lat_deg) <= 90) & (np.abs(p.lon_deg) <= 180)
    if ok.sum() < 2:
        return float("nan")
    return float(_GEOD.line_length(p.lon_deg[ok], p.lat_deg[ok]))


def _describe(i: int, p: RoutePath) -> str:
    length = _path_length_m(p)
    ls = (
        "?"
        if not np.isfinite(length)
        else (f"{length / 1000:.2f} km" if length >= 1000 else f"{length:.0f} m")
    )
    timed = ", timed" if p.time_unix_s is not None else ""
    return f"[{i}] {limits.shorten(p.name)!r} ({p.kind}, {p.n_points} points, {ls}{timed})"


LIST_CANDIDATES = 8
"""Candidates named in a refusal (the longest ones); the rest are counted."""


def _listing(cands: list[RoutePath]) -> str:
    lengths = np.nan_to_num([_path_length_m(p) for p in cands], nan=-1.0)
    order = sorted(range(len(cands)), key=lambda i: -lengths[i])
    shown = sorted(order[:LIST_CANDIDATES])
    text = "; ".join(_describe(i + 1, cands[i]) for i in shown)
    rest = len(cands) - len(shown)
    if rest:
        text += (
            f"; and {rest} more (the {len(shown)} longest are listed; "
            "--path longest takes the longest, or pass a name or index)"
        )
    return text


def select_path(cands: list[RoutePath], spec: str | int | None, source) -> RoutePath:
    """Choose one candidate: the only one, or the one ``spec`` names or indexes (1-based).

    Refusals list the first :data:`LIST_CANDIDATES` candidates (longest first) with a count of
    the others and a hint, so the message stays one readable line whatever the file holds.
    """
    if spec is None or spec == "":
        if len(cands) == 1:
            return cands[0]
        raise InputError(
            source,
            f"holds {len(cands)} candidate paths; choose one with --path NAME or --path INDEX: {_listing(cands)}",
        )
    spec = str(spec)
    exact = [p for p in cands if p.name == spec]
    if len(exact) == 1:
        return exact[0]
    folded = [p for p in cands if p.name.casefold() == spec.casefold()]
    if len(folded) == 1:
        return folded[0]
    if len(exact) > 1 or len(folded) > 1:
        raise InputError(
            source, f"several paths are named {spec!r}; use an index instead: {_listing(cands)}"
        )
    if spec.lstrip("+").isdigit():
        k = int(spec)
        if 1 <= k <= len(cands):
            return cands[k - 1]
        raise InputError(
            source, f"--path {k}: there are only {len(cands)} candidate paths: {_listing(cands)}"
        )
    raise InputError(source, f"no path named {spec!r}; candidates: {_listing(cands)}")


def _first_bad(mask: np.ndarray) -> int:
    return int(np.flatnonzero(mask)[0])


def _check_geodetic(lat, lon, alt, source, what="point") -> None:
    for arr, name in ((lat, "latitude"), (lon, "longitude"), (alt, "height")):
        bad = ~np.isfinite(arr)
        if bad.any():
            i = _first_bad(bad)
            label = what if what == "origin" else f"{what} {i + 1}"
            raise InputError(source, f"{label}: {name} is {arr[i]} (not a finite number)")
    for arr, name, lo, hi, unit in (
        (lat, "latitude", -90.0, 90.0, "deg"),
        (lon, "longitude", -180.0, 180.0, "deg"),
        (alt, "height", -11_000.0, 100_000.0, "m"),
    ):
        bad = (arr < lo) | (arr > hi)
        if bad.any():
            i = _first_bad(bad)
            label = what if what == "origin" else f"{what} {i + 1}"
            raise InputError(
                source, f"{label}: {name} {arr[i]:g} {unit} is outside [{lo:g}, {hi:g}] {unit}"
            )


def _check_enu(enu: np.ndarray, source) -> None:
    bad = ~np.isfinite(enu)
    if bad.any():
        i = int(np.flatnonzero(bad.any(axis=1))[0])
        raise InputError(
            source, f"row {i + 1}: E/N/U value is not a finite number ({enu[i].tolist()})"
        )


def _when(p: RoutePath, t: float) -> str:
    return iso_utc(t) if p.time_is_absolute else f"{t:g} s"


def _clock(p: RoutePath, pos: np.ndarray, dt: float | None, warnings: list[str], source):
    """Decide the clock of a path: returns (time_s or None, time source label, start UTC)."""
    t = p.time_unix_s
    if t is not None:
        have = np.isfinite(t)
        if not have.all():
            warnings.append(
                f"only {int(have.sum())} of {len(t)} points have a time: the clock is not "
                "usable and the path is treated as untimed"
            )
            t = None
        elif np.ptp(t) == 0.0:
            warnings.append(
                f"all {len(t)} points have the same time ({_when(p, float(t[0]))}): the clock is "
                "not usable and the path is treated as untimed"
            )
            t = None
        else:
            moves = np.any(pos[1:] != pos[:-1], axis=1)
            stuck = (np.diff(t) <= 0) & moves
            if moves.any() and stuck.sum() >= 0.5 * moves.sum():
                warnings.append(
                    f"the time does not advance on {int(stuck.sum())} of {int(moves.sum())} moves "
                    "(placeholder timestamps?): the clock is not usable and the path is treated "
                    "as untimed"
                )
                t = None
    if t is not None:
        if dt is not None:
            warnings.append("the file has a clock: the dt option is ignored")
        if p.time_is_absolute:
            out = ~((t >= TIME_RANGE_S[0]) & (t <= TIME_RANGE_S[1]))
            if out.any():
                i = _first_bad(out)
                raise InputError(
                    source,
                    f"point {i + 1}: time {float(t[i]):.6g} s (POSIX) is outside the years 1 "
                    "to 9999",
                )
        start = iso_utc(float(t[0])) if p.time_is_absolute else None
        rel = t - t[0]
        if not np.isfinite(rel).all():  # differences of finite huge values may overflow
            raise InputError(source, "the times span more than a float can hold")
        return rel, "file", start
    if dt is not None:
        if not (np.isfinite(dt) and dt > 0 and np.isfinite(dt * p.n_points)):
            raise InputError("--dt", f"{dt!r} must be a positive number of seconds")
        return np.arange(p.n_points) * float(dt), f"uniform dt = {dt:g} s (option)", None
    return None, None, None


def _dedupe(table: dict, timed: bool, source, warnings: list[str]) -> dict:
    """Drop exact duplicates (timed) or repeated positions (untimed); refuse bad clocks."""
    pos = table["pos"]
    same_pos = np.all(pos[1:] == pos[:-1], axis=1)
    if timed:
        t = table["time"]
        same_t = t[1:] == t[:-1]
        dup = same_t & same_pos
        keep = np.concatenate([[True], ~dup])
        if dup.any():
            warnings.append(
                f"dropped {int(dup.sum())} exact duplicate points (same time and position)"
            )
        for k in table:
            table[k] = table[k][keep]
        dtime = np.diff(table["time"])
        bad = dtime <= 0
        if bad.any():
            i = _first_bad(bad)
            kind = "repeats" if dtime[i] == 0 else "goes backwards"
            raise InputError(
                source,
                f"time {kind} at point {i + 2} of the kept points ({table['time'][i + 1]:.3f} s after "
                f"{table['time'][i]:.3f} s) while the position changes: the point order is ambiguous",
            )
    else:
        keep = np.concatenate([[True], ~same_pos])
        if not keep.all():
            warnings.append(
                f"dropped {int((~keep).sum())} repeated consecutive positions (an untimed path has no stops)"
            )
        for k in table:
            table[k] = table[k][keep]
    return table


def ingest(src: str | Path, **options) -> Ingested:
    """Read, select, validate and convert one path of a route file.

    Parameters
    ----------
    src : path-like
        Any route file of :data:`imugen.ingest.formats.FORMATS`.
    **options
        Fields of :class:`~imugen.ingest.options.IngestOptions`: ``path`` (candidate name or
        1-based index; ``"longest"`` after a gap split), ``origin`` (an
        :class:`~imugen.core.frames.Origin` or ``"LAT,LON,H"``; default the origin carried from
        a previous stage, else the first point), ``dt`` (uniform clock of an untimed path, s),
        ``utm``, the validation limits ``max_speed_kmh``, ``max_extent_km`` (None: no limit),
        ``gap_warn_s`` (see the module docstring), ``vehicle`` (whose limits decide what is an
        outlier, :mod:`imugen.ingest.clean`), ``max_gap_s`` and ``gaps`` (time gaps longer
        than ``max_gap_s`` split the path, or are bridged: :mod:`imugen.ingest.segments`).

    Returns
    -------
    Ingested
        ``table`` columns: ``time_s`` (timed paths only), ``lat_deg``, ``lon_deg``, ``alt_m``,
        ``e_m``, ``n_m``, ``u_m`` (and ``utm_e_m``, ``utm_n_m``); ``meta`` dict for the file.
    """
    return read(src, IngestOptions(**options))


ALL = "all"
"""``--path=all``: one route per candidate path (:func:`read_all`)."""


def read(src: str | Path, options: IngestOptions) -> Ingested:
    """:func:`ingest` with its options object."""
    o = options
    if isinstance(o.path, str) and o.path.strip().casefold() == ALL:
        raise InputError("--path", "all makes one route per path: use read_all (or the CLI)")
    if isinstance(o.path, str) and o.path.strip().casefold().startswith(ALL + ":"):
        return read_one(src, o.path.strip()[len(ALL) + 1 :], o)
    with np.errstate(over="ignore", invalid="ignore"):  # overflows are refused, not printed
        return _ingest(
            src, o.path, o.origin, o.dt, o.utm, o.max_speed_kmh, o.max_extent_km, o.gap_warn_s,
            o.vehicle, o.max_gap_s, o.gaps, o.navsatfix_status, o.pose_world,
            o.pose_world_yaw_deg,
        )  # fmt: skip


def route_ids(cands: list[RoutePath]) -> list[str]:
    """Stable ids of a file's paths: ``<name slug>-<hash>`` (``morning-walk-3f9a2c``).

    The hash is the first 6 hex digits of the SHA-256 of the path's name and its first point
    (latitude and longitude to 1e-7 deg, or the first E N U row to 1 mm), so a path keeps its
    id when other paths are added to or removed from the file (a file index would not). Two
    paths with the same name and first point take ``-2``, ``-3``, ... in file order.
    """
    out, seen = [], {}
    for p in cands:
        if p.enu_m is not None and len(p.enu_m):
            first = ",".join(f"{x:.3f}" for x in p.enu_m[0])
        elif p.n_points:
            first = f"{float(p.lat_deg[0]):.7f},{float(p.lon_deg[0]):.7f}"
        else:
            first = ""
        digest = hashlib.sha256(f"{p.name}\0{first}".encode()).hexdigest()[:6]
        slug = re.sub(r"[^a-z0-9]+", "-", p.name.casefold()).strip("-")[:40].strip("-")
        rid = f"{slug}-{digest}" if slug else digest
        seen[rid] = seen.get(rid, 0) + 1
        out.append(rid if seen[rid] == 1 else f"{rid}-{seen[rid]}")
    return out


def _candidates(src: Path, navsatfix_status: str):
    if src.is_dir() and (src / "metadata.yaml").is_file():  # a ROS 2 bag's folder
        src = src / "metadata.yaml"
    raw = limits.read_input(src)
    return src, raw, read_route_file(src, raw, navsatfix_status=navsatfix_status)


def path_ids(src: str | Path, navsatfix_status: str = "lenient") -> list[str]:
    """The route ids ``--path=all`` would give ``src``'s paths (:func:`route_ids`), reading
    the file only (no cleaning): what the workflow expands ``paths: all`` into at parse time.
    Paths too small to be a route (fewer than two points) are left out."""
    _, _, cands = _candidates(Path(src), navsatfix_status)
    return [rid for rid, p in zip(route_ids(cands), cands, strict=True) if p.n_points >= 2]


def _ingest_alone(src, cand, raw, o: IngestOptions) -> Ingested:
    with np.errstate(over="ignore", invalid="ignore"):
        return _ingest(
            src, None, o.origin, o.dt, o.utm, o.max_speed_kmh, o.max_extent_km,
            o.gap_warn_s, o.vehicle, o.max_gap_s, o.gaps, o.navsatfix_status, o.pose_world,
            o.pose_world_yaw_deg, [cand], raw,
        )  # fmt: skip


def read_one(src: str | Path, rid: str, options: IngestOptions) -> Ingested:
    """``--path=all:ID``: the path of ``src`` whose id (:func:`route_ids`) is ``rid``, ingested
    alone as :func:`read_all` ingests it (one route of a ``paths: all`` route in the workflow)."""
    src, raw, cands = _candidates(Path(src), options.navsatfix_status)
    ids = route_ids(cands)
    if rid not in ids:
        shown = ", ".join(ids[:LIST_CANDIDATES]) + (", ..." if len(ids) > LIST_CANDIDATES else "")
        raise InputError(src, f"--path=all:{rid}: no path has this id (ids: {shown})")
    ing = _ingest_alone(src, cands[ids.index(rid)], raw, options)
    ing.meta["route_id"] = rid
    return ing


def read_all(src: str | Path, options: IngestOptions) -> tuple[list[tuple[str, Ingested]], list]:
    """``--path=all``: every candidate path of ``src`` as its own route.

    Each path is ingested alone (split at gaps, cleaned and checked as a file holding only it);
    a path that is refused is skipped. Returns ``([(id, Ingested), ...], [(id, reason), ...])``
    (ids from :func:`route_ids`); raises :class:`InputError` when no path is read.
    """
    src, raw, cands = _candidates(Path(src), options.navsatfix_status)
    done, refused = [], []
    for rid, cand in zip(route_ids(cands), cands, strict=True):
        try:
            ing = _ingest_alone(src, cand, raw, options)
        except InputError as exc:
            refused.append((rid, str(exc)))
            continue
        ing.meta["route_id"] = rid
        done.append((rid, ing))
    if not done:
        reasons = "; ".join(f"{rid}: {why}" for rid, why in refused[:3])
        raise InputError(
            src, f"--path=all: none of its {len(cands)} paths could be read ({reasons})"
        )
    return done, refused


def distance_from_origin_m(origin: Origin, lat_deg, lon_deg) -> np.ndarray:
    """Geodesic distance [m] on the WGS-84 ellipsoid from the origin's foot to each point's,
    shape (N,) (``pyproj.Geod.inv``; heights ignored; a true distance at any range, unlike the
    horizontal part of the origin's ENU, which is ``R sin(d / R)``)."""
    lat = np.asarray(lat_deg, float)
    lon = np.asarray(lon_deg, float)
    _, _, d = _GEOD.inv(
        np.full_like(lon, origin.lon_deg), np.full_like(lat, origin.lat_deg), lon, lat
    )
    return np.asarray(d, float)


def _densify_untimed(lat, lon, alt):
    """Untimed geodetic path: vertices joined by geodesics (:func:`imugen.core.geodesic.densify`);
    returns the densified lat, lon, alt and the metadata entry."""
    n = len(lat)
    lat, lon, alt, _ = densify(lat, lon, alt, GEODESIC_STEP_M)
    meta = {
        "method": "WGS-84 geodesics between the vertices (pyproj.Geod), height linear in distance",
        "step_m": GEODESIC_STEP_M,
        "sagitta_m": sagitta_m(GEODESIC_STEP_M),
        "points_added": len(lat) - n,
    }
    return lat, lon, alt, meta


def _ingest(
    src, path, origin, dt, utm, max_speed_kmh, max_extent_km, gap_warn_s, vehicle, max_gap_s, gaps,
    navsatfix_status="lenient", pose_world="enu", pose_world_yaw_deg=0.0, cands=None, raw=None,
) -> Ingested:  # fmt: skip
    src = Path(src)
    for name, value in (
        ("--max-speed-kmh", max_speed_kmh),
        ("--max-extent-km", 1.0 if max_extent_km is None else max_extent_km),
        ("--gap-warn-s", gap_warn_s),
    ):
        if not (np.isfinite(value) and value > 0):
            raise InputError(name, f"{value!r} must be a positive number")
    if isinstance(origin, str):
        origin = parse_origin(origin)
    if src.is_dir() and (src / "metadata.yaml").is_file():  # a ROS 2 bag's folder
        src = src / "metadata.yaml"
    if cands is None:
        raw = limits.read_input(src)
        cands = read_route_file(src, raw, navsatfix_status=navsatfix_status)
    elif raw is None:
        raise ValueError("candidates need the file's bytes (raw)")
    warnings: list[str] = []
    p, segments = choose_path(
        cands,
        path,
        max_gap_s=max_gap_s,
        gaps=gaps,
        source=src,
        warnings=warnings,
        select=select_path,
        vehicle=vehicle,
    )
    warnings += p.warnings
    n_in = p.n_points
    pose_cleaning = None
    if p.attitude is not None:  # a pose trajectory (imugen.ingest.pose)
        p, pose_cleaning = ipose.clean_attitude(p, src, warnings)
        p = ipose.on_the_earth(p, pose_world, pose_world_yaw_deg, src)
    if p.n_points < 2:
        raise InputError(src, f"path {p.name!r} has {n_in} point(s): a path needs at least two")

    origin_from = "option" if origin is not None else None
    if origin is None and p.carried.get("origin"):
        o = p.carried["origin"]
        origin = Origin(float(o["lat_deg"]), float(o["lon_deg"]), float(o["alt_m"]))
        _check_geodetic(*(np.array([v]) for v in origin.as_dict().values()), src, "origin")
        origin_from = "carried from " + str(p.carried.get("source", "the previous stage"))

    if p.enu_m is not None:
        _check_enu(p.enu_m, src)
        if origin is None:
            raise InputError(
                src,
                "E N U rows need an origin to be placed on the Earth: pass --origin=LAT,LON,H "
                "(the geodetic position of the first row)",
            )
        # E N U rows start at the origin; a pose file's world has its origin there
        enu_first = p.enu_m if p.attitude is not None else p.enu_m - p.enu_m[0]
        _check_enu(enu_first, src)  # differences of finite huge values may overflow
        far = ~(np.linalg.norm(enu_first, axis=1) <= ENU_SPAN_M)
        if far.any():
            i = _first_bad(far)
            raise InputError(
                src,
                f"row {i + 1} lies more than {ENU_SPAN_M / 1e3:,.0f} km from the first row "
                "(farther than two points near the Earth can be); check the units (metres)",
            )
        frame = LocalFrame(origin)
        lat, lon, alt = frame.to_geodetic(enu_first)
        _check_geodetic(lat, lon, alt, src)
        pos = enu_first
    else:
        lat, lon, alt = p.lat_deg, p.lon_deg, p.alt_m
        _check_geodetic(lat, lon, alt, src)
        pos = np.column_stack([lat, lon, alt])

    time_s, time_source, start_utc = _clock(p, pos, dt, warnings, src)
    timed = time_s is not None
    cols = {"pos": pos, "lat": lat, "lon": lon, "alt": alt}
    cols["alt_missing"] = np.zeros(p.n_points, bool) if p.alt_missing is None else p.alt_missing
    if p.attitude is not None:
        if time_s is None:
            raise InputError(src, "a pose trajectory needs its times (no usable clock)")
        cols["att"] = p.attitude
    if timed:
        cols["time"] = time_s
    cols = _dedupe(cols, timed, src, warnings)
    enu_frame = LocalFrame(origin) if p.enu_m is not None else None
    cols, cleaning = clean_path(
        cols, p, timed=timed, vehicle=vehicle, source=src, warnings=warnings, enu_frame=enu_frame
    )
    lat, lon, alt = cols["lat"], cols["lon"], cols["alt"]
    if len(lat) < 2:
        raise InputError(
            src,
            f"path {p.name!r} has fewer than two distinct points: all points are the same location",
        )

    geodesic = None
    if not timed and p.enu_m is None:
        lat, lon, alt, geodesic = _densify_untimed(lat, lon, alt)
    if origin is None:
        origin = Origin(float(lat[0]), float(lon[0]), float(alt[0]))
        origin_from = "first point"
    frame = LocalFrame(origin)
    enu = frame.to_enu(lat, lon, alt)

    seg = np.linalg.norm(np.diff(enu, axis=0), axis=1)
    length_3d = float(seg.sum())
    if length_3d == 0.0:
        raise InputError(src, f"path {p.name!r} has zero length: all points are the same location")
    dist = distance_from_origin_m(origin, lat, lon)
    lon_jump = np.abs(np.diff(lon)) > 180.0
    crosses = bool(lon_jump.any())
    if max_extent_km is not None and not dist.max() <= max_extent_km * 1000.0:  # NaN-safe
        i = int(np.argmax(np.where(np.isfinite(dist), dist, np.inf)))
        raise InputError(
            src,
            f"path {p.name!r} reaches {dist[i] / 1000:,.0f} km (geodesic) from its origin, beyond "
            f"--max-extent-km {max_extent_km:g}; raise or drop the limit (routes of any length "
            "are simulated in ECEF)",
        )
    if crosses:
        warnings.append(
            f"the path crosses the antimeridian after point {_first_bad(lon_jump) + 1}; "
            "ENU is computed through ECEF and is continuous there"
        )

    gaps = {}
    if timed:
        t = cols["time"]
        dts = np.diff(t)
        speed_kmh = seg / dts * 3.6
        bad = speed_kmh > max_speed_kmh
        if bad.any():
            i = int(np.argmax(np.where(bad, speed_kmh, -1)))
            raise InputError(
                src,
                f"implied speed {speed_kmh[i]:,.0f} km/h between points {i + 1} and {i + 2} of the kept "
                f"points ({seg[i]:.1f} m in {dts[i]:g} s) exceeds the limit of {max_speed_kmh:g} km/h "
                "(a GPS spike?); fix the file or raise --max-speed-kmh",
            )
        big = dts > gap_warn_s
        gaps = {"count_over_warn": int(big.sum()), "max_s": float(dts.max()), "warn_s": gap_warn_s}
        if big.any():
            warnings.append(
                f"{int(big.sum())} time gaps longer than {gap_warn_s:g} s (longest {dts.max():g} s): "
                "kept; the truth stage interpolates through them"
            )

    data = {}
    if timed:
        data[tenu.TIME] = cols["time"]
    data.update({tenu.LAT: lat, tenu.LON: lon, tenu.ALT: alt})
    data.update({c: enu[:, i] for i, c in enumerate(tenu.ENU)})
    if p.attitude is not None:
        q = ipose.level_attitude(cols["att"], p.attitude_frame, origin, enu)
        data.update({c: q[:, i] for i, c in enumerate(tenu.ATTITUDE)})
    utm_meta = None
    if utm:
        try:
            crs = utm_crs(origin)
        except ValueError as exc:
            raise InputError(src, f"--utm: {exc}") from None
        data[tenu.UTM[0]], data[tenu.UTM[1]] = to_utm(lat, lon, crs)
        utm_meta = {"epsg": crs.to_epsg(), "name": crs.name}
    table = pd.DataFrame(data)

    meta = {
        "stage": "ingest",
        "imugen_version": __version__,
        "source": str(src),
        "source_sha256": hashlib.sha256(raw).hexdigest(),
        "path": p.name,
        "path_kind": p.kind,
        "candidates": len(cands),
        "origin": origin.as_dict(),
        "origin_from": origin_from,
        "frame": "local ENU (x East, y North, z Up) of the origin's topocentric frame, WGS-84",
        "method": LocalFrame.method,
        "units": {k: v for k, v in UNITS.items() if k in data},
        "timed": timed,
        "time_source": time_source,
        "start_time_utc": start_utc,
        "altitude_mode": p.altitude_mode,
        "altitude_trusted": p.altitude_trusted,
        "points_in": n_in,
        "points_out": len(table),
        "length_3d_m": length_3d,
        "length_horizontal_m": float(_GEOD.line_length(lon, lat)),
        "max_distance_from_origin_m": float(dist.max()),
        "crosses_antimeridian": crosses,
        "duration_s": float(cols["time"][-1]) if timed else None,
        "gaps": gaps or None,
        "cleaning": cleaning,
        "geodesic": geodesic,
        "segments": segments,
        "utm": utm_meta,
        "pose": None
        if p.attitude is None
        else ipose.report(p, pose_world, pose_world_yaw_deg, pose_cleaning or {}),
        "notes": list(p.notes),
        "warnings": warnings,
    }
    return Ingested(table=table, meta=meta, warnings=warnings)


def write(ing: Ingested, out: str | Path) -> Path:
    """Write the table atomically (temporary name, then rename) as .parquet or .csv."""
    out = Path(out)
    suffix = out.suffix.lower()
    if suffix not in (".parquet", ".csv"):
        raise InputError(out, "output must end in .parquet or .csv")
    if suffix == ".parquet":
        return tenu.write(ing.table, ing.meta, out)
    with atomic_output(out) as tmp, tmp.open("w", encoding="utf-8", newline="\n") as fh:
        fh.write("# imugen: " + json.dumps(ing.meta) + "\n")
        ing.table.to_csv(fh, index=False)
    return out


def run(src: str | Path, out: str | Path, options: IngestOptions | None = None) -> Ingested:
    """Ingest ``src`` with ``options`` and write ``out``; returns the result."""
    ing = read(src, options or IngestOptions())
    write(ing, out)
    return ing


def all_outputs(out: str | Path, ids: list[str]) -> list[Path]:
    """Where ``--path=all`` writes: ``OUT`` without its suffix as a folder, one file per route
    id with ``OUT``'s suffix (``routes/walks.parquet`` -> ``routes/walks/007-x.parquet``)."""
    out = Path(out)
    return [out.parent / out.stem / f"{rid}{out.suffix}" for rid in ids]


def run_all(src, out, options: IngestOptions):
    """``--path=all``: :func:`read_all`, each route written to :func:`all_outputs`."""
    out = Path(out)
    if out.suffix.lower() not in (".parquet", ".csv"):
        raise InputError(out, "output must end in .parquet or .csv")
    done, refused = read_all(src, options)
    paths = all_outputs(out, [rid for rid, _ in done])
    paths[0].parent.mkdir(parents=True, exist_ok=True)
    for (_, ing), p in zip(done, paths, strict=True):
        write(ing, p)
    return list(zip(paths, (ing for _, ing in done), strict=True)), refused


def main(options: IngestOptions, src, output) -> None:
    """``imugen ingest``: :func:`run`, then its warnings and a summary line on stderr
    (``--path=all``: :func:`run_all`, a line per route and per refused path)."""
    if isinstance(options.path, str) and options.path.strip().casefold() == ALL:
        written, refused = run_all(src, output, options)
        for p, ing in written:
            m = ing.meta
            print(printable(f"{p}: path {m['path']!r}, {m['points_out']} points, "
                            f"{m['length_3d_m']:.1f} m, {len(ing.warnings)} warnings"),
                  file=sys.stderr)  # fmt: skip
        for rid, why in refused:
            print(printable(f"imugen: warning: {src}: path {rid} not read: {why}"), file=sys.stderr)
        return
    ing = run(src, output, options)
    for w in ing.warnings:
        print(printable(f"imugen: warning: {src}: {w}"), file=sys.stderr)
    m = ing.meta
    clock = f"timed {m['duration_s']:.1f} s" if m["timed"] else "untimed"
    o = m["origin"]
    print(
        f"{output}: path {m['path']!r}, {m['points_out']} points, {m['length_3d_m']:.1f} m, "
        f"{clock}, origin {o['lat_deg']:.7f},{o['lon_deg']:.7f},{o['alt_m']:.2f}",
        file=sys.stderr,
    )
