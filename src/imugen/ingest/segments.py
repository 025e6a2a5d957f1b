"""Choosing the path of a route file: trivial candidates, time gaps, ``--path longest``.

Gaps
    A timed path whose clock jumps by more than ``max_gap_s`` (default :data:`MAX_GAP_S`) is
    judged by motion with ``gaps="auto"`` (the default): bridged when the straight geodesic
    leg across it needs a speed within the vehicle class's limit and at most
    :data:`AUTO_SPEED_RATIO` times the speed around it (or :data:`AUTO_SPEED_FLOOR_MPS`) and
    it lasts at most :data:`AUTO_MAX_BRIDGE_S`, else split. A bridged gap gets virtual fixes along that leg moving as the simplest motion
    (:func:`leg_profile`): the speed changed at the class's acceleration to a held speed that
    covers the leg, or, when that speed would be a creep, a stop (braking, waiting,
    accelerating; what a car in a car park does), never a loop; every gap, its length,
    distance and the motion chosen are in the metadata and a warning. With ``gaps="split"``
    (the fixed-time rule) it is split at every such gap
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
from dataclasses import dataclass, replace
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
#: ``gaps="auto"``: spacing (s) of the virtual fixes along a bridged gap (1 s while braking or
#: accelerating: :data:`AUTO_RAMP_STEP_S`).
AUTO_STEP_S = 5.0
AUTO_RAMP_STEP_S = 1.0
#: ``gaps="auto"``: longest gap (s) bridged; a longer one is split (a logger left off for hours
#: is no motion to invent, and its virtual fixes and truth would grow without bound).
AUTO_MAX_BRIDGE_S = 3600.0
#: ``gaps="auto"``: no virtual fix closer than this (s) to a real one (the fit blends there).
AUTO_END_FREE_S = 2.5
#: ``gaps="auto"``: acceleration (m/s^2) of the braking and accelerating phases of a bridged
#: gap, per vehicle class (the classes' comfortable figures, :mod:`imugen.truth.vehicles`); at
#: most :data:`AUTO_ACCEL_MARGIN` times it where the fixes leave no room, never more (the speeds
#: at the gap's ends are lowered instead).
AUTO_ACCEL_MPS2 = {"car": 2.0, "bicycle": 1.0, "pedestrian": 0.5, "aircraft": 2.0,
                   "airliner": 1.5, "multirotor": 2.0}  # fmt: skip
AUTO_ACCEL_MARGIN = 2.0
#: ``gaps="auto"``: a leg slower than this (m/s) between the braking and accelerating phases is
#: a stop: the vehicle halts, waits and leaves (a car park, a red light), it does not creep.
AUTO_STOP_SPEED_MPS = 0.3
#: Duration of a half-cosine speed ramp per (speed change / peak acceleration): pi / 2.
RAMP = np.pi / 2.0
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


def _around(step_v: np.ndarray, ok: np.ndarray, idx) -> float:
    """Median of the step speeds ``step_v[idx]`` that are not gaps (``ok``); 0 when none."""
    idx = [j for j in idx if 0 <= j < len(step_v) and ok[j]]
    return float(np.median(step_v[idx])) if idx else 0.0


def judge_gaps(p: RoutePath, max_gap_s: float, vehicle: str) -> list[dict]:
    """Every gap longer than ``max_gap_s`` of a timed geodetic path, judged by motion (module
    docstring): ``index`` (the fix before it), ``at_s`` (from the start), ``length_s``,
    ``distance_m``, ``speed_needed_mps``, ``speed_around_mps``, ``speed_in_mps`` and
    ``speed_out_mps`` (the step speeds just before and after), ``bridge`` (bool) and, for a
    bridged gap, the motion across it (:func:`leg_profile`): ``kind`` (``"stop"`` or
    ``"leg"``), ``leg_in_mps``, ``leg_speed_mps``, ``leg_out_mps``, ``stop_s``,
    ``accel_mps2``."""
    t = p.time_unix_s
    if t is None or p.enu_m is not None or len(t) < 2 or not np.isfinite(t).all():
        return []
    dts = np.diff(t)
    _, _, d = _GEOD.inv(p.lon_deg[:-1], p.lat_deg[:-1], p.lon_deg[1:], p.lat_deg[1:])
    d = np.asarray(d, float)
    big = dts > max_gap_s
    step_v = np.where(dts > 0, d / np.where(dts > 0, dts, 1.0), 0.0)
    vmax = AUTO_MAX_SPEED_MPS.get(vehicle, max(AUTO_MAX_SPEED_MPS.values()))
    accel = AUTO_ACCEL_MPS2.get(vehicle, 1.0)
    out = []
    for i in np.flatnonzero(big):
        around = _around(step_v, ~big, [*range(i - 5, i), *range(i + 1, i + 6)])
        v_in = _around(step_v, ~big, range(i - 3, i))
        v_out = _around(step_v, ~big, range(i + 1, i + 4))
        need = float(d[i] / dts[i])
        ok = need <= vmax and need <= max(AUTO_SPEED_RATIO * around, AUTO_SPEED_FLOOR_MPS)
        ok = ok and dts[i] <= AUTO_MAX_BRIDGE_S
        g = {
            "index": int(i), "at_s": float(t[i] - t[0]), "length_s": float(dts[i]),
            "distance_m": float(d[i]), "speed_needed_mps": need, "speed_around_mps": around,
            "speed_in_mps": v_in, "speed_out_mps": v_out, "bridge": bool(ok),
        }  # fmt: skip
        if ok:
            g.update(leg_profile(float(d[i]), float(dts[i]), v_in, v_out, accel).summary())
        out.append(g)
    return out


@dataclass(frozen=True)
class LegProfile:
    """Motion along a bridged gap's geodesic: from ``v0`` to ``vc``, ``vc`` held (a stop when
    0), then to ``v1`` (speeds m/s, ``T`` s). Each speed change is a half-cosine ramp (no step
    in the acceleration, so no jerk spike where it starts or ends) of peak acceleration ``a``
    (m/s^2): it lasts ``RAMP |dv| / a`` and covers the distance of a linear ramp."""

    v0: float
    vc: float
    v1: float
    a: float
    T: float

    @property
    def t0(self) -> float:
        return RAMP * abs(self.v0 - self.vc) / self.a if self.a > 0 else 0.0

    @property
    def t1(self) -> float:
        return RAMP * abs(self.v1 - self.vc) / self.a if self.a > 0 else 0.0

    def distance(self, t: np.ndarray) -> np.ndarray:
        """Distance (m) along the leg at times ``t`` (s from its start), shape of ``t``."""

        def ramp(u, dur, va, vb):  # distance of a half-cosine ramp from va to vb after u s
            if dur <= 0.0:
                return va * u
            return va * u + 0.5 * (vb - va) * (u - dur / np.pi * np.sin(np.pi * u / dur))

        t = np.clip(np.asarray(t, float), 0.0, self.T)
        s = ramp(np.minimum(t, self.t0), self.t0, self.v0, self.vc)
        s = s + self.vc * np.clip(t - self.t0, 0.0, self.T - self.t0 - self.t1)
        return s + ramp(np.clip(t - (self.T - self.t1), 0.0, self.t1), self.t1, self.vc, self.v1)

    def times(self) -> np.ndarray:
        """Times (s) of the virtual fixes inside the leg: every :data:`AUTO_RAMP_STEP_S` while
        the speed changes, every :data:`AUTO_STEP_S` while it is held."""
        t_hold = self.T - self.t1
        parts = [
            np.arange(AUTO_RAMP_STEP_S, self.t0, AUTO_RAMP_STEP_S),
            np.arange(self.t0, t_hold, AUTO_STEP_S),
            np.arange(t_hold, self.T, AUTO_RAMP_STEP_S),
        ]
        t = np.unique(np.concatenate(parts))
        return t[(t > AUTO_END_FREE_S) & (t < self.T - AUTO_END_FREE_S)]

    def summary(self) -> dict:
        stop = self.vc == 0.0
        return {
            "kind": "stop" if stop else "leg", "leg_in_mps": float(self.v0),
            "leg_speed_mps": float(self.vc),
            "leg_out_mps": float(self.v1),
            "stop_s": float(self.T - self.t0 - self.t1) if stop else 0.0,
            "accel_mps2": float(self.a),
        }  # fmt: skip


def leg_profile(d: float, T: float, v0: float, v1: float, a: float) -> LegProfile:
    """The simplest motion across a gap of ``d`` m in ``T`` s entered at ``v0`` and left at
    ``v1`` (m/s): change speed (peak acceleration ``a``, m/s^2) to a held speed that covers ``d``; when that
    speed would be below :data:`AUTO_STOP_SPEED_MPS`, a stop (brake, wait, accelerate), the
    acceleration lowered (or raised, at most :data:`AUTO_ACCEL_MARGIN` ``a``) so braking and
    accelerating cover ``d``; where even that cannot, the end speeds are lowered."""

    def dist(vc, acc):
        return float(LegProfile(v0, vc, v1, acc, T).distance(np.array(T)))

    def feasible(vc, acc):
        return RAMP * (abs(v0 - vc) + abs(v1 - vc)) / acc <= T

    hi = max(v0, v1, 2.0 * d / T) + 1.0
    if not (feasible(hi, a) and dist(hi, a) >= d):  # ramps too long for the gap: held speed
        return LegProfile(d / T, d / T, d / T, a, T)
    leg = None
    if feasible(0.0, a) and dist(0.0, a) < d:
        lo = 0.0
        for _ in range(80):  # distance grows with the held speed (module docstring)
            mid = 0.5 * (lo + hi)
            lo, hi = (mid, hi) if dist(mid, a) < d else (lo, mid)
        leg = LegProfile(v0, 0.5 * (lo + hi), v1, a, T)
        if leg.vc >= AUTO_STOP_SPEED_MPS:
            return leg
    # a stop: braking and accelerating cover d
    e = 0.5 * (v0**2 + v1**2)
    if e <= 0.0 or d <= 0.0:
        return leg or LegProfile(0.0, 0.0, 0.0, a, T)
    acc, k = RAMP * e / d, 1.0  # braking and accelerating cover RAMP e / acc
    if acc > AUTO_ACCEL_MARGIN * a:  # no room: lower the speeds at the ends
        acc = AUTO_ACCEL_MARGIN * a
        k = np.sqrt(acc * d / (RAMP * e))
    if RAMP * k * (v0 + v1) / acc > T:  # too short a gap to stop in
        return leg or LegProfile(d / T, d / T, d / T, a, T)
    return LegProfile(k * v0, 0.0, k * v1, acc, T)


def bridge_gaps(p: RoutePath, gaps: list[dict]) -> RoutePath:
    """``p`` with virtual fixes along the geodesic of each gap to bridge, moving as
    :func:`leg_profile` says (a held speed, or a stop with its braking and accelerating
    phases); heights linear in the distance along the leg; the other gaps untouched."""
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
        leg = LegProfile(
            g["leg_in_mps"], g["leg_speed_mps"], g["leg_out_mps"], g["accel_mps2"], g["length_s"]
        )
        tv = leg.times()
        if len(tv):
            d = g["distance_m"]
            f = np.clip(leg.distance(tv) / d, 0.0, 1.0) if d > 0 else np.zeros(len(tv))
            az, _, _ = _GEOD.inv(p.lon_deg[i], p.lat_deg[i], p.lon_deg[i + 1], p.lat_deg[i + 1])
            lon, lat, _ = _GEOD.fwd(
                np.full(len(tv), p.lon_deg[i]), np.full(len(tv), p.lat_deg[i]),
                np.full(len(tv), az), f * d,
            )  # fmt: skip
            parts_lon.append(np.asarray(lon, float))
            parts_lat.append(np.asarray(lat, float))
            parts_alt.append(p.alt_m[i] + f * (p.alt_m[i + 1] - p.alt_m[i]))
            parts_t.append(p.time_unix_s[i] + tv)
            parts_miss.append(np.full(len(tv), bool(miss[i] or miss[i + 1])))
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


def _report_gaps(chosen, judged, starts, limit, info, warnings) -> None:
    """``gaps="auto"``: every judged gap of the chosen path's source in the metadata, the
    spans of virtual fixes (``virtual_s``), and one warning with the counts, the invented
    distance and the first gaps in words."""
    source_name = next((n for n, g in judged.items() if chosen.name.startswith(n)), None)
    every = judged.get(source_name, [])
    bridged = [g for g in every if g["bridge"]]
    split = [g for g in every if not g["bridge"]]
    invented = float(sum(g["distance_m"] for g in bridged))
    total = length_m(chosen)
    info["gaps"] = every
    info["bridged_gaps"] = len(bridged)
    info["invented_m"] = invented
    t = chosen.time_unix_s
    if bridged and t is not None and source_name in starts:
        # where the chosen path's fixes are virtual (s from its first fix, as ``time_s``): the
        # truth stage estimates the fixes' noise from the real ones
        t0 = float(t[0])
        spans = [(starts[source_name] + g["at_s"] - t0, g["length_s"]) for g in bridged]
        info["virtual_s"] = [
            [a, a + n] for a, n in spans if a >= -1e-6 and a + n <= float(t[-1]) - t0 + 1e-6
        ]
    if every:
        shown = "; ".join(_gap_text(g) for g in every[:REPORT_GAPS])
        more = f"; and {len(every) - REPORT_GAPS} more" if len(every) > REPORT_GAPS else ""
        warnings.append(
            f"{len(every)} time gaps longer than {limit:g} s judged by motion: {len(bridged)} "
            f"bridged ({sum(g.get('kind') == 'stop' for g in bridged)} as stops; "
            f"{invented:.0f} m invented, {100 * invented / max(total, 1e-9):.1f} % of the path), "
            f"{len(split)} split (no plausible motion across them): {shown}{more} "
            "(each in the metadata, segments.gaps)"
        )


#: Gaps named one by one in the warning of :func:`_report_gaps` (all are in the metadata).
REPORT_GAPS = 5


def _gap_text(g: dict) -> str:
    """One gap in words: where, how long, how far, and what was done."""
    head = f"at {g['at_s']:.0f} s, {g['length_s']:.0f} s over {g['distance_m']:.0f} m"
    if not g["bridge"]:
        return f"{head}: split"
    if g["kind"] == "stop":
        return f"{head}: a stop of {g['stop_s']:.0f} s (braking at {g['accel_mps2']:.2g} m/s^2)"
    return f"{head}: a leg at {g['leg_speed_mps']:.2g} m/s"


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
    starts: dict[str, float] = {}  # unix time of the first fix of each judged path
    for p in cands:
        if gaps == "auto":
            judged[p.name] = g = judge_gaps(p, limit, vehicle)
            if g:
                starts[p.name] = float(p.time_unix_s[0])
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
        _report_gaps(chosen, judged, starts, limit, info, warnings)
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
