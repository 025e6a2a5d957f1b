"""Speed against accuracy: three ways to make and integrate an ideal IMU, at 1-1000 Hz.

Scene: the paper's reference trajectory (shared/data/trajectories/seed_reference_trajectory_enu.txt,
1 s per row, 620 s), ingested with origin 31.63,-7.99,480.6, car, flat Earth. The continuous
truth is imugen's smoothing spline; every method starts from it and is scored against it at the
IMU samples t_k (position: 3-D distance; attitude: rotation angle between true and computed
attitude). Each method's IMU data is integrated by the integrator its data type calls for.

1. forward differences + Euler angles (the paper's way, ``paper_method.py``): positions of the
   smooth truth sampled at R; v_k, a_k forward differences; attitude from v_k; gyro from
   Euler-angle forward differences; f_b = C_bn (a_k - g_n). Its samples are declared at t_k, so
   (1b) they go through the standard rate-sample integrator of method 2 (primary score). For
   reference (1a) they also go through their own forward-Euler dual, which closes by
   construction whatever the signals are (not a fidelity measure). Signal fidelity: RMS error
   of f_b and omega_ib_b against the true instantaneous IMU at t_k.
2. spline + sampled rates + standard integrator: the true instantaneous gyro/accelerometer
   samples at t_k through ``imugen.navigate.mechanize.mechanize_rates`` (trapezoid + coning + sculling).
3. spline + exact increments (imugen's default): the truth's dtheta/dv through
   ``imugen.navigate.mechanize.mechanize``.

Wall time = synthesis (from the ingested ENU table to IMU data) + mechanization, one sequence,
median of repeats, numba compilation excluded by a warm-up. Method 1's synthesis is the spline
fit + positions at R + differences; methods 2 and 3 share ``imugen.truth.build_truth`` (which
produces rates and increments together). For context, method 3 is also timed on a batch.

Usage::

    python benchmarks/bench_accuracy.py [--rates 1 10 100 1000] [--batch 100] [--out DIR]

Writes accuracy.csv, accuracy.md, accuracy.json, accuracy.png, accuracy.svg into DIR
(default benchmarks/results/, git-ignored) and prints the Markdown table.
"""

from __future__ import annotations

import os

for _v in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "NUMBA_NUM_THREADS"):
    os.environ.setdefault(_v, "1")

import argparse  # noqa: E402
import json  # noqa: E402
import platform  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402

from imugen import truth as tr  # noqa: E402
from imugen.core import earth as ea  # noqa: E402
from imugen.core import rotations as rot  # noqa: E402
from imugen.ingest.stage import ingest  # noqa: E402
from imugen.navigate import mechanize as M  # noqa: E402
from imugen.tables import truth as col  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))
import paper_method as pm  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
PAPER = ROOT.parent / "shared" / "data" / "trajectories" / "seed_reference_trajectory_enu.txt"
ORIGIN = "31.63,-7.99,480.6"

METHODS = {
    "1a": "forward diff. + Euler, own forward-Euler dual (closes by construction)",
    "1b": "forward diff. + Euler samples -> standard integrator",
    "2": "spline + sampled rates + standard integrator",
    "3": "spline + exact increments (default)",
}
PRIMARY = ("1b", "2", "3")  # the Pareto front is taken over these (see module docstring)


def timed(fn, repeats):
    """(median wall time [s], last result) of ``repeats`` calls."""
    t, out = timed_many({"f": fn}, repeats)
    return t["f"], out["f"]


def timed_many(fns, repeats):
    """Median wall times and last results of several callables, interleaved repeat by repeat
    (so load from other processes on the machine spreads evenly over them)."""
    ts = {k: [] for k in fns}
    out = {}
    for _ in range(repeats):
        for k, fn in fns.items():
            t0 = time.perf_counter()
            out[k] = fn()
            ts[k].append(time.perf_counter() - t0)
    return {k: float(np.median(v)) for k, v in ts.items()}, out


def att_err(q_est, q_true):
    """Rotation angle [rad] between quaternions (..., 4)."""
    d = rot.quat_mul(rot.quat_conj(q_est), q_true)
    return 2.0 * np.arctan2(np.linalg.norm(d[..., 1:], axis=-1), np.abs(d[..., 0]))


def scores(p, q, P, Q):
    """Final and max 3-D position error [m], max attitude error [rad] over the common samples."""
    n = len(p)
    e = np.linalg.norm(p - P[:n], axis=1)
    return float(e[-1]), float(e.max()), float(att_err(q, Q[:n]).max())


def rms_norm(x):
    return float(np.sqrt(np.mean(np.sum(x * x, axis=1))))


def warm_up(frame):
    z = np.zeros((3, 3))
    M.mechanize(z, z, 0.01, np.zeros(3), np.zeros(3), [1.0, 0, 0, 0], frame)
    pm.mechanize(z, z, 0.01, 9.8, np.zeros(3), np.zeros(3), np.zeros(3))


def run_rate(ing, R, repeats):
    dt = 1.0 / R
    rows = []
    vp = tr.VEHICLES["car"]
    tt = ing.table[col.TIME].to_numpy()
    K = int(np.floor((tt[-1] - tt[0]) * R + 1e-9)) + 1  # as build_truth (checked below)

    def synth23():  # methods 2 and 3: imugen truth (rates and increments together)
        return tr.build_truth(
            ing.table, ing.meta, rate_hz=R, earth="flat", vehicle="car", verbose=False
        )

    def synth1():  # method 1: the same spline's positions at R, then forward differences
        motion, _, _ = tr.build_motion(ing.table, ing.meta, vp, tr.BuildOptions())
        p = motion.position(motion.t0 + np.arange(K) * dt)
        return p, pm.synthesize(p, dt, g0)

    o = ing.meta["origin"]
    frame = ea.OriginFrame.from_deg(o["lat_deg"], o["lon_deg"], o["alt_m"], model="flat")
    g0 = frame.g0
    timed_many({"23": synth23, "1": synth1}, 1)  # warm-up (first calls, page faults)
    t_s, res = timed_many({"23": synth23, "1": synth1}, repeats)
    t_syn, t_syn1 = t_s["23"], t_s["1"]
    df, meta = res["23"]
    p1, imu = res["1"]
    if len(df) != K:
        raise RuntimeError(f"expected {K} samples at {R} Hz, truth has {len(df)}")
    P = df[list(col.POS)].to_numpy()
    V = df[list(col.VEL)].to_numpy()
    Q = df[list(col.QUAT)].to_numpy()
    W = df[list(col.GYRO)].to_numpy()
    F = df[list(col.ACCEL)].to_numpy()
    DTH = np.ascontiguousarray(df[list(col.DTHETA)].to_numpy()[1:])
    DV = np.ascontiguousarray(df[list(col.DV)].to_numpy()[1:])
    warm_up(frame)

    dev = float(np.max(np.abs(p1 - P)))
    if dev > 1e-6:
        raise RuntimeError(f"method 1 positions differ from the truth table by {dev:.3g} m")
    t_m, nav = timed_many(
        {
            "3": lambda: M.mechanize(DTH, DV, dt, P[0], V[0], Q[0], frame),
            "2": lambda: M.mechanize_rates(W, F, dt, P[0], V[0], Q[0], frame),
            # 1a: own forward-Euler dual, initial state = its own first samples (as the paper)
            "1a": lambda: pm.mechanize(
                imu.gyro_b, imu.accel_b, dt, g0, p1[0], imu.v_n[0], imu.euler[0]
            ),
            # 1b: samples declared at t_k -> standard integrator, true initial state (as 2 and 3)
            "1b": lambda: M.mechanize_rates(imu.gyro_b, imu.accel_b, dt, P[0], V[0], Q[0], frame),
        },
        repeats,
    )
    rows.append(("3", R, K, t_syn, t_m["3"], *scores(nav["3"].p_n, nav["3"].q_nb, P, Q), 0, 0))
    rows.append(("2", R, K, t_syn, t_m["2"], *scores(nav["2"].p_n, nav["2"].q_nb, P, Q), 0, 0))
    # method 1: signal fidelity against the true instantaneous IMU at t_k
    f_rms = rms_norm(imu.accel_b - F[: K - 2])
    w_rms = rms_norm(imu.gyro_b - W[: K - 2])
    Pa, _, Ea = nav["1a"]
    qa = rot.dcm_to_quat(pm.dcm_from_euler(Ea))
    self_att = float(np.max(np.abs(Ea - imu.euler)))
    rows.append(("1a", R, K, t_syn1, t_m["1a"], *scores(Pa, qa, P, Q), f_rms, w_rms))
    rows.append(
        ("1b", R, K, t_syn1, t_m["1b"], *scores(nav["1b"].p_n, nav["1b"].q_nb, P, Q), f_rms, w_rms)
    )
    extra = {"self_closure_max_euler_err_rad": self_att, "truth_build_s": t_syn, "fit": meta["fit"]}
    return rows, extra, (DTH, DV, P, V, Q, frame, dt, t_syn, K)


def run_batch(ctx, S, repeats):
    """Method 3 on S identical sequences: mechanization time per sample-sequence."""
    DTH, DV, P, V, Q, frame, dt, t_syn, K = ctx
    dth = np.ascontiguousarray(np.broadcast_to(DTH, (S, *DTH.shape)))
    dvb = np.ascontiguousarray(np.broadcast_to(DV, (S, *DV.shape)))
    every = max(1, round(1.0 / dt))  # store positions at 1 Hz
    t, nav = timed(
        lambda: M.mechanize(dth, dvb, dt, P[0], V[0], Q[0], frame, every=every, outputs=("p",)),
        repeats,
    )
    err = float(np.max(np.linalg.norm(nav.p_end_n - P[-1], axis=1)))
    n = S * (K - 1)
    return {
        "rate_hz": round(1.0 / dt),
        "sequences": S,
        "samples": K,
        "mech_s": t,
        "mech_ns_per_sample_seq": 1e9 * t / n,
        "mech_msamples_per_s": n / t / 1e6,
        "with_shared_synthesis_ns_per_sample_seq": 1e9 * (t + t_syn) / n,
        "final_position_error_m_max_over_batch": err,
    }


def pareto(df):
    """Boolean Series: row not dominated (time and max position error) among PRIMARY rows."""
    on = pd.Series(False, index=df.index)
    prim = df[df.method.isin(PRIMARY)]
    for i, r in prim.iterrows():
        dom = (
            (prim.total_s <= r.total_s)
            & (prim.max_pos_err_m <= r.max_pos_err_m)
            & ((prim.total_s < r.total_s) | (prim.max_pos_err_m < r.max_pos_err_m))
        )
        on[i] = not dom.any()
    return on


def markdown(df):
    head = (
        "| method | rate Hz | samples | synthesis s | mechanization s | total s "
        "| final pos. err m | max pos. err m | max att. err rad | f_b RMS err m/s² "
        "| ω RMS err rad/s | Pareto |"
    )
    lines = [head, "|" + "---|" * 12]

    def g(x):
        return f"{x:.2e}" if x != 0 else "0"

    for _, r in df.iterrows():
        fid = (
            (g(r.f_rms_err_mps2), g(r.w_rms_err_radps)) if r.method.startswith("1") else ("—", "—")
        )
        par = "yes" if r.pareto else ("n/a" if r.method == "1a" else "no")
        lines.append(
            f"| {r.method} {METHODS[r.method]} | {r.rate_hz:g} | {r.samples} | {r.synth_s:.4f} "
            f"| {r.mech_s:.4f} | {r.total_s:.4f} | {g(r.final_pos_err_m)} | {g(r.max_pos_err_m)} "
            f"| {g(r.max_att_err_rad)} | {fid[0]} | {fid[1]} | {par} |"
        )
    return "\n".join(lines)


def chart(df, out):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    style = {
        "1a": ("#999999", "o", "none"),
        "1b": ("#d62728", "o", None),
        "2": ("#1f77b4", "s", None),
        "3": ("#2ca02c", "D", None),
    }
    fig, ax = plt.subplots(figsize=(8.5, 7.0))
    floor = 1e-16
    for m in ("1a", "1b", "2", "3"):
        d = df[df.method == m].sort_values("rate_hz")
        c, mk, fc = style[m]
        y = np.maximum(d.max_pos_err_m.to_numpy(), floor)
        ax.plot(d.total_s, y, "-", color=c, lw=0.8, alpha=0.5)
        ax.plot(
            d.total_s,
            y,
            mk,
            color=c,
            mfc=fc if fc else c,
            ms=7,
            label=f"{m}: {METHODS[m]}" + (" — not a fidelity measure" if m == "1a" else ""),
        )
        for x, yy, r in zip(d.total_s, y, d.rate_hz, strict=True):
            ax.annotate(
                f"{r:g} Hz", (x, yy), textcoords="offset points", xytext=(5, 4), fontsize=8, color=c
            )
    front = df[df.pareto].sort_values("total_s")
    ax.step(
        front.total_s,
        np.maximum(front.max_pos_err_m, floor),
        where="post",
        color="k",
        lw=1.0,
        ls="--",
        label="Pareto front (1b, 2, 3)",
    )
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("wall time, synthesis + mechanization, one sequence [s]")
    ax.set_ylabel("max 3-D position error vs continuous truth [m]")
    ax.set_title("Paper trajectory (620 s, car, flat Earth): closure error against wall time")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8, loc="upper center", bbox_to_anchor=(0.5, -0.11), ncol=1, frameon=False)
    fig.tight_layout()
    for ext in ("png", "svg"):
        fig.savefig(out / f"accuracy.{ext}", dpi=150)
    plt.close(fig)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rates", type=float, nargs="+", default=[1, 10, 100, 1000])
    ap.add_argument("--batch", type=int, default=100, help="sequences for the batched timing")
    ap.add_argument("--batch-rate", type=float, default=100.0)
    ap.add_argument(
        "--repeats",
        type=int,
        default=7,
        help="timing repeats (x3 at <= 10 Hz, at most 3 at >= 1 kHz)",
    )
    ap.add_argument("--out", type=Path, default=ROOT / "benchmarks" / "results")
    ap.add_argument(
        "--write-docs", action="store_true", help="also write docs/data/bench_accuracy_full.md"
    )
    a = ap.parse_args(argv)
    if not PAPER.exists():
        sys.exit(f"paper trajectory not found: {PAPER}")
    a.out.mkdir(parents=True, exist_ok=True)
    t_start = time.perf_counter()
    ing = ingest(PAPER, origin=ORIGIN, dt=1.0)
    rows, extras, batch = [], {}, None
    for R in a.rates:
        # cheap rates get more repeats (their ~0.04 s timings are the most exposed to load)
        rep = 3 * a.repeats if R <= 10 else (a.repeats if R < 1000 else min(a.repeats, 3))
        r, ex, ctx = run_rate(ing, R, rep)
        rows += r
        extras[f"{R:g}"] = {k: v for k, v in ex.items() if k != "fit"}
        extras["fit"] = ex["fit"]
        if R == a.batch_rate and a.batch > 0:
            batch = run_batch(ctx, a.batch, 3)
        del ctx
        print(f"[{time.perf_counter() - t_start:6.1f} s] {R:g} Hz done", file=sys.stderr)
    df = pd.DataFrame(
        rows,
        columns=[
            "method",
            "rate_hz",
            "samples",
            "synth_s",
            "mech_s",
            "final_pos_err_m",
            "max_pos_err_m",
            "max_att_err_rad",
            "f_rms_err_mps2",
            "w_rms_err_radps",
        ],
    )
    df.insert(5, "total_s", df.synth_s + df.mech_s)
    order = {"1a": 0, "1b": 1, "2": 2, "3": 3}
    df = df.sort_values(
        ["method", "rate_hz"], key=lambda s: s.map(order) if s.name == "method" else s
    ).reset_index(drop=True)
    df["pareto"] = pareto(df)
    df.to_csv(a.out / "accuracy.csv", index=False)
    md = markdown(df)
    (a.out / "accuracy.md").write_text(md + "\n")
    if a.write_docs:
        import docs_data

        docs_data.write("bench_accuracy_full", md)
    chart(df, a.out)
    info = {
        "scene": str(PAPER.name),
        "origin": ORIGIN,
        "earth": "flat",
        "vehicle": "car",
        "python": platform.python_version(),
        "machine": platform.machine(),
        "cpu_count": os.cpu_count(),
        "per_rate": extras,
        "batch": batch,
        "default_on_pareto_front": {
            f"{r:g}": bool(df[(df.method == "3") & (df.rate_hz == r)].pareto.iloc[0])
            for r in a.rates
        },
        "runtime_s": time.perf_counter() - t_start,
    }
    (a.out / "accuracy.json").write_text(json.dumps(info, indent=1, default=float) + "\n")
    print(md)
    if batch:
        print(
            f"\nbatched method 3, {batch['sequences']} sequences at {batch['rate_hz']} Hz: "
            f"{batch['mech_ns_per_sample_seq']:.1f} ns per sample-sequence "
            f"({batch['mech_msamples_per_s']:.1f} M/s, one core); with the shared synthesis "
            f"{batch['with_shared_synthesis_ns_per_sample_seq']:.1f} ns"
        )
    for r in a.rates:
        print(
            f"method 1a self-closure at {r:g} Hz: max Euler-angle deviation "
            f"{extras[f'{r:g}']['self_closure_max_euler_err_rad']:.2e} rad"
        )
    print(
        "default (method 3) on the Pareto front at: "
        + ", ".join(
            f"{k} Hz: {'yes' if v else 'no'}" for k, v in info["default_on_pareto_front"].items()
        )
    )
    print(f"runtime {info['runtime_s']:.1f} s; outputs in {a.out}", file=sys.stderr)


if __name__ == "__main__":
    main()
