"""Where each sensor preset sits against real parts: Allan deviation of every preset (closed
form, nominal figures, at 100 Hz) over the measured curves of the shared ADIS16405 recordings.

Reads ``../shared/data/imu/adis16405_static/*.parquet`` (three still units, 2.78 h at 100 Hz:
see that folder's README), computes the overlapping Allan deviation of each of their 9 gyro
and 9 accelerometer axes (mean removed), and draws, per sensor, the band of the measured axes
and each preset's expected Allan deviation from its grade (white noise through the preset's
output bandwidth, quantization, bias instability -- flicker or Gauss-Markov with its start --,
rate random walk, a ``slow_bias``: :class:`imugen.sensors.noise_terms.AxisModel`, the same closed forms the
fit uses) over a record of the same length. Writes ``docs/figures/presets_vs_real.png`` and
prints a table (gyro ADEV at 0.01 s and 1 s, minimum and where; the same for the
accelerometer) with the machine's load and the CPU seconds beside the wall time.

Usage::

    python benchmarks/presets_vs_real.py [--shared ../shared] [-o docs/figures/presets_vs_real.png]
"""

from __future__ import annotations

import argparse
import math
import os
import time
from pathlib import Path

import numpy as np
import pandas as pd

from imugen.core import units
from imugen.sensors import fit as F
from imugen.sensors.grades import presets
from imugen.sensors.noise_terms import AxisModel

RATE = 100.0
SHOWN = ("consumer", "industrial", "tactical", "adis16405", "phone", "paper_low_cost")
UNIT = {"gyro": ("deg_per_h", "deg/h"), "accel": ("ug", "ug")}


def preset_model(spec, rate_hz: float) -> AxisModel:
    """The nominal noise model of one axis (x) of a preset's sensor."""

    def v(p):
        return 0.0 if p is None else float(p.value[0])

    filt = None
    if spec.bandwidth is not None:
        filt = spec.bandwidth.output_filter(spec.sensor, rate_hz)
    kw = {}
    bi = spec.bias_instability
    if bi is not None:
        floor = bi.allan_floor_from_level(float(bi.level.value[0]))
        if bi.model == "flicker":
            kw = dict(bi_model="flicker", bi_floor=floor, bi_band=bi.flicker_band,
                      bi_components=bi.components, bi_start=bi.start)  # fmt: skip
        else:
            kw = dict(bi_model="gauss_markov", bi_floor=floor,
                      bi_T=float(bi.correlation_time.value[0]), bi_start=bi.start)  # fmt: skip
    sb = spec.slow_bias  # the second, slow Gauss-Markov (the measured preset's)
    if sb is not None:
        kw.update(slow_peak=sb.allan_floor_from_level(float(sb.level.value[0])),
                  slow_T=float(sb.correlation_time.value[0]))  # fmt: skip
    return AxisModel(
        rate_hz=rate_hz,
        white=v(spec.white_noise),
        filt=filt,
        lsb=v(spec.quantization),
        quant_mode=spec.quantization_mode,
        rrw=v(spec.rate_random_walk),
        **kw,
    )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    repo = Path(__file__).resolve().parents[1]
    ap.add_argument("--shared", default=str(repo.parent / "shared"))
    ap.add_argument(
        "-o", "--output", default=str(repo / "docs" / "figures" / "presets_vs_real.png")
    )
    a = ap.parse_args()
    t0, c0 = time.perf_counter(), time.process_time()
    files = sorted((Path(a.shared) / "data" / "imu" / "adis16405_static").glob("*.parquet"))
    if not files:
        raise SystemExit(f"no ADIS16405 recordings under {a.shared}/data/imu/adis16405_static")
    meas = {"gyro": [], "accel": []}
    K = None
    for f in files:
        df = pd.read_parquet(f)
        K = len(df) if K is None else min(K, len(df))
    mo = F.octaves(K, 0.25)
    tau = mo / RATE
    for f in files:
        df = pd.read_parquet(f).iloc[:K]
        for i, s in enumerate(("gyro", "accel")):
            for j in range(3):
                y = df.iloc[:, 3 * i + j].to_numpy(np.float64)
                meas[s].append(np.sqrt(F.oavar(y, mo)))
    P = presets()
    curves = {s: {n: np.sqrt(preset_model(P[n].sensor(s), RATE).avar(mo, K)) for n in SHOWN}
              for s in meas}  # fmt: skip

    from imugen.core.plotting import figure, save, style

    out = Path(a.output)
    out.parent.mkdir(parents=True, exist_ok=True)
    with style():
        fig = figure(figsize=(11, 4.8), layout="constrained")
        axes = fig.subplots(1, 2)
        for ax, s in zip(axes, ("gyro", "accel"), strict=True):
            u, label = UNIT[s]
            fu = units.unit(u).factor
            M = np.array(meas[s]) / fu
            ax.fill_between(tau, M.min(0), M.max(0), color="0.75", lw=0,
                            label="ADIS16405, 3 units x 3 axes (measured)")  # fmt: skip
            ax.loglog(tau, np.median(M, 0), color="0.35", lw=1.5, label="measured median")
            for n in SHOWN:
                ax.loglog(tau, curves[s][n] / fu, lw=1.2, label=n)
            ax.set_xlabel("averaging time tau [s]")
            ax.set_ylabel(f"Allan deviation [{label}]")
            ax.set_title(f"{s}: presets (nominal, {RATE:g} Hz) vs a real part")
            ax.grid(True, which="both", alpha=0.3)
            ax.legend(fontsize=7)
        path = save(fig, out.with_suffix(""), (out.suffix.lstrip(".") or "png",), 150)[0]
    # the table
    i1 = int(np.argmin(np.abs(tau - 1.0)))
    print(f"{'':18s} gyro [deg/h]                    accel [ug]")
    print(f"{'':18s} {'0.01 s':>8s} {'1 s':>8s} {'min':>8s} {'at s':>7s}   "
          f"{'0.01 s':>8s} {'1 s':>8s} {'min':>8s} {'at s':>7s}")  # fmt: skip

    def row(name, g, ac):
        cells = []
        for c in (g, ac):
            k = int(np.argmin(c))
            cells.append(f"{c[0]:8.3g} {c[i1]:8.3g} {c[k]:8.3g} {tau[k]:7.3g}")
        print(f"{name:18s} " + "   ".join(cells))

    fg, fa = units.unit("deg_per_h").factor, units.unit("ug").factor
    row("ADIS16405 median", np.median(meas["gyro"], 0) / fg, np.median(meas["accel"], 0) / fa)
    for n in SHOWN:
        row(n, curves["gyro"][n] / fg, curves["accel"][n] / fa)
    for s in ("gyro", "accel"):
        r = curves[s]["adis16405"] / np.median(meas[s], 0)
        print(f"adis16405 / measured median, {s}: " + " ".join(
            f"{t:g}s {x:.2f}" for t, x in zip(tau, r, strict=True)))  # fmt: skip
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else math.nan
    print(f"wrote {path}; wall {time.perf_counter() - t0:.1f} s, CPU "
          f"{time.process_time() - c0:.1f} s, load average {load:.2f}, {os.cpu_count()} CPUs")  # fmt: skip


if __name__ == "__main__":
    main()
