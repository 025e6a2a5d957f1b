"""The paper's Table 2 beside ours: its grades with our closed-loop strapdown and with its bug.

The paper's published MATLAB (see the project's review of it) never feeds the gyro-integrated
attitude back into the navigation: position is computed with the *true* attitude (bug B1), so
only accelerometer errors reach the position. This script draws the same Monte-Carlo sequences
of the paper's three grades (`paper_low_cost`, `paper_industrial`, `paper_tactical`: white noise
only, as its code does) on its reference trajectory and evaluates them twice:

* closed loop (imugen's mechanization, the physics a real INS obeys);
* open loop, "seed-compatible": velocity and position integrated with the true attitude, as the
  paper's code does; the position error is then driven by the accelerometer errors alone.

RMSE per axis over 1 Hz epochs from the first one, Total = sqrt(E^2 + N^2 + U^2) (the paper's
definition), as median [5th-95th percentile] over the sequences.

Usage: python benchmarks/paper_table2.py [--sequences 300] [--rate-hz 10] [--out DIR]
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np
import pandas as pd

from imugen.core.earth import OriginFrame
from imugen.core.rotations import quat_to_dcm
from imugen.evaluate.stage import sequence_metrics
from imugen.ingest.stage import ingest
from imugen.navigate.mechanize import mechanize
from imugen.simulate.stage import simulate
from imugen.tables import truth as col
from imugen.truth import build_truth

REPO = Path(__file__).resolve().parents[1]
PAPER = REPO / "resources" / "paper" / "seed_reference_trajectory_enu.txt"
TABLE2 = {  # the paper's Table 2, metres: East, North, Up, Total
    "paper_low_cost": (9.22, 16.94, 26.75, 32.98),
    "paper_industrial": (0.58, 1.28, 8.88, 8.99),
    "paper_tactical": (0.01, 0.13, 1.06, 1.07),
}


def errors_table(err, t, every):
    """(S, K, 3) position errors -> long table at the evaluation epochs."""
    idx = np.arange(0, err.shape[1], every)
    S = err.shape[0]
    e = err[:, idx]
    return pd.DataFrame(
        {
            "sequence": np.repeat(np.arange(S), len(idx)),
            "time_s": np.tile(t[idx], S),
            "err_e_m": e[..., 0].ravel(),
            "err_n_m": e[..., 1].ravel(),
            "err_u_m": e[..., 2].ravel(),
        }
    )


def open_loop(truth, dv_meas, dt):
    """Position error of the paper's open attitude loop: true attitude, measured dv.

    With the true attitude, v_{k+1} - v_k = C_nb(t_k) dv_k + g dt exactly for the true dv, so
    the velocity error is the running sum of C_nb(t_k) (dv_meas - dv_true); position by the
    trapezoid rule.
    """
    C = quat_to_dcm(truth[list(col.QUAT)].to_numpy()[:-1])  # (K-1, 3, 3), interval starts
    ddv = dv_meas[:, 1:] - truth[list(col.DV)].to_numpy()[None, 1:]  # (S, K-1, 3)
    dv_n = np.einsum("kij,skj->ski", C, ddv)
    v_err = np.concatenate([np.zeros((dv_n.shape[0], 1, 3)), np.cumsum(dv_n, axis=1)], axis=1)
    steps = 0.5 * dt * (v_err[:, 1:] + v_err[:, :-1])
    return np.concatenate([np.zeros((dv_n.shape[0], 1, 3)), np.cumsum(steps, axis=1)], axis=1)


def fmt(values):
    p5, p50, p95 = np.percentile(values, [5, 50, 95])
    return f"{p50:.3g} [{p5:.3g}-{p95:.3g}]"


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sequences", type=int, default=300)
    ap.add_argument("--rate-hz", type=float, default=10.0)
    ap.add_argument("--seed", type=int, default=20251150)
    ap.add_argument("--out", type=Path, default=REPO / "benchmarks" / "results")
    a = ap.parse_args(argv)
    t0 = time.perf_counter()
    ing = ingest(PAPER, origin="31.63,-7.99,480.6", dt=1.0)
    truth, _ = build_truth(ing.table, ing.meta, rate_hz=a.rate_hz, earth="flat", verbose=False)
    frame = OriginFrame.from_deg(31.63, -7.99, 480.6, model="flat")
    t = truth[col.TIME].to_numpy()
    dt = 1.0 / a.rate_hz
    every = round(a.rate_hz)
    p_true = truth[list(col.POS)].to_numpy()
    rows = []
    for grade, paper in TABLE2.items():
        sh = simulate(truth, grade, sequences=a.sequences, seed=a.seed, shard=0)
        dth, dv = sh.data["dtheta"], sh.data["dv"]
        nav = mechanize(
            dth[:, 1:],
            dv[:, 1:],
            dt,
            p_true[0],
            truth[list(col.VEL)].to_numpy()[0],
            truth[list(col.QUAT)].to_numpy()[0],
            frame,
            outputs=("p",),
        )
        closed = sequence_metrics(errors_table(nav.p_n - p_true[None], t, every), 1.0)
        opened = sequence_metrics(errors_table(open_loop(truth, dv, dt), t, every), 1.0)
        for label, m in (("closed loop (imugen)", closed), ("open loop (paper's code)", opened)):
            rows.append(
                {
                    "grade": grade,
                    "mechanization": label,
                    "East": fmt(m.rmse_east_m),
                    "North": fmt(m.rmse_north_m),
                    "Up": fmt(m.rmse_up_m),
                    "Total": fmt(m.rmse_total_m),
                    "paper Table 2 (E/N/U/Total)": " / ".join(f"{x:g}" for x in paper),
                    "paper Total percentile": f"{(m.rmse_total_m < paper[3]).mean():.0%}"
                    if label.startswith("open")
                    else "",
                }
            )
    df = pd.DataFrame(rows)
    cols = list(df.columns)
    md = ["| " + " | ".join(cols) + " |", "|" + "---|" * len(cols)]
    md += ["| " + " | ".join(str(v) for v in r) + " |" for r in df.itertuples(index=False)]
    text = (
        f"RMSE (m), median [5-95 %] over {a.sequences} sequences, paper trajectory, "
        f"{a.rate_hz:g} Hz, flat Earth, 1 Hz epochs\n\n" + "\n".join(md) + "\n"
    )
    a.out.mkdir(parents=True, exist_ok=True)
    (a.out / "paper_table2.md").write_text(text)
    print(text)
    print(f"({time.perf_counter() - t0:.1f} s)")


if __name__ == "__main__":
    main()
