"""Robust cleaning of a GNSS track at ingestion: outliers, missing heights, noise levels.

Real logs hold spikes (a fix kilometres off for one epoch), multipath heights (tens of metres
for a few epochs) and fixes without a height. Instead of refusing the file, ingestion removes
what a vehicle cannot do and says so; it refuses only when too little survives.

Criterion (timed paths)
    For every point the *chord deviation* ``d_i = |p_i - p̂_i|``, where ``p̂_i`` interpolates
    linearly in time between its kept neighbours (end points: extrapolation from the next
    two), is the displacement a detour through ``p_i`` needs. A vehicle whose acceleration is
    bounded by ``a_max`` deviates from the chord by at most ``a_max dt_a dt_b / 2`` (exact for
    constant acceleration; ``dt_a``, ``dt_b`` the time steps on either side), and white
    position noise of standard deviation ``sigma`` adds ``sigma sqrt(1.5)`` per axis. A point is
    an outlier when ``d_i > a_max dt_a dt_b / 2 + K_SIGMA sigma sqrt(1.5)``. ``sigma`` is
    estimated robustly from the median chord deviation (median of a Rayleigh variable for the
    horizontal, of a half-normal one for the vertical), so a few outliers cannot inflate it.
    In each run of consecutive violations the point farthest from the median of the
    predictions of its neighbour pairs is removed and the deviations recomputed, until none violates: a spike's
    neighbours, which violate the chord criterion too but sit on the median, are kept. Horizontal outliers remove the point; vertical
    ones (multipath heights) only its height, which is then interpolated.
Refusal
    When more than ``1 - MIN_KEPT_FRACTION`` (50 %) of the points are outliers the file is
    refused: beyond that fraction the median no longer describes the track (breakdown point of
    the median), so the criterion cannot tell the track from its outliers.
Missing heights
    Points the reader marks without a height (GPX without ``<ele>``, NMEA RMC-only epochs, IGC
    fixes without GNSS altitude, ROS NaN) get a height interpolated linearly in time (untimed:
    along the horizontal distance) between their neighbours, held at the ends; counted and
    flagged in the metadata, never 0 m inside a track.
Noise
    Horizontal and vertical position noise (m) estimated separately from the median chord
    deviations of the kept points; on sparse fixes they include real manoeuvres, so they are
    upper bounds.
Metadata (``cleaning`` of the ingest metadata, carried through the CSV stage)
    ``vehicle``, ``limits``, ``k_sigma``, ``min_kept_fraction``, ``points_in``,
    ``outliers_removed`` and ``outlier_points`` (1-based, of the points kept after duplicate
    removal), ``heights_rejected``, ``heights_filled`` and ``height_filled_points`` (1-based
    rows of the output), ``noise_horizontal_m``, ``noise_vertical_m`` (None when untimed),
    ``at_rest`` (:func:`merge_rest`, None when no run of GPS jitter at rest was found).
At rest
    Runs of consecutive fixes that are GPS jitter around one place (:func:`rest_runs`) are
    put at their centroid: one point on an untimed path, every fix kept (heights held) on a
    timed one, so the truth neither crawls through the jitter nor counts it as path.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from imugen.core.errors import InputError
from imugen.core.jit import njit

if TYPE_CHECKING:
    from imugen.core.frames import LocalFrame


@dataclass(frozen=True)
class Limits:
    """Motion a vehicle class can perform (SI), used to recognise impossible fixes.

    Attributes
    ----------
    max_accel_mps2 : float
        Horizontal acceleration bound (m/s^2), braking and turning combined.
    max_vaccel_mps2 : float
        Vertical acceleration bound (m/s^2).
    """

    max_accel_mps2: float
    max_vaccel_mps2: float
    max_speed_mps: float = 350.0


#: Generous physical bounds per vehicle class: a car brakes or corners at up to about 1 g; a
#: bicycle or a runner at about 0.6 g; an aircraft pulls several g. Vertical bounds are those
#: of road crests and dips (car, bicycle), of steps and jumps (pedestrian), of manoeuvres
#: (aircraft).
VEHICLE_LIMITS = {
    "car": Limits(10.0, 5.0, 90.0),
    "bicycle": Limits(6.0, 4.0, 30.0),
    "pedestrian": Limits(6.0, 4.0, 15.0),
    "aircraft": Limits(30.0, 30.0, 350.0),
    "airliner": Limits(30.0, 30.0, 350.0),
    "multirotor": Limits(30.0, 30.0, 40.0),
}
#: Outlier threshold in noise standard deviations (a 2-D Gaussian exceeds 5 sigma with
#: probability 4e-6).
K_SIGMA = 5.0
#: Least fraction of the points that must survive outlier removal.
MIN_KEPT_FRACTION = 0.5
#: Most point numbers listed in the metadata (``outlier_points``, ``height_filled_points``).
MAX_LISTED = 1000
#: Neighbours on each side whose pair predictions pick the outlier of a violating run.
MEDIAN_HALF_WINDOW = 3
#: Floor of the noise estimates (m): quantised coordinates can give a median deviation of 0.
NOISE_FLOOR_M = 0.05

#: Ceiling of the noise estimates (m): GNSS noise is metres; a median deviation implying more
#: is a track mostly made of outliers, which the ceiling lets the criterion find and refuse.
NOISE_CEILING_M = 20.0

_RAYLEIGH_MEDIAN = np.sqrt(2.0 * np.log(2.0))  # median of a unit Rayleigh variable
_HALFNORMAL_MEDIAN = 0.6744897501960817  # median of |N(0, 1)|
_CHORD = np.sqrt(1.5)  # std of p_i - (p_{i-1} + p_{i+1}) / 2 per unit of position noise


def chord_deviation(t: np.ndarray, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Deviation of every point from the chord of its neighbours, and its acceleration factor.

    Parameters
    ----------
    t : ndarray, shape (n,)
        Strictly increasing times (s), n >= 3.
    x : ndarray, shape (n, k)
        Positions (m).

    Returns
    -------
    d : ndarray, shape (n,)
        ``|x_i - x̂_i|`` (m), ``x̂_i`` the linear interpolation (ends: extrapolation) of the
        neighbours at ``t_i``.
    w : ndarray, shape (n,)
        ``dt_a dt_b / 2`` (s^2): a constant acceleration ``a`` deviates by ``a w``.
    """
    dt = np.diff(t)
    lo, hi = np.arange(len(t)) - 1, np.arange(len(t)) + 1
    lo[0], hi[0] = 1, 2
    lo[-1], hi[-1] = len(t) - 3, len(t) - 2
    lam = (t - t[lo]) / (t[hi] - t[lo])
    pred = x[lo] + lam[:, None] * (x[hi] - x[lo])
    d = np.linalg.norm(x - pred, axis=1)
    w = np.empty(len(t))
    w[1:-1] = dt[:-1] * dt[1:] / 2
    w[0] = dt[0] * (dt[0] + dt[1]) / 2
    w[-1] = dt[-1] * (dt[-1] + dt[-2]) / 2
    return d, w


def noise_sigma(d: np.ndarray, dims: int) -> float:
    """Position noise (m) from chord deviations: median / (median of the unit distribution).

    Bounded to [:data:`NOISE_FLOOR_M`, :data:`NOISE_CEILING_M`].
    """
    scale = _RAYLEIGH_MEDIAN if dims == 2 else _HALFNORMAL_MEDIAN
    return min(max(float(np.median(d)) / (scale * _CHORD), NOISE_FLOOR_M), NOISE_CEILING_M)


def median_residual(
    t: np.ndarray, x: np.ndarray, at: np.ndarray | None = None, half: int = MEDIAN_HALF_WINDOW
) -> np.ndarray:
    """Distance of every point from the median prediction of its neighbours.

    Every pair of neighbours ``(i - a, i + b)``, ``1 <= a, b <= half``, predicts ``x_i`` by
    linear interpolation in time; the per-axis median of these predictions is robust to
    outliers among the neighbours (a spike spoils only the pairs it is in). The first and the
    last point, which have neighbours on one side only, extrapolate from pairs on that side.

    Parameters
    ----------
    t : ndarray, shape (n,)
        Strictly increasing times (s), n >= 3.
    x : ndarray, shape (n, k)
        Positions (m).
    at : ndarray of int, shape (m,), optional
        Points to evaluate (default all).

    Returns
    -------
    ndarray, shape (m,)
        ``|x_i - median prediction|`` (m) at the points ``at``.
    """
    n = len(t)
    i = np.arange(n) if at is None else np.asarray(at)
    straddle = [(-a, b) for a in range(1, half + 1) for b in range(1, half + 1)]
    one_side = [(a, b) for a in range(1, half + 1) for b in range(a + 1, half + 2)]
    one_side += [(-b, -a) for a, b in one_side]
    preds = []
    for lo, hi in straddle + one_side:
        j, k = i + lo, i + hi
        ok = (j >= 0) & (k < n) & (j != k)
        if (lo, hi) in one_side:
            ok &= (i == 0) | (i == n - 1)
        j, k = np.where(ok, j, 0), np.where(ok, k, 1)
        lam = (t[i] - t[j]) / (t[k] - t[j])
        p = x[j] + lam[:, None] * (x[k] - x[j])
        p[~ok] = np.nan
        preds.append(p)
    med = np.nanmedian(np.stack(preds, axis=1), axis=1)
    return np.linalg.norm(x[i] - med, axis=1)


#: Predecessors the speed gate looks back over (:func:`speed_outliers`).
SPEED_GATE_WINDOW = 120


def speed_outliers(
    t: np.ndarray, x: np.ndarray, v_max: float, sigma: float, window: int = SPEED_GATE_WINDOW
) -> np.ndarray:
    """Fixes no vehicle of speed ``v_max`` could have reached: indexes off the longest chain of
    fixes whose consecutive steps are all possible (issue 27).

    A step from fix i to fix j is possible when ``|x_j - x_i| <= v_max (t_j - t_i) + K_SIGMA
    sigma sqrt(2)``. The kept fixes are the longest time-ordered chain of possible steps
    (dynamic programming over ``window`` predecessors): a cold-start offset at the start, a
    plateau of multipath fixes or a far excursion cannot join the track without two impossible
    steps, so the chain leaves them out (the acceleration criterion of :func:`find_outliers`
    takes a long plateau for the track, and a smooth excursion passes it).

    Parameters
    ----------
    t : ndarray, shape (n,)
        Times [s], increasing.
    x : ndarray, shape (n, 2)
        Horizontal positions [m].
    v_max : float
        The vehicle class's top speed [m/s].
    sigma : float
        Horizontal noise of one coordinate [m].

    Returns
    -------
    ndarray of int
        Indexes of the outlying fixes (sorted).
    """
    t = np.asarray(t, float)
    x = np.asarray(x, float)
    n = len(t)
    if n < 3:
        return np.zeros(0, dtype=int)
    tol = K_SIGMA * sigma * np.sqrt(2.0)
    best = np.ones(n, dtype=int)  # longest chain ending at j
    prev = np.full(n, -1)
    for j in range(1, n):
        i0 = max(0, j - window)
        d = np.hypot(x[i0:j, 0] - x[j, 0], x[i0:j, 1] - x[j, 1])
        ok = d <= v_max * (t[j] - t[i0:j]) + tol
        if ok.any():
            cand = np.where(ok, best[i0:j], 0)
            i = j - 1 - int(np.argmax(cand[::-1]))  # the latest among the longest
            best[j] = best[i] + 1
            prev[j] = i
    keep = np.zeros(n, dtype=bool)
    j = int(np.argmax(best))
    while j >= 0:
        keep[j] = True
        j = prev[j]
    return np.flatnonzero(~keep)


def find_outliers(t: np.ndarray, x: np.ndarray, a_max: float) -> np.ndarray:
    """Indices of the points whose chord deviation no bounded acceleration explains.

    Detection by the chord criterion (module docstring); within each run of consecutive
    violating points one point is removed per pass, the one farthest from the median
    prediction of its neighbours (:func:`median_residual`; then the largest violation), because a spike's neighbours violate the
    chord criterion too but sit on the median. Passes repeat until nothing violates.

    Parameters
    ----------
    t : ndarray, shape (n,)
        Strictly increasing times (s).
    x : ndarray, shape (n, k)
        Positions (m): k = 2 horizontal, k = 1 vertical.
    a_max : float
        Acceleration bound (m/s^2).

    Returns
    -------
    ndarray of int
        Sorted indices of the outliers.
    """
    keep = np.ones(len(t), dtype=bool)
    dims = x.shape[1]
    while keep.sum() >= 4:
        idx = np.flatnonzero(keep)
        d, w = chord_deviation(t[idx], x[idx])
        sigma = noise_sigma(d, dims)
        ratio = d / (a_max * w + K_SIGMA * sigma * _CHORD)
        over = np.flatnonzero(ratio > 1.0)
        if not len(over):
            break
        run = np.cumsum(np.diff(over, prepend=-2) > 1)
        resid = median_residual(t[idx], x[idx], over)
        order = np.lexsort((ratio[over], resid, run))
        last = np.flatnonzero(np.diff(run[order], append=run[order][-1] + 1))
        keep[idx[over[order[last]]]] = False
        if (~keep).sum() > (1.0 - MIN_KEPT_FRACTION) * len(t):
            break
    return np.flatnonzero(~keep)


def fill(x: np.ndarray, values: np.ndarray, missing: np.ndarray) -> np.ndarray:
    """Interpolate ``values`` linearly in ``x`` where ``missing``; held at the ends."""
    out = values.copy()
    have = ~missing
    out[missing] = np.interp(x[missing], x[have], values[have])
    return out


def _frame(cols: dict, enu_frame: LocalFrame | None) -> LocalFrame:
    """The metric frame of :func:`_metric`: ``enu_frame``, else the first point's."""
    if enu_frame is not None:
        return enu_frame
    from imugen.core.frames import LocalFrame, Origin  # pyproj: only when a file is geographic

    return LocalFrame(Origin(float(cols["lat"][0]), float(cols["lon"][0]), float(cols["alt"][0])))


def _metric(cols: dict, enu_frame: LocalFrame | None) -> np.ndarray:
    """Positions (n, 3) [m] in :func:`_frame`."""
    if enu_frame is not None:
        return np.array(cols["pos"], dtype=float)
    return _frame(cols, None).to_enu(cols["lat"], cols["lon"], cols["alt"])


def clean_path(
    cols: dict,
    p,
    *,
    timed: bool,
    vehicle: str,
    source: str | Path,
    warnings: list[str],
    enu_frame: LocalFrame | None = None,
) -> tuple[dict, dict]:
    """Fill missing heights and remove outliers of one ingested path.

    Parameters
    ----------
    cols : dict of ndarray
        Ingestion's per-point columns ``pos`` (n, 3), ``lat``, ``lon``, ``alt``, ``alt_missing``
        and, when timed, ``time`` (s); all shape (n,) but ``pos``.
    p : RoutePath
        The path as read (altitude mode and trust, carried metadata).
    timed : bool
        Whether ``cols["time"]`` is the clock.
    vehicle : str
        Key of :data:`VEHICLE_LIMITS`.
    source : path-like
        File name for messages.
    warnings : list of str
        Appended with what was done.
    enu_frame : LocalFrame, optional
        For E N U input (``pos`` in metres): the frame giving lat/lon/alt back.

    Returns
    -------
    cols : dict
        The columns with outliers removed and heights filled.
    report : dict
        Counts and estimates for the metadata (see the module docstring).
    """
    if p.carried.get("cleaning"):
        return cols, dict(p.carried["cleaning"], carried=True)
    if vehicle not in VEHICLE_LIMITS:
        raise InputError("--vehicle", f"{vehicle!r} is not one of {', '.join(VEHICLE_LIMITS)}")
    lim = VEHICLE_LIMITS[vehicle]
    n_in = len(cols["lat"])
    missing = np.asarray(cols.pop("alt_missing"), dtype=bool)
    report = {
        "vehicle": vehicle,
        "limits": asdict(lim),
        "k_sigma": K_SIGMA,
        "min_kept_fraction": MIN_KEPT_FRACTION,
        "points_in": n_in,
        "outliers_removed": 0,
        "outlier_points": [],
        "heights_rejected": 0,
        "heights_filled": 0,
        "height_filled_points": [],
        "noise_horizontal_m": None,
        "noise_vertical_m": None,
    }
    kml = p.kind in ("LineString", "Track")
    if kml and p.altitude_mode is None and np.any(cols["alt"] != 0):
        warnings.append(
            "heights kept as written although the file gives no altitudeMode (KML default "
            "clampToGround); they are flagged as untrusted in the metadata"
        )
    enu = _metric(cols, enu_frame)
    if not timed and n_in >= 5 and stale_first(enu):
        for k in cols:
            cols[k] = cols[k][1:]
        enu, missing = enu[1:], missing[1:]
        report["stale_first_removed"] = True
        warnings.append(
            "removed the first point: it lies where the path ends, and its leg to the next "
            "point is longer than any the path draws (a logger's last known position, "
            "written before its first fix)"
        )
    if timed and n_in >= 4:
        t = cols["time"]
        d_h, _ = chord_deviation(t, enu[:, :2])
        fast = speed_outliers(t, enu[:, :2], lim.max_speed_mps, noise_sigma(d_h, 2))
        if len(fast) > (1.0 - MIN_KEPT_FRACTION) * n_in:  # the class, not the fixes, is wrong
            warnings.append(
                f"most of the track moves faster than a {vehicle}'s {lim.max_speed_mps:g} m/s: "
                "no speed gate applied; check --vehicle"
            )
            fast = np.zeros(0, dtype=int)
        rest = np.setdiff1d(np.arange(n_in), fast)
        bad = np.union1d(fast, rest[find_outliers(t[rest], enu[rest, :2], lim.max_accel_mps2)])
        if len(fast):
            warnings.append(
                f"removed {len(fast)} fixes no {vehicle} could reach (steps beyond "
                f"{lim.max_speed_mps:g} m/s plus noise from the longest consistent chain: a "
                "cold start, a multipath plateau or an excursion)"
            )
        report["speed_outliers_removed"] = len(fast)
        if len(bad) > (1.0 - MIN_KEPT_FRACTION) * n_in:
            raise InputError(
                source,
                f"{len(bad)} of {n_in} points are outliers for a {vehicle} (implied acceleration "
                f"above {lim.max_accel_mps2:g} m/s^2 plus {K_SIGMA:g} sigma of noise): less than "
                f"{MIN_KEPT_FRACTION:.0%} of the track survives; check --vehicle or the file",
            )
        if len(bad):
            keep = np.ones(n_in, dtype=bool)
            keep[bad] = False
            for k in cols:
                cols[k] = cols[k][keep]
            enu, missing, t = enu[keep], missing[keep], t[keep]
            report["outliers_removed"] = len(bad)
            report["outlier_points"] = (bad[:MAX_LISTED] + 1).tolist()
            acc = np.setdiff1d(bad, fast)
            shown = ", ".join(str(i + 1) for i in acc[:10]) + (", ..." if len(acc) > 10 else "")
            if len(acc):
                warnings.append(
                    f"removed {len(acc)} horizontal outliers (points {shown} of the kept points; "
                    f"implied acceleration beyond a {vehicle}'s {lim.max_accel_mps2:g} m/s^2 plus "
                    "noise)"
                )
        if np.any(cols["alt"][~missing] != 0):
            have = np.flatnonzero(~missing)
            if len(have) >= 4:
                vbad = have[find_outliers(t[have], enu[have, 2:], lim.max_vaccel_mps2)]
                if len(vbad):
                    missing = missing.copy()
                    missing[vbad] = True
                    report["heights_rejected"] = len(vbad)
                    warnings.append(
                        f"rejected {len(vbad)} outlying heights (multipath?): vertical "
                        f"acceleration beyond {lim.max_vaccel_mps2:g} m/s^2 plus noise; "
                        "interpolated from their neighbours"
                    )
    if missing.any() and not missing.all():
        x = cols["time"] if timed else _along(enu)
        filled = fill(x, enu[:, 2] if enu_frame is not None else cols["alt"], missing)
        if enu_frame is not None:
            cols["pos"] = np.column_stack([enu[:, :2], filled])
            cols["lat"], cols["lon"], cols["alt"] = enu_frame.to_geodetic(cols["pos"])
        else:
            cols["alt"] = filled
            cols["pos"] = np.column_stack([cols["lat"], cols["lon"], filled])
        n_fill = int(missing.sum()) - report["heights_rejected"]
        report["heights_filled"] = int(missing.sum())
        report["height_filled_points"] = (np.flatnonzero(missing)[:MAX_LISTED] + 1).tolist()
        if n_fill:
            warnings.append(
                f"{n_fill} points have no height: interpolated from their neighbours "
                "(not 0 m), flagged in the metadata"
            )
        enu = _metric(cols, enu_frame)
    if timed and len(cols["time"]) >= 3:  # before the fixes at rest coincide
        d_h, _ = chord_deviation(cols["time"], enu[:, :2])
        d_v, _ = chord_deviation(cols["time"], enu[:, 2:])
        report["noise_horizontal_m"] = noise_sigma(d_h, 2)
        report["noise_vertical_m"] = noise_sigma(d_v, 1)
    report["at_rest"] = None
    enu = _metric(cols, enu_frame)  # the frame of the points kept (a stale first one removed)
    h_read = enu[:, 2].copy()  # the heights as read (timed: merge_rest keeps every fix)
    if "att" not in cols:  # a pose trajectory is not a GNSS log
        noise = report["noise_horizontal_m"] if timed else UNTIMED_NOISE_M
        cols, enu, rest = merge_rest(cols, enu, noise or UNTIMED_NOISE_M, timed=timed,
                                     enu_frame=enu_frame)  # fmt: skip
        report["at_rest"] = rest
        if rest:
            what = (
                "their fixes placed at the cluster's centroid (the truth stands still there)"
                if timed
                else "each merged into one point (an untimed path has no stops)"
            )
            warnings.append(
                f"{rest['count']} clusters of GPS jitter at rest ({rest['fixes']} fixes within "
                f"{rest['radius_m']:.1f} m of their centroid, no heading kept): {what}; path "
                f"length {rest['length_before_m']:.0f} -> {rest['length_after_m']:.0f} m"
            )
    if timed and vehicle in FIXED_WING and len(cols["time"]) >= 3:
        h_new, runs = still_heights(cols["time"], enu, report["noise_horizontal_m"])
        if runs:
            drift = float(np.max(np.abs(h_new - h_read)))
            if enu_frame is not None:
                cols["pos"] = np.column_stack([enu[:, :2], h_new])
                cols["lat"], cols["lon"], cols["alt"] = enu_frame.to_geodetic(cols["pos"])
            else:
                cols["alt"] = cols["alt"] + (h_new - enu[:, 2])
                cols["pos"] = np.column_stack([cols["lat"], cols["lon"], cols["alt"]])
            enu = _metric(cols, enu_frame)
            report["still_runs_s"] = [[float(cols["time"][a]), float(cols["time"][b])]
                                      for a, b in runs]  # fmt: skip
            warnings.append(
                f"{len(runs)} stretches where the aircraft stands still (longest "
                f"{max(cols['time'][b] - cols['time'][a] for a, b in runs):.0f} s): their GPS "
                f"heights, wandering up to {drift:.1f} m, held at the heights where it moves "
                "(a parked aircraft does not climb)"
            )
    return cols, report


#: :func:`stale_first`: the first leg is this many times the median leg, or more ...
STALE_LEG_RATIO = 20.0
#: ... and at least this long (m) ...
STALE_MIN_M = 1000.0
#: ... and the first point lies within this fraction of that leg from the path's end.
STALE_END_FRACTION = 0.05


def stale_first(enu: np.ndarray) -> bool:
    """Whether an untimed path's first point (``enu`` (n, 3), m) is a stale fix: a logger's
    last known position (where the previous recording ended, here the path's end) written
    before its first fix, so that the path starts with a jump out and a flight back: its
    first leg is at least :data:`STALE_LEG_RATIO` times the median leg and
    :data:`STALE_MIN_M`, and the point lies within :data:`STALE_END_FRACTION` of that leg
    from the last point."""
    legs = np.linalg.norm(np.diff(enu[:, :2], axis=0), axis=1)
    first = float(legs[0])
    to_end = float(np.linalg.norm(enu[0, :2] - enu[-1, :2]))
    return bool(
        first >= max(STALE_LEG_RATIO * float(np.median(legs[1:])), STALE_MIN_M)
        and to_end <= STALE_END_FRACTION * first
    )


#: Classes whose heights are held while they stand still (:func:`still_heights`): fixed-wing
#: aircraft cannot hover, so a height change at rest is the GPS's (a multirotor can).
FIXED_WING = ("aircraft", "airliner")
#: :func:`still_heights`: standing still is a horizontal speed below this (m/s) over
#: :data:`STILL_WINDOW_S` (plus the fixes' noise), for at least :data:`STILL_MIN_S`.
STILL_SPEED_MPS = 0.3
STILL_WINDOW_S = 10.0
STILL_MIN_S = 30.0
#: :func:`still_heights`: the height at an end of a still stretch is the median over this (s).
STILL_END_S = 20.0


def still_heights(
    t: np.ndarray, enu: np.ndarray, noise_m: float
) -> tuple[np.ndarray, list[tuple[int, int]]]:
    """Heights of a timed path with those of its still stretches held (a parked aircraft).

    A fix is still when the horizontal displacement across the fixes within
    :data:`STILL_WINDOW_S` around it is below :data:`STILL_SPEED_MPS` times their span plus
    :data:`K_SIGMA` times the noise of a difference of two fixes (``noise_m``, m); runs
    of still fixes lasting :data:`STILL_MIN_S` or more are still stretches. Inside one, the
    height is that where the vehicle moves again (the median of the last :data:`STILL_END_S`
    of it), or where it came to rest when it never moves again; between two moving phases,
    linear in time from the one to the other (continuous with both). Returns the heights
    (n,) and the stretches as (first, last) fix indexes.
    """
    t = np.asarray(t, float)
    lo = np.searchsorted(t, t - 0.5 * STILL_WINDOW_S)
    hi = np.searchsorted(t, t + 0.5 * STILL_WINDOW_S, side="right") - 1
    span = t[hi] - t[lo]
    move = np.linalg.norm(enu[hi, :2] - enu[lo, :2], axis=1)
    still = (span > 0) & (move < STILL_SPEED_MPS * span + K_SIGMA * np.sqrt(2.0) * noise_m)
    edges = np.flatnonzero(np.diff(np.r_[0, still.astype(np.int8), 0]))
    runs = [(int(a), int(b)) for a, b in zip(edges[::2], edges[1::2] - 1, strict=True)
            if t[b] - t[a] >= STILL_MIN_S]  # fmt: skip
    return hold_heights(t, enu[:, 2], runs), runs


def hold_heights(t: np.ndarray, h: np.ndarray, runs: list[tuple[int, int]]) -> np.ndarray:
    """Heights ``h`` (n,) with those of the stretches at rest ``runs`` ((first, last) fix
    indexes) held: the height where the vehicle moves again (the median of the last
    :data:`STILL_END_S` of the stretch), or where it came to rest when it never moves again;
    between two moving phases, linear in time from the one to the other."""
    h = np.asarray(h, float).copy()
    for a, b in runs:
        first = np.median(h[a : np.searchsorted(t, t[a] + STILL_END_S, side="right")])
        last = np.median(h[np.searchsorted(t, t[b] - STILL_END_S) : b + 1])
        if a == 0 or b == len(t) - 1:  # the file starts or ends at rest: one height
            h[a : b + 1] = last if a == 0 and b < len(t) - 1 else first
        else:
            h[a : b + 1] = first + (last - first) * (t[a : b + 1] - t[a]) / (t[b] - t[a])
    return h


#: :func:`rest_runs`: fewest consecutive fixes that make a cluster at rest.
REST_MIN_FIXES = 10
#: :func:`rest_runs`: most mean cosine of the turns between a cluster's consecutive legs. GPS
#: jitter at rest makes legs that are differences of white noise (correlation -1/2 between
#: consecutive legs: they reverse more often than they continue, mean cosine -0.41); a path,
#: however slow or tight, continues its heading (mean cosine near +1).
REST_MAX_TURN_COS = 0.0
#: :func:`rest_runs`: a timed run at rest lasts at least :data:`STILL_MIN_S` and progresses at
#: most this fast (m/s) beyond its noise (a receiver's position wanders slowly at rest; a queue
#: creeps at 0.5 m/s, a slow walk at 0.3 m/s).
REST_CREEP_MPS = 0.02
#: :func:`rest_runs`: most drift between a run's halves, in standard deviations of its white
#: noise: mistaking motion for rest makes a stop-and-go truth, mistaking rest for motion leaves
#: the stop to the truth's fit, so the test is tight (true rest fails it with probability
#: ``exp(-REST_DRIFT_SIGMAS^2 / 2)``, 1 %, and is then found from the next fix).
REST_DRIFT_SIGMAS = 3.0
#: Horizontal noise (m, one coordinate) an untimed path's clusters are judged with: an untimed
#: file has no clock to estimate it from; a consumer receiver standing near buildings.
UNTIMED_NOISE_M = 5.0


@njit(cache=True)
def _rest_runs(
    xy, t, radius, sigma, drift_sigmas, creep_mps, min_fixes, min_s, max_cos
):  # pragma: no cover
    n = xy.shape[0]
    out = np.empty((n, 2), dtype=np.int64)
    k = 0
    i = 0
    while i < n:
        sx, sy = xy[i, 0], xy[i, 1]
        # the run is i .. j-1, each fix within radius of the run's centroid; the fixes before
        # the newest lie within far + |c - (ax, ay)| of it (triangle inequality), checked one
        # by one only when that bound exceeds the radius (a long stay costs O(m), not O(m^2))
        ax, ay, far = sx, sy, 0.0
        j = i + 1
        while j < n:
            cx, cy = (sx + xy[j, 0]) / (j - i + 1), (sy + xy[j, 1]) / (j - i + 1)
            ok = np.hypot(xy[j, 0] - cx, xy[j, 1] - cy) <= radius
            if ok and far + np.hypot(cx - ax, cy - ay) > radius:
                far = 0.0
                for m in range(i, j):
                    far = max(far, np.hypot(xy[m, 0] - cx, xy[m, 1] - cy))
                ok = far <= radius
                ax, ay = cx, cy
            if not ok:
                break
            far = max(far, np.hypot(xy[j, 0] - ax, xy[j, 1] - ay))
            sx += xy[j, 0]
            sy += xy[j, 1]
            j += 1
        found = False
        m_run = j - i
        if m_run >= min_fixes and t[j - 1] - t[i] >= min_s:
            cos_sum = 0.0
            for m in range(i + 1, j - 1):
                ax, ay = xy[m, 0] - xy[m - 1, 0], xy[m, 1] - xy[m - 1, 1]
                bx, by = xy[m + 1, 0] - xy[m, 0], xy[m + 1, 1] - xy[m, 1]
                na, nb = np.hypot(ax, ay), np.hypot(bx, by)
                cos_sum += (ax * bx + ay * by) / (na * nb) if na * nb > 0 else 1.0
            h = i + m_run // 2  # halves i .. h-1 and h .. j-1
            c1 = xy[i:h].sum(axis=0) / (h - i)
            c2 = xy[h:j].sum(axis=0) / (j - h)
            dt = t[h:j].mean() - t[i:h].mean()
            drift = np.hypot(c2[0] - c1[0], c2[1] - c1[1])
            found = (cos_sum / (m_run - 2) <= max_cos) and (
                drift <= drift_sigmas * 2.0 * sigma / np.sqrt(m_run) + creep_mps * dt
            )
        if found:  # its ends: no fix moving away at the start or the end (arrival, departure)
            cx, cy = sx / m_run, sy / m_run
            a, b = i, j - 1
            while (
                j < n
                and b - a + 1 > min_fixes
                and np.hypot(xy[b, 0] - cx, xy[b, 1] - cy)
                > np.hypot(xy[b - 1, 0] - cx, xy[b - 1, 1] - cy)
            ):
                b -= 1
            while (
                i > 0
                and b - a + 1 > min_fixes
                and np.hypot(xy[a, 0] - cx, xy[a, 1] - cy)
                > np.hypot(xy[a + 1, 0] - cx, xy[a + 1, 1] - cy)
            ):
                a += 1
            out[k, 0], out[k, 1] = a, b
            k += 1
            i = b + 1
        else:
            i += 1
    return out[:k]


def rest_runs(
    enu: np.ndarray, noise_m: float, t: np.ndarray | None = None
) -> list[tuple[int, int]]:
    """Runs of consecutive fixes that are GPS jitter around one place: a vehicle at rest.

    A run is at rest when it holds at least :data:`REST_MIN_FIXES` fixes and

    - every one lies within the receiver's noise radius ``K_SIGMA noise_m`` of the run's
      horizontal centroid (a 2-D Gaussian fix strays beyond it with probability
      ``exp(-K_SIGMA^2 / 2)``, 4e-6);
    - its legs keep no heading: the mean cosine of the turns between consecutive legs is at
      most :data:`REST_MAX_TURN_COS` (jitter reverses; a tight circle continues);
    - it does not progress: the centroids of its first and second halves (``m`` fixes in
      all) differ by at most :data:`REST_DRIFT_SIGMAS` standard deviations of that difference
      under white noise (``2 noise_m / sqrt(m)``) plus, when timed, :data:`REST_CREEP_MPS`
      times the time between the halves (a slow walk or a creeping car progresses, however
      noisy its fixes);
    - when timed, it lasts at least :data:`STILL_MIN_S` (shorter stops are the truth fit's).

    Runs are grown greedily from the first fix, each as long as the radius allows; then fixes
    moving away from the centroid at its end (or towards it at its start: departure and
    arrival) are left out of it, except at the ends of the path.

    Parameters
    ----------
    enu : ndarray, shape (n, 2) or (n, 3)
        Positions (m); the horizontal is used.
    noise_m : float
        Horizontal noise of one coordinate (m).
    t : ndarray, shape (n,), optional
        Times (s); None for an untimed path.

    Returns
    -------
    list of (int, int)
        (first, last) fix index of each run, in order, not overlapping.
    """
    xy = np.ascontiguousarray(np.asarray(enu, float)[:, :2])
    if len(xy) < REST_MIN_FIXES:
        return []
    tt = np.zeros(len(xy)) if t is None else np.ascontiguousarray(t, dtype=float)
    creep, min_s = (0.0, 0.0) if t is None else (REST_CREEP_MPS, STILL_MIN_S)
    runs = _rest_runs(
        xy, tt, K_SIGMA * float(noise_m), float(noise_m), REST_DRIFT_SIGMAS, creep,
        REST_MIN_FIXES, min_s, REST_MAX_TURN_COS,
    )  # fmt: skip
    return [(int(a), int(b)) for a, b in runs]


def _length(enu: np.ndarray) -> float:
    return float(np.linalg.norm(np.diff(enu[:, :2], axis=0), axis=1).sum())


def merge_rest(
    cols: dict, enu: np.ndarray, noise_m: float, *, timed: bool, enu_frame: LocalFrame | None
) -> tuple[dict, np.ndarray, dict | None]:
    """Put each run of fixes at rest (:func:`rest_runs`) at its centroid.

    Untimed, the run becomes one point at its horizontal centroid and median height (a path
    without a clock has no stops); timed, its fixes are kept with their times and all placed
    at the run's horizontal centroid, their heights held (:func:`hold_heights`), so the truth
    stands exactly still there instead of crawling through the jitter.

    ``enu`` (n, 3) [m] are the points in :func:`_frame` (of ``cols``' first point, or
    ``enu_frame``). Returns the columns, their positions in that frame, and the
    report (None when no run is found): ``runs`` (first and last 1-based point numbers of
    the kept points, at most :data:`MAX_LISTED`), ``fixes`` (in the runs), ``radius_m``,
    ``noise_m``, ``length_before_m`` and ``length_after_m`` (horizontal path length).
    """
    runs = rest_runs(enu, noise_m, cols["time"] if timed else None)
    if not runs:
        return cols, enu, None
    before = _length(enu)
    new = enu.copy()
    keep = np.ones(len(enu), dtype=bool)
    for a, b in runs:
        new[a : b + 1, :2] = enu[a : b + 1, :2].mean(axis=0)
        if not timed:
            new[a, 2] = np.median(enu[a : b + 1, 2])
            keep[a + 1 : b + 1] = False
    if timed:  # GPS heights wander at rest: held as a parked vehicle's (still_heights)
        new[:, 2] = hold_heights(cols["time"], enu[:, 2], runs)
    frame = _frame(cols, enu_frame)  # the one ``enu`` is in (:func:`_metric`)
    at = np.zeros(len(enu), dtype=bool)
    for a, b in runs:
        at[a : b + 1] = True
    lat, lon, alt = frame.to_geodetic(new[at])
    cols["lat"], cols["lon"], cols["alt"] = (
        c.astype(float) for c in (cols["lat"], cols["lon"], cols["alt"])
    )
    cols["lat"][at], cols["lon"][at], cols["alt"][at] = lat, lon, alt
    if enu_frame is not None:
        cols["pos"] = new
    else:
        cols["pos"] = np.column_stack([cols["lat"], cols["lon"], cols["alt"]])
    for k in cols:
        cols[k] = cols[k][keep]
    new = new[keep]
    report = {
        "runs": [[a + 1, b + 1] for a, b in runs[:MAX_LISTED]],
        "count": len(runs),
        "fixes": int(sum(b - a + 1 for a, b in runs)),
        "radius_m": K_SIGMA * float(noise_m),
        "noise_m": float(noise_m),
        "merged_to_one_point": not timed,
        "runs_s": [[float(cols["time"][a]), float(cols["time"][b])] for a, b in runs]
        if timed
        else None,
        "length_before_m": before,
        "length_after_m": _length(new),
    }
    return cols, new, report


def _along(enu: np.ndarray) -> np.ndarray:
    step = np.hypot(*np.diff(enu[:, :2], axis=0).T)
    return np.concatenate([[0.0], np.cumsum(step)]) + np.arange(len(enu)) * 1e-9
