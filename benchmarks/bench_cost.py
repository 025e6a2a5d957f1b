"""Cost of one shard job (noise -> IMU shard -> navigation errors) in CPU seconds, against its floor.

The machine this project runs on is shared: wall time depends on what else runs, CPU seconds
(user + system, from ``/usr/bin/time`` of each job, or ``time.process_time`` in-process) are what
compare between runs. Every figure is recorded with the load average at the time.

Measures (results in ``benchmarks/results/cost.{json,md}``, chart ``docs/figures/cost_vs_work``):

* floors, in CPU seconds on one core: the normal-variate floor -- the same generator as the
  injection (PCG64 ``standard_normal``, float64) drawing the same number of variates (sequences
  x samples x the grade's normals per sample) into one preallocated ``(CHUNK, 3)`` buffer, best
  of 3 -- and the mechanization kernel (``imugen.navigate.mechanize.mechanize`` on in-memory increments);
* injection: the generation loop of a shard (plan made beforehand) into a null sink and its
  ratio to the normal-variate floor (floor CPU / injection CPU, same variates; the two
  interleaved, best of 3 each); the same through the shard writer (Parquet file, float32,
  implicit clock);
* start-up: ``imugen simulate --help`` and a 1-sequence job, fused (``imugen simulate TRUTH -o
  SHARD --navigate NAV``) and the former two jobs (``imugen simulate`` then ``imugen navigate``);
* growth: fused jobs of ``--growth`` sequences on the paper scene at 100 Hz, least CPU of
  ``--repeats`` runs each (CPU, wall, peak RSS), a least-squares fit ``CPU = a + b * work``
  (work = sequences x samples), and from it the 10,000-sequence run in shards of
  ``--per-shard`` against its floor (normals + mechanization + disk, as issue 14 defines it:
  the mechanization rate measured again after every growth job and the best taken; the disk as
  the CPU of ``os.write`` of the shard's own bytes per sample-sequence, in 4 MiB blocks to a
  fresh file, best of 3). The 10,000-sequence figure is an extrapolation of the fit, labelled
  as such, unless ``--full`` runs it.

Usage::

    python benchmarks/bench_cost.py [--grade industrial] [--growth 1 10 50 250 1000]
        [--per-shard 250 1000] [--repeats 2] [--scratch /tmp/imugen-cost] [--full]
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import shutil
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

from imugen.simulate.plan import plan_shard
from imugen.simulate.sinks import WriterSink

ROOT = Path(__file__).resolve().parents[1]
ROUTE = ROOT / "resources" / "paper" / "seed_reference_trajectory_enu.txt"
ORIGIN = "31.63,-7.99,480.6"
OUT = ROOT / "benchmarks" / "results"
FIG = ROOT / "docs" / "figures" / "cost_vs_work"
IMUGEN = [sys.executable, "-m", "imugen"]


def log(msg: str) -> None:
    print(f"[{time.strftime('%H:%M:%S')}] {msg}", file=sys.stderr, flush=True)


def load() -> list[float]:
    return [round(x, 2) for x in os.getloadavg()]


def timed(args, env=None) -> dict:
    """Run a command under ``/usr/bin/time``: wall, user+sys CPU, peak RSS."""
    fmt = "%e %U %S %M"
    r = subprocess.run(
        ["/usr/bin/time", "-f", fmt, *map(str, args)],
        capture_output=True,
        text=True,
        env=env,
    )
    if r.returncode:
        raise RuntimeError(r.stderr[-2000:])
    e, u, s, m = r.stderr.strip().splitlines()[-1].split()
    return {"wall_s": float(e), "cpu_s": float(u) + float(s), "rss_mib": int(m) / 1024}


def best(args, repeats=3) -> dict:
    """The run of least CPU among ``repeats`` (the others paid for cache misses or contention)."""
    runs = [timed(args) for _ in range(repeats)]
    return min(runs, key=lambda r: r["cpu_s"])


def prepare_truth(scratch: Path) -> Path:
    truth = scratch / "paper" / "truth.parquet"
    if not truth.exists():
        enu = scratch / "paper" / "enu.parquet"
        enu.parent.mkdir(parents=True, exist_ok=True)
        subprocess.run([*IMUGEN, "ingest", ROUTE, "-o", enu, "--origin", ORIGIN, "--dt", "1.0"],
                       check=True, capture_output=True)  # fmt: skip
        subprocess.run([*IMUGEN, "truth", enu, "-o", truth, "--rate-hz", "100"],
                       check=True, capture_output=True)  # fmt: skip
    return truth


# --- floors (in-process CPU time) -----------------------------------------------------------
def normals_cpu(n_variates: int) -> float:
    """The normal-variate floor: CPU seconds of PCG64 ``standard_normal`` (float64, the
    injection's generator) drawing ``n_variates`` (the injection's own count) into one
    preallocated ``(CHUNK, 3)`` buffer."""
    from imugen.simulate.stage import CHUNK

    rng = np.random.Generator(np.random.PCG64(0))
    buf = np.empty((CHUNK, 3))
    calls, rest = divmod(int(n_variates), buf.size)
    tail = buf.reshape(-1)[:rest]
    rng.standard_normal(out=buf)
    t0 = time.process_time()
    for _ in range(calls):
        rng.standard_normal(out=buf)
    rng.standard_normal(out=tail)
    return time.process_time() - t0


def mech_rate(truth_path: Path, batch: int = 16) -> float:
    """Mechanization kernel: sample-sequences per CPU second (flat Earth, in memory)."""
    from imugen.navigate.mechanize import mechanize
    from imugen.tables import truth as ttruth

    tr = ttruth.read(truth_path, arrow=True)
    dth = np.ascontiguousarray(np.broadcast_to(tr.dtheta[1:], (batch, tr.K - 1, 3)))
    dv = np.ascontiguousarray(np.broadcast_to(tr.dv[1:], (batch, tr.K - 1, 3)))
    x0 = (tr.p_n[0], tr.v_n[0], tr.q_nb[0])
    frame = tr.origin_frame()
    mechanize(dth[:1, :100], dv[:1, :100], tr.dt, *x0, frame, every=100, outputs=("p", "q"))
    best_ = 0.0
    for _ in range(3):
        t0 = time.process_time()
        mechanize(dth, dv, tr.dt, *x0, frame, every=100, outputs=("p", "q"))
        best_ = max(best_, batch * (tr.K - 1) / (time.process_time() - t0))
    return best_


def disk_rate(scratch: Path, nbytes: int = 256 << 20) -> float:
    """The disk floor: bytes per CPU second of ``os.write`` (4 MiB blocks) to a fresh file,
    best of 3 (the page-cache copy every writer pays; no encoding)."""
    block = np.random.default_rng(0).integers(0, 255, 4 << 20, dtype=np.uint8).tobytes()
    path = scratch / "disk-floor.bin"
    best_ = 0.0
    for _ in range(3):
        path.unlink(missing_ok=True)
        fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o644)
        t0 = time.process_time()
        for _ in range(nbytes // len(block)):
            os.write(fd, block)
        t = time.process_time() - t0
        os.close(fd)
        best_ = max(best_, nbytes / max(t, 1e-9))
    path.unlink(missing_ok=True)
    return best_


class _Null:
    def put(self, *a):
        pass


def injection(truth_path: Path, grade: str, M: int, repeats: int = 3) -> dict:
    """Generation loop of an M-sequence shard (the plan -- truth read, draws -- made before the
    clock starts): into a null sink, and through the shard writer (Parquet, float32, implicit
    clock) to a file; CPU seconds, best of ``repeats``."""
    from imugen.simulate import stage as S
    from imugen.tables import shard as tshard

    S._loop(plan_shard(str(truth_path), grade, 1, 1, 0), _Null())  # kernels loaded
    plan = plan_shard(str(truth_path), grade, M, 1, 0)
    out = truth_path.parent / "inj.parquet"

    def null():
        return S._loop(plan, _Null())

    def write():
        times = plan.truth.times()
        dt = S._nominal_dt(plan.truth)
        with tshard.writer(out, plan.meta, plan.names, "float32", time_s=times, dt=dt) as w:
            S._loop(plan, WriterSink(w, plan.ids))
            w.labels = plan.label_columns()

    nps = null()
    n_var = nps * M * plan.truth.K
    floor = lambda: normals_cpu(n_var)  # noqa: E731
    # interleaved, best of each: the floor and the injection see the same machine load
    runs = {"floor": [], "null": [], "write": []}
    for _ in range(repeats):
        for key, f in (("floor", floor), ("null", null), ("write", write)):
            t0 = time.process_time()
            f()
            runs[key].append(time.process_time() - t0)
    t_floor, t_null, t_write = (min(runs[k]) for k in ("floor", "null", "write"))
    out.unlink()
    tshard.labels_path(out).unlink()
    work = M * plan.truth.K
    return {
        "sequences": M,
        "samples": plan.truth.K,
        "normals_per_sample": nps,
        "floor_cpu_s": t_floor,
        "normals_per_cpu_s": n_var / t_floor,
        "null_cpu_s": t_null,
        "write_cpu_s": t_write,
        "null_samples_per_cpu_s": work / t_null,
        "write_samples_per_cpu_s": work / t_write,
    }


def fit_line(x, y):
    A = np.column_stack([np.ones(len(x)), np.asarray(x, float)])
    (a, b), *_ = np.linalg.lstsq(A, np.asarray(y, float), rcond=None)
    return float(a), float(b)


def chart(runs, fit, floor_per_work, out_stem: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    x = np.array([r["work"] for r in runs], float)
    y = np.array([r["cpu_s"] for r in runs], float)
    xx = np.geomspace(x.min() / 2, max(x.max(), 1e10 / 4) * 1.5, 200)
    fig, ax = plt.subplots(figsize=(7, 4.6), layout="constrained")
    ax.loglog(x, y, "o", ms=7, label="fused shard job (measured CPU, user+sys)")
    a, b = fit
    ax.loglog(xx, a + b * xx, "k-", lw=1, label=f"fit {a:.2f} s + {b * 1e9:.0f} s per 1e9")
    ax.loglog(xx, floor_per_work * xx, "r--", lw=1, label="floor: normals + mechanization + disk")
    ax.set_xlabel("work = sequences x samples per sequence")
    ax.set_ylabel("CPU seconds per job")
    ax.set_title("Cost of one shard job (synthesis + write + navigation)")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8, loc="upper left")
    out_stem.parent.mkdir(parents=True, exist_ok=True)
    for ext in ("png", "svg"):
        fig.savefig(out_stem.with_suffix(f".{ext}"), dpi=120)
    plt.close(fig)


def markdown(res: dict) -> str:
    f, inj, st = res["floors"], res["injection"], res["startup"]
    L = [
        f"Machine: {res['machine']['cpu']}, {res['machine']['cores']} cores, shared; load average "
        f"{res['load_start']} at the start, {res['load_end']} at the end. CPU seconds (user + "
        "sys) are the comparable figures; wall time is shown beside them for the record.",
        "",
        "| quantity | CPU s | wall s | note |",
        "|---|--:|--:|---|",
        f"| `python -c 'import numpy, numba, pyarrow.parquet'` | {st['imports']['cpu_s']:.2f} | "
        f"{st['imports']['wall_s']:.2f} | the imports no job avoids |",
        f"| `imugen simulate --help` | {st['help']['cpu_s']:.2f} | {st['help']['wall_s']:.2f} | "
        "parser only |",
        f"| 1-sequence fused job (`simulate --navigate`) | {st['fused_1']['cpu_s']:.2f} | "
        f"{st['fused_1']['wall_s']:.2f} | peak RSS {st['fused_1']['rss_mib']:.0f} MiB |",
        f"| 1-sequence `simulate` + `navigate` (two jobs) | {st['two_1']['cpu_s']:.2f} | "
        f"{st['two_1']['wall_s']:.2f} | before: two start-ups |",
        "",
        f"Floors (one core, CPU time): normals {f['normals_per_cpu_s'] / 1e6:.1f} M/s x "
        f"{inj['normals_per_sample']:g} per sample; mechanization "
        f"{f['mech_per_cpu_s'] / 1e6:.1f} M sample-sequences/s; disk (`os.write`) "
        f"{f['disk_bytes_per_cpu_s'] / 1e9:.2f} GB/CPU-s x {f['bytes_per_work']:.1f} bytes per "
        f"sample-sequence: {f['per_work_s'] * 1e9:.0f} CPU-s per 1e9 sample-sequences.",
        "",
        f"Injection ({inj['sequences']} x {inj['samples']} samples, grade {res['grade']}): "
        f"{inj['null_samples_per_cpu_s'] / 1e6:.2f} M samples/CPU-s into a null sink against a "
        f"normal-variate bound of {f['normal_bound'] / 1e6:.2f} M: ratio "
        f"**{inj['ratio_null']:.2f}**; through the Parquet writer "
        f"{inj['write_samples_per_cpu_s'] / 1e6:.2f} M/CPU-s (ratio {inj['ratio_write']:.2f}).",
        "",
        "| sequences | samples | work | CPU s | wall s | peak RSS MiB | load |",
        "|--:|--:|--:|--:|--:|--:|---|",
    ]
    for r in res["growth"]:
        L.append(
            f"| {r['sequences']} | {r['samples']} | {r['work']:.3g} | {r['cpu_s']:.2f} | "
            f"{r['wall_s']:.1f} | {r['rss_mib']:.0f} | {r['load']} |"
        )
    a, b = res["fit"]
    p = res["projection"]
    L += ["", f"Fit: CPU = {a:.2f} s per job + {b * 1e9:.0f} s per 1e9 sample-sequences.", ""]
    for q in res["projections"]:
        L.append(
            f"Projected from the fit (not run): {q['sequences']} sequences x {q['samples']} "
            f"samples in {q['shards']} shards of {q['per_shard']}: **{q['cpu_s']:.0f} CPU-s** "
            f"against a floor of {q['floor_s']:.0f} CPU-s (normals + mechanization + disk): "
            f"**{q['ratio']:.2f}x** (target 1.5x)."
        )
    if p["measured"]:
        L.append(
            f"Measured (`--full`): {p['shards']} shards of {p['per_shard']}: "
            f"**{p['cpu_s']:.0f} CPU-s**, {p['ratio']:.2f}x the floor."
        )
    L.append(
        "Snakemake's own CPU and the per-route jobs (ingest, truth, evaluate, figures) are not "
        "included."
    )
    return "\n".join(L) + "\n"


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--grade", default="industrial")
    ap.add_argument("--growth", type=int, nargs="+", default=[1, 10, 50, 250, 1000])
    ap.add_argument("--per-shard", type=int, nargs="+", default=[250, 1000],
                    help="shard sizes of the projected run (the first is --full's)")  # fmt: skip
    ap.add_argument("--sequences", type=int, default=10_000, help="size of the projected run")
    ap.add_argument("--injection-sequences", type=int, default=50)
    ap.add_argument("--scratch", default="/tmp/imugen-cost")
    ap.add_argument("--full", action="store_true", help="run the projected shards for real")
    ap.add_argument("--out", default=str(OUT))
    ap.add_argument("--repeats", type=int, default=2, help="runs of each growth job (least CPU)")
    a = ap.parse_args()
    scratch = Path(a.scratch)
    scratch.mkdir(parents=True, exist_ok=True)
    res = {"grade": a.grade, "load_start": load()}
    res["machine"] = {"cpu": platform.processor() or platform.machine(), "cores": os.cpu_count()}
    truth = prepare_truth(scratch)
    log("injection")
    inj = injection(truth, a.grade, a.injection_sequences)
    log("floors")
    nr = inj["normals_per_cpu_s"]
    mech = [mech_rate(truth)]  # measured again beside every growth job; the best counts
    inj["ratio_null"] = inj["floor_cpu_s"] / inj["null_cpu_s"]
    inj["ratio_write"] = inj["floor_cpu_s"] / inj["write_cpu_s"]
    res["injection"] = inj
    log("start-up")
    d = scratch / "jobs"
    shutil.rmtree(d, ignore_errors=True)
    d.mkdir()
    common = ["--grade", a.grade, "--seed", "1", "--shard", "0"]
    res["startup"] = {
        "imports": best([sys.executable, "-c", "import numpy, numba, pyarrow.parquet"], 5),
        "help": best([*IMUGEN, "simulate", "--help"]),
        "fused_1": best(
            [
                *IMUGEN,
                "simulate",
                truth,
                "-o",
                d / "s.parquet",
                "--navigate",
                d / "n.parquet",
                "--sequences",
                "1",
                *common,
            ],
            5,
        ),
    }
    two = []
    for _ in range(3):
        s = timed([*IMUGEN, "simulate", truth, "-o", d / "s.parquet", "--sequences", "1", *common])
        n = timed([*IMUGEN, "navigate", truth, d / "s.parquet", "-o", d / "n.parquet"])
        two.append({k: s[k] + n[k] for k in ("cpu_s", "wall_s")})
    res["startup"]["two_1"] = min(two, key=lambda r: r["cpu_s"])
    growth = []
    for M in a.growth:
        log(f"growth: {M} sequences")
        r = best([*IMUGEN, "simulate", truth, "-o", d / "s.parquet", "--navigate", d / "n.parquet",
                  "--sequences", str(M), *common], repeats=a.repeats)  # fmt: skip
        K = inj["samples"]
        growth.append({**r, "sequences": M, "samples": K, "work": M * K, "load": load(),
                       "shard_bytes": (d / "s.parquet").stat().st_size})  # fmt: skip
        mech.append(mech_rate(truth))
    res["growth"] = growth
    mr = max(mech)
    bound = nr / inj["normals_per_sample"]
    big = max(growth, key=lambda g: g["work"])
    bytes_per_work = big["shard_bytes"] / big["work"]  # the shard's own bytes
    dr = disk_rate(scratch)
    per_work = inj["normals_per_sample"] / nr + 1.0 / mr + bytes_per_work / dr
    res["floors"] = {"normals_per_cpu_s": nr, "mech_per_cpu_s": mr, "normal_bound": bound,
                     "disk_bytes_per_cpu_s": dr, "bytes_per_work": bytes_per_work,
                     "per_work_s": per_work, "mech_runs_per_cpu_s": mech}  # fmt: skip
    fit = fit_line([g["work"] for g in growth], [g["cpu_s"] for g in growth])
    res["fit"] = fit
    N, K = a.sequences, inj["samples"]
    floor = per_work * N * K
    res["projections"] = []
    for M in a.per_shard:
        shards = -(-N // M)
        cpu = shards * fit[0] + fit[1] * N * K
        res["projections"].append({"sequences": N, "per_shard": M, "shards": shards,
                                   "samples": K, "cpu_s": cpu, "floor_s": floor,
                                   "ratio": cpu / floor, "measured": False})  # fmt: skip
    M = a.per_shard[0]
    shards = -(-N // M)
    if a.full:
        cpu = 0.0
        for k in range(shards):
            m = min(M, N - k * M)
            cpu += timed([*IMUGEN, "simulate", truth, "-o", d / "s.parquet", "--navigate",
                          d / "n.parquet", "--sequences", str(m), "--shard-size", str(M),
                          "--grade", a.grade, "--seed", "1", "--shard", str(k)])["cpu_s"]  # fmt: skip
    else:
        cpu = shards * fit[0] + fit[1] * N * K
    res["projection"] = {"sequences": N, "per_shard": M, "shards": shards, "samples": K,
                         "cpu_s": cpu, "floor_s": floor, "ratio": cpu / floor,
                         "measured": a.full}  # fmt: skip
    res["load_end"] = load()
    shutil.rmtree(d, ignore_errors=True)
    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    (out / "cost.json").write_text(json.dumps(res, indent=1))
    (out / "cost.md").write_text(markdown(res))
    chart(growth, fit, per_work, FIG)
    print(markdown(res))
    return 0


if __name__ == "__main__":
    sys.exit(main())
