"""Figures of a route's results: the paper's Figure 8, 3-D tracks, error growth, IMU signals.

Every function reads the stage files (truth, navigation errors, metrics, IMU shards; formats
in :mod:`imugen.tables`), draws one figure
with Matplotlib (object API, Agg renderer, no display, no global pyplot state), writes it
atomically as ``<out_stem>.<ext>`` for each requested format and returns the paths written.

Output is reproducible byte for byte for a given Matplotlib version: drawing starts from
Matplotlib's default style (a user's matplotlibrc does not leak in), SVG ids are salted with a
fixed string, glyphs are embedded as paths and the date stamps are left out.

A navigated position is the truth position at the evaluation epoch plus the navigation error
stored by ``imugen navigate`` (East/North/Up at the true position, metres, turned back into the
navigation frame). Routes longer than :data:`imugen.figures.mapview.LONG_ROUTE_M` (100 km) are drawn on
a map projection with a scale bar in km (:mod:`imugen.figures.mapview`); shorter ones on the tangent
plane of their origin, East/North in metres.

Allan deviation per grade against its specification is drawn by
:func:`imugen.allan.stage.plot_allan`; it is not duplicated here.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping, Sequence
from pathlib import Path

import numpy as np
import pandas as pd

from imugen.core.earth import OriginFrame
from imugen.core.errors import InputError
from imugen.core.options import pairs
from imugen.core.plotting import figure as _figure
from imugen.core.plotting import format_length
from imugen.core.plotting import save as _save
from imugen.core.plotting import style as _style
from imugen.figures import mapview
from imugen.figures.common import error_bands, grade_colours, grade_errors, grade_styles
from imugen.figures.options import REPRESENTATIVE, FiguresOptions
from imugen.tables import SEQUENCE
from imugen.tables import metrics as tmetrics
from imugen.tables import nav as tnav
from imugen.tables import shard as tshard
from imugen.tables import truth as col

__all__ = [
    "REPRESENTATIVE",
    "clip_box",
    "error_vs_time",
    "error_vs_time_figure",
    "figure8",
    "figure8_figure",
    "format_length",
    "imu_signals",
    "interval_rates",
    "representative_sequence",
    "trajectories_3d",
    "zoom_extent",
    "zoom_window",
]

ERR = tnav.ERR_POS
TRACK = tnav.ERR_TRACK
RMSE_TOTAL = tmetrics.RMSE_TOTAL
#: at most this many points of a densely sampled line are drawn (every k-th sample)
MAX_POINTS = 20_000


# ----------------------------------------------------------------------------------------
# representative sequence, zoom window, error bands (pure helpers, tested)


def representative_sequence(metrics: pd.DataFrame, how: str = "median") -> int:
    """Id of the sequence representing a grade, by its ``rmse_total_m``.

    Parameters
    ----------
    metrics : DataFrame
        One row per sequence with ``rmse_total_m`` and the id in a ``sequence`` column or
        the index.
    how : {"median", "best", "worst"}
        ``median``: the sequence at the (lower) median of the sorted RMSE totals, i.e. rank
        ``(n - 1) // 2`` of ``n`` (the exact median for odd ``n``); ``best``: smallest;
        ``worst``: largest. Among sequences with the chosen RMSE, the smallest id; NaN totals
        are ignored.
    """
    if how not in REPRESENTATIVE:
        raise InputError("representative", f"{how!r} is not one of {', '.join(REPRESENTATIVE)}")
    if SEQUENCE in metrics.columns:
        seq = metrics[SEQUENCE].to_numpy()
    else:
        seq = metrics.index.to_numpy()
    r = metrics[RMSE_TOTAL].to_numpy(dtype=np.float64)
    ok = ~np.isnan(r)
    if not ok.any():
        raise InputError("metrics", "no sequence with a finite rmse_total_m")
    seq, r = seq[ok], r[ok]
    rank = {"best": 0, "worst": len(r) - 1, "median": (len(r) - 1) // 2}[how]
    value = np.sort(r)[rank]
    return int(seq[r == value].min())  # ties: the smallest id holding that RMSE


def zoom_window(t_start: float, t_end: float, fraction: float) -> tuple[float, float]:
    """Time span of the last ``fraction`` of ``[t_start, t_end]`` (s)."""
    if not 0.0 < fraction <= 1.0:
        raise InputError("zoom_fraction", f"must be in (0, 1], got {fraction!r}")
    return t_end - fraction * (t_end - t_start), t_end


def zoom_extent(
    window: tuple[float, float],
    tracks: Iterable[tuple[np.ndarray, np.ndarray, np.ndarray]],
    pad: float = 0.05,
) -> tuple[float, float, float, float]:
    """East/North box holding every track's points inside a time window.

    Parameters
    ----------
    window : (t0, t1)
        Time span, s.
    tracks : iterable of (t (K,), e (K,), n (K,))
        Times (s) and positions (m).
    pad : float
        Margin added on each side, as a fraction of the larger side.

    Returns
    -------
    (e_min, e_max, n_min, n_max) : metres
    """
    t0, t1 = window
    es, ns = [], []
    for t, e, n in tracks:
        m = (t >= t0) & (t <= t1) & np.isfinite(e) & np.isfinite(n)
        es.append(np.asarray(e)[m])
        ns.append(np.asarray(n)[m])
    e = np.concatenate(es) if es else np.empty(0)
    n = np.concatenate(ns) if ns else np.empty(0)
    if e.size == 0:
        raise InputError("zoom_fraction", "no point of any track falls in the zoom window")
    lo_e, hi_e, lo_n, hi_n = e.min(), e.max(), n.min(), n.max()
    side = max(hi_e - lo_e, hi_n - lo_n, 1.0)  # at least a metre across
    m = pad * side
    return lo_e - m, hi_e + m, lo_n - m, hi_n + m


def clip_box(
    box: tuple[float, float, float, float],
    ref: tuple[float, float, float, float],
    factor: float | None,
) -> tuple[float, float, float, float]:
    """``box`` cut to a square of ``factor`` times the larger half-side of ``ref``, same centre.

    Keeps a panel on the route when a grade drifts far away (its track then leaves the
    panel); ``factor=None`` returns ``box`` unchanged. Boxes are (e_min, e_max, n_min, n_max).
    """
    if factor is None:
        return box
    if not factor >= 1.0:
        raise InputError("clip_factor", f"must be at least 1 (or null), got {factor!r}")
    ce, cn = (ref[0] + ref[1]) / 2, (ref[2] + ref[3]) / 2
    L = factor * max(ref[1] - ref[0], ref[3] - ref[2]) / 2
    return max(box[0], ce - L), min(box[1], ce + L), max(box[2], cn - L), min(box[3], cn + L)


# ----------------------------------------------------------------------------------------
# reading


def _read_metrics(path) -> pd.DataFrame:
    return tmetrics.read(path)


def _read_nav_sequence(paths: Sequence, sid: int, grade: str) -> pd.DataFrame:
    """Navigation errors of sequence ``sid`` from whichever shard holds it."""
    for p in paths:
        df = tnav.read(p, [SEQUENCE, col.TIME, *ERR], filters=[(SEQUENCE, "==", int(sid))])
        if len(df):
            return df.sort_values(col.TIME, kind="stable")
    raise InputError(grade, f"sequence {sid} of the metrics is in none of the navigation files")


def _truth_track(path, queries: Mapping[str, np.ndarray], max_points: int = MAX_POINTS):
    """Stream the truth positions once.

    Returns a decimated track ``(t, e, n, u)`` (every k-th sample plus the last, at most
    about ``max_points``) and, for each query, the positions (K, 3) interpolated at its times
    (exact at sample times).
    """
    cols = [col.TIME, *col.POS]
    total = col.samples(path)
    if total == 0:
        raise InputError(path, "truth table is empty")
    stride = max(1, math.ceil(total / max_points))
    names = list(queries)
    qt = [np.asarray(queries[k], dtype=np.float64) for k in names]
    qpos = [np.full((q.size, 3), np.nan) for q in qt]
    keep: list[np.ndarray] = []
    prev = None  # last row of the previous batch, (4,)
    start = 0
    last = None
    for a in col.iter_batches(path, cols):
        idx = np.arange(start, start + a.shape[0])
        keep.append(a[idx % stride == 0])
        start += a.shape[0]
        last = a[-1]
        b = a if prev is None else np.vstack([prev, a])
        for q, out in zip(qt, qpos, strict=True):
            m = (q >= b[0, 0]) & (q <= b[-1, 0])
            if m.any():
                out[m] = np.column_stack([np.interp(q[m], b[:, 0], b[:, j]) for j in (1, 2, 3)])
        prev = a[-1:]
    track = np.vstack(keep)
    if (total - 1) % stride:
        track = np.vstack([track, last])
    t0, t1 = track[0, 0], track[-1, 0]
    for k, q, out in zip(names, qt, qpos, strict=True):
        bad = np.isnan(out[:, 0])
        if bad.any():
            raise InputError(
                path,
                f"{k}: epochs {q[bad][0]:g} s ... outside the truth's span [{t0:g}, {t1:g}] s",
            )
    return tuple(track.T), dict(zip(names, qpos, strict=True))


def _representatives(truth_path, nav_paths_by_grade, metrics_by_grade, how):
    """Truth track ``(t, x, y, z)`` in map coordinates (:class:`imugen.figures.mapview.RouteMap`), per
    grade the representative navigated track (``t``, ``e``, ``n``, ``u`` in the same
    coordinates, ``h_err`` the horizontal error in the local level), and the map."""
    reps = {}
    for g, paths in nav_paths_by_grade.items():
        if g not in metrics_by_grade:
            raise InputError(g, "no metrics file given for this grade")
        m = _read_metrics(metrics_by_grade[g])
        sid = representative_sequence(m, how)
        rmse = float(m.loc[m[SEQUENCE] == sid, RMSE_TOTAL].iloc[0])
        nav = _read_nav_sequence(list(paths), sid, g)
        reps[g] = {"sequence": sid, "rmse": rmse, "count": len(m), "nav": nav}
    track, at = _truth_track(
        truth_path, {g: r["nav"][col.TIME].to_numpy() for g, r in reps.items()}
    )
    p_track = np.column_stack(track[1:])
    meta = col.read_meta(truth_path)
    if "origin" in meta and "earth" in meta:
        rmap = mapview.RouteMap.for_route(col.origin_frame(meta), p_track)
    else:  # a bare table without its origin: the tangent plane it is written in
        rmap = mapview.RouteMap(OriginFrame(0.0, 0.0, 0.0, "flat"))
    xyz = rmap.xyz(p_track)
    track = (track[0], xyz[:, 0], xyz[:, 1], xyz[:, 2])
    for g, r in reps.items():
        err = r.pop("nav")
        d = err[list(ERR)].to_numpy(dtype=np.float64)
        pos = rmap.xyz(rmap.navigated_n(at[g], d))
        r["t"] = err[col.TIME].to_numpy(dtype=np.float64)
        r["e"], r["n"], r["u"] = pos[:, 0], pos[:, 1], pos[:, 2]
        r["h_err"] = np.hypot(d[:, 0], d[:, 1])
    return track, reps, rmap


def _rep_label(g, r, how):
    # the sequence's index within its route (ids are route-scoped: route_id << 31 | index)
    index = int(tshard.split_ids(np.array([r["sequence"]], np.int64))[1][0])
    return f"{g}: RMSE {format_length(r['rmse'])} (sequence {index}, {how} of {r['count']})"


# ----------------------------------------------------------------------------------------
# figures


def figure8_figure(
    truth_path,
    nav_paths_by_grade: Mapping[str, Sequence],
    metrics_by_grade: Mapping[str, str | Path],
    *,
    zoom_fraction: float = 0.2,
    representative: str = "median",
    clip_factor: float | None = 3.0,
):
    """The Matplotlib figure of :func:`figure8` (for saving, or for inspecting its artists)."""
    track, reps, rmap = _representatives(
        truth_path, nav_paths_by_grade, metrics_by_grade, representative
    )
    t, e, n, _ = track
    window = zoom_window(t[0], t[-1], zoom_fraction)
    styles = grade_styles(reps)
    from matplotlib.patches import Rectangle

    fig = _figure(figsize=(15, 6.2), layout="constrained")
    ax_a, ax_b, ax_c = fig.subplots(1, 3, width_ratios=(1, 1, 1.1))
    tracks = [(r["t"], r["e"], r["n"]) for r in reps.values()]
    whole = (t[0], t[-1])
    box_a = clip_box(
        zoom_extent(whole, [(t, e, n), *tracks], pad=0.03),
        zoom_extent(whole, [(t, e, n)], pad=0.03),
        clip_factor,
    )
    # zoom: the reference over the window and the END of every plotted track, cut to
    # ``clip_factor`` times the reference's own window (a grade kilometres away is marked at
    # the edge with its distance instead of turning the zoom into a map of its drift)
    ends = [(np.array([r["t"][-1]]), r["e"][-1:], r["n"][-1:]) for r in reps.values()]
    lo_e, hi_e, lo_n, hi_n = clip_box(
        zoom_extent(window, [(t, e, n), *ends], pad=0.08),
        zoom_extent(window, [(t, e, n)], pad=0.08),
        clip_factor,
    )
    half = max(hi_e - lo_e, hi_n - lo_n) / 2  # square box: equal scales on a square panel
    ce, cn = (lo_e + hi_e) / 2, (lo_n + hi_n) / 2
    off = 0  # ends marked on the zoom's edge (their labels stacked)
    for ax, zoom in ((ax_a, False), (ax_b, True)):
        m = (t >= window[0]) if zoom else slice(None)
        ax.plot(e[m], n[m], color="black", lw=0.9, label="reference (truth)", zorder=3)
        for g, r in reps.items():
            mr = (r["t"] >= window[0]) if zoom else slice(None)
            ax.plot(
                r["e"][mr], r["n"][mr], lw=1.2, label=_rep_label(g, r, representative), **styles[g]
            )
            if zoom:
                ax.plot(
                    [e[-1], r["e"][-1]], [n[-1], r["n"][-1]], ":", lw=0.7, color=styles[g]["color"]
                )
                off += _zoom_end(ax, g, r, (e[-1], n[-1]), (ce, cn, half), styles[g]["color"], off)
        ax.plot(e[-1], n[-1], "ks", ms=4, zorder=5, label=None if zoom else "end")
        if zoom:
            ax.set_xlim(ce - half, ce + half)
            ax.set_ylim(cn - half, cn + half)
        else:
            ax.plot(e[0], n[0], "k^", ms=5, zorder=4, label="start")
            ax.add_patch(
                Rectangle(
                    (ce - half, cn - half),
                    2 * half,
                    2 * half,
                    fill=False,
                    ls="--",
                    lw=0.8,
                    ec="0.4",
                )
            )
            ax.set_xlim(box_a[0], box_a[1])
            ax.set_ylim(box_a[2], box_a[3])
        ax.set_aspect("equal", adjustable="box")
        _map_axes(ax, rmap)
    # error growth of the same sequences: what the zoom shows, on a scale that fits any grade
    for g, r in reps.items():
        err = r["h_err"]
        ax_c.plot(r["t"], np.where(err > 0, err, np.nan), lw=1.2, **styles[g])
    ax_c.axvspan(*window, color="0.9", zorder=0, label="zoom window")
    ax_c.set_yscale("log")
    ax_c.set_xlabel("time [s]")
    ax_c.set_ylabel("horizontal error [m]")
    ax_a.set_title("(a) reference and one sequence per grade", loc="left")
    ax_b.set_title(f"(b) last {100 * zoom_fraction:g} % of the time and the ends", loc="left")
    ax_c.set_title("(c) horizontal error of the same sequences", loc="left")
    fig.legend(*ax_a.get_legend_handles_labels(), loc="outside lower center", ncols=2)
    return fig


def _zoom_end(ax, g, r, ref_end, box, color, row=0) -> int:
    """The end of grade ``g``'s track in the zoom: a dot where it lies inside the square
    ``box`` (centre e, n and half-side), else a triangle on the box's edge towards it, labelled
    with its distance from the reference's end (the zoom stays a zoom; ``row``: labels
    already placed, stacked below). Returns 1 for an edge mark, else 0."""
    ce, cn, half = box
    ge, gn = float(r["e"][-1]), float(r["n"][-1])
    de, dn = ge - ce, gn - cn
    out = max(abs(de), abs(dn)) / half if half > 0 else 0.0
    if out <= 1.0:
        ax.plot(ge, gn, "o", ms=4, color=color, zorder=4)
        return 0
    k = 0.97 / out  # on the edge, just inside
    pe, pn = ce + k * de, cn + k * dn
    ax.plot(pe, pn, marker=(3, 0, np.degrees(np.arctan2(dn, de)) - 90.0), ms=7, color=color,
            zorder=4, ls="none")  # fmt: skip
    dist = float(np.hypot(ge - ref_end[0], gn - ref_end[1]))
    ax.annotate(
        f"{g}: end {format_length(dist)} away", (pe, pn),
        xytext=(-6 if de > 0 else 6, -9 * row), textcoords="offset points",
        ha="right" if de > 0 else "left", va="center", fontsize="x-small", color=color,
        clip_on=True,
    )  # fmt: skip
    return 1


def _map_axes(ax, rmap: mapview.RouteMap) -> None:
    """Axis labels of a map panel; a long route's also get km ticks and a scale bar (call
    after the limits are set; ``adjustable="box"`` keeps them)."""
    xl, yl, _ = rmap.labels()
    ax.set_xlabel(xl)
    ax.set_ylabel(yl)
    if rmap.projected:
        mapview.km_ticks(ax)
        mapview.add_scale_bar(ax, rmap)
    else:
        ax.ticklabel_format(style="sci", scilimits=(-3, 4))


def figure8(
    truth_path,
    nav_paths_by_grade: Mapping[str, Sequence],
    metrics_by_grade: Mapping[str, str | Path],
    out_stem,
    *,
    zoom_fraction: float = 0.2,
    representative: str = "median",
    clip_factor: float | None = 3.0,
    formats: Sequence[str] = ("png", "svg"),
    dpi: float = 150,
) -> list[Path]:
    """The paper's Figure 8: reference and one navigated sequence per grade, East-North.

    (a) the whole route: truth (black) and, per grade, the sequence whose RMSE total is the
    ``representative`` one (median, best or worst) of that grade, never drawn beyond
    ``clip_factor`` times the reference's extent (:func:`clip_box`) so a grade drifting
    kilometres away does not shrink the route to a dot; (b) the last ``zoom_fraction`` of the
    time in a square box that holds the reference over that time and the end of every plotted
    track (dotted lines join the reference's end to each grade's end), cut to ``clip_factor``
    times the reference's own window: an end beyond is a triangle on the edge, pointing to it,
    labelled with its distance (a zoom holding every end was no zoom when one grade drifted
    kilometres: axes of 1e5-1e7 m); (c) the horizontal error of the same
    sequences against time on a log scale, which reads for metre and megametre errors alike.
    Grades keep their class hue; the paper's presets are darker and dashed, calibrated variants
    lighter and dash-dotted (:func:`grade_styles`); the legend gives each grade's RMSE total
    in readable units (:func:`format_length`). Equal axis scales in (a) and (b).

    Returns
    -------
    list of Path
    """
    with _style():
        fig = figure8_figure(
            truth_path,
            nav_paths_by_grade,
            metrics_by_grade,
            zoom_fraction=zoom_fraction,
            representative=representative,
            clip_factor=clip_factor,
        )
        return _save(fig, out_stem, formats, dpi)


def trajectories_3d(
    truth_path,
    nav_paths_by_grade: Mapping[str, Sequence],
    metrics_by_grade: Mapping[str, str | Path],
    out_stem,
    *,
    representative: str = "median",
    vertical_exaggeration: float | None = None,
    clip_factor: float | None = 3.0,
    formats: Sequence[str] = ("png", "svg"),
    dpi: float = 150,
) -> list[Path]:
    """3-D tracks (East, North, Up) of the reference and one sequence per grade.

    The horizontal axes share one scale; the vertical box height is at least a third of the
    horizontal extent (the vertical is exaggerated when the route is flat), or exactly
    ``vertical_exaggeration`` times the horizontal scale when given. Track points farther
    from the reference's centre than ``clip_factor`` times its larger horizontal half-extent
    (on any axis) are left out, so that a drifting grade does not shrink the route to a dot;
    ``clip_factor=None`` keeps every point.

    Returns
    -------
    list of Path
    """
    track, reps, rmap = _representatives(
        truth_path, nav_paths_by_grade, metrics_by_grade, representative
    )
    _, e, n, u = track
    styles = grade_styles(reps)
    xyz = {g: np.column_stack([r["e"], r["n"], r["u"]]) for g, r in reps.items()}
    if clip_factor is not None:
        ref = clip_box(
            (-np.inf, np.inf, -np.inf, np.inf), (e.min(), e.max(), n.min(), n.max()), clip_factor
        )
        L = (ref[1] - ref[0]) / 2
        c = np.array([(ref[0] + ref[1]) / 2, (ref[2] + ref[3]) / 2, (u.min() + u.max()) / 2])
        for p in xyz.values():
            p[(np.abs(p - c) > L).any(axis=1)] = np.nan
    allv = [np.concatenate([x, *(p[:, j] for p in xyz.values())]) for j, x in enumerate((e, n, u))]
    rng = [float(np.nanmax(v) - np.nanmin(v)) or 1.0 for v in allv]
    h = max(rng[0], rng[1])
    rz = rng[2] * vertical_exaggeration if vertical_exaggeration else max(rng[2], h / 3)
    with _style():
        fig = _figure(figsize=(8, 6.5), layout="constrained")
        ax = fig.add_subplot(projection="3d")
        ax.plot(e, n, u, color="black", lw=0.8, label="reference (truth)")
        for g, r in reps.items():
            ax.plot(*xyz[g].T, lw=1.1, label=_rep_label(g, r, representative), **styles[g])
        ax.scatter([e[0]], [n[0]], [u[0]], color="black", marker="^", s=20, label="start")
        ax.set_box_aspect((rng[0], rng[1], rz))
        ax.view_init(elev=25, azim=-60)
        ax.locator_params(nbins=5)
        for setter, label in zip(
            (ax.set_xlabel, ax.set_ylabel, ax.set_zlabel), rmap.labels(), strict=True
        ):
            setter(label)
        if rmap.projected:
            mapview.km_ticks(ax)
        ax.set_title("Reference and one sequence per grade (3-D)")
        fig.legend(*ax.get_legend_handles_labels(), loc="outside lower center", ncols=2)
        return _save(fig, out_stem, formats, dpi)


_ERROR_PANELS = (
    ("horizontal", "horizontal error [m]", "Horizontal position error"),
    ("up", "|up error| [m]", "Vertical position error"),
    ("along", "|along-track error| [m]", "Along-track error"),
    ("cross", "|cross-track error| [m]", "Cross-track error"),
)


def error_vs_time_figure(nav_paths_by_grade: Mapping[str, Sequence]):
    """The Matplotlib figure of :func:`error_vs_time` (for saving or inspecting its artists)."""
    styles = grade_styles(nav_paths_by_grade)
    stats = {}
    for g, paths in nav_paths_by_grade.items():
        time, err = grade_errors(list(paths), g)
        stats[g] = (time, err["horizontal"].shape[0], {k: error_bands(v) for k, v in err.items()})
        del err
    panels = [p for p in _ERROR_PANELS if all(p[0] in b for _, _, b in stats.values())]
    fig = _figure(figsize=(9 if len(panels) == 2 else 13, 6.5), layout="constrained")
    axes = fig.subplots(2, len(panels) // 2, sharex=True, squeeze=False).T.ravel()
    for ax, (key, ylabel, title) in zip(axes, panels, strict=True):
        for g, (time, S, bands) in stats.items():
            p05, p50, p95 = (np.where(b > 0, b, np.nan) for b in bands[key])
            ax.fill_between(time, p05, p95, color=styles[g]["color"], alpha=0.2, lw=0)
            ax.plot(time, p50, lw=1.2, label=f"{g} (median, 5-95 %, {S} seq.)", **styles[g])
        ax.set_yscale("log")
        ax.set_ylabel(ylabel)
        ax.set_title(title)
        ax.grid(True, which="both", alpha=0.3)
    for ax in axes[1::2]:
        ax.set_xlabel("time [s]")
    axes[0].legend(loc="lower right")
    return fig


def error_vs_time(
    nav_paths_by_grade: Mapping[str, Sequence],
    out_stem,
    *,
    formats: Sequence[str] = ("png", "svg"),
    dpi: float = 150,
) -> list[Path]:
    """Position error against time per grade: median and 5-95 % band over sequences.

    Panels with a log scale: horizontal error hypot(east, north) and |up| error, metres (East,
    North, Up at the true position); with navigation tables holding the track columns also
    |along-track| and |cross-track| (a 2 x 2 figure). Navigation files are read one at a
    time, only the error columns; per grade only the (sequences, epochs) matrices of the errors
    are kept.

    Returns
    -------
    list of Path
    """
    with _style():
        return _save(error_vs_time_figure(nav_paths_by_grade), out_stem, formats, dpi)


def interval_rates(time_s: np.ndarray, increments: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Mean rates over the sample intervals from increments, at the interval midpoints.

    Parameters
    ----------
    time_s : ndarray (K,)
        Sample times of one sequence, increasing (s).
    increments : ndarray (K, ...)
        Increment of the interval ending at each row (row 0 holds no interval), e.g. rad, m/s.

    Returns
    -------
    t_mid : ndarray (K-1,)
        Interval midpoints (s).
    rates : ndarray (K-1, ...)
        increment / interval length (e.g. rad/s, m/s^2).
    """
    t = np.asarray(time_s, dtype=np.float64)
    dt = np.diff(t)
    inc = np.asarray(increments, dtype=np.float64)[1:]
    return t[1:] - dt / 2, inc / dt.reshape((-1,) + (1,) * (inc.ndim - 1))


def _window(window_s, t0: float, t1: float) -> tuple[float, float]:
    if window_s is None:
        return t0, t1
    if np.ndim(window_s) == 0:
        w = float(window_s)
        if not w > 0:
            raise InputError("window_s", f"must be positive, got {window_s!r}")
        return t0, t0 + w
    a, b = (float(x) for x in window_s)
    if not b > a:
        raise InputError("window_s", f"window end must be after its start, got {window_s!r}")
    return a, b


def imu_signals(
    truth_path,
    shard_path,
    out_stem,
    *,
    sequence: int | None = None,
    window_s: float | tuple[float, float] | None = None,
    max_points: int = MAX_POINTS,
    formats: Sequence[str] = ("png", "svg"),
    dpi: float = 150,
) -> list[Path]:
    """True against measured IMU signals of one sequence: gyro x/y/z (deg/s), accel x/y/z (m/s^2).

    Measured rates are the shard's rate columns when it has them; otherwise they are
    reconstructed from the increments as dtheta/dt and dv/dt, i.e. the mean over each
    sample interval, drawn at the interval midpoint (the figure says so). Truth rates are
    the instantaneous ``gyro_*``/``accel_*`` columns of the truth table.

    Parameters
    ----------
    sequence : int, optional
        Global sequence id; default the first sequence of the shard.
    window_s : float or (t0, t1), optional
        A float keeps the first ``window_s`` seconds; a pair keeps ``[t0, t1]`` (s).
    max_points : int
        Longer lines are thinned to every k-th sample (stated on the figure).

    Returns
    -------
    list of Path
    """
    meta = tshard.read_meta(shard_path)
    grade = meta.get("grade", {}).get("name", "measured")
    names = tshard.column_names(shard_path)
    rates = all(c in names for c in (*col.GYRO, *col.ACCEL))
    incs = all(c in names for c in (*col.DTHETA, *col.DV))
    if not (rates or incs):
        raise InputError(shard_path, "holds neither rate nor increment columns")
    gyro_cols, accel_cols = (col.GYRO, col.ACCEL) if rates else (col.DTHETA, col.DV)
    if sequence is None:
        ids = meta.get("sequence_ids")
        if ids:
            sequence = int(ids[0])
        else:
            sequence = int(tshard.read(shard_path, [SEQUENCE]).column(0)[0].as_py())
    tbl = tshard.read(
        shard_path,
        columns=[col.TIME, *gyro_cols, *accel_cols],
        filters=[(SEQUENCE, "==", int(sequence))],
    )
    if tbl.num_rows < 2:
        raise InputError(shard_path, f"holds no sequence {sequence}")
    t = tbl.column(col.TIME).to_numpy().astype(np.float64)
    order = np.argsort(t, kind="stable")
    t = t[order]
    meas = np.column_stack(
        [tbl.column(c).to_numpy().astype(np.float64)[order] for c in (*gyro_cols, *accel_cols)]
    )
    w0, w1 = _window(window_s, t[0], t[-1])
    if incs and not rates:
        t, meas = interval_rates(t, meas)
        note = (
            "Measured: interval means dtheta/dt, dv/dt of the increments, drawn at interval "
            "midpoints; truth: instantaneous rates."
        )
    else:
        note = "Measured: sampled rates of the shard; truth: instantaneous rates."
    m = (t >= w0) & (t <= w1)
    t, meas = t[m], meas[m]
    if t.size == 0:
        raise InputError("window_s", f"no sample of sequence {sequence} in [{w0:g}, {w1:g}] s")
    truth = col.read_arrow(
        truth_path,
        columns=[col.TIME, *col.GYRO, *col.ACCEL],
        filters=[(col.TIME, ">=", w0), (col.TIME, "<=", w1)],
    )
    tt = truth.column(col.TIME).to_numpy().astype(np.float64)
    tv = np.column_stack(
        [truth.column(c).to_numpy().astype(np.float64) for c in (*col.GYRO, *col.ACCEL)]
    )
    ks = max(1, math.ceil(t.size / max_points))
    kt = max(1, math.ceil(tt.size / max_points))
    if max(ks, kt) > 1:
        note += f" Thinned for drawing: every k-th sample (k = {ks} measured, {kt} true)."
    scale = np.array([180 / np.pi] * 3 + [1.0] * 3)
    colour = grade_colours([grade])[grade]
    with _style():
        fig = _figure(figsize=(11, 7.5), layout="constrained")
        axes = fig.subplots(3, 2, sharex=True)
        for j in range(6):
            ax = axes[j % 3, j // 3]
            axis = "xyz"[j % 3]
            ax.plot(
                t[::ks],
                meas[::ks, j] * scale[j],
                color=colour,
                lw=0.6,
                alpha=0.8,
                label=f"measured ({grade})",
            )
            ax.plot(tt[::kt], tv[::kt, j] * scale[j], color="black", lw=0.9, label="true")
            if j < 3:
                ax.set_ylabel(f"gyro {axis} [deg/s]")
            else:
                ax.set_ylabel(f"accel {axis} [m/s$^2$]")
        axes[2, 0].set_xlabel("time [s]")
        axes[2, 1].set_xlabel("time [s]")
        axes[0, 0].set_title("Angular rate (body)")
        axes[0, 1].set_title("Specific force (body)")
        axes[0, 0].legend(loc="upper right")
        fig.suptitle(f"IMU signals, {grade}, sequence {sequence}")
        fig.supxlabel(note, fontsize=8)
        return _save(fig, out_stem, formats, dpi)


def run(truth_path, outdir, options: FiguresOptions, *, nav, metrics, imu) -> None:
    """Every route figure into ``outdir``: Figure 8, the 3-D trajectories, the errors against
    time and, per grade of ``imu`` (``{grade: shard}``), its IMU signals. ``nav``:
    ``{grade: [navigation error tables]}``; ``metrics``: ``{grade: metrics table}``."""
    o = options
    out = Path(outdir)
    kw = {"formats": o.formats, "dpi": o.dpi}
    figure8(
        truth_path, nav, metrics, out / "figure8", zoom_fraction=o.zoom_fraction,
        representative=o.representative, **kw,
    )  # fmt: skip
    trajectories_3d(
        truth_path, nav, metrics, out / "trajectories_3d", representative=o.representative, **kw
    )
    error_vs_time(nav, out / "error_vs_time", **kw)
    for grade, shard in imu.items():
        imu_signals(truth_path, shard, out / f"imu_{grade}", **kw)


def main(options: FiguresOptions, truth, outdir, nav, metrics, imu) -> None:
    """``imugen figures`` (``GRADE=PATH`` inputs)."""
    first = {g: p[0] for g, p in pairs(metrics, "--metrics").items()}
    shards = {g: p[0] for g, p in pairs(imu, "--imu").items()}
    run(truth, outdir, options, nav=pairs(nav, "--nav"), metrics=first, imu=shards)
