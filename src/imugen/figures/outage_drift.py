"""Drift at the end of each GNSS outage per grade: a table and a figure (``imugen outage-drift``).

From the per-sequence metrics of ``imugen evaluate`` (:mod:`imugen.tables.metrics`), per grade
and outage length ``D``: the aided horizontal error at the last epoch of the outage
(``outage_<D>s_end_m``) and, beside it, the free-inertial 3-D drift ``D`` s after a true start
(``drift_<D>s_m``, where ``evaluate.segments_s`` holds ``D``), each as the median and 5-95 %
over the sequences with such an outage; one table (CSV and Markdown) and one figure against the
outage length (log scale; grade colours of :func:`imugen.figures.common.grade_styles`). The
error growth during the outages is :mod:`imugen.figures.outage`.

This module owns the outage-drift statistic (:func:`outage_errors`, :func:`bands`): the
GNSS-denied benchmark's table (``imugen learn table``, :mod:`imugen.learn.table`) lays out
the same figures per split, route and baseline through it.
"""

from __future__ import annotations

import re
from collections.abc import Mapping
from pathlib import Path

import numpy as np
import pandas as pd

from imugen.core.errors import InputError
from imugen.core.io import atomic_output
from imugen.core.options import pairs
from imugen.core.plotting import figure as _figure
from imugen.core.plotting import save as _save
from imugen.core.plotting import style as _style
from imugen.figures.common import grade_styles
from imugen.figures.options import OutageDriftOptions
from imugen.tables import metrics as tmetrics

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


def outage_errors(m: pd.DataFrame, D: float) -> tuple[np.ndarray, np.ndarray]:
    """The per-sequence errors of an outage length ``D`` (s) in one metrics table.

    Returns
    -------
    aided_end, free_drift : ndarray, shape (sequences,) or (0,)
        ``outage_<D>s_end_m``: the aided horizontal error at the last epoch of the outage
        (NaN for a sequence without such an outage), and ``drift_<D>s_m``: the free-inertial
        3-D drift ``D`` s after a true start; metres; empty where the column is absent.
    """
    cols = (f"outage_{D:g}s_end_m", f"drift_{D:g}s_m")
    aided, free = (m[c].to_numpy(float) if c in m.columns else np.array([]) for c in cols)
    return aided, free


def bands(v: np.ndarray) -> tuple[int, float, float, float]:
    """``(n, median, p05, p95)`` of the finite values of ``v`` (NaN where none is)."""
    v = np.asarray(v, float)
    v = v[np.isfinite(v)]
    if not len(v):
        return 0, np.nan, np.nan, np.nan
    p05, p50, p95 = np.percentile(v, [5, 50, 95])
    return len(v), float(p50), float(p05), float(p95)


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
        for D in sorted(float(x.group(1)) for c in m.columns if (x := _END.match(c))):
            aided, free = outage_errors(m, D)
            n, *aided_bands = bands(aided)
            rows.append([g, D, n, *aided_bands, *bands(free)[1:]])
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
    handles, labels = ax.get_legend_handles_labels()  # below the axes: never over a curve
    fig.legend(handles, labels, loc="outside lower center", ncols=2, fontsize="small")
    return fig


def main(options: OutageDriftOptions, output, table, metrics) -> None:
    """``imugen outage-drift``."""
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
    "DRIFT_COLUMNS",
    "bands",
    "drift_markdown",
    "outage_drift",
    "outage_drift_figure",
    "outage_errors",
]
