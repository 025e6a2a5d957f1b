"""Figure of error growth during GNSS outages per grade, free inertial beside it.

Left panel: from the aided tables of ``imugen aid`` (:mod:`imugen.tables.aided`), every outage
run of every sequence (consecutive evaluation epochs without a fix, ``since_fix_s > 0``, that
follow an epoch with a fix) becomes one curve of horizontal error ``hypot(err_e, err_n)`` against
the time since the last evaluated epoch with a fix (at most one evaluation step before the first
epoch without one); its first point is the error at that epoch, the error at the outage start.
Runs of every length are pooled: at each time the median and the 5-95 % band are over the runs
still without GNSS then. Right panel: the free-inertial horizontal error of the navigation tables
(``imugen navigate``: strapdown from the true state at ``t_0``) against time since ``t_0``, over
the same span, median and 5-95 % band over sequences. Log scale; shared plotting style
(:mod:`imugen.core.plotting`), grade colours of :mod:`imugen.figures.stage`.

Drift at the end of each outage (``imugen outage-drift``, :func:`outage_drift`): from the
per-sequence metrics of ``imugen evaluate`` (:mod:`imugen.tables.metrics`), per grade and outage
length ``D``: the aided horizontal error at the last epoch of the outage (``outage_<D>s_end_m``)
and, beside it, the free-inertial 3-D drift ``D`` s after a true start (``drift_<D>s_m``, where
``evaluate.segments_s`` holds ``D``), each as the median and 5-95 % over sequences; one table
(CSV and Markdown) and one figure against the outage length.
"""

from __future__ import annotations

import re
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np
import pandas as pd

from imugen.core.errors import InputError
from imugen.core.options import pairs
from imugen.core.plotting import figure as _figure
from imugen.core.plotting import save as _save
from imugen.core.plotting import style as _style
from imugen.figures.common import error_bands, grade_errors, grade_styles
from imugen.figures.options import OutageDriftOptions, OutageFigureOptions
from imugen.tables import SEQUENCE, TIME
from imugen.tables import aided as taided

OUTAGE_COLUMNS = [SEQUENCE, TIME, *taided.ERR_POS[:2], taided.SINCE_FIX]


def outage_curves(aided: pd.DataFrame, step_s: float) -> tuple[np.ndarray, np.ndarray]:
    """Horizontal error of every outage run on a common time grid.

    Parameters
    ----------
    aided : DataFrame
        Rows of an aided table (``sequence``, ``time_s``, ``err_e_m``, ``err_n_m``,
        ``since_fix_s``), any order.
    step_s : float
        Evaluation step (s): times since the run's start are rounded to multiples of it.

    Returns
    -------
    time_s : ndarray (T,)
        ``0, step, 2 step, ...`` up to the longest run.
    err : ndarray (R, T)
        One row per run: the error at the start epoch (the last with a fix) then at each
        epoch of the run; NaN after the run ends (and at grid times without an epoch).
    """
    if not step_s > 0:
        raise ValueError(f"step must be > 0 s, got {step_s!r}")
    a = aided.sort_values([SEQUENCE, TIME], kind="stable")
    seq = a[SEQUENCE].to_numpy()
    t = a[TIME].to_numpy(float)
    h = np.hypot(a[taided.ERR_POS[0]].to_numpy(float), a[taided.ERR_POS[1]].to_numpy(float))
    since = a[taided.SINCE_FIX].to_numpy(float)
    nofix = since > 0
    fix = since == 0
    same_prev = np.r_[False, seq[1:] == seq[:-1]]
    # a run starts at a row without a fix whose previous row (same sequence) had one
    starts = np.flatnonzero(nofix & same_prev & np.r_[False, fix[:-1]])
    ends = np.flatnonzero(nofix & ~(np.r_[same_prev[1:], False] & np.r_[nofix[1:], False]))
    run_rows = list(zip(starts - 1, ends[np.searchsorted(ends, starts)], strict=True))
    if not run_rows:
        return np.zeros(1), np.zeros((0, 1))
    bins = [np.rint((t[b : e + 1] - t[b]) / step_s).astype(np.int64) for b, e in run_rows]
    T = int(max(b[-1] for b in bins)) + 1
    err = np.full((len(run_rows), T), np.nan)
    for i, ((b, e), k) in enumerate(zip(run_rows, bins, strict=True)):
        err[i, k] = h[b : e + 1]
    return np.arange(T) * step_s, err


def _grade_runs(paths: Sequence, grade: str, step_s: float | None):
    """``(time, err)`` of :func:`outage_curves` over the aided tables of one grade."""
    parts = []
    for p in paths:
        if step_s is None:
            step_s = 1.0 / float(taided.read_meta(p).get("eval_rate_hz", 1.0))
        parts.append(taided.read(p, columns=OUTAGE_COLUMNS))
    if not parts:
        raise InputError(grade, "no aided tables")
    time, err = outage_curves(pd.concat(parts, ignore_index=True), step_s)
    if not len(err):
        raise InputError(grade, "the aided tables hold no outage (no epoch without a fix)")
    return time, err


def outage_growth_figure(
    aided_paths_by_grade: Mapping[str, Sequence],
    nav_paths_by_grade: Mapping[str, Sequence],
    *,
    step_s: float | None = None,
):
    """The Matplotlib figure of :func:`outage_growth` (for saving, or inspecting its artists)."""
    if not aided_paths_by_grade:
        raise InputError("--aided", "no aided tables given")
    styles = grade_styles([*aided_paths_by_grade, *nav_paths_by_grade])
    aided = {}
    for g, paths in aided_paths_by_grade.items():
        time, err = _grade_runs(list(paths), g, step_s)
        aided[g] = (time, len(err), error_bands(err))
    span = max(v[0][-1] for v in aided.values())
    free = {}
    for g, paths in nav_paths_by_grade.items():
        time, err = grade_errors(list(paths), g)
        keep = time - time[0] <= span + 1e-9
        free[g] = (time[keep] - time[0], err["horizontal"].shape[0],
                   error_bands(err["horizontal"][:, keep]))  # fmt: skip
    fig = _figure(figsize=(10, 4.2), layout="constrained")
    ax_a, ax_f = fig.subplots(1, 2, sharex=True)
    for ax, data, what, title in (
        (ax_a, aided, "outages", "Aided: error growth during GNSS outages"),
        (ax_f, free, "seq.", "Free inertial from the true start"),
    ):
        for g, (time, n, bands) in data.items():
            p05, p50, p95 = (np.where(b > 0, b, np.nan) for b in bands)
            ax.fill_between(time, p05, p95, color=styles[g]["color"], alpha=0.2, lw=0)
            ax.plot(time, p50, lw=1.2, label=f"{g} (median, 5-95 %, {n} {what})", **styles[g])
        ax.set_yscale("log")
        ax.set_title(title)
        ax.grid(True, which="both", alpha=0.3)
        if data:
            ax.legend(loc="lower right")
    ax_a.set_xlabel("time since the last epoch with GNSS [s]")
    ax_f.set_xlabel("time since start [s]")
    ax_a.set_ylabel("horizontal error [m]")
    return fig


def outage_growth(
    aided_paths_by_grade: Mapping[str, Sequence],
    nav_paths_by_grade: Mapping[str, Sequence],
    out_stem,
    *,
    step_s: float | None = None,
    formats: Sequence[str] = ("png", "svg"),
    dpi: float = 150,
) -> list[Path]:
    """Draw the figure (module docstring) and write it as ``<out_stem>.<ext>`` per format.

    ``aided_paths_by_grade``: the aided tables of each grade; ``nav_paths_by_grade``: the
    navigation error tables (may be empty, or name a subset of the grades). ``step_s``
    defaults to the aided tables' evaluation step. Returns the paths written.
    """
    with _style():
        fig = outage_growth_figure(aided_paths_by_grade, nav_paths_by_grade, step_s=step_s)
        return _save(fig, out_stem, formats, dpi)


def main(options: OutageFigureOptions, output, aided, nav) -> None:
    """``imugen outage-figure``."""
    outage_growth(
        pairs(aided, "--aided"), pairs(nav, "--nav"), output, formats=options.formats,
        dpi=options.dpi,
    )  # fmt: skip


_END = re.compile(r"^outage_(\d+(?:\.\d+)?)s_end_m$")
DRIFT_COLUMNS = [
    "grade",
    "outage_s",
    "sequences",
    "aided_end_m",
    "aided_end_p05_m",
    "aided_end_p95_m",
    "free_inertial_drift_m",
    "free_inertial_drift_p05_m",
    "free_inertial_drift_p95_m",
]
"""Columns of the outage-drift table (:func:`outage_drift`)."""


def _bands(v: np.ndarray) -> tuple[float, float, float]:
    v = v[np.isfinite(v)]
    if not len(v):
        return (np.nan,) * 3
    p05, p50, p95 = np.percentile(v, [5, 50, 95])
    return float(p50), float(p05), float(p95)


def outage_drift(metrics_by_grade: Mapping[str, pd.DataFrame]) -> pd.DataFrame:
    """Drift at the end of each outage length, per grade (module docstring).

    Parameters
    ----------
    metrics_by_grade : mapping of str to DataFrame
        Per-sequence metrics of each grade (``imugen evaluate``), with ``outage_<D>s_end_m``
        columns and, optionally, ``drift_<D>s_m``.

    Returns
    -------
    DataFrame
        :data:`DRIFT_COLUMNS`, one row per grade and outage length ``outage_s`` (ascending);
        ``sequences`` counts the sequences with such an outage; metres; the free-inertial
        columns are NaN where the metrics hold no ``drift_<D>s_m``.
    """
    rows = []
    for g, m in metrics_by_grade.items():
        ends = sorted((float(x.group(1)), x.group(0)) for c in m.columns if (x := _END.match(c)))
        for D, col in ends:
            aided = m[col].to_numpy(float)
            drift = f"drift_{D:g}s_m"
            free = m[drift].to_numpy(float) if drift in m.columns else np.array([])
            rows.append([g, D, int(np.isfinite(aided).sum()), *_bands(aided), *_bands(free)])
    if not rows:
        raise InputError("--metrics", "no outage_<D>s_end_m column: no GNSS outage was evaluated")
    return pd.DataFrame(rows, columns=DRIFT_COLUMNS)


def _fmt(m: float, lo: float, hi: float) -> str:
    if not np.isfinite(m):
        return "-"
    return f"{m:.3g} [{lo:.3g}-{hi:.3g}]"


def drift_markdown(table: pd.DataFrame) -> str:
    """The outage-drift table as Markdown: median [5-95 %] over sequences, metres."""
    lines = [
        "Drift at the end of each GNSS outage: aided horizontal error at the last epoch "
        "without GNSS; free inertial: 3-D drift as long after a true start; median over "
        "sequences [5th-95th percentile], metres.",
        "",
        "| grade | outage (s) | sequences | aided end (m) | free inertial (m) |",
        "|---|---|---|---|---|",
    ]
    for r in table.itertuples(index=False):
        aided = _fmt(r.aided_end_m, r.aided_end_p05_m, r.aided_end_p95_m)
        free = _fmt(
            r.free_inertial_drift_m, r.free_inertial_drift_p05_m, r.free_inertial_drift_p95_m
        )
        lines.append(f"| {r.grade} | {r.outage_s:g} | {r.sequences} | {aided} | {free} |")
    return "\n".join(lines) + "\n"


def outage_drift_figure(table: pd.DataFrame):
    """The Matplotlib figure of the outage-drift table: error at the end of each outage
    against its length, per grade, median with 5-95 % bars; free inertial dashed."""
    styles = grade_styles(list(dict.fromkeys(table["grade"])))
    fig = _figure(figsize=(6.4, 4.2), layout="constrained")
    ax = fig.subplots()
    for g, t in table.groupby("grade", sort=False):
        c = styles[g]["color"]
        x = t["outage_s"].to_numpy(float)
        for stem, ls, marker, face, label in (
            ("aided_end", "-", "o", c, f"{g}: aided (GNSS lost)"),
            ("free_inertial_drift", "--", "s", "none", f"{g}: free inertial"),
        ):
            y = t[f"{stem}_m"].to_numpy(float)
            if not np.isfinite(y).any():
                continue
            err = np.abs(np.vstack([y - t[f"{stem}_p05_m"], t[f"{stem}_p95_m"] - y]))
            ax.errorbar(x, y, yerr=err, color=c, ls=ls, marker=marker, mfc=face, capsize=3,
                        lw=1.2, label=label)  # fmt: skip
    ax.set_yscale("log")
    ax.set_xticks(sorted(set(table["outage_s"])))
    ax.set_xlabel("GNSS outage length [s]")
    ax.set_ylabel("error at the end of the outage [m]")
    ax.set_title("Drift at the end of each GNSS outage (median, 5-95 %)")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(loc="best", fontsize="small")
    return fig


def main_drift(options: OutageDriftOptions, output, table, metrics) -> None:
    """``imugen outage-drift``."""
    from imugen.core.io import atomic_output
    from imugen.tables import metrics as tmetrics

    by_grade = {}
    for g, paths in pairs(metrics, "--metrics").items():
        by_grade[g] = pd.concat([tmetrics.read(p) for p in paths], ignore_index=True)
    drift = outage_drift(by_grade)
    table = Path(table)
    with atomic_output(table) as tmp:
        tmp.write_text(drift.to_csv(index=False, float_format="%.6g"))
    with atomic_output(table.with_suffix(".md")) as tmp:
        tmp.write_text(drift_markdown(drift))
    with _style():
        _save(outage_drift_figure(drift), output, options.formats, options.dpi)


__all__ = [
    "outage_curves",
    "outage_drift",
    "outage_drift_figure",
    "outage_growth",
    "outage_growth_figure",
]
