"""Strapdown mechanization throughput: numba kernel vs pure NumPy vs pyins, same data, same run.

Scene: the paper's reference trajectory (shared/data/trajectories/seed_reference_trajectory_enu.txt,
1 s per row) -> imugen truth at 100 Hz (61 900 increments) -> a batch of 1 000 sequences (the truth
increments plus a small per-sequence constant gyro/accelerometer bias, so no two are alike).

Measured, single thread (the numbers are per core):
* numba kernel (``imugen.navigate.mechanize``), sequences in chunks, positions only at every 100th sample
  (1 Hz) into one preallocated output, reused input buffers;
* the same recursion in pure NumPy (vectorized across the 1 000 sequences, Python loop over
  time) on the same batch (identical sequences as broadcast views: same arithmetic, no copies);
* pyins 1.0.1 (PyPI ``python-ins``, optional) ``Integrator.integrate`` and its numba core, one
  sequence at a time (pyins has no batch API), run in the interpreter given by
  ``--pyins-python`` (a separate virtualenv); skipped with a message when unavailable;
* compile time of the kernel in a fresh process with an empty numba cache, and the start-up
  time of a second process that loads the cached kernel;
* the ``geodetic`` kernel (ECEF navigation coordinates) on the same truth expressed in ECEF;
* zero-error closure of the kernel (every model) and of pyins (wgs84) on the same truth;
* rates per wall-clock second and per CPU second of the process (the machine is shared);
* peak resident memory.

Usage::

    python benchmarks/bench_mechanize.py [--scene FILE] [--sequences 1000] [--numpy-steps all]
        [--repeat 3] [--no-compile] [--pyins-python /work/pyinsvenv/bin/python] [--json out.json]
        [--rate-hz 100] [--every RATE]

``--rate-hz`` sets the IMU rate of the truth (the rotating kernels' cost depends on it through
the gravitation node block ``m = round(GRAVITY_NODE_S / dt)``); positions are stored at 1 Hz
unless ``--every`` says otherwise.

``--numpy-steps 0`` skips the NumPy rows; the kernel rates are the best of ``--repeat`` passes
(CPU seconds of the process, ``time.process_time``: the machine is shared), and the load
average is printed at the start, after each kernel and at the end.
"""

from __future__ import annotations

import os

for _v in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "NUMBA_NUM_THREADS"):
    os.environ.setdefault(_v, "1")

import argparse  # noqa: E402
import json  # noqa: E402
import resource  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import textwrap  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

from imugen.core import earth as E  # noqa: E402
from imugen.core import rotations as rot  # noqa: E402
from imugen.navigate import mechanize as M  # noqa: E402
from imugen.navigate._kernel import S_FB  # noqa: E402
from imugen.tables import truth as col  # noqa: E402

# the pure NumPy twin of the kernel is a test oracle (tests/oracles/strapdown.py)
sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
from oracles.strapdown import mechanize_numpy  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
PAPER = ROOT.parent / "shared" / "data" / "trajectories" / "seed_reference_trajectory_enu.txt"
ORIGIN = "31.6295,-7.9811,0"  # arbitrary (the paper's file has no origin); height 0 for pyins


def peak_rss_mb() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def compile_times() -> dict:
    """Kernel compile time (fresh cache) and cached start-up, each in a new process."""
    code = textwrap.dedent("""
        import json, time
        t0 = time.perf_counter()
        import numpy as np
        from imugen.core import earth as E
        from imugen.navigate import mechanize as M
        t1 = time.perf_counter()
        fr = E.OriginFrame.from_deg(31.6, -8.0, 0.0)
        z = np.zeros((3, 3))
        for model in ("flat", "wgs84"):
            M.mechanize(z, z, 0.01, np.zeros(3), np.zeros(3), [1, 0, 0, 0], fr.with_model(model))
        t2 = time.perf_counter()
        print(json.dumps({"import_s": t1 - t0, "first_call_s": t2 - t1}))
    """)
    out = {}
    with tempfile.TemporaryDirectory() as cache:
        env = dict(os.environ, NUMBA_CACHE_DIR=cache)
        for label in ("cold", "cached"):
            r = subprocess.run(
                [sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True
            )
            out[label] = json.loads(r.stdout.strip().splitlines()[-1])
    return out


def build_scene(scene: Path, rate_hz: float, model: str):
    """Truth table and frame; ``geodetic`` is the ``wgs84`` truth expressed in ECEF (the body
    increments are the same)."""
    from imugen import truth
    from imugen.ingest.stage import ingest

    ing = ingest(scene, dt=1.0, origin=ORIGIN)
    tm = "wgs84" if model == "geodetic" else model
    df, meta = truth.build_truth(ing.table, ing.meta, rate_hz=rate_hz, earth=tm, verbose=False)
    o = meta["origin"]
    frame = E.OriginFrame.from_deg(o["lat_deg"], o["lon_deg"], o["alt_m"], model=model)
    if model == "geodetic":
        n = frame.with_model("wgs84")
        C = n.C_en
        df = df.copy()
        df[list(col.POS)] = n.ecef_from_n(df[list(col.POS)].to_numpy())
        df[list(col.VEL)] = df[list(col.VEL)].to_numpy() @ C
        q_en = rot.dcm_to_quat(C.T)
        df[list(col.QUAT)] = rot.quat_mul(q_en[None, :], df[list(col.QUAT)].to_numpy())
    return df, frame


def run_numba(df, frame, S, chunk, every, rng, repeat=1):
    dth0 = df[list(col.DTHETA)].to_numpy()[1:]
    dv0 = df[list(col.DV)].to_numpy()[1:]
    P = df[list(col.POS)].to_numpy()
    V = df[list(col.VEL)].to_numpy()
    Q = df[list(col.QUAT)].to_numpy()
    dt = float(df[col.TIME].iloc[1] - df[col.TIME].iloc[0])
    cpu0 = time.process_time()
    N = len(dth0)
    M_out = N // every + 1
    out = np.zeros((S, M_out, 3))  # touched once, reused
    buf_t = np.zeros((chunk, N, 3))
    buf_v = np.zeros((chunk, N, 3))
    # per-sequence constant biases: gyro 10 deg/h, accel 50 ug (1 sigma); sequence 0 ideal
    bg = rng.normal(size=(S, 3)) * 10.0 * E.DEG_PER_H * dt
    ba = rng.normal(size=(S, 3)) * 50.0 * E.MICRO_G * dt
    bg[0] = 0.0
    ba[0] = 0.0
    # warm-up (loads the cached kernel)
    M.Mechanizer(frame, dt, P[0], V[0], Q[0], 1).run(dth0[None, :10], dv0[None, :10])
    passes = []  # (wall, CPU) of the kernel calls, one entry per pass over all S sequences
    t0 = time.perf_counter()
    q_end = None
    fallback = 0.0
    for _ in range(repeat):
        t_kernel = 0.0
        c_kernel = 0.0
        for a in range(0, S, chunk):
            b = min(S, a + chunk)
            n = b - a
            np.add(dth0, bg[a:b, None, :], out=buf_t[:n])
            np.add(dv0, ba[a:b, None, :], out=buf_v[:n])
            mech = M.Mechanizer(frame, dt, P[0], V[0], Q[0], n)
            out[a:b, 0] = P[0]
            t1 = time.perf_counter()
            c1 = time.process_time()
            mech.run(buf_t[:n], buf_v[:n], out_p=out[a:b], every=every)
            t_kernel += time.perf_counter() - t1
            c_kernel += time.process_time() - c1
            if a == 0:
                q_end = mech.q_nb[0]
            fallback += mech.state[:, S_FB].sum()
        passes.append((t_kernel, c_kernel))
    t_kernel = min(p[0] for p in passes)
    c_kernel = min(p[1] for p in passes)
    t_total = time.perf_counter() - t0
    cpu = time.process_time() - cpu0
    idx = np.arange(0, N + 1, every)
    err = np.linalg.norm(out[0] - P[idx], axis=1)
    dq = _quat_mul(_quat_conj(Q[-1]), q_end)
    return {
        "samples": N,
        "sequences": S,
        "kernel_s": t_kernel,
        "total_s": t_total,
        "msps_kernel": S * N / t_kernel / 1e6,
        "kernel_cpu_s": c_kernel,
        "msps_kernel_cpu": S * N / c_kernel / 1e6,
        "msps_total": S * N * repeat / t_total / 1e6,
        "passes": repeat,
        "passes_cpu_s": [p[1] for p in passes],
        "cpu_s": cpu,
        "load_avg_1min": os.getloadavg()[0],
        "closure_final_m": float(np.linalg.norm(out[0, -1] - P[N])) if N % every == 0 else None,
        "closure_max_1hz_m": float(err.max()),
        "closure_att_final_rad": float(2 * np.arcsin(min(1.0, np.linalg.norm(dq[1:])))),
        "spread_final_m": float(np.std(np.linalg.norm(out[:, -1] - P[idx[-1]], axis=1))),
        "peak_rss_mb": peak_rss_mb(),
        "gravity_node_blocks": int(M.kernel_params(frame, dt)[M.K_MB]),
        "blocks_exact_gravity_fraction": float(fallback / repeat / S)
        / max(1, N // int(M.kernel_params(frame, dt)[M.K_MB])),
    }


def run_numpy(df, frame, S, steps, every):
    dth0 = df[list(col.DTHETA)].to_numpy()[1:]
    dv0 = df[list(col.DV)].to_numpy()[1:]
    N = len(dth0) if steps is None else min(steps, len(dth0))
    dt = float(df[col.TIME].iloc[1] - df[col.TIME].iloc[0])
    P = df[list(col.POS)].to_numpy()
    V = df[list(col.VEL)].to_numpy()
    Q = df[list(col.QUAT)].to_numpy()
    dth = np.broadcast_to(dth0[:N], (S, N, 3))
    dv = np.broadcast_to(dv0[:N], (S, N, 3))
    t0 = time.perf_counter()
    c0 = time.process_time()
    Pn, _, _ = mechanize_numpy(dth, dv, dt, P[0], V[0], Q[0], frame, every=every)
    el = time.perf_counter() - t0
    cpu = time.process_time() - c0
    idx = np.arange(0, N + 1, every)
    return {
        "samples": N,
        "sequences": S,
        "seconds": el,
        "msps": S * N / el / 1e6,
        "msps_cpu": S * N / cpu / 1e6,
        "closure_max_1hz_m": float(np.max(np.linalg.norm(Pn[0] - P[idx], axis=1))),
        "peak_rss_mb": peak_rss_mb(),
    }


def _quat_conj(q):
    return np.array([q[0], -q[1], -q[2], -q[3]])


def _quat_mul(a, b):
    aw, ax, ay, az = a
    bw, bx, by, bz = b
    return np.array(
        [
            aw * bw - ax * bx - ay * by - az * bz,
            aw * bx + ax * bw + ay * bz - az * by,
            aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw,
        ]
    )


def _dcm(q):
    w, x, y, z = q
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
            [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
            [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
        ]
    )


PYINS_SCRIPT = textwrap.dedent("""
    import json, sys, time
    import numpy as np, pandas as pd
    import pyins
    from pyins import strapdown, transform
    from pyins._numba_integrate import integrate
    d = np.load(sys.argv[1])
    reps = int(sys.argv[2])
    dt = float(d["dt"]); th = d["theta"]; dv = d["dv"]; n = len(th)
    t = np.arange(n + 1) * dt
    inc = pd.DataFrame(np.hstack([np.full((n, 1), dt), th, dv]), index=t[1:],
                       columns=["dt", "theta_x", "theta_y", "theta_z", "dv_x", "dv_y", "dv_z"])
    rph0 = transform.mat_to_rph(d["C0"])
    pva = pd.Series(np.hstack([d["lla0"], d["vel0"], rph0]),
                    index=["lat", "lon", "alt", "VN", "VE", "VD", "roll", "pitch", "heading"],
                    name=0.0)
    tj = time.process_time(); strapdown.Integrator(pva).integrate(inc.iloc[:10]); tj = time.process_time() - tj
    best = []
    for _ in range(reps):
        integ = strapdown.Integrator(pva)
        t0 = time.process_time(); traj = integ.integrate(inc); best.append(time.process_time() - t0)
    # the numba core alone (no pandas), same arrays
    lla = np.empty((n + 1, 3)); vel = np.empty((n + 1, 3)); mat = np.empty((n + 1, 3, 3))
    core = []; core_wall = []
    for _ in range(reps):
        lla[0] = d["lla0"]; vel[0] = d["vel0"]; mat[0] = d["C0"]
        t0 = time.process_time(); w0 = time.perf_counter()
        integrate(np.full(n, dt), lla, vel, mat, np.ascontiguousarray(th), np.ascontiguousarray(dv), 0, True)
        core.append(time.process_time() - t0); core_wall.append(time.perf_counter() - w0)
    end = traj[["lat", "lon", "alt"]].to_numpy()[-1]
    err = transform.compute_lla_difference(end, d["lla_end"])
    C_end = transform.mat_from_rph(traj[["roll", "pitch", "heading"]].to_numpy()[-1])
    D = C_end.T @ d["C_end"]
    ang = float(np.arccos(np.clip((np.trace(D) - 1) / 2, -1, 1)))
    print(json.dumps({"version": getattr(pyins, "__version__", "1.0"), "samples": n,
                      "jit_s": tj, "integrate_s": min(best), "core_s": min(core),
                      "msps_integrate": n / min(best) / 1e6, "msps_core": n / min(core) / 1e6,
                      "msps_core_wall": n / min(core_wall) / 1e6,
                      "closure_final_m": float(np.linalg.norm(err)), "closure_att_rad": ang}))
""")


def run_pyins(df, frame, python, reps):
    """pyins on the wgs84 truth converted to its conventions (NED, FRD, degrees)."""
    if not python or not Path(python).exists():
        return {"skipped": f"pyins interpreter {python!r} not found"}
    r = subprocess.run([python, "-c", "import pyins"], capture_output=True, text=True)
    if r.returncode != 0:
        return {
            "skipped": f"pyins not importable with {python}: {r.stderr.strip().splitlines()[-1]}"
        }
    T_ne = np.array([[0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, -1.0]])  # ENU -> NED
    T_bf = np.diag([1.0, -1.0, -1.0])  # FLU <-> FRD
    dth = df[list(col.DTHETA)].to_numpy()[1:] @ T_bf
    dv = df[list(col.DV)].to_numpy()[1:] @ T_bf
    P = df[list(col.POS)].to_numpy()
    V = df[list(col.VEL)].to_numpy()
    Q = df[list(col.QUAT)].to_numpy()
    lat, lon, h = frame.geodetic_from_n(P[[0, -1]])
    lla = np.stack([np.degrees(lat), np.degrees(lon), h], axis=1)
    dt = float(df[col.TIME].iloc[1] - df[col.TIME].iloc[0])
    with tempfile.TemporaryDirectory() as tmp:
        f = Path(tmp) / "inc.npz"
        np.savez(
            f,
            dt=dt,
            theta=dth,
            dv=dv,
            lla0=lla[0],
            lla_end=lla[1],
            vel0=T_ne @ V[0],
            C0=T_ne @ _dcm(Q[0]) @ T_bf,
            C_end=T_ne @ _dcm(Q[-1]) @ T_bf,
        )
        r = subprocess.run(
            [python, "-c", PYINS_SCRIPT, str(f), str(reps)], capture_output=True, text=True
        )
    if r.returncode != 0:
        return {"skipped": f"pyins run failed: {r.stderr.strip()[-300:]}"}
    return json.loads(r.stdout.strip().splitlines()[-1])


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--sequences", type=int, default=1000)
    ap.add_argument("--scene", type=Path, default=PAPER, help="the paper's ENU trajectory file")
    ap.add_argument("--chunk", type=int, default=50, help="sequences per kernel call")
    ap.add_argument(
        "--every", type=int, default=None, help="store every N-th position (default: 1 Hz)"
    )
    ap.add_argument("--rate-hz", type=float, default=100.0, help="IMU rate of the truth")
    ap.add_argument("--earth", default="flat,wgs84,geodetic")
    ap.add_argument(
        "--numpy-steps", default="all", help="time steps for the NumPy version ('all' or a number)"
    )
    ap.add_argument("--pyins-python", default="/work/pyinsvenv/bin/python")
    ap.add_argument("--pyins-reps", type=int, default=5)
    ap.add_argument("--repeat", type=int, default=3, help="kernel passes per model (best kept)")
    ap.add_argument("--no-compile", action="store_true", help="skip the compile-time runs")
    ap.add_argument("--json", type=Path, default=None)
    args = ap.parse_args(argv)
    if not args.scene.exists():
        sys.exit(f"scene file missing: {args.scene}")
    res = {"machine": {"cpu_count": os.cpu_count(), "threads": 1}}
    res["load_avg_start"] = os.getloadavg()
    print(f"load average (1, 5, 15 min) at start: {res['load_avg_start']}", flush=True)
    if not args.no_compile:
        print("compile times (fresh numba cache, then cached) ...", flush=True)
        res["compile"] = compile_times()
        print(json.dumps(res["compile"]), flush=True)
    steps = None if args.numpy_steps == "all" else int(args.numpy_steps)
    if args.every is None:
        args.every = max(1, round(args.rate_hz))
    res["rate_hz"] = args.rate_hz
    print(f"rate {args.rate_hz:g} Hz, positions stored every {args.every} samples", flush=True)
    for model in args.earth.split(","):
        df, frame = build_scene(args.scene, args.rate_hz, model)
        print(
            f"[{model}] numba kernel, {args.sequences} sequences x {len(df) - 1} steps ...",
            flush=True,
        )
        r = run_numba(
            df, frame, args.sequences, args.chunk, args.every, np.random.default_rng(1), args.repeat
        )
        res[f"numba_{model}"] = r
        print(json.dumps(r), flush=True)
        if steps != 0:
            print(f"[{model}] NumPy, {args.sequences} sequences ...", flush=True)
            r = run_numpy(df, frame, args.sequences, steps, args.every)
            res[f"numpy_{model}"] = r
            print(json.dumps(r), flush=True)
        if model == "wgs84":
            print("[wgs84] pyins ...", flush=True)
            r = run_pyins(df, frame, args.pyins_python, args.pyins_reps)
            res["pyins_wgs84"] = r
            print(json.dumps(r), flush=True)
    res["peak_rss_mb"] = peak_rss_mb()
    res["load_avg_end"] = os.getloadavg()
    print(
        f"\nsummary at {args.rate_hz:g} Hz (million sample-sequences per second, one core; "
        f"load average at start "
        f"{res['load_avg_start'][0]:.1f}, at end {res['load_avg_end'][0]:.1f})"
    )
    for key, val in res.items():
        if key.startswith("numba_"):
            print(
                f"  {key:15s} kernel {val['msps_kernel']:7.2f} (per CPU second "
                f"{val['msps_kernel_cpu']:6.2f})  incl. input prep "
                f"{val['msps_total']:6.2f}  closure max (stored) {val['closure_max_1hz_m']:.2e} m  "
                f"(CPU {val['cpu_s']:.1f} s, load {val['load_avg_1min']:.1f})"
            )
        elif key.startswith("numpy_"):
            print(f"  {key:15s} {val['msps']:7.2f} (per CPU second {val['msps_cpu']:.2f})")
        elif key.startswith("pyins") and "skipped" not in val:
            print(
                f"  {key:14s} Integrator.integrate {val['msps_integrate']:.2f}  numba core "
                f"{val['msps_core']:.2f} (wall {val.get('msps_core_wall', float('nan')):.2f})  "
                f"closure final {val['closure_final_m']:.2e} m"
            )
        elif key.startswith("pyins"):
            print(f"  {key:14s} skipped: {val['skipped']}")
    print(f"  peak RSS {res['peak_rss_mb']:.0f} MB")
    base = res.get("numba_wgs84")
    if base:
        print("\nkernels per CPU second (best of --repeat passes), relative to wgs84:")
        for key in ("numba_flat", "numba_wgs84", "numba_geodetic"):
            if key in res:
                v = res[key]["msps_kernel_cpu"]
                print(
                    f"  {key[6:]:9s} {v:6.2f} Msps/CPU-s  cost x{base['msps_kernel_cpu'] / v:.2f}"
                )
    if args.json:
        args.json.write_text(json.dumps(res, indent=1))


if __name__ == "__main__":
    main()
