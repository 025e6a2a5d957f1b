"""Outage table of a workflow run: aided error at the end of each outage length, time to
exceed 10 m, and free inertial beside it (README "GNSS-denied scenarios and the aided baseline").

    python benchmarks/outage_table.py RESULTS_DIR ROUTE [--grades consumer industrial tactical] \
        [--write-docs]

Reads ``RESULTS_DIR/ROUTE/rmse.csv`` (``imugen tables``: ``outage_<D>s_end_m`` and the
free-inertial ``drift_<D>s_m`` with their 5-95 %) and the route's aided tables
(``aided/<grade>/shard-*.parquet``) for the time to exceed 10 m of horizontal error within each
outage (per outage run: the first epoch above 10 m, time since the last epoch with GNSS;
"never" when the run ends below it). Prints one Markdown table: median [5-95 %] over outages;
``--write-docs`` also writes it to ``docs/data/outage_<ROUTE>.md`` (the Validation page).
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
import pandas as pd

from imugen.figures.outage import OUTAGE_COLUMNS, outage_curves
from imugen.tables import aided as taided

LIMIT_M = 10.0


def _fmt(m, lo, hi) -> str:
    def one(x):
        return "never" if not np.isfinite(x) else f"{x:.3g}"

    return f"{one(m)} [{one(lo)}-{one(hi)}]"


def time_to_limit(results: Path, route: str, grade: str) -> dict[float, np.ndarray]:
    """Per outage duration (s, rounded): the time to exceed 10 m of every run (inf: never)."""
    paths = sorted((results / route / "aided" / grade).glob("shard-*.parquet"))
    df = pd.concat([taided.read(p, columns=OUTAGE_COLUMNS) for p in paths], ignore_index=True)
    step = 1.0 / float(taided.read_meta(paths[0]).get("eval_rate_hz", 1.0))
    time, err = outage_curves(df, step)
    out: dict[float, list] = {}
    for row in err:
        n = int(np.flatnonzero(np.isfinite(row))[-1])
        over = np.flatnonzero(row > LIMIT_M)
        out.setdefault(float(np.round(time[n])), []).append(time[over[0]] if len(over) else np.inf)
    return {d: np.array(v) for d, v in out.items()}


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("results", type=Path)
    ap.add_argument("route")
    ap.add_argument("--grades", nargs="+", default=["consumer", "industrial", "tactical"])
    ap.add_argument("--durations", nargs="+", type=float, default=[30, 60, 120, 180])
    ap.add_argument("--write-docs", action="store_true", help="write docs/data/outage_ROUTE.md")
    a = ap.parse_args(argv)
    lines = []
    rmse = pd.read_csv(a.results / a.route / "rmse.csv").set_index("grade")
    head = ["grade", "sequences"]
    for d in a.durations:
        head += [f"{d:g} s: aided end", "free inertial", "aided > 10 m after"]
    lines.append("| " + " | ".join(head) + " |")
    lines.append("|" + "---|" * len(head))
    for g in a.grades:
        r = rmse.loc[g]
        ttl = time_to_limit(a.results, a.route, g)
        cells = [g, str(int(r["sequences"]))]
        for d in a.durations:
            s = f"outage_{d:g}s_end"
            cells.append(_fmt(r[f"{s}_m"], r[f"{s}_p05_m"], r[f"{s}_p95_m"]))
            f = f"drift_{d:g}s"
            cells.append(_fmt(r[f"{f}_m"], r[f"{f}_p05_m"], r[f"{f}_p95_m"]))
            # the run lasts D s after the outage start, one evaluation step more since the fix
            v = next((v for k, v in ttl.items() if abs(k - d) <= 1.0), np.array([]))
            if len(v):
                q = np.percentile(v, [50, 5, 95], method="inverted_cdf")
                cells.append(_fmt(*q) + f" ({len(v)})")
            else:
                cells.append("-")
        lines.append("| " + " | ".join(cells) + " |")
    print("\n".join(lines))
    if a.write_docs:
        import docs_data

        docs_data.write(f"outage_{a.route}", "\n".join(lines))


if __name__ == "__main__":
    main()
