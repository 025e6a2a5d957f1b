"""Regenerate the ``adis16405`` preset's noise figures with ``imugen grade fit``'s own path.

Fits each of the three shared ADIS16405 units (``../shared/data/imu/adis16405_static``, 2.78 h
still at 100 Hz, internal rate 819.2 Hz) with :func:`imugen.sensors.fit.fit_grade` (flicker or
Gauss-Markov floor chosen by its width, the second slow Gauss-Markov ``slow_bias`` where it
lowers the weighted chi-square by > 5 %, rate random walk, quantization, output filter) and
prints, per sensor and figure, the median of the 9 axes (3 units x 3 axes) and their min..max,
with each unit's choice: the numbers the preset's ``[ADIS-fit]`` entries carry (figure = median,
range = min..max). Prints the machine's load and the CPU seconds beside the wall time.

Usage::

    python benchmarks/fit_adis16405_preset.py [--shared ../shared]
"""

from __future__ import annotations

import argparse
import os
import time
from pathlib import Path

import numpy as np
import pandas as pd

from imugen.sensors import fit as F


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    repo = Path(__file__).resolve().parents[1]
    ap.add_argument("--shared", default=str(repo.parent / "shared"))
    a = ap.parse_args()
    t0, c0 = time.perf_counter(), time.process_time()
    files = sorted((Path(a.shared) / "data" / "imu" / "adis16405_static").glob("*.parquet"))
    if not files:
        raise SystemExit(f"no ADIS16405 recordings under {a.shared}/data/imu")
    rows = {"gyro": [], "accel": []}
    for f in files:
        X = pd.read_parquet(f).to_numpy(np.float64)
        r = F.fit_grade({"gyro": X[:, :3], "accel": X[:, 3:]}, 100.0, internal_rate_hz=819.2,
                        source=f.name)  # fmt: skip
        for s, sf in r["sensors"].items():
            u = F.SENSOR_UNITS[s]
            print(f"{f.name} {s}: {sf.choice}")
            for am in sf.models:
                rows[s].append({
                    "white_noise": am.white / F.UNITS[u["white_noise"]],
                    "bias_instability": am.bi_floor / F.UNITS[u["bias_instability"]],
                    "bi_model": sf.bi_kind,
                    "bi_band_or_T": sf.bi_par,
                    "slow_bias": am.slow_peak / F.UNITS[u["bias_instability"]],
                    "slow_T": sf.slow_T or 0.0,
                    "rate_random_walk": am.rrw,
                })  # fmt: skip
    for s, rs in rows.items():
        u = F.SENSOR_UNITS[s]
        print(f"\n{s} (9 axes: median, min..max)")
        for k in ("white_noise", "bias_instability", "slow_bias", "slow_T", "rate_random_walk"):
            v = np.array([r[k] for r in rs], float)
            if k == "rate_random_walk":
                v = v / (F.UNITS[u["bias_instability"]] if s == "gyro" else 9.80665e-6)
                v = v * (60.0 if s == "gyro" else 1.0)
                unit = "deg_per_h_per_sqrt_h" if s == "gyro" else "ug_per_sqrt_s"
            else:
                unit = "s" if k == "slow_T" else u.get(k, u["bias_instability"])
            print(f"  {k:18s} {np.median(v):10.4g}  {v.min():10.4g} .. {v.max():10.4g} {unit}")
        print("  bias models:", sorted({(r["bi_model"], str(np.round(r["bi_band_or_T"], 3)))
                                         for r in rs}))  # fmt: skip
    print(f"\nwall {time.perf_counter() - t0:.1f} s, CPU {time.process_time() - c0:.1f} s, "
          f"load {os.getloadavg()[0]:.2f} ({os.cpu_count()} CPUs)")  # fmt: skip


if __name__ == "__main__":
    main()
