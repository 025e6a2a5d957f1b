"""Outage growth figure: run extraction against a constructed table, properties over random
tables, the figure's curves and legends from files written through the table contracts."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from imugen.core.plotting import style
from imugen.figures.outage import outage_curves, outage_growth, outage_growth_figure
from imugen.tables import aided as taided
from imugen.tables import nav as tnav


def _table(seq, t, since, h):
    """Aided rows with horizontal error ``h`` all east (north 0)."""
    n = len(t)
    return pd.DataFrame(
        {"sequence": seq, "time_s": t, "err_e_m": h, "err_n_m": np.zeros(n), "since_fix_s": since}
    )


def test_runs_of_a_constructed_table():
    # sequence 7: NaN (before the first fix), fix, fix, 3 rows without, fix, 2 rows without (end)
    t = np.arange(9.0)
    since = np.array([np.nan, 0, 0, 1, 2, 3, 0, 1, 2])
    h = np.array([9.0, 1, 2, 3, 4, 5, 6, 7, 8])
    a = _table(7, t, since, h)
    # sequence 8, given first and shuffled: one run starting at its first fix row
    b = _table(8, [0.0, 1.0, 2.0], [0.0, 1.0, 2.0], [-0.5, 0.7, 0.9])
    df = pd.concat([b, a]).sample(frac=1.0, random_state=1)
    time, err = outage_curves(df, 1.0)
    np.testing.assert_array_equal(time, [0.0, 1.0, 2.0, 3.0])
    want = np.array([[2, 3, 4, 5], [6, 7, 8, np.nan], [0.5, 0.7, 0.9, np.nan]])
    np.testing.assert_array_equal(err, want)  # by sequence then time; hypot: |east|
    # an outage end off the grid rounds to the nearest step; no run: empty
    c = _table(1, [0.0, 1.0, 1.9], [0.0, 1.0, 1.9], [1.0, 2.0, 3.0])
    np.testing.assert_array_equal(outage_curves(c, 1.0)[1], [[1.0, 2.0, 3.0]])
    assert outage_curves(_table(1, [0.0, 1.0], [0.0, 0.0], [1.0, 1.0]), 1.0)[1].shape == (0, 1)


@settings(max_examples=40, deadline=None)
@given(
    st.lists(st.lists(st.booleans(), min_size=1, max_size=25), min_size=1, max_size=4),
    st.integers(0, 2**31),
)
def test_every_curve_starts_at_the_error_at_outage_start(fix_lists, seed):
    rng = np.random.default_rng(seed)
    frames, starts = [], []
    for s, fixes in enumerate(fix_lists):
        fixes = np.asarray(fixes)
        t = np.arange(len(fixes), dtype=float)
        last = np.where(fixes, t, -np.inf)
        last = np.maximum.accumulate(last)
        since = np.where(np.isfinite(last), t - last, np.nan)
        e, n = rng.normal(size=(2, len(t)))
        frames.append(
            pd.DataFrame(
                {"sequence": s, "time_s": t, "err_e_m": e, "err_n_m": n, "since_fix_s": since}
            )
        )
        # brute force: a fix row followed by a row without a fix starts a run
        for k in range(len(t) - 1):
            if fixes[k] and not fixes[k + 1]:
                j = k + 1
                while j + 1 < len(t) and not fixes[j + 1]:
                    j += 1
                starts.append((np.hypot(e[k], n[k]), j - k + 1))
    _, err = outage_curves(pd.concat(frames), 1.0)
    assert len(err) == len(starts)
    np.testing.assert_allclose(err[:, 0], [h for h, _ in starts])
    np.testing.assert_array_equal(np.isfinite(err).sum(axis=1), [m for _, m in starts])


def test_figure_curves_and_legends(tmp_path):
    """Two grades: outages at 1 Hz whose error grows as err0 + c tau^2; the median curve of
    the figure starts at the median error at outage start and legends name the grades."""
    rng = np.random.default_rng(0)
    aided, nav = {}, {}
    starts = {}
    for g, c in (("consumer", 0.05), ("tactical", 0.001)):
        rows = []
        t = np.arange(0.0, 200.0)
        for s in range(6):
            since = np.where((t >= 50) & (t < 110), t - 49, 0.0)  # fix until 49 s, 60 s without
            h = rng.uniform(0.5, 2.0) + c * since**2
            rows.append(_table(s, t, since, h))
            starts.setdefault(g, []).append(h[49])
        df = pd.concat(rows)
        for col in taided.COLUMNS:
            if col not in df:
                df[col] = 0.0
        p = tmp_path / g / "aided.parquet"
        taided.write(df, {"eval_rate_hz": 1.0}, p)
        n = pd.DataFrame({"sequence": np.repeat(np.arange(6), len(t)), "time_s": np.tile(t, 6)})
        n["err_e_m"], n["err_n_m"], n["err_u_m"] = c * n["time_s"] ** 3, 0.0, 0.0
        for col in tnav.COLUMNS:
            if col not in n:
                n[col] = 0.0
        q = tmp_path / g / "nav.parquet"
        tnav.write(n, {}, q)
        aided[g], nav[g] = [p], [q]
    with style():
        fig = outage_growth_figure(aided, nav)
    ax_a, ax_f = fig.axes
    labels = [t.get_text() for t in ax_a.get_legend().get_texts()]
    assert labels[0].startswith("consumer") and labels[1].startswith("tactical")
    assert all("6 outages" in x for x in labels)
    assert [t.get_text().split()[0] for t in ax_f.get_legend().get_texts()] == list(aided)
    for line, g, c in zip(ax_a.get_lines(), aided, (0.05, 0.001), strict=True):
        x, y = line.get_data()
        assert x[0] == 0 and y[0] == pytest.approx(np.median(starts[g]))
        assert x[-1] == 60  # the outage's last epoch, 60 s after the last fix
        assert y[-1] == pytest.approx(np.median(starts[g]) + c * 60**2)
    x, y = ax_f.get_lines()[0].get_data()
    assert x[-1] == 60 and y[-1] == pytest.approx(0.05 * 60**3)  # free inertial, same span
    paths = outage_growth(aided, nav, tmp_path / "fig", formats=["png"], dpi=50)
    assert [p.name for p in paths] == ["fig.png"] and paths[0].stat().st_size > 1000


def _metrics(ends, drift=None):
    """Per-sequence metrics with ``outage_<D>s_end_m`` (and ``drift_<D>s_m``) columns."""
    df = pd.DataFrame({f"outage_{D:g}s_end_m": v for D, v in ends.items()})
    for D, v in (drift or {}).items():
        df[f"drift_{D:g}s_m"] = v
    return df


def test_outage_drift_table_of_constructed_metrics():
    """Median and 5-95 % over the sequences that had each outage; free inertial beside it where
    the metrics hold the same length; lengths ascending per grade, in the grades' order."""
    from imugen.figures.outage_drift import DRIFT_COLUMNS, outage_drift

    a60 = np.array([1.0, 2.0, 3.0, np.nan, 5.0])  # one sequence without a 60 s outage
    a30 = np.arange(5.0)
    tab = outage_drift(
        {
            "tactical": _metrics({60: a60, 30: a30}, drift={30: 10 * a30}),
            "consumer": _metrics({30: a30 + 1}),
        }
    )
    assert list(tab.columns) == DRIFT_COLUMNS
    assert list(zip(tab.grade, tab.outage_s, strict=True)) == [
        ("tactical", 30),
        ("tactical", 60),
        ("consumer", 30),
    ]
    assert tab.sequences.tolist() == [5, 4, 5]
    r = tab.iloc[1]
    v = a60[np.isfinite(a60)]
    np.testing.assert_allclose(
        [r.aided_end_m, r.aided_end_p05_m, r.aided_end_p95_m], np.percentile(v, [50, 5, 95])
    )
    assert np.isnan(r.free_inertial_drift_m)  # no drift_60s_m
    np.testing.assert_allclose(tab.iloc[0].free_inertial_drift_m, 20.0)
    np.testing.assert_allclose(tab.iloc[2].aided_end_m, 3.0)


def test_outage_drift_refuses_metrics_without_outages():
    from imugen.core.errors import InputError
    from imugen.figures.outage_drift import outage_drift

    with pytest.raises(InputError, match="no GNSS outage"):
        outage_drift({"consumer": pd.DataFrame({"rmse_total_m": [1.0]})})


def test_outage_drift_command_writes_table_markdown_and_figure(tmp_path):
    """``imugen outage-drift`` on metrics written through their contract: the CSV, its
    Markdown twin and the figure (one line per grade and kind, log scale)."""
    from imugen.cli import main
    from imugen.figures.outage_drift import outage_drift_figure
    from imugen.tables import metrics as tmetrics

    paths = []
    for g, k in (("consumer", 10.0), ("tactical", 1.0)):
        df = _metrics({30: k * np.arange(1.0, 5.0), 60: k * np.arange(2.0, 6.0)}, {30: [9.0] * 4})
        df.insert(0, "sequence", np.arange(4))
        df["rmse_total_m"] = 1.0
        paths.append(tmetrics.write(df, {}, tmp_path / f"{g}.parquet"))
    out = tmp_path / "fig" / "outage_drift"
    csv = tmp_path / "outage_drift.csv"
    argv = ["outage-drift", f"--output={out}", f"--table={csv}", "--formats", "png"]
    assert main(argv + [f"--metrics={p.stem}={p}" for p in paths]) == 0
    tab = pd.read_csv(csv)
    assert tab.grade.tolist() == ["consumer", "consumer", "tactical", "tactical"]
    np.testing.assert_allclose(tab.aided_end_m, [25.0, 35.0, 2.5, 3.5])
    md = csv.with_suffix(".md").read_text()
    assert (
        "| consumer | 60 | 4 | 35 [" in md and "| tactical | 60 | 4 | 3.5 [2.15-4.85] | - |" in md
    )
    assert (out.parent / "outage_drift.png").stat().st_size > 1000
    with style():
        fig = outage_drift_figure(tab)
    ax = fig.axes[0]
    assert ax.get_yscale() == "log"
    labels = ax.get_legend_handles_labels()[1]
    assert labels == [
        "consumer: aided (GNSS lost)", "consumer: free inertial",
        "tactical: aided (GNSS lost)", "tactical: free inertial",
    ]  # fmt: skip
    fig.canvas.draw()  # the legend sits outside the axes: it hides no curve
    (legend,) = fig.legends
    box, axes_box = legend.get_window_extent(), ax.get_window_extent()
    assert not box.overlaps(axes_box)
