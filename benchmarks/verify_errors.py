"""Verification of the sensor error model with plots (full-length versions of the unit tests).

1. Allan deviation of static shards (allantools) at 10, 100 and 1000 Hz for a test grade whose
   white noise, flicker floor and rate random walk each dominate a decade, and for every
   shipped preset (nominal levels): configured vs measured, plots ``allan_*.png``.
2. Error growth, each source alone, 1,000 sequences on a still level IMU (flat Earth),
   mechanized with :mod:`imugen.navigate.mechanize`: RMS position error against the closed forms
   (accel bias b t^2/2, gyro bias g w t^3/6, VRW N sqrt(t^3/3), ARW g N sqrt(t^5/20)) over time,
   plot ``growth.png``.

Writes ``verify_errors.json`` with every number into the output folder.

Usage: python benchmarks/verify_errors.py OUT_DIR [--quick]
"""

from __future__ import annotations

import argparse
import json
import math
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from imugen.allan import stage as allan
from imugen.allan.options import AllanOptions
from imugen.core.earth import OriginFrame
from imugen.navigate.mechanize import mechanize
from imugen.sensors.grades import grade_from_config, presets
from imugen.simulate import stage as S
from imugen.simulate.options import SimulateOptions
from imugen.simulate.sources import DEFAULT_STATIC_ORIGIN
from imugen.tables import shard as tshard

TEST_GRADE = {
    "id": 9001,
    "gyro": {
        "white_noise": {"value": 0.0118, "unit": "deg_per_sqrt_h"},
        "bias_instability": {
            "value": 1.0,
            "unit": "deg_per_h",
            "kind": "allan_floor",
            "model": "flicker",
            "flicker_band": {"min": 0.1, "max": 10, "unit": "s"},
        },
        "rate_random_walk": {"value": 36.7, "unit": "deg_per_h_per_sqrt_h"},
    },
    "accel": {
        "white_noise": {"value": 0.01, "unit": "m_per_s_per_sqrt_h"},
        "bias_instability": {
            "value": 20,
            "unit": "ug",
            "kind": "allan_floor",
            "correlation_time": {"value": 3.0, "unit": "s"},
        },
        "rate_random_walk": {"value": 100, "unit": "ug_per_sqrt_h"},
    },
}


def allan_part(out: Path, quick: bool) -> dict:
    res = {}
    g = grade_from_config("allan_test", TEST_GRADE)
    dur = 900.0 if quick else 3600.0
    for rate in (10.0, 100.0, 1000.0):
        sh = S.simulate(None, g, sequences=8, seed=1, static_s=dur, rate_hz=rate, draw="nominal")
        cv = allan.allan_curves(sh, max_sequences=8)
        rep = allan.allan_report(sh, curves=cv)
        allan.plot_allan(cv, out / f"allan_test_{int(rate)}hz.png", rep)
        res[f"test_grade_{int(rate)}hz"] = rep
        print(f"test grade {rate:g} Hz:", {k: round(v["ratio"], 3) for k, v in rep.items()})
    for name in presets():
        p = out / f"static_{name}.parquet"
        opts = SimulateOptions(
            grade=name, sequences=8, seed=1, shard=0, static_s=1800.0 if quick else 7200.0,
            rate_hz=100.0, draw="nominal",
        )  # fmt: skip
        S.run(None, p, opts)
        rep = allan.run(p, out / f"allan_{name}.png", AllanOptions(max_sequences=8))
        res[name] = rep
        p.unlink()
        tshard.labels_path(p).unlink()
        print(f"{name}:", {k: round(v["ratio"], 3) for k, v in rep.items()})
    return res


def growth_part(out: Path, quick: bool) -> dict:
    rate, T = 20.0, 120.0
    dt = 1.0 / rate
    frame = OriginFrame.from_deg(*DEFAULT_STATIC_ORIGIN, model="flat")
    g0 = frame.g0
    cases = {
        "accel_bias": (
            {"accel": {"turn_on_bias": {"value": 1, "unit": "mg", "kind": "one_sigma"}}},
            lambda sh, t: math.sqrt(np.mean(sh.accel.b_on**2)) * t**2 / 2,
            (0, 1, 2),
        ),
        "gyro_bias": (
            {"gyro": {"turn_on_bias": {"value": 10, "unit": "deg_per_h", "kind": "one_sigma"}}},
            lambda sh, t: g0 * math.sqrt(np.mean(sh.gyro.b_on[:, :2] ** 2)) * t**3 / 6,
            (0, 1),
        ),
        "vrw": (
            {"accel": {"white_noise": {"value": 0.5, "unit": "m_per_s_per_sqrt_h"}}},
            lambda sh, t: 0.5 / 60 * np.sqrt(t**3 / 3),
            (0, 1, 2),
        ),
        "arw": (
            {"gyro": {"white_noise": {"value": 1.0, "unit": "deg_per_sqrt_h"}}},
            lambda sh, t: g0 * math.pi / 180 / 60 * np.sqrt(t**5 / 20),
            (0, 1),
        ),
    }
    res = {}
    fig, axes = plt.subplots(1, 4, figsize=(16, 4))
    for ax, (name, (cfg, closed, axes_used)) in zip(axes, cases.items(), strict=True):
        grd = grade_from_config(name, {"id": 7000, **cfg})
        M = 1000 if quick else 4000
        sh = S.simulate(None, grd, sequences=M, seed=1, static_s=T, rate_hz=rate)
        nav = mechanize(
            sh.data["dtheta"][:, 1:],
            sh.data["dv"][:, 1:],
            dt,
            np.zeros(3),
            np.zeros(3),
            np.array([1.0, 0, 0, 0]),
            frame,
            every=int(rate),
            outputs=("p",),
        )
        t = nav.index * dt
        p = nav.p_n[:, :, list(axes_used)]
        rms = np.sqrt(np.mean(p**2, axis=(0, 2)))
        pred = np.array([closed(sh, tt) for tt in t])
        ratio = rms[1:] / pred[1:]
        res[name] = {
            "sequences": M,
            "ratio_at_T": float(ratio[-1]),
            "ratio_min": float(ratio.min()),
            "ratio_max": float(ratio.max()),
        }
        print(
            f"growth {name}: ratio at T {ratio[-1]:.4f} (range {ratio.min():.4f}..{ratio.max():.4f})"
        )
        ax.loglog(t[1:], rms[1:], "k.", label=f"mechanized RMS ({M} seq.)")
        ax.loglog(t[1:], pred[1:], "r-", label="closed form")
        ax.set_title(name)
        ax.set_xlabel("t [s]")
        ax.set_ylabel("position error RMS [m]")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(out / "growth.png", dpi=110)
    plt.close(fig)
    return res


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("out_dir")
    ap.add_argument("--quick", action="store_true", help="shorter runs")
    a = ap.parse_args()
    out = Path(a.out_dir)
    out.mkdir(parents=True, exist_ok=True)
    res = {"allan": allan_part(out, a.quick), "growth": growth_part(out, a.quick)}
    (out / "verify_errors.json").write_text(json.dumps(res, indent=1))
    print(f"wrote {out}/verify_errors.json and plots")


if __name__ == "__main__":
    main()
