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

The drift at the end of each outage, as a table and a figure: :mod:`imugen.figures.outage_drift`.
"""

from __future__ import annotations

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
from imugen.figures.options import OutageFigureOptions
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


__all__ = ["outage_curves", "outage_growth", "outage_growth_figure"]
