"""Evaluation stage: navigation errors -> per-sequence RMSE -> per-grade tables.

Per sequence, over the evaluation epochs (every epoch of the navigation error table, the
first one included, as the paper does):

- ``rmse_east_m``, ``rmse_north_m``, ``rmse_up_m``: root mean square of the position error
  along each ENU axis;
- ``rmse_total_m = sqrt(E^2 + N^2 + U^2)`` of those three (the paper's "Total");
- ``final_east_m`` ... ``final_3d_m``: error at the last epoch; ``final_pct_distance``: final
  horizontal error as a percentage of the horizontal distance travelled.

Relative drift (``segments``, seconds ``T``): how far the navigation drifts in ``T`` seconds
from a correct start, the figure drift-correction papers report. For each start ``t_s`` the
sequence is mechanized again from the TRUE position, velocity and attitude at ``t_s`` over the
IMU's own increments of ``[t_s, t_s + T]``; the drift of that start is the 3-D position error at
``t_s + T``. Starts slide by ``T / 2`` from ``t_0`` (``t_s = 0, T/2, T, ...`` while the segment
fits: half-overlapping segments, each sample in two of them), so a route of duration ``D``
gives ``floor(2 (D - T) / T) + 1`` starts and costs two extra navigations per ``T``.
``drift_<T>s_m`` is the mean over the starts (a sequence shorter than ``T`` has none: NaN).
With a constant accelerometer bias ``b`` alone the drift of every start is ``|b| T^2 / 2``.

Per grade: the median over sequences of each value (``east_m``, ``north_m``, ``up_m``,
``total_m``, ``drift_<T>s_m``, ...) with its 5th and 95th percentiles (``*_p05_m``,
``*_p95_m``).
"""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
import pandas as pd

from imugen.tables import metrics as tmetrics
from imugen.tables import nav as tnav
from imugen.tables import truth as ttruth

ERR = tnav.ERR_POS
AXES = tmetrics.AXES


def sequence_metrics(nav: pd.DataFrame, distance_m: float) -> pd.DataFrame:
    """Per-sequence RMSE and final errors.

    Parameters
    ----------
    nav : DataFrame
        Columns ``sequence``, ``time_s`` and ``err_e_m``, ``err_n_m``, ``err_u_m`` (metres),
        one row per sequence and evaluation epoch.
    distance_m : float
        Horizontal distance travelled by the truth over the evaluated span (m).

    Returns
    -------
    DataFrame
        One row per sequence (index ``sequence``).
    """
    nav = nav.sort_values(["sequence", "time_s"], kind="stable")
    g = nav.groupby("sequence", sort=True)
    out = pd.DataFrame(index=pd.Index(sorted(nav["sequence"].unique()), name="sequence"))
    sq = nav[list(ERR)].pow(2)
    sq["sequence"] = nav["sequence"].to_numpy()
    ms = sq.groupby("sequence", sort=True).mean()
    for axis, col in zip(AXES, ERR, strict=True):
        out[f"rmse_{axis}_m"] = np.sqrt(ms[col].to_numpy())
    out["rmse_total_m"] = np.sqrt(sum(out[f"rmse_{a}_m"] ** 2 for a in AXES))
    last = g.tail(1).set_index("sequence")
    for axis, col in zip(AXES, ERR, strict=True):
        out[f"final_{axis}_m"] = last[col]
    out["final_horizontal_m"] = np.hypot(last[ERR[0]], last[ERR[1]])
    out["final_3d_m"] = np.sqrt((last[list(ERR)] ** 2).sum(axis=1))
    out["final_pct_distance"] = (
        100.0 * out["final_horizontal_m"] / distance_m if distance_m > 0 else np.nan
    )
    out["epochs"] = g.size()
    return out


_STATS = {
    "east_m": "rmse_east_m",
    "north_m": "rmse_north_m",
    "up_m": "rmse_up_m",
    "total_m": "rmse_total_m",
    "final_3d_m": "final_3d_m",
    "final_pct_distance": "final_pct_distance",
}


def drift_column(T: float) -> str:
    """Name of the drift after ``T`` seconds: ``drift_30s_m``."""
    return f"drift_{T:g}s_m"


def segment_starts(samples: int, n: int) -> np.ndarray:
    """Start samples of the segments of ``n`` intervals in ``samples`` samples (step ``n/2``)."""
    if n < 1 or n > samples - 1:
        return np.zeros(0, np.int64)
    return np.arange(0, samples - 1 - n + 1, max(1, round(n / 2)), dtype=np.int64)


def segment_drift(truth_path, imu_path, segments_s, *, batch: int | None = None) -> pd.DataFrame:
    """Relative drift of every sequence of an IMU shard (see the module docstring).

    Parameters
    ----------
    truth_path, imu_path : path
        The route's truth and one IMU shard (increments, compensated or raw, or rates only),
        navigated as :mod:`imugen.navigate` does.
    segments_s : sequence of float
        Segment durations ``T`` (s).
    batch : int, optional
        Sequences mechanized together (default from the navigation memory budget).

    Returns
    -------
    DataFrame
        Index ``sequence``; one column ``drift_<T>s_m`` (metres) per ``T``.
    """
    from imugen.mechanize import compensate_raw, increments_from_rates, mechanize
    from imugen.navigate import batch_size
    from imugen.tables import shard as tshard

    truth = ttruth.read(truth_path, columns=[ttruth.TIME, *ttruth.POS, *ttruth.VEL, *ttruth.QUAT])
    K, dt, rate = truth.K, truth.dt, truth.rate_hz
    frame = truth.origin_frame()
    p, v, q = truth.p_n, truth.v_n, truth.q_nb
    columns, kind = tshard.measurement(imu_path)
    rates = kind == "rates"
    raw = not rates and tshard.increment_kind(tshard.read_meta(imu_path)) == "raw"
    ids_all, out = [], {drift_column(T): [] for T in segments_s}
    batch = batch or max(1, batch_size(K) // 2)  # segments hold about twice the samples
    for ids, a, c in tshard.iter_blocks(imu_path, columns, K, batch, 0 if rates else 1):
        if rates:
            dth, dvb = increments_from_rates(a, c, dt)
        else:  # raw increments get navigation's coning/sculling correction first
            dth, dvb = compensate_raw(a, c) if raw else (a, c)
        ids_all.append(ids.copy())
        for T in segments_s:
            n = round(T * rate)
            starts = segment_starts(K, n)
            if not len(starts):
                out[drift_column(T)].append(np.full(len(ids), np.nan))
                continue
            rows = starts[:, None] + np.arange(n)
            S = len(starts)
            nav = mechanize(
                dth[:, rows].reshape(-1, n, 3),
                dvb[:, rows].reshape(-1, n, 3),
                dt,
                np.tile(p[starts], (len(ids), 1)),
                np.tile(v[starts], (len(ids), 1)),
                np.tile(q[starts], (len(ids), 1)),
                frame,
                every=n,
                outputs=("p",),
            )
            err = nav.p_n[:, -1].reshape(len(ids), S, 3) - p[starts + n][None]
            out[drift_column(T)].append(np.linalg.norm(err, axis=-1).mean(axis=1))
    index = pd.Index(np.concatenate(ids_all) if ids_all else [], name="sequence")
    return pd.DataFrame({k: np.concatenate(v) if v else [] for k, v in out.items()}, index=index)


def grade_row(grade: str, metrics: pd.DataFrame) -> dict:
    """Median and 5-95 % of each per-sequence value, for one grade."""
    row: dict = {"grade": grade, "sequences": len(metrics)}
    stats = dict(_STATS)
    stats.update({c: c for c in metrics.columns if c.startswith("drift_")})
    for name, col in stats.items():
        v = metrics[col].to_numpy(dtype=float)
        v = v[np.isfinite(v)] if col.startswith("drift_") else v
        p05, p50, p95 = np.percentile(v, [5, 50, 95]) if len(v) else (np.nan,) * 3
        stem = name[:-2] if name.endswith("_m") else name
        unit = "_m" if name.endswith("_m") else ""
        row[name] = p50
        row[f"{stem}_p05{unit}"] = p05
        row[f"{stem}_p95{unit}"] = p95
    return row


def grade_table(rows: list[dict]) -> pd.DataFrame:
    """Table with one row per grade; the first columns are those the README documents."""
    df = pd.DataFrame(rows)
    first = ["grade", "east_m", "north_m", "up_m", "total_m", "total_p05_m", "total_p95_m"]
    return df[first + [c for c in df.columns if c not in first]]


def _fmt(x: float) -> str:
    if not np.isfinite(x):
        return "n/a"
    if x == 0 or 1e-3 <= abs(x) < 1e5:
        return f"{x:.3g}" if abs(x) < 10 else f"{x:,.1f}"
    return f"{x:.2e}"


def display_table(table: pd.DataFrame) -> pd.DataFrame:
    """Human table: RMSE E/N/U/Total as median [5-95 %] over sequences."""
    rows = []
    for _, r in table.iterrows():
        row = {"grade": r["grade"], "sequences": int(r["sequences"])}
        for label, stem in (
            ("East", "east"),
            ("North", "north"),
            ("Up", "up"),
            ("Total", "total"),
            ("Final 3-D", "final_3d"),
        ):
            row[f"{label} (m)"] = (
                f"{_fmt(r[stem + '_m'])} [{_fmt(r[stem + '_p05_m'])}-{_fmt(r[stem + '_p95_m'])}]"
            )
        row["Final % dist."] = _fmt(r["final_pct_distance"])
        for c in table.columns:
            if c.startswith("drift_") and not c.endswith(("_p05_m", "_p95_m")):
                stem = c[: -len("_m")]
                row[f"Drift {stem[6:-1]} s (m)"] = (
                    f"{_fmt(r[c])} [{_fmt(r[stem + '_p05_m'])}-{_fmt(r[stem + '_p95_m'])}]"
                )
        rows.append(row)
    return pd.DataFrame(rows)


def write_tables(table: pd.DataFrame, out_csv: str | Path) -> dict[str, Path]:
    """Write the grade table as CSV (machine) and Markdown, LaTeX and HTML (human)."""
    out_csv = Path(out_csv)
    stem = out_csv.with_suffix("")
    paths = {
        "csv": out_csv,
        "md": stem.with_suffix(".md"),
        "tex": stem.with_suffix(".tex"),
        "html": stem.with_suffix(".html"),
    }
    from imugen.io import atomic_output

    def write_text(path: Path, text: str) -> None:
        with atomic_output(path) as tmp:
            tmp.write_text(text)

    write_text(paths["csv"], table.to_csv(index=False, float_format="%.6g"))
    human = display_table(table)
    caption = (
        "RMSE of position per grade: median over sequences [5th-95th percentile], metres; "
        "Total = sqrt(E^2 + N^2 + U^2); Drift T s = mean 3-D error T s after true starts "
        "every T/2 s."
    )
    cols = list(human.columns)
    md = ["| " + " | ".join(cols) + " |", "|" + "---|" * len(cols)]
    md += ["| " + " | ".join(str(v) for v in r) + " |" for r in human.itertuples(index=False)]
    write_text(paths["md"], caption + "\n\n" + "\n".join(md) + "\n")

    def tex(v) -> str:
        return str(v).replace("%", r"\%").replace("_", r"\_")

    lines = [
        r"\begin{table}",
        r"\centering",
        rf"\caption{{{tex(caption)}}}",
        r"\label{tab:rmse}",
        r"\begin{tabular}{l" + "r" * (len(cols) - 1) + "}",
        r"\hline",
        " & ".join(tex(c) for c in cols) + r" \\",
        r"\hline",
        *(" & ".join(tex(v) for v in r) + r" \\" for r in human.itertuples(index=False)),
        r"\hline",
        r"\end{tabular}",
        r"\end{table}",
    ]
    write_text(paths["tex"], "\n".join(lines) + "\n")
    write_text(
        paths["html"],
        f"<p>{caption}</p>\n" + human.to_html(index=False, border=0, classes="rmse") + "\n",
    )
    return paths


def horizontal_distance_m(truth_path) -> float:
    """Horizontal distance travelled by the truth (sum of its E-N steps), metres."""
    en = ttruth.read_arrow(truth_path, columns=list(ttruth.POS[:2]))
    e, n = (en.column(c).to_numpy() for c in ttruth.POS[:2])
    return float(np.hypot(np.diff(e), np.diff(n)).sum())


def run(truth, nav_paths, out, *, grade: str, segments_s=(), imu_paths=()) -> Path:
    """Per-sequence metrics of one grade's navigation shards -> Parquet (index ``sequence``).

    With ``segments_s``, the relative drift of every sequence of ``imu_paths`` (the grade's IMU
    shards, which must hold the same sequences as the navigation files) is added.
    """
    from imugen.errors import InputError

    distance = horizontal_distance_m(truth)
    # one navigation file at a time (a sequence lives in one shard): memory stays at one
    # file plus one metrics row per sequence, whatever the number of shards
    parts = [
        sequence_metrics(tnav.read(p, columns=["sequence", "time_s", *ERR]), distance)
        for p in nav_paths
    ]
    metrics = pd.concat(parts).sort_index(kind="stable")
    if not metrics.index.is_unique:
        dup = metrics.index[metrics.index.duplicated()][0]
        raise InputError(grade, f"sequence {dup} appears in more than one navigation file")
    segments_s = [float(T) for T in segments_s]
    if any(not np.isfinite(T) or T <= 0 for T in segments_s):
        raise InputError("--segments", f"segment durations must be > 0 s, got {segments_s}")
    if segments_s:
        if not imu_paths:
            raise InputError("--segments", "relative drift needs the IMU shards (--imu)")
        drift = pd.concat([segment_drift(truth, p, segments_s) for p in imu_paths])
        if not drift.index.is_unique or set(drift.index) != set(metrics.index):
            raise InputError(grade, "the IMU shards do not hold the sequences of the navigation")
        metrics = metrics.join(drift)
        short = [T for T in segments_s if metrics[drift_column(T)].isna().all()]
        if short:
            warnings.warn(
                f"{grade}: no segment of {short} s fits the route: drift is NaN", stacklevel=2
            )
    meta = {
        "stage": "evaluate",
        "grade": grade,
        "truth": str(truth),
        "nav": [str(p) for p in nav_paths],
        "distance_horizontal_m": distance,
        "segments_s": segments_s,
        "segment_step": "T/2",
        "units": "metres; final_pct_distance in % of the horizontal distance travelled",
    }
    return tmetrics.write(metrics, meta, out)


def run_tables(metrics_paths, out_csv) -> dict[str, Path]:
    """Gather per-grade metrics files into the RMSE table (CSV, Markdown, LaTeX, HTML)."""
    rows = []
    for p in metrics_paths:
        grade = tmetrics.read_meta(p)["grade"]
        rows.append(grade_row(grade, tmetrics.read(p).set_index("sequence")))
    return write_tables(grade_table(rows), out_csv)
