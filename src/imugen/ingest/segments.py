"""Choosing the path of a route file: trivial candidates, time gaps, ``--path longest``.

Gaps
    A timed path whose clock jumps by more than ``max_gap_s`` (default :data:`MAX_GAP_S`) is
    never bridged silently. With ``gaps="split"`` (the default) it is split at every such gap
    into parts named ``"<name> / part k"``, which become candidate paths like GPX track
    segments: ``--path`` names or indexes one (indexes count the parts), ``--path longest``
    takes the longest. When the file holds one path (or ``--path`` names a path that was
    split), its longest part is taken with a warning listing the others, so a workflow does
    not stop on a long log with a few gaps, yet no motion is invented in them. Parts of a
    single point are dropped (noted). ``gaps="bridge"`` keeps the path whole and warns: the
    truth stage then interpolates through the gaps.
Trivial candidates
    When ``--path`` is not given and exactly one candidate is a real path, it is taken with a
    warning naming the others; a candidate is trivial when it has fewer than
    :data:`MIN_REAL_POINTS` points or is shorter than :data:`MIN_REAL_LENGTH_M`.
Segments of one track
    When ``--path`` is not given and the candidates continue each other (:func:`chain`):
    timed, each starting after the previous ends, within ``max_gap_s``, no farther than
    :data:`JOIN_SPEED_MPS` could go in the pause (plus :data:`JOIN_DISTANCE_M`); or untimed, each
    starting within :data:`JOIN_DISTANCE_M` of the previous end), the whole file is one path,
    joined with a warning. Otherwise the refusal lists the candidates.
"""

from __future__ import annotations

import itertools
from dataclasses import replace
from pathlib import Path

import numpy as np
from pyproj import Geod

from imugen.core.errors import InputError
from imugen.ingest.route import RoutePath

#: Default longest time gap (s) a path may hold before it is split.
MAX_GAP_S = 60.0
#: Fewest points of a real path.
MIN_REAL_POINTS = 5
#: Shortest real path (m).
MIN_REAL_LENGTH_M = 25.0
GAP_MODES = ("split", "bridge", "auto")
#: ``gaps="auto"``: fastest straight-line speed (m/s) a bridged gap may need, per vehicle class.
AUTO_MAX_SPEED_MPS = {"car": 60.0, "bicycle": 20.0, "pedestrian": 4.0, "aircraft": 90.0,
                      "airliner": 280.0}  # fmt: skip
#: ``gaps="auto"``: a gap may need at most this times the speed around it (or the floor below).
AUTO_SPEED_RATIO = 2.0
#: ``gaps="auto"``: speed (m/s) a gap may always need, within the class's limit.
AUTO_SPEED_FLOOR_MPS = 1.5
#: ``gaps="auto"``: spacing (s) of the virtual fixes along a bridged gap.
AUTO_STEP_S = 5.0
#: Largest distance (m) between the end of a segment and the start of the next it continues.
JOIN_DISTANCE_M = 50.0
#: Fastest straight-line speed (m/s) across the pause between continuing segments.
JOIN_SPEED_MPS = 70.0
_GEOD = Geod(ellps="WGS84")


def length_m(p: RoutePath) -> float:
    """Horizontal length (m) of a candidate: geodesic, or along its E N U rows."""
    if p.enu_m is not None:
        return float(np.nansum(np.hypot(*np.diff(p.enu_m[:, :2], axis=0).T)))
    ok = np.isfinite(p.lat_deg) & np.isfinite(p.lon_deg)
    ok &= (np.abs(p.lat_deg) <= 90) & (np.abs(p.lon_deg) <= 180)
    if ok.sum() < 2:
        return 0.0
    return float(_GEOD.line_length(p.lon_deg[ok], p.lat_deg[ok]))


def _label(p: RoutePath) -> str:
    m = length_m(p)
    size = f"{m / 1000:.2f} km" if m >= 1000 else f"{m:.0f} m"
    span = ""
    t = p.time_unix_s
    if t is not None and np.isfinite(t).all() and len(t) > 1:
        span = f", {t[-1] - t[0]:.0f} s"
    return f"{p.name!r} ({p.n_points} points, {size}{span})"


def _slice(p: RoutePath, sl: slice, name: str, note: str) -> RoutePath:
    def cut(a):
        return None if a is None else a[sl]

    geo = p.enu_m is None
    return replace(
        p,
        name=name,
        lat_deg=p.lat_deg[sl] if geo else p.lat_deg,
        lon_deg=p.lon_deg[sl] if geo else p.lon_deg,
        alt_m=p.alt_m[sl] if geo else p.alt_m,
        enu_m=cut(p.enu_m),
        time_unix_s=cut(p.time_unix_s),
        alt_missing=cut(p.alt_missing),
        attitude=cut(p.attitude),
        notes=[*p.notes, note],
        warnings=list(p.warnings),
    )


def split_at_gaps(p: RoutePath, max_gap_s: float) -> list[RoutePath]:
    """Split ``p`` at every time step longer than ``max_gap_s``; ``[p]`` when there is none.

    Paths without a complete clock are returned whole (their clock is decided later).
    """
    t = p.time_unix_s
    if t is None or len(t) < 2 or not np.isfinite(t).all():
        return [p]
    cuts = np.flatnonzero(np.diff(t) > max_gap_s) + 1
    if not len(cuts):
        return [p]
    bounds = [0, *cuts.tolist(), len(t)]
    spans = [(a, b) for a, b in itertools.pairwise(bounds) if b - a >= 2]
    dropped = len(bounds) - 1 - len(spans)
    gap_s = np.diff(t)[cuts - 1]
    note = (
        f"split at {len(cuts)} time gaps longer than {max_gap_s:g} s (longest {gap_s.max():g} s)"
        + (f"; {dropped} single-point parts dropped" if dropped else "")
    )
    if len(spans) == 1:
        a, b = spans[0]
        return [_slice(p, slice(a, b), p.name, note)]
    return [
        _slice(p, slice(a, b), f"{p.name} / part {k}", f"part {k} of {len(spans)}: {note}")
        for k, (a, b) in enumerate(spans, start=1)
    ]


def _sole_real(cands: list[RoutePath], warnings: list[str]) -> list[RoutePath]:
    real = [p for p in cands if p.n_points >= MIN_REAL_POINTS and length_m(p) >= MIN_REAL_LENGTH_M]
    if len(real) != 1:
        return cands
    others = "; ".join(_label(p) for p in cands if p is not real[0])
    warnings.append(
        f"took {real[0].name!r}, the only real path of the {len(cands)} candidates (the others "
        f"have fewer than {MIN_REAL_POINTS} points or {MIN_REAL_LENGTH_M:g} m: {others})"
    )
    return real


def judge_gaps(p: RoutePath, max_gap_s: float, vehicle: str) -> list[dict]:
    """Every gap longer than ``max_gap_s`` of a timed geodetic path, judged by motion (module
    docstring): ``index`` (the fix before it), ``at_s`` (from the start), ``length_s``,
    ``distance_m``, ``speed_needed_mps``, ``speed_around_mps``, ``bridge`` (bool)."""
    t = p.time_unix_s
    if t is None or p.enu_m is not None or len(t) < 2 or not np.isfinite(t).all():
        return []
    dts = np.diff(t)
    _, _, d = _GEOD.inv(p.lon_deg[:-1], p.lat_deg[:-1], p.lon_deg[1:], p.lat_deg[1:])
    d = np.asarray(d, float)
    big = dts > max_gap_s
    step_v = np.where(dts > 0, d / np.where(dts > 0, dts, 1.0), 0.0)
    vmax = AUTO_MAX_SPEED_MPS.get(vehicle, max(AUTO_MAX_SPEED_MPS.values()))
    out = []
    for i in np.flatnonzero(big):
        near = [j for j in range(max(0, i - 5), min(len(dts), i + 6)) if j != i and not big[j]]
        around = float(np.median(step_v[near])) if near else 0.0
        need = float(d[i] / dts[i])
        ok = need <= vmax and need <= max(AUTO_SPEED_RATIO * around, AUTO_SPEED_FLOOR_MPS)
        out.append({
            "index": int(i), "at_s": float(t[i] - t[0]), "length_s": float(dts[i]),
            "distance_m": float(d[i]), "speed_needed_mps": need, "speed_around_mps": around,
            "bridge": bool(ok),
        })  # fmt: skip
    return out


def bridge_gaps(p: RoutePath, gaps: list[dict]) -> RoutePath:
    """``p`` with virtual fixes along the geodesic of each gap to bridge (constant speed, every
    :data:`AUTO_STEP_S`; heights linear in time); the others untouched."""
    parts_lat, parts_lon, parts_alt, parts_t, parts_miss = [], [], [], [], []
    miss = p.alt_missing if p.alt_missing is not None else np.zeros(p.n_points, bool)
    start = 0
    for g in (g for g in gaps if g["bridge"]):
        i = g["index"]
        sl = slice(start, i + 1)
        parts_lat.append(p.lat_deg[sl])
        parts_lon.append(p.lon_deg[sl])
        parts_alt.append(p.alt_m[sl])
        parts_t.append(p.time_unix_s[sl])
        parts_miss.append(miss[sl])
        n = int(np.ceil(g["length_s"] / AUTO_STEP_S)) - 1
        if n > 0:
            pts = _GEOD.npts(p.lon_deg[i], p.lat_deg[i], p.lon_deg[i + 1], p.lat_deg[i + 1], n)
            f = np.arange(1, n + 1) / (n + 1)
            parts_lon.append(np.array([q[0] for q in pts]))
            parts_lat.append(np.array([q[1] for q in pts]))
            parts_alt.append(p.alt_m[i] + f * (p.alt_m[i + 1] - p.alt_m[i]))
            parts_t.append(p.time_unix_s[i] + f * g["length_s"])
            parts_miss.append(np.full(n, bool(miss[i] or miss[i + 1])))
        start = i + 1
    if start == 0:
        return p
    sl = slice(start, None)
    parts_lat.append(p.lat_deg[sl])
    parts_lon.append(p.lon_deg[sl])
    parts_alt.append(p.alt_m[sl])
    parts_t.append(p.time_unix_s[sl])
    parts_miss.append(miss[sl])
    m = np.concatenate(parts_miss)
    return replace(
        p,
        lat_deg=np.concatenate(parts_lat),
        lon_deg=np.concatenate(parts_lon),
        alt_m=np.concatenate(parts_alt),
        time_unix_s=np.concatenate(parts_t),
        alt_missing=m if m.any() else None,
        notes=list(p.notes),
        warnings=list(p.warnings),
    )


def _split_at(p: RoutePath, cuts: np.ndarray, max_gap_s: float) -> list[RoutePath]:
    """``p`` split after the fixes ``cuts`` (the indexes before the gaps)."""
    t = p.time_unix_s
    if not len(cuts):
        return [p]
    bounds = [0, *(np.asarray(cuts) + 1).tolist(), len(t)]
    spans = [(a, b) for a, b in itertools.pairwise(bounds) if b - a >= 2]
    gap_s = np.diff(t)[np.asarray(cuts)]
    note = (
        f"split at {len(cuts)} time gaps longer than {max_gap_s:g} s that no plausible motion "
        f"explains (longest {gap_s.max():g} s)"
    )
    if not spans:
        return []
    if len(spans) == 1:
        a, b = spans[0]
        return [_slice(p, slice(a, b), p.name, note)]
    return [
        _slice(p, slice(a, b), f"{p.name} / part {k}", f"part {k} of {len(spans)}: {note}")
        for k, (a, b) in enumerate(spans, start=1)
    ]


def _report_gaps(chosen, group, judged, limit, info, warnings) -> None:
    """``gaps="auto"``: every judged gap of the chosen path's source in the metadata, and one
    warning with the counts and the invented distance."""
    source_name = next((n for n, g in judged.items() if chosen.name.startswith(n)), None)
    every = judged.get(source_name, [])
    bridged = [g for g in every if g["bridge"]]
    split = [g for g in every if not g["bridge"]]
    invented = float(sum(g["distance_m"] for g in bridged))
    total = length_m(chosen)
    info["gaps"] = every
    info["bridged_gaps"] = len(bridged)
    info["invented_m"] = invented
    if every:
        warnings.append(
            f"{len(every)} time gaps longer than {limit:g} s judged by motion: {len(bridged)} "
            f"bridged by straight legs at the speed they need ({invented:.0f} m invented, "
            f"{100 * invented / max(total, 1e-9):.1f} % of the path), {len(split)} split "
            f"(no plausible motion across them); each is listed in the metadata (segments.gaps)"
        )


def chain(cands: list[RoutePath], max_gap_s: float) -> bool:
    """True when the candidates, in file order, are segments of one track (module docstring)."""
    if len(cands) < 2 or any(p.enu_m is not None or p.n_points < 1 for p in cands):
        return False
    timed = [p.time_unix_s is not None and np.isfinite(p.time_unix_s).all() for p in cands]
    if any(timed) and not all(timed):
        return False
    if len({p.altitude_trusted for p in cands}) > 1:
        return False
    for a, b in itertools.pairwise(cands):
        _, _, d = _GEOD.inv(a.lon_deg[-1], a.lat_deg[-1], b.lon_deg[0], b.lat_deg[0])
        if not np.isfinite(d):
            return False
        if timed[0]:
            gap = float(b.time_unix_s[0] - a.time_unix_s[-1])
            if not (0.0 <= gap <= max_gap_s and d <= JOIN_DISTANCE_M + JOIN_SPEED_MPS * gap):
                return False
        elif d > JOIN_DISTANCE_M:
            return False
    return True


def join(cands: list[RoutePath], source) -> RoutePath:
    """The candidates of a :func:`chain` as one path (the first's name, ``"<name> + k more"``)."""

    def cat(attr):
        vals = [getattr(p, attr) for p in cands]
        return None if any(v is None for v in vals) else np.concatenate(vals)

    missing = [
        p.alt_missing if p.alt_missing is not None else np.zeros(p.n_points, bool) for p in cands
    ]
    alt_missing = np.concatenate(missing)
    first = cands[0]
    names = ", ".join(repr(p.name) for p in cands)
    return replace(
        first,
        name=f"{first.name} + {len(cands) - 1} more" if len(cands) > 1 else first.name,
        lat_deg=cat("lat_deg"),
        lon_deg=cat("lon_deg"),
        alt_m=cat("alt_m"),
        time_unix_s=cat("time_unix_s"),
        alt_missing=alt_missing if alt_missing.any() else None,
        notes=[*first.notes, f"joined {len(cands)} segments of one track: {names}"],
        warnings=list(dict.fromkeys(w for p in cands for w in p.warnings)),
    )


def _longest(group: list[RoutePath], why: str, warnings: list[str]) -> RoutePath:
    best = max(group, key=length_m)
    others = [p for p in group if p is not best]
    if others:
        warnings.append(
            f"{why}: took the longest, {_label(best)}; not used: "
            + "; ".join(_label(p) for p in others)
            + " (choose one with --path NAME or INDEX, or bridge the gaps with --gaps bridge)"
        )
    return best


def choose_path(
    cands: list[RoutePath],
    spec: str | int | None,
    *,
    max_gap_s: float | None,
    gaps: str,
    source: str | Path,
    warnings: list[str],
    select,
    vehicle: str = "car",
) -> tuple[RoutePath, dict]:
    """Choose one candidate path, splitting at gaps first (see the module docstring).

    Parameters
    ----------
    cands : list of RoutePath
        Every candidate of the file, as read.
    spec : str or int or None
        ``--path``: a name, a 1-based index, ``"longest"``, or None.
    max_gap_s : float or None
        Longest time gap kept inside a path (s); None: :data:`MAX_GAP_S`.
    gaps : {"split", "bridge", "auto"}
        What to do with longer gaps (``auto``: judged by motion, :func:`judge_gaps`).
    source : path-like
        File name for messages.
    warnings : list of str
        Appended with what was decided.
    select : callable
        ``select(cands, spec, source)``: the name/index selection of :mod:`imugen.ingest.stage`.
    vehicle : str
        Vehicle class (``gaps="auto"``).

    Returns
    -------
    path : RoutePath
    info : dict
        For the metadata: ``mode``, ``max_gap_s``, ``parts`` (of the chosen path's original),
        ``not_used`` (names of the other parts; with ``longest``, of every other candidate),
        ``bridged_gaps``.
    """
    if gaps not in GAP_MODES:
        raise InputError("--gaps", f"{gaps!r} is not one of {', '.join(GAP_MODES)}")
    limit = MAX_GAP_S if max_gap_s is None else float(max_gap_s)
    if not (np.isfinite(limit) and limit > 0):
        raise InputError("--max-gap-s", f"{max_gap_s!r} must be a positive number of seconds")
    carried = cands[0].carried.get("segments") if len(cands) == 1 else None
    if carried:
        return cands[0], dict(carried, carried=True)
    info = {"mode": gaps, "max_gap_s": limit, "parts": 1, "not_used": [], "bridged_gaps": 0}
    spec_s = None if spec is None or spec == "" else str(spec)
    if spec_s is None and len(cands) > 1 and chain(cands, limit):
        warnings.append(
            f"joined the {len(cands)} paths of the file, segments of one track that continue "
            f"each other in time and space ({', '.join(_label(p) for p in cands[:5])}"
            f"{', ...' if len(cands) > 5 else ''}; choose one with --path NAME or INDEX)"
        )
        cands = [join(cands, source)]
    if spec_s is None and len(cands) > 1:
        cands = _sole_real(cands, warnings)
    groups: dict[str, list[RoutePath]] = {}
    expanded: list[RoutePath] = []
    judged: dict[str, list[dict]] = {}
    for p in cands:
        if gaps == "auto":
            judged[p.name] = g = judge_gaps(p, limit, vehicle)
            cuts = np.array([x["index"] for x in g if not x["bridge"]], int)
            parts = [
                bridge_gaps(q, judge_gaps(q, limit, vehicle)) for q in _split_at(p, cuts, limit)
            ]
            if len(parts) == 1:
                parts[0] = replace(parts[0], name=p.name)
        else:
            parts = split_at_gaps(p, limit) if gaps == "split" else [p]
        if len(parts) > 1:
            groups[p.name] = parts
        expanded += parts
    if not expanded:
        raise InputError(
            source,
            f"no path is left after splitting at time gaps longer than {limit:g} s: every part "
            "has a single point (raise --max-gap-s, or keep the gaps with --gaps=bridge)",
        )
    if spec_s is not None and spec_s.casefold() == "longest":
        chosen = _longest(expanded, "--path longest", warnings)
        group = next((g for g in groups.values() if any(q is chosen for q in g)), [chosen])
        info["not_used"] = [p.name for p in expanded if p is not chosen]
    else:
        group = None
        if spec_s is None and len(cands) == 1 and groups:
            group = groups[cands[0].name]
        elif spec_s is not None and spec_s not in {p.name for p in expanded}:
            hits = [n for n in groups if n == spec_s] or [
                n for n in groups if n.casefold() == spec_s.casefold()
            ]
            group = groups[hits[0]] if len(hits) == 1 else None
        if group is not None:
            why = f"{len(group)} parts after splitting at gaps longer than {limit:g} s"
            chosen = _longest(group, why, warnings)
        else:
            chosen = select(expanded, spec, source)
            group = next((g for g in groups.values() if any(q is chosen for q in g)), [chosen])
    info["parts"] = len(group)
    info["not_used"] = info["not_used"] or [p.name for p in group if p is not chosen]
    if gaps == "auto":
        _report_gaps(chosen, group, judged, limit, info, warnings)
    t = chosen.time_unix_s
    if gaps == "bridge" and t is not None and np.isfinite(t).all():
        n_long = int((np.diff(t) > limit).sum())
        info["bridged_gaps"] = n_long
        if n_long:
            warnings.append(
                f"bridged {n_long} time gaps longer than {limit:g} s (--gaps bridge, longest "
                f"{np.diff(t).max():g} s): the truth stage interpolates motion through them"
            )
    return chosen, info
