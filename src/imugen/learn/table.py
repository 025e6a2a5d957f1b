"""The GNSS-denied benchmark's table and figure (``imugen learn table``, :mod:`imugen.learn.stage`).

Per route, grade, baseline and outage length ``D``: the median and 95th percentile over
sequences of the horizontal error at the end of an outage of ``D`` s, from the metrics of
``imugen evaluate`` (:mod:`imugen.evaluate.stage`): ``outage_<D>s_end_m`` of the aided filter
on the raw IMU (``aided``) and on the IMU corrected by the reference model (``aided_learned``),
and for ``free_inertial`` the drift ``drift_<D>s_m`` (3-D error ``D`` s after a true start,
mean over the sequence's starts), through the outage-drift statistic of
:mod:`imugen.figures.outage_drift` (:func:`~imugen.figures.outage_drift.outage_errors`,
:func:`~imugen.figures.outage_drift.bands`), which owns it. Columns :data:`COLUMNS`; written as CSV and Markdown. The
figure: one panel per grade, median error against outage length per baseline (test routes
solid, validation dashed), 95th percentiles as thin lines of the same style.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from imugen.core.errors import InputError
from imugen.figures.outage_drift import bands, outage_errors
from imugen.tables import metrics as tmetrics

COLUMNS = ("split", "route", "grade", "baseline", "outage_s", "sequences", "median_m", "p95_m")
"""The table's columns (``sequences``: those with a finite value)."""
BASELINES = ("free_inertial", "aided", "aided_learned")


def pairs(items, flag) -> dict[tuple[str, str], str]:
    """``ROUTE,GRADE=PATH`` items of ``flag`` -> ``{(route, grade): path}``."""
    out = {}
    for item in items or ():
        key, sep, path = item.partition("=")
        route, comma, grade = key.partition(",")
        if not (sep and comma and route and grade and path):
            raise InputError(flag, f"{item!r} is not ROUTE,GRADE=PATH")
        out[(route, grade)] = path
    return out


def rows(aided: dict, learned: dict, splits: dict, durations) -> pd.DataFrame:
    """The table (:data:`COLUMNS`) from metrics paths keyed by ``(route, grade)``."""
    out = []
    for (route, grade), path in aided.items():
        frames = [("aided", tmetrics.read(path))]
        if (route, grade) in learned:
            frames.append(("aided_learned", tmetrics.read(learned[(route, grade)])))
        for D in durations:
            raw_end, free = outage_errors(frames[0][1], D)
            values = [("free_inertial", free), ("aided", raw_end)]
            values += [(b, outage_errors(m, D)[0]) for b, m in frames[1:]]
            for baseline, v in values:
                n, med, _, p95 = bands(v)
                out.append((splits.get(route, ""), route, grade, baseline, float(D), n, med, p95))
    df = pd.DataFrame(out, columns=list(COLUMNS))
    order = {b: i for i, b in enumerate(BASELINES)}
    return df.sort_values(
        ["split", "route", "grade", "baseline", "outage_s"],
        key=lambda c: c.map(order) if c.name == "baseline" else c, kind="stable",
    ).reset_index(drop=True)  # fmt: skip


def markdown(df: pd.DataFrame) -> str:
    """One row per split, route, grade and baseline; per outage length ``median [p95]`` (m)."""
    durs = sorted(df["outage_s"].unique())
    head = ["split", "route", "grade", "baseline", *(f"{d:g} s: median [p95] m" for d in durs)]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for key, g in df.groupby(["split", "route", "grade", "baseline"], sort=False):
        cells = list(key)
        for d in durs:
            r = g[g["outage_s"] == d]
            if not len(r) or not np.isfinite(r["median_m"].iloc[0]):
                cells.append("-")
            else:
                cells.append(f"{r['median_m'].iloc[0]:.3g} [{r['p95_m'].iloc[0]:.3g}]")
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


def draw(df: pd.DataFrame):
    """The Matplotlib figure (module docstring)."""
    from imugen.core.plotting import figure as _figure

    grades = list(dict.fromkeys(df["grade"]))
    fig = _figure(figsize=(4.2 * len(grades), 3.8), layout="constrained")
    axes = np.atleast_1d(fig.subplots(1, len(grades), sharey=True))
    colours = dict(zip(BASELINES, ("0.45", "C0", "C3"), strict=True))
    shown = df[df["split"] != "train"]
    for ax, grade in zip(axes, grades, strict=True):
        for (split, route, baseline), g in shown[shown["grade"] == grade].groupby(
            ["split", "route", "baseline"], sort=False
        ):
            ls = "-" if split == "test" else "--"
            ax.plot(g["outage_s"], g["median_m"], ls, marker="o", ms=3, color=colours[baseline],
                    label=f"{baseline}, {route} ({split})")  # fmt: skip
            ax.plot(g["outage_s"], g["p95_m"], ls, lw=0.6, color=colours[baseline])
        ax.set_yscale("log")
        ax.set_title(grade)
        ax.set_xlabel("outage length [s]")
        ax.grid(True, which="both", alpha=0.3)
    axes[0].set_ylabel("horizontal error at the outage end [m]\n(median; thin: 95th pct.)")
    handles, labels = axes[-1].get_legend_handles_labels()  # below the axes: never over a curve
    fig.legend(handles, labels, loc="outside lower center", ncols=3, fontsize=6)
    return fig
