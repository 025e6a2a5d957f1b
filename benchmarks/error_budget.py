"""Which sensor error terms drive navigation drift, per grade (run on demand, not a test).

Scene: the paper's reference trajectory (``resources/paper/seed_reference_trajectory_enu.txt``,
620 s, 1 s per row) -> truth at ``--rate-hz`` (default 100 Hz, Earth model ``auto``). For each
grade, ``--sequences`` sequences are simulated with every configured term, then with each term
alone (the same draws: a term's realization does not depend on the others), then with the
effective error alone (every term but white noise and quantization) and with white noise and
quantization alone; each set is navigated in memory (:func:`imugen.navigate_arrays`) and the
median over sequences of the RMSE of the 3-D position error (1 Hz epochs) and of the final
horizontal error is reported, in metres.

Usage: python benchmarks/error_budget.py [--grades consumer industrial tactical navigation]
       [--sequences 16] [--rate-hz 100] [--seed 1] [--json out.json]
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np

from imugen import navigate_arrays
from imugen import truth as T
from imugen.ingest.stage import ingest
from imugen.sensors.grades import get_grade
from imugen.simulate import stage as S
from imugen.tables import truth as ttruth

PAPER = (
    Path(__file__).resolve().parents[1]
    / "resources"
    / "paper"
    / "seed_reference_trajectory_enu.txt"
)
ORIGIN = "31.63,-7.99,480.6"
NOISE = ("white_noise", "quantization")


def paper_truth(rate_hz: float) -> ttruth.Truth:
    ing = ingest(PAPER, origin=ORIGIN, dt=1.0)
    df, meta = T.build_truth(ing.table, ing.meta, rate_hz=rate_hz, earth="auto", verbose=False)
    return ttruth.Truth(df, meta)


def drift(tr, grade, terms, M, seed) -> tuple[float, float]:
    """Median RMSE (3-D) and median final horizontal error (m) of M sequences."""
    sh = S.simulate(tr.frame, grade, sequences=M, seed=seed, terms=terms, route="paper")
    err = navigate_arrays(tr, sh)
    e = err[["err_e_m", "err_n_m", "err_u_m"]].to_numpy().reshape(M, -1, 3)
    rmse = np.sqrt((e**2).sum(-1).mean(-1))
    final = np.hypot(e[:, -1, 0], e[:, -1, 1])
    return float(np.median(rmse)), float(np.median(final))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument(
        "--grades", nargs="+", default=["consumer", "industrial", "tactical", "navigation"]
    )
    ap.add_argument("--sequences", type=int, default=16)
    ap.add_argument("--rate-hz", type=float, default=100.0)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--json", default=None)
    a = ap.parse_args()
    t0 = time.perf_counter()
    tr = paper_truth(a.rate_hz)
    out = {"rate_hz": a.rate_hz, "sequences": a.sequences, "earth": tr.meta["earth"], "grades": {}}
    for g in a.grades:
        configured = sorted(
            set(get_grade(g).gyro.configured()) | set(get_grade(g).accel.configured())
        )
        rows = {"all": drift(tr, g, None, a.sequences, a.seed)}
        rows["effective error (all but white noise, quantization)"] = drift(
            tr, g, [t for t in configured if t not in NOISE], a.sequences, a.seed
        )
        rows["white noise + quantization"] = drift(
            tr, g, [t for t in configured if t in NOISE], a.sequences, a.seed
        )
        for term in configured:
            rows[term] = drift(tr, g, [term], a.sequences, a.seed)
        out["grades"][g] = rows
        print(f"\n{g} (median over {a.sequences} sequences; RMSE 3-D m, final horizontal m)")
        for k, (r, f) in sorted(rows.items(), key=lambda kv: -kv[1][0]):
            print(f"  {k:55s} {r:12.4g} {f:12.4g}")
    out["seconds"] = time.perf_counter() - t0
    print(f"\n{out['seconds']:.0f} s")
    if a.json:
        Path(a.json).write_text(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()
