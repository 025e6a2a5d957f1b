"""Evaluation stage: navigation errors -> per-sequence RMSE -> per-grade tables.

Per sequence, over the evaluation epochs (every epoch of the navigation error table, the
first one included, as the paper does):

- ``rmse_east_m``, ``rmse_north_m``, ``rmse_up_m``: root mean square of the position error
  along each ENU axis;
- ``rmse_total_m = sqrt(E^2 + N^2 + U^2)`` of those three (the paper's "Total");
- ``final_east_m`` ... ``final_3d_m``: error at the last epoch; ``final_pct_distance``: final
  horizontal error as a percentage of the horizontal distance travelled;
- ``rmse_along_m``, ``rmse_cross_m``: RMSE of the along-track and cross-track errors (over the
  epochs where they are defined), ``final_along_m``, ``final_cross_m``: their signed values at
  the last epoch (cross positive to the left of the track). Absent for navigation tables
  written before the track columns existed.

East/North/Up are those of the navigation table: the local level at the TRUE position
(:mod:`imugen.navigate.local_errors`), whatever the Earth model (``flat``: the ENU of the origin,
unchanged; ``geodetic``, whose navigation coordinates are ECEF: still East/North/Up).

Relative drift (``segments``, seconds ``T``): how far the navigation drifts in ``T`` seconds
from a correct start, the figure drift-correction papers report. For each start ``t_s`` the
sequence is mechanized again from the TRUE position, velocity and attitude at ``t_s`` over the
IMU's own increments; the drift after ``T`` is the 3-D position error at ``t_s + T``. Starts slide
by ``T_max / 2`` from ``t_0``, ``T_max`` the longest requested ``T`` that fits the route
(``t_s = 0, T_max/2, T_max, ...`` while ``t_s + T_max`` fits: half-overlapping segments), and one
mechanization of ``T_max`` per start yields every ``T``, so a route of duration ``D`` gives
``floor(2 (D - T_max) / T_max) + 1`` starts and costs two extra navigations whatever the number
of ``T``. ``drift_<T>s_m`` is the mean over the starts (NaN for a ``T`` longer than the route).
With a constant accelerometer bias ``b`` alone the drift of every start is ``|b| T^2 / 2``.

Aided navigation (``aided``, the error tables of ``imugen aid``, :mod:`imugen.tables.aided`),
per sequence:

- ``aided_total_m``: RMSE (sqrt(E^2 + N^2 + U^2) of the per-axis RMSE) over the epochs where the
  filter used a GNSS fix and no scenario was active: the figure "with GNSS";
- ``aided_along_m``, ``aided_cross_m``: the same RMSE of the along- and cross-track errors;
- ``aided_nees_pos``: mean over those epochs of ``sum_i (err_i / sd_i)^2 / 3`` with the filter's
  reported sigmas (about 1 for a consistent filter; per-axis, correlations ignored);
- ``outage_<D>s_end_m``: horizontal error at the last epoch of an outage of ``D`` s (the last
  epoch before GNSS returns; ``D`` the time since the last fix, rounded to the second); NaN for
  a sequence without such an outage (mean when it has several);
- ``time_to_10m_s``: time from the last fix to the first evaluation epoch of the sequence's
  first outage where the horizontal error exceeds 10 m (resolution: the evaluation step);
  infinite when it never does.

Meaningless free-inertial figures: a grade whose median final 3-D free-inertial error exceeds
:data:`MEANINGLESS_EARTH_FRACTION` of the Earth radius, or :data:`MEANINGLESS_EXTENT_FACTOR`
times the scene's extent (diagonal of the bounding box of the truth in the ENU of its origin),
is flagged (``free_inertial_meaningless`` in rmse.csv, the human tables' grade label, and a
warning recommending the aided figures, logged by ``evaluate`` for the grade and again by
``tables``): the error then describes a solution that left the planet or the map, not the IMU
(a consumer IMU free-running for hours reaches thousands of Earth radii). The local-level
errors stay finite then: only the true position sets their axes.

Per grade: the median over sequences of each value (``east_m``, ``north_m``, ``up_m``,
``total_m``, ``drift_<T>s_m``, ...) with its 5th and 95th percentiles (``*_p05_m``,
``*_p95_m``).
"""

from __future__ import annotations

import math
import sys
import warnings
from pathlib import Path

import numpy as np
import pandas as pd

from imugen.evaluate.options import EvaluateOptions, TablesOptions
from imugen.tables import metrics as tmetrics
from imugen.tables import nav as tnav
from imugen.tables import truth as ttruth

ERR = tnav.ERR_POS
TRACK = tnav.ERR_TRACK
AXES = tmetrics.AXES
EARTH_RADIUS_M = 6_371_000.0
MEANINGLESS_EARTH_FRACTION = 0.1
"""Flag when the median final free-inertial error exceeds this fraction of the Earth radius."""
MEANINGLESS_EXTENT_FACTOR = 100.0
"""... or this multiple of the scene's extent (diagonal of the ENU bounding box of the truth)."""
POSITION_BATCH = 1 << 18
"""Truth rows per block when streaming positions (distance, extent)."""
TIME_TO_M = 10.0
"""Horizontal error threshold of ``time_to_10m_s`` (m)."""


def outage_column(D: float) -> str:
    """Name of the error at the end of an outage of ``D`` seconds: ``outage_60s_end_m``."""
    return f"outage_{D:g}s_end_m"


def aided_metrics(aided: pd.DataFrame) -> pd.DataFrame:
    """Per-sequence aided figures (module docstring) from an aided error table (index ``sequence``)."""
    from imugen.tables import aided as taided

    a = aided.sort_values(["sequence", "time_s"], kind="stable")
    seqs = np.sort(a["sequence"].unique())
    out = pd.DataFrame(index=pd.Index(seqs, name="sequence"))
    on = a[(a[taided.GNSS_USED] == 1) & (a[taided.STATE] == 0)]
    ms = on[list(ERR)].pow(2).groupby(on["sequence"]).mean()
    out["aided_total_m"] = np.sqrt(ms.sum(axis=1)).reindex(seqs)
    if set(TRACK) <= set(a.columns):
        mt = on[list(TRACK)].pow(2).groupby(on["sequence"]).mean().reindex(seqs)
        out["aided_along_m"] = np.sqrt(mt[TRACK[0]].to_numpy())
        out["aided_cross_m"] = np.sqrt(mt[TRACK[1]].to_numpy())
    z2 = (on[list(ERR)].to_numpy() / on[list(taided.SD_POS)].to_numpy()) ** 2
    out["aided_nees_pos"] = (
        pd.Series(z2.sum(axis=1) / 3.0, index=on.index).groupby(on["sequence"]).mean()
    ).reindex(seqs)
    h = np.hypot(a[ERR[0]].to_numpy(), a[ERR[1]].to_numpy())
    nofix = a[taided.SINCE_FIX].to_numpy() > 0
    seq = a["sequence"].to_numpy()
    # runs without a fix that started after a fix (since_fix_s finite): end = last row of a run
    nxt_same = np.r_[seq[1:] == seq[:-1], False]
    nxt_nofix = np.r_[nofix[1:], False]
    end = nofix & ~(nxt_same & nxt_nofix)
    ends = pd.DataFrame(
        {"sequence": seq[end], "D": np.round(a[taided.SINCE_FIX].to_numpy()[end]), "h": h[end]}
    )
    for D, grp in ends.groupby("D"):
        out[outage_column(float(D))] = grp.groupby("sequence")["h"].mean().reindex(seqs)
    # time to exceed 10 m in the first outage of each sequence
    start = nofix & ~np.r_[False, (seq[1:] == seq[:-1]) & nofix[:-1]]
    run_id = np.cumsum(start)
    first_run = pd.Series(run_id).where(nofix).groupby(seq).transform("min").to_numpy()
    inrun = nofix & (run_id == first_run)
    over = inrun & (h > TIME_TO_M)
    tt = pd.Series(a[taided.SINCE_FIX].to_numpy()[over]).groupby(seq[over]).min()
    has = pd.Series(inrun).groupby(seq).any().reindex(seqs)
    out["time_to_10m_s"] = np.where(has.to_numpy(), np.inf, np.nan)
    out.loc[tt.index, "time_to_10m_s"] = tt.to_numpy()
    return out


def sequence_metrics(nav: pd.DataFrame, distance_m: float) -> pd.DataFrame:
    """Per-sequence RMSE and final errors.

    Parameters
    ----------
    nav : DataFrame
        Columns ``sequence``, ``time_s`` and ``err_e_m``, ``err_n_m``, ``err_u_m`` (metres),
        optionally ``err_along_m``, ``err_cross_m``, one row per sequence and evaluation epoch.
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
    if set(TRACK) <= set(nav.columns):
        tr = nav[list(TRACK)].pow(2)
        tr["sequence"] = nav["sequence"].to_numpy()
        mt = tr.groupby("sequence", sort=True).mean()  # NaN (no track direction) skipped
        for name, c in zip(("along", "cross"), TRACK, strict=True):
            out[f"rmse_{name}_m"] = np.sqrt(mt[c].to_numpy())
            out[f"final_{name}_m"] = last[c]
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
_TRACK_STATS = {
    "along_m": "rmse_along_m",
    "cross_m": "rmse_cross_m",
    "final_along_m": "final_along_m",
    "final_cross_m": "final_cross_m",
}


def drift_column(T: float) -> str:
    """Name of the drift after ``T`` seconds: ``drift_30s_m``."""
    return f"drift_{T:g}s_m"


def segment_starts(samples: int, n: int) -> np.ndarray:
    """Start samples of segments of ``n`` intervals in ``samples`` samples: every ``n/2``."""
    if n < 1 or n > samples - 1:
        return np.zeros(0, np.int64)
    return np.arange(0, samples - 1 - n + 1, max(1, round(n / 2)), dtype=np.int64)


def segment_drift(
    truth_path, imu_path, segments_s, *, batch: int | None = None, vertical=None
) -> pd.DataFrame:
    """Relative drift of every sequence of an IMU shard (see the module docstring).

    Parameters
    ----------
    truth_path, imu_path : path
        The route's truth and one IMU shard (increments, compensated or raw, or rates only),
        navigated as :mod:`imugen.navigate.stage` does.
    segments_s : sequence of float
        Segment durations ``T`` (s).
    batch : int, optional
        Sequences mechanized together (default from the navigation memory budget).
    vertical : imugen.navigate.vertical.VerticalSpec, optional
        Vertical channel, resolved for the longest segment (default ``auto``: free for
        segments up to 1,710 s; damped by the true height beyond).

    Returns
    -------
    DataFrame
        Index ``sequence``; one column ``drift_<T>s_m`` (metres) per ``T``.
    """
    from imugen.core.earth import earth_rate_n
    from imugen.navigate.mechanize import (
        compensate_raw,
        increments_from_rates,
        mechanize,
        reference_heights,
    )
    from imugen.navigate.navigator import batch_size
    from imugen.navigate.vertical import VerticalSpec
    from imugen.sensors.mounting import imu_states
    from imugen.tables import shard as tshard

    cols = [ttruth.TIME, *ttruth.POS, *ttruth.VEL, *ttruth.QUAT, *ttruth.GYRO]
    truth = ttruth.read(truth_path, columns=cols)
    K, dt, rate = truth.K, truth.dt, truth.rate_hz
    frame = truth.origin_frame()
    p, v, q = truth.p_n, truth.v_n, truth.q_nb
    columns, kind = tshard.measurement(imu_path)
    rates = kind == "rates"
    smeta = tshard.read_meta(imu_path)
    raw = not rates and tshard.increment_kind(smeta) == "raw"
    # a mounted IMU starts from, and is compared with, its own truth (imugen.sensors.mounting)
    labels = tshard.read_labels(imu_path, smeta) if smeta.get("mounting") else None
    Om = earth_rate_n(frame)
    ids_all, out = [], {drift_column(T): [] for T in segments_s}
    ns = {T: round(T * rate) for T in segments_s}
    fit = sorted({n for n in ns.values() if 1 <= n <= K - 1})
    n_max = fit[-1] if fit else 0
    starts = segment_starts(K, n_max)
    every = math.gcd(*fit) if fit else 1  # store only the epochs some T needs
    S = len(starts)
    vc = (vertical or VerticalSpec()).resolve(frame, n_max * dt)
    h_seg = None
    if vc.damped and S:
        h_seg = reference_heights(p, frame)[starts[:, None] + np.arange(n_max + 1)]
    batch = batch or max(1, batch_size(K) // 2)  # segments hold about twice the samples
    for ids, a, c in tshard.iter_blocks(imu_path, columns, K, batch, 0 if rates else 1):
        ids_all.append(ids.copy())
        if not S:
            for T in segments_s:
                out[drift_column(T)].append(np.full(len(ids), np.nan))
            continue
        if rates:
            dth, dvb = increments_from_rates(a, c, dt)
        else:  # raw increments get navigation's coning/sculling correction first
            dth, dvb = compensate_raw(a, c) if raw else (a, c)
        rows = starts[:, None] + np.arange(n_max)
        mount = tshard.mounting(labels, ids)
        if mount is None:
            x0 = [np.tile(x[starts], (len(ids), 1)) for x in (p, v, q)]
        else:
            x0 = imu_states(p[starts], v[starts], q[starts], truth.omega_ib_b[starts], Om, *mount)
            x0 = [x.reshape(len(ids) * S, -1) for x in x0]
        nav = mechanize(
            dth[:, rows].reshape(-1, n_max, 3),
            dvb[:, rows].reshape(-1, n_max, 3),
            dt,
            *x0,
            frame,
            every=every,
            outputs=("p",),
            gains=vc.kernel_gains(),
            href=None if h_seg is None else np.tile(h_seg, (len(ids), 1)),
        )
        pos = nav.p_n.reshape(len(ids), S, -1, 3)  # at 0, every, 2 every, ..., n_max
        for T, n in ns.items():
            if n not in fit:
                out[drift_column(T)].append(np.full(len(ids), np.nan))
                continue
            k = starts + n
            if mount is None:
                ref = p[k][None]
            else:
                ref = imu_states(p[k], None, q[k], None, Om, *mount)[0]
            err = pos[:, :, n // every] - ref
            out[drift_column(T)].append(np.linalg.norm(err, axis=-1).mean(axis=1))
    index = pd.Index(np.concatenate(ids_all) if ids_all else [], name="sequence")
    return pd.DataFrame({k: np.concatenate(v) if v else [] for k, v in out.items()}, index=index)


def _vertical_spec(record: dict | None):
    """The :class:`~imugen.navigate.vertical.VerticalSpec` a navigation table's record was
    made with (default ``auto`` when none is recorded)."""
    from imugen.navigate.vertical import VerticalSpec

    if not record:
        return VerticalSpec()
    return VerticalSpec(
        record.get("requested") or "auto",
        int(record.get("order") or 3),
        float(record.get("time_constant_s") or 100.0),
        record.get("reference") or "truth",
    )


_OPTIONAL = ("drift_", "aided_", "outage_", "time_to_")


def grade_row(grade: str, metrics: pd.DataFrame) -> dict:
    """Median and 5-95 % of each per-sequence value, for one grade."""
    row: dict = {"grade": grade, "sequences": len(metrics)}
    stats = dict(_STATS)
    stats.update({k: c for k, c in _TRACK_STATS.items() if c in metrics.columns})
    stats.update({c: c for c in metrics.columns if c.startswith(_OPTIONAL)})
    for name, col in stats.items():
        v = metrics[col].to_numpy(dtype=float)
        if col == "time_to_10m_s":  # inf = never: order statistics, no interpolation
            v = v[~np.isnan(v)]
            q = np.percentile(v, [5, 50, 95], method="inverted_cdf") if len(v) else [np.nan] * 3
            p05, p50, p95 = q
        else:
            optional = col.startswith(_OPTIONAL) or col in _TRACK_STATS.values()
            v = v[np.isfinite(v)] if optional else v
            p05, p50, p95 = np.percentile(v, [5, 50, 95]) if len(v) else (np.nan,) * 3
        unit = next((u for u in ("_m", "_s") if name.endswith(u)), "")
        stem = name[: len(name) - len(unit)]
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
            ("Along", "along"),
            ("Cross", "cross"),
            ("Final 3-D", "final_3d"),
        ):
            if stem + "_m" not in table.columns:
                continue
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
        for c in table.columns:
            if c == "aided_total_m" or (c.startswith("outage_") and c.endswith("_end_m")):
                stem = c[: -len("_m")]
                label = "Aided total" if c == "aided_total_m" else f"Outage {stem[7:-5]} s end"
                row[f"{label} (m)"] = (
                    f"{_fmt(r[c])} [{_fmt(r[stem + '_p05_m'])}-{_fmt(r[stem + '_p95_m'])}]"
                )
        if "time_to_10m_s" in table.columns:
            v = r["time_to_10m_s"]
            row["To 10 m (s)"] = "never" if v == np.inf else _fmt(v)
        if r.get("free_inertial_meaningless"):
            row["grade"] = f"{r['grade']} (free-inertial meaningless)"
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
    from imugen.core.io import atomic_output

    def write_text(path: Path, text: str) -> None:
        with atomic_output(path) as tmp:
            tmp.write_text(text)

    write_text(paths["csv"], table.to_csv(index=False, float_format="%.6g"))
    human = display_table(table)
    caption = (
        "RMSE of position per grade: median over sequences [5th-95th percentile], metres; "
        "East/North/Up at the true position, Along/Cross the true track; "
        "Total = sqrt(E^2 + N^2 + U^2); Drift T s = mean 3-D error T s after true starts "
        "every T_max/2 s."
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


def _position_batches(truth_path):
    """``(frame, iterator of p_n blocks (n, 3))`` of a truth file, streamed (bounded memory
    whatever the route's length)."""
    frame = ttruth.origin_frame(ttruth.read_meta(truth_path))
    return frame, ttruth.iter_batches(truth_path, list(ttruth.POS), POSITION_BATCH)


def _up_n(frame, p_n: np.ndarray) -> np.ndarray:
    """Unit ellipsoidal normal (local Up) at positions ``p_n`` (K, 3), resolved in n."""
    if frame.model == "flat":
        return np.broadcast_to([0.0, 0.0, 1.0], p_n.shape)
    lat, lon, _ = frame.geodetic_from_n(p_n)
    up_e = np.column_stack([np.cos(lat) * np.cos(lon), np.cos(lat) * np.sin(lon), np.sin(lat)])
    return up_e @ frame.C_en.T


def horizontal_distance_m(truth_path) -> float:
    """Horizontal distance travelled by the truth, metres: the sum of its steps projected on
    the local level at each step's start (East-North steps in ``flat``)."""
    frame, blocks = _position_batches(truth_path)
    total, prev = 0.0, None
    for p in blocks:
        if prev is not None:
            p = np.vstack([prev, p])
        prev = p[-1:]
        if len(p) < 2:
            continue
        d = np.diff(p, axis=0)
        vert = np.einsum("ij,ij->i", d, _up_n(frame, p[:-1]))
        total += float(np.sqrt(np.maximum(np.einsum("ij,ij->i", d, d) - vert**2, 0.0)).sum())
    return total


def extent_m(truth_path) -> float:
    """Diagonal of the truth's bounding box in the ENU of its origin, metres (the scene's
    extent; a chord-based size for routes beyond the tangent plane)."""
    frame, blocks = _position_batches(truth_path)
    lo, hi = np.full(3, np.inf), np.full(3, -np.inf)
    for p in blocks:
        if frame.model == "geodetic":
            p = frame.with_model("wgs84").n_from_ecef(p)
        if len(p):
            lo, hi = np.minimum(lo, p.min(axis=0)), np.maximum(hi, p.max(axis=0))
    return float(np.sqrt(np.sum((hi - lo) ** 2))) if np.isfinite(lo).all() else 0.0


def run(truth, nav_paths, out, options: EvaluateOptions, *, imu_paths=(), aided_paths=()) -> Path:
    """Per-sequence metrics of one grade's navigation shards -> Parquet (index ``sequence``).

    With ``options.segments_s``, the relative drift of every sequence of ``imu_paths`` (the
    grade's IMU shards, which must hold the same sequences as the navigation files) is added;
    with ``aided_paths`` (the grade's aided error tables), the aided figures (module
    docstring).
    """
    from imugen.core.errors import InputError

    grade, segments_s = options.grade, options.segments_s

    distance = horizontal_distance_m(truth)
    # the navigation's vertical channel (its tables' metadata; older tables: none recorded)
    vertical = next(
        (m for m in (tnav.read_meta(p).get("vertical_channel") for p in nav_paths) if m), None
    )
    # one navigation file at a time (a sequence lives in one shard): memory stays at one
    # file plus one metrics row per sequence, whatever the number of shards
    parts = [
        sequence_metrics(
            tnav.read(
                p, columns=["sequence", "time_s", *ERR, *(TRACK if tnav.has_track(p) else ())]
            ),
            distance,
        )
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
        spec = _vertical_spec(vertical)
        drift = pd.concat([segment_drift(truth, p, segments_s, vertical=spec) for p in imu_paths])
        if not drift.index.is_unique or set(drift.index) != set(metrics.index):
            raise InputError(grade, "the IMU shards do not hold the sequences of the navigation")
        metrics = metrics.join(drift)
        short = [T for T in segments_s if metrics[drift_column(T)].isna().all()]
        if short:
            warnings.warn(
                f"{grade}: no segment of {short} s fits the route: drift is NaN", stacklevel=2
            )
    if aided_paths:
        from imugen.tables import aided as taided

        aid = pd.concat([aided_metrics(taided.read(p)) for p in aided_paths])
        if not aid.index.is_unique or not set(aid.index) <= set(metrics.index):
            raise InputError(grade, "the aided tables do not hold the sequences of the navigation")
        metrics = metrics.join(aid)
    extent = extent_m(truth)
    warn_meaningless(
        grade, float(metrics[tmetrics.FINAL_3D].median()), extent, bool(aided_paths), vertical
    )
    meta = {
        "stage": "evaluate",
        "grade": grade,
        "extent_m": extent,
        "aided": [str(p) for p in aided_paths],
        "truth": str(truth),
        "nav": [str(p) for p in nav_paths],
        "distance_horizontal_m": distance,
        "segments_s": segments_s,
        "segment_step": "T_max/2",
        "vertical_channel": vertical,
        "units": "metres; final_pct_distance in % of the horizontal distance travelled",
        "error_frame": "East/North/Up at the true position; along/cross the true track, "
        "cross positive left",
    }
    return tmetrics.write(metrics, meta, out)


def run_tables(metrics_paths, out_csv) -> dict[str, Path]:
    """Gather per-grade metrics files into the RMSE table (CSV, Markdown, LaTeX, HTML)."""
    rows = []
    for p in metrics_paths:
        meta = tmetrics.read_meta(p)
        row = grade_row(meta["grade"], tmetrics.read(p).set_index("sequence"))
        row["free_inertial_meaningless"] = warn_meaningless(
            meta["grade"],
            row["final_3d_m"],
            meta.get("extent_m"),
            "aided_total_m" in row,
            meta.get("vertical_channel"),
        )
        rows.append(row)
    return write_tables(grade_table(rows), out_csv)


def main(options: EvaluateOptions, truth, nav, output, imu, aided) -> None:
    """``imugen evaluate``."""
    run(truth, nav, output, options, imu_paths=imu, aided_paths=aided)


def main_tables(options: TablesOptions, metrics, output) -> None:
    """``imugen tables``: :func:`run_tables`, then the Markdown table on stderr."""
    paths = run_tables(metrics, output)
    print(paths["md"].read_text(), file=sys.stderr)


def warn_meaningless(
    grade: str, final_3d_m: float, extent: float | None, aided: bool, vertical: dict | None = None
) -> bool:
    """:func:`meaningless`, with a warning naming the grade when True (and, with the
    navigation's ``vertical`` channel record, why: the free vertical channel's growth)."""
    from imugen.navigate.vertical import meaningless_reason

    if not meaningless(final_3d_m, extent):
        return False
    why = meaningless_reason(vertical)
    warnings.warn(
        f"{grade}: median final free-inertial error {final_3d_m:.3g} m "
        f"({final_3d_m / EARTH_RADIUS_M:.3g} Earth radii) exceeds "
        f"{MEANINGLESS_EARTH_FRACTION:.0%} of the Earth radius or "
        f"{MEANINGLESS_EXTENT_FACTOR:g} x the scene's extent: the scene is too long for unaided "
        "inertial navigation and its free-inertial figures say nothing about the IMU"
        + (f" ({why})" if why else "")
        + "; "
        + (
            "use the aided figures (aided_total_m, outage_*_end_m)"
            if aided
            else "turn on gnss.enabled and use the aided figures"
        ),
        stacklevel=3,
    )
    return True


def meaningless(final_3d_m: float, extent: float | None) -> bool:
    """True when a free-inertial error has left the planet or the scene (module docstring), or
    is not a finite number."""
    lim = MEANINGLESS_EARTH_FRACTION * EARTH_RADIUS_M
    if extent is not None and extent > 0:
        lim = min(lim, MEANINGLESS_EXTENT_FACTOR * float(extent))
    # a solution that overflowed (inf) or broke down (NaN) is as meaningless as a far one
    return bool(not np.isfinite(final_3d_m) or final_3d_m > lim)
