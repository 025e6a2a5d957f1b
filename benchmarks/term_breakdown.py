"""Error budget by term: each error term of each grade alone, over the paper's scene.

The paper's trajectory (``resources/paper/seed_reference_trajectory_enu.txt``, origin 31.63 N,
7.99 W, 480.6 m, one point per second, car) is turned into a truth at ``--rate-hz`` (100 Hz),
then, for every grade and every term the grade configures, ``--sequences`` Monte-Carlo
sequences are simulated with only that term on (``simulate(..., terms=["gyro.<term>"])``, the
API of ``imugen simulate --terms``), mechanized from the true initial state (free inertial,
no aiding) and evaluated at 1 Hz epochs as the workflow does (:func:`imugen.evaluate.stage.
sequence_metrics`). A last row per grade has every term on. The sequences of a term are the
same draws whether it runs alone or with the others (each term has its own random streams), so
the rows are comparable.

Output: ``term_breakdown.md`` and ``.csv`` in ``--out``: per grade and term the median total
RMSE (sqrt(E^2 + N^2 + U^2)) and the median final 3-D error in metres, and the terms that
dominate each grade's drift (largest median final error alone).

Usage: python benchmarks/term_breakdown.py [--sequences 50] [--rate-hz 100] [--earth wgs84]
       [--grades consumer,tactical,...] [--out DIR]
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np
import pandas as pd

from imugen.core.earth import OriginFrame
from imugen.evaluate.stage import sequence_metrics
from imugen.ingest.stage import ingest
from imugen.navigate.mechanize import mechanize
from imugen.sensors.grades import SENSORS, TERMS, get_grade
from imugen.simulate.stage import simulate
from imugen.tables import truth as col
from imugen.truth import build_truth

REPO = Path(__file__).resolve().parents[1]
PAPER = REPO / "resources" / "paper" / "seed_reference_trajectory_enu.txt"
ORIGIN = (31.63, -7.99, 480.6)
GRADES = (
    "consumer",
    "industrial",
    "tactical",
    "navigation",
    "consumer_calibrated",
    "industrial_calibrated",
    "tactical_calibrated",
    "navigation_calibrated",
)
ALL = "all terms"
VIB = "vibration ({}) alone"
VIB_ALL = "all terms + vibration ({})"


def grade_terms(name: str) -> list[str]:
    """``sensor.term`` for every term the grade configures, gyro first."""
    g = get_grade(name)
    return [f"{s}.{t}" for s in SENSORS for t in g.sensor(s).configured()]


def run_term(truth, frame, grade, terms, sequences, seed, rate_hz, batch=25, vibration=None):
    """Per-sequence metrics (:func:`imugen.evaluate.stage.sequence_metrics`) with ``terms`` on."""
    t = truth[col.TIME].to_numpy()
    p_true = truth[list(col.POS)].to_numpy()
    v0 = truth[list(col.VEL)].to_numpy()[0]
    q0 = truth[list(col.QUAT)].to_numpy()[0]
    dt = 1.0 / rate_hz
    every = max(1, round(rate_hz))
    metrics = []
    for shard in range(0, sequences, batch):
        M = min(batch, sequences - shard)
        sh = simulate(
            truth,
            grade,
            sequences=M,
            seed=seed,
            shard=shard // batch,
            shard_size=batch,
            terms=terms,
            vibration=vibration,
        )
        nav = mechanize(
            sh.data["dtheta"][:, 1:],
            sh.data["dv"][:, 1:],
            dt,
            p_true[0],
            v0,
            q0,
            frame,
            every=every,
            outputs=("p",),
        )
        err = nav.p_n - p_true[nav.index][None]
        S, E = err.shape[:2]
        table = pd.DataFrame(
            {
                "sequence": np.repeat(np.arange(S) + shard, E),
                "time_s": np.tile(t[nav.index], S),
                "err_e_m": err[..., 0].ravel(),
                "err_n_m": err[..., 1].ravel(),
                "err_u_m": err[..., 2].ravel(),
            }
        )
        metrics.append(sequence_metrics(table, 1.0))
    return pd.concat(metrics)


def fmt(x: float) -> str:
    if x >= 100:
        return f"{x:,.0f}"
    if x >= 1:
        return f"{x:.3g}"
    return f"{x:.2g}"


def markdown(df: pd.DataFrame, grades) -> str:
    """Rows: terms; columns: grades; cells: 'RMSE / final' in metres ('-' not configured)."""
    order = {f"{s}.{t}": (i, j) for i, s in enumerate(SENSORS) for j, t in enumerate(TERMS)}
    extra = [t for t in dict.fromkeys(df.term) if t.startswith(("vibration", "all terms +"))]
    plain = (t for t in set(df.term) if t != ALL and t not in extra)
    terms = [*sorted(plain, key=order.__getitem__), ALL, *extra]
    lines = [
        "| term | " + " | ".join(grades) + " |",
        "|---|" + "---|" * len(grades),
    ]
    for term in terms:
        cells = []
        for g in grades:
            r = df[(df.grade == g) & (df.term == term)]
            cells.append(
                "-" if r.empty else f"{fmt(r.rmse_total_m.iloc[0])} / {fmt(r.final_3d_m.iloc[0])}"
            )
        name = f"`{term}`" if term in order else f"**{term}**"
        lines.append(f"| {name} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def dominant(df: pd.DataFrame, grade: str, share: float = 0.25) -> str:
    """Terms whose final error alone is at least ``share`` of the largest one, largest first."""
    r = df[(df.grade == grade) & df.term.str.contains(".", regex=False)]
    r = r.sort_values("final_3d_m", ascending=False)
    top = r.final_3d_m.iloc[0]
    keep = r[r.final_3d_m >= share * top]
    return ", ".join(f"`{t}` ({fmt(f)} m)" for t, f in zip(keep.term, keep.final_3d_m, strict=True))


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sequences", type=int, default=50)
    ap.add_argument("--rate-hz", type=float, default=100.0)
    ap.add_argument("--earth", choices=["flat", "wgs84"], default="wgs84")
    ap.add_argument("--seed", type=int, default=20251150)
    ap.add_argument("--grades", default=",".join(GRADES))
    ap.add_argument("--out", type=Path, default=REPO / "benchmarks" / "results")
    ap.add_argument(
        "--write-docs", action="store_true", help="also write docs/data/term_breakdown.md"
    )
    ap.add_argument(
        "--vibration",
        default="car",
        help="also rows for this vibration alone and with every term (off: none)",
    )
    a = ap.parse_args(argv)
    grades = [g for g in a.grades.split(",") if g]
    t0 = time.perf_counter()
    ing = ingest(PAPER, origin=",".join(map(str, ORIGIN)), dt=1.0)
    truth, _ = build_truth(ing.table, ing.meta, rate_hz=a.rate_hz, earth=a.earth, verbose=False)
    frame = OriginFrame.from_deg(*ORIGIN, model=a.earth)
    print(f"truth: {len(truth)} samples ({time.perf_counter() - t0:.1f} s)", flush=True)
    rows = []
    v = a.vibration
    for g in grades:
        runs = [(t, [t], None) for t in grade_terms(g)] + [(ALL, None, None)]
        if v != "off":
            runs += [(VIB.format(v), [], v), (VIB_ALL.format(v), None, v)]
        for term, terms, vib in runs:
            ts = time.perf_counter()
            m = run_term(truth, frame, g, terms, a.sequences, a.seed, a.rate_hz, vibration=vib)
            rmse, final = float(m.rmse_total_m.median()), float(m.final_3d_m.median())
            p05, p95 = np.percentile(m.rmse_total_m, [5, 95])
            rows.append(
                {
                    "grade": g,
                    "term": term,
                    "rmse_total_m": rmse,
                    "final_3d_m": final,
                    "rmse_total_p05_m": p05,
                    "rmse_total_p95_m": p95,
                }
            )
            print(
                f"{g:24s} {term:32s} RMSE {rmse:12.4g} m  final {final:12.4g} m "
                f"({time.perf_counter() - ts:.1f} s)",
                flush=True,
            )
    df = pd.DataFrame(rows)
    uncal = [g for g in grades if not g.endswith("_calibrated")]
    cal = [g for g in grades if g.endswith("_calibrated")]
    parts = [
        f"Median total RMSE / median final 3-D error (m) of each term alone, {a.sequences} "
        f"sequences per cell, paper scene (620 s), {a.rate_hz:g} Hz, {a.earth} Earth, free "
        "inertial from the true initial state, 1 Hz epochs.\n"
    ]
    for group in (uncal, cal):
        if group:
            parts.append(markdown(df, group) + "\n")
    parts.append("Dominant terms (final error alone at least 25 % of the largest):\n")
    parts += [f"- {g}: {dominant(df, g)}" for g in grades]
    text = "\n".join(parts) + "\n"
    a.out.mkdir(parents=True, exist_ok=True)
    df.to_csv(a.out / "term_breakdown.csv", index=False)
    (a.out / "term_breakdown.md").write_text(text)
    if a.write_docs:
        import docs_data

        docs_data.write(
            "term_breakdown", "\n".join(markdown(df, g) + "\n" for g in (uncal, cal) if g)
        )
    print(text)
    print(f"({time.perf_counter() - t0:.1f} s)")


if __name__ == "__main__":
    main()
