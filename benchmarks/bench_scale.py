"""Scale benchmark: the whole workflow through ``snakemake -j2`` at 10,000 sequences (run on demand).

Measures in one run (results in ``benchmarks/results/scale.{json,md}`` and the chart
``scale_growth.{png,svg}``):

* the machine: CPU, cores, memory, versions, load average before and after;
* the floors, measured here: the disk's own sequential write rate (``dd`` of a 2 GiB file with
  ``conv=fdatasync``, then deleted), NumPy's normal-variate rate (PCG64 ``standard_normal``
  into a reused buffer, one core), the mechanization kernel (``imugen.navigate.mechanize.mechanize``
  on in-memory contiguous increments, one core); from them, for each run, the time floors on
  ``--cores`` cores: ``normals = N K n_per_sample / (rate cores)``,
  ``mechanization = N (K-1) / (rate cores)``, ``disk = bytes written / dd rate``;
* the main run: the paper scene (``resources/paper``, origin 31.63,-7.99,480.6, 1 s per row) at
  100 Hz, one grade, ``--sequences`` (10,000) sequences, ``--per-shard`` (250) per shard,
  through ``snakemake -j2`` from an empty working directory, target ``all`` with
  ``exports.mat: false`` (a .mat of 10,000 sequences is a 20 GB file, not a dataset format) and
  a small Allan check (60 s, 1 sequence). Every ``imugen`` call of the workflow goes through a
  wrapper that records its wall time, CPU time and peak RSS (``/usr/bin/time``), so time per
  stage and peak memory per job come from the real run. Then ``sync`` is timed (data still in
  the page cache), bytes written are summed, and the write rate is set against ``dd``'s;
* Snakemake's own time to build the DAG and dry-run (``snakemake -n``) the 10,000-sequence
  configuration, with 250 and with 10 sequences per shard (1,000 shards), from an empty folder,
  and of the finished main run (everything up to date);
* per-job fixed cost: ``imugen simulate`` and ``imugen navigate`` of a 1-sequence shard;
* cost growth: the same workflow with 100 and 1,000 sequences at 100 Hz, with 1,000 and
  10,000 at 10 Hz and with 100 at 1000 Hz (``--growth`` to change), shards sized to a constant
  work of 250 x 62,001 sample-sequences (at least two shards), plus 1,000 sequences at 100 Hz in
  shards of 50 (5x the jobs: the per-shard overhead); a least-squares fit
  ``wall = a + b * work`` and ``bytes = c + d * work``;
* storage choices on a real shard of the main run: float32/float64, dictionary on/off,
  BYTE_STREAM_SPLIT, compression none/snappy/lz4/zstd, dictionary on ``time_s``, row-group size:
  file size, write and read rates.

Usage::

    python benchmarks/bench_scale.py [--sequences 10000] [--per-shard 250] [--grade industrial]
        [--scratch DIR] [--cores 2] [--growth N@HZ ...] [--skip-growth] [--skip-storage]
        [--keep] [--quick]

``--quick`` runs 200 sequences and small growth points (a smoke test of the script, ~2 min).
The scratch directory (default ``/tmp/imugen-scale``) must be on the disk being measured; the
main run needs about 20 GB there (deleted at the end unless ``--keep``).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import platform
import shutil
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

from imugen.sensors.ideal import ArrayTruth
from imugen.simulate.options import SimulateOptions
from imugen.simulate.plan import plan_shard

ROOT = Path(__file__).resolve().parents[1]
SNAKEFILE = ROOT / "Snakefile"
ROUTE = ROOT / "resources" / "paper" / "seed_reference_trajectory_enu.txt"
ORIGIN = [31.63, -7.99, 480.6]
OUT = ROOT / "benchmarks" / "results"
VENV_BIN = Path(sys.executable).parent
SEED = 20251150
WORK_PER_SHARD = 250 * 61_901
"""Sample-sequences per shard of the sizing rule (250 sequences of the paper scene at 100 Hz)."""


def nice_shard_size(n: int, samples: int) -> int:
    """Sequences per shard: about WORK_PER_SHARD sample-sequences, at least two shards, rounded
    down to 1, 2, 2.5 or 5 x 10^k (so that it divides the round N of the growth runs)."""
    target = max(1, min(WORK_PER_SHARD // samples, math.ceil(n / 2)))
    best = 1
    for k in range(0, 10):
        for m in (1, 2, 2.5, 5):
            v = int(m * 10**k)
            if v == m * 10**k and v <= target:
                best = max(best, v)
    return best


WRAPPER = r"""#!/bin/bash
# imugen, timed: appends "stage start wall user sys maxrss_kB exit" to $IMUGEN_TIMELOG
stage="$1"
case " $* " in *" --static "*) stage="allan_static" ;; esac
t0=$(date +%s.%N)
exec /usr/bin/time -a -o "$IMUGEN_TIMELOG" -f "$stage $t0 %e %U %S %M %x" "$IMUGEN_REAL" "$@"
"""


# --- helpers ----------------------------------------------------------------------------------
def log(msg: str) -> None:
    print(f"[{time.strftime('%H:%M:%S')}] {msg}", flush=True)


def machine() -> dict:
    cpu = "unknown"
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    mem = None
    try:
        for line in Path("/proc/meminfo").read_text().splitlines():
            if line.startswith("MemTotal"):
                mem = int(line.split()[1]) * 1024
    except OSError:
        pass
    import numba
    import pyarrow
    import snakemake

    import imugen

    return {
        "cpu": cpu,
        "cpu_count": os.cpu_count(),
        "memory_bytes": mem,
        "python": platform.python_version(),
        "numpy": np.__version__,
        "numba": numba.__version__,
        "pyarrow": pyarrow.__version__,
        "snakemake": snakemake.__version__,
        "imugen": imugen.__version__,
        "kernel": platform.release(),
    }


def tree_bytes(path: Path) -> dict:
    """Bytes of the files under ``path`` by kind (imu shards, labels, nav, other)."""
    out = {"imu": 0, "labels": 0, "nav": 0, "other": 0, "files": 0}
    for dirpath, _, files in os.walk(path):
        for f in files:
            p = Path(dirpath) / f
            try:
                n = p.stat().st_size
            except OSError:
                continue
            out["files"] += 1
            parts = p.relative_to(path).parts
            if f.endswith(".labels.parquet"):
                out["labels"] += n
            elif "imu" in parts:
                out["imu"] += n
            elif "nav" in parts:
                out["nav"] += n
            else:
                out["other"] += n
    out["total"] = out["imu"] + out["labels"] + out["nav"] + out["other"]
    return out


def dd_rate(scratch: Path, mib: int) -> dict:
    """Sequential write rate of the scratch disk: dd of ``mib`` MiB with conv=fdatasync."""
    p = scratch / "dd.test"
    t0 = time.perf_counter()
    r = subprocess.run(
        ["dd", "if=/dev/zero", f"of={p}", "bs=1M", f"count={mib}", "conv=fdatasync"],
        capture_output=True,
        text=True,
    )
    el = time.perf_counter() - t0
    p.unlink(missing_ok=True)
    if r.returncode:
        raise RuntimeError(r.stderr)
    return {"bytes": mib << 20, "s": el, "bytes_per_s": (mib << 20) / el, "dd": r.stderr.strip()}


def normals_rate(seconds: float = 3.0) -> float:
    """Normals per second on one core (PCG64 standard_normal float64 into a reused buffer)."""
    from imugen.simulate.stage import CHUNK

    rng = np.random.default_rng(0)
    buf = np.empty((CHUNK, 3))
    rng.standard_normal(out=buf)
    n, t0 = 0, time.perf_counter()
    while time.perf_counter() - t0 < seconds:
        rng.standard_normal(out=buf)
        n += buf.size
    return n / (time.perf_counter() - t0)


def normals_per_sample(truth_path: Path, grade: str) -> float:
    """Normals the grade draws per IMU sample (both sensors), from the simulator itself."""
    from imugen.simulate import stage as S

    class Null:
        def put(self, *a):
            pass

    tr = ArrayTruth.read(truth_path)
    tr.K = min(tr.K, 2 * S.CHUNK)
    opts = SimulateOptions(grade=grade, sequences=1, seed=1, shard=0)
    return float(S._loop(plan_shard(tr, opts), Null()))


def mech_rate(truth_path: Path, batch: int = 16, repeats: int = 3) -> float:
    """Sample-sequences per second of the mechanization kernel on one core (as navigate calls it)."""
    from imugen.navigate.mechanize import mechanize
    from imugen.tables import truth as ttruth

    tr = ttruth.read(truth_path)
    dth, dv = tr.dtheta[1:], tr.dv[1:]
    p0, v0, q0 = tr.p_n[0], tr.v_n[0], tr.q_nb[0]
    rate = tr.rate_hz
    every = max(1, round(rate))
    rng = np.random.default_rng(0)
    dt = 1.0 / rate
    a = np.ascontiguousarray(dth[None] + rng.normal(0, 1e-7, (batch, 1, 3)))
    b = np.ascontiguousarray(dv[None] + rng.normal(0, 1e-6, (batch, 1, 3)))
    frame = tr.origin_frame()
    mechanize(a[:1], b[:1], dt, p0, v0, q0, frame, every=every, outputs=("p", "q"))  # compile
    best = math.inf
    for _ in range(repeats):
        t0 = time.perf_counter()
        mechanize(a, b, dt, p0, v0, q0, frame, every=every, outputs=("p", "q"))
        best = min(best, time.perf_counter() - t0)
    return batch * dth.shape[0] / best


def config(n: int, per_shard: int, rate_hz: float, grade: str) -> dict:
    return {
        "routes": {
            "paper": {
                "file": str(ROUTE),
                "origin": ORIGIN,
                "dt_s": 1.0,
                "vehicle": "car",
            }
        },
        "truth": {"rate_hz": rate_hz, "earth": "auto"},
        "grades": {grade: {}},
        "simulate": {"sequences": n, "sequences_per_shard": per_shard, "seed": SEED},
        "navigate": {"eval_rate_hz": 1.0},
        "exports": {"mat": False},
        "allan": {"static_s": 60, "rate_hz": 100, "sequences": 1},
    }


def snakemake_cmd(wd: Path, cfg: Path, cores: int, *extra: str) -> list[str]:
    return [
        sys.executable,
        "-m",
        "snakemake",
        "-s",
        str(SNAKEFILE),
        "-d",
        str(wd),
        "--configfile",
        str(cfg),
        "-j",
        str(cores),
        *extra,
    ]


def prepare(wd: Path, n: int, per_shard: int, rate_hz: float, grade: str) -> Path:
    if wd.exists():
        shutil.rmtree(wd)
    wd.mkdir(parents=True)
    cfg = wd / "config.json"  # JSON is YAML; Snakemake reads both
    cfg.write_text(json.dumps(config(n, per_shard, rate_hz, grade), indent=1))
    return cfg


def dry_run(wd: Path, cfg: Path, cores: int) -> dict:
    t0 = time.perf_counter()
    r = subprocess.run(snakemake_cmd(wd, cfg, cores, "-n"), capture_output=True, text=True)
    el = time.perf_counter() - t0
    if r.returncode:
        raise RuntimeError(r.stdout[-3000:] + r.stderr[-3000:])
    text = r.stdout + r.stderr
    jobs = 0 if "Nothing to be done" in text else None
    for line in text.splitlines():
        if line.strip().startswith("total"):
            try:
                jobs = int(line.split()[-1])
            except ValueError:
                pass
    return {"s": el, "jobs": jobs}


def parse_timelog(path: Path) -> list[dict]:
    jobs = []
    if not path.exists():
        return jobs
    for line in path.read_text().splitlines():
        f = line.split()
        if len(f) != 7 or f[0].startswith("Command"):
            continue
        stage, t0, wall, user, sys_, rss, rc = f
        jobs.append(
            {
                "stage": stage,
                "start": float(t0),
                "wall": float(wall),
                "cpu": float(user) + float(sys_),
                "user": float(user),
                "sys": float(sys_),
                "rss": int(rss) * 1024,
                "rc": int(rc),
            }
        )
    return jobs


def stage_table(jobs: list[dict]) -> dict:
    out: dict = {}
    for j in jobs:
        s = out.setdefault(
            j["stage"],
            {"jobs": 0, "wall_sum": 0.0, "cpu_sum": 0.0, "sys_sum": 0.0, "rss_max": 0},
        )
        s["jobs"] += 1
        s["wall_sum"] += j["wall"]
        s["cpu_sum"] += j["cpu"]
        s["sys_sum"] += j["sys"]
        s["rss_max"] = max(s["rss_max"], j["rss"])
        s["first_start"] = min(s.get("first_start", math.inf), j["start"])
        s["last_end"] = max(s.get("last_end", -math.inf), j["start"] + j["wall"])
    for s in out.values():
        s["wall_mean"] = s["wall_sum"] / s["jobs"]
    return out


def tool_env(scratch: Path, timelog: Path) -> dict:
    bindir = scratch / "bin"
    bindir.mkdir(parents=True, exist_ok=True)
    w = bindir / "imugen"
    w.write_text(WRAPPER)
    w.chmod(0o755)
    env = dict(os.environ)
    env["PATH"] = f"{bindir}:{VENV_BIN}:{env.get('PATH', '')}"
    env["IMUGEN_REAL"] = str(VENV_BIN / "imugen")
    env["IMUGEN_TIMELOG"] = str(timelog)
    return env


def run_workflow(
    scratch: Path, name: str, n: int, per_shard: int, rate_hz: float, grade: str, cores: int
) -> dict:
    """One clean run of ``snakemake -j cores`` (target all); wall, sync, bytes, jobs."""
    wd = scratch / name
    cfg = prepare(wd, n, per_shard, rate_hz, grade)
    timelog = scratch / f"{name}.timelog"
    timelog.unlink(missing_ok=True)
    env = tool_env(scratch, timelog)
    os.sync()
    load0 = os.getloadavg()
    log(f"run {name}: N={n} M={per_shard} {rate_hz:g} Hz ...")
    t0 = time.time()
    with open(scratch / f"{name}.snakemake.log", "w") as fh:
        r = subprocess.run(snakemake_cmd(wd, cfg, cores), stdout=fh, stderr=fh, env=env)
    wall = time.time() - t0
    if r.returncode:
        raise RuntimeError(f"snakemake failed, see {scratch / f'{name}.snakemake.log'}")
    t1 = time.perf_counter()
    os.sync()
    sync_s = time.perf_counter() - t1
    jobs = parse_timelog(timelog)
    stages = stage_table(jobs)
    for s in stages.values():
        s["first_start"] -= t0
        s["last_end"] -= t0
    nbytes = tree_bytes(wd / "results")
    K = None
    truth = wd / "results" / "paper" / "truth.parquet"
    if truth.exists():
        import pyarrow.parquet as pq

        K = pq.ParquetFile(truth).metadata.num_rows
    res = {
        "name": name,
        "sequences": n,
        "per_shard": per_shard,
        "shards": math.ceil(n / per_shard),
        "rate_hz": rate_hz,
        "samples": K,
        "work": n * K if K else None,
        "wall_s": wall,
        "sync_s": sync_s,
        "bytes": nbytes,
        "jobs": len(jobs),
        "cpu_s": sum(j["cpu"] for j in jobs),
        "rss_max": max((j["rss"] for j in jobs), default=0),
        "failed_jobs": sum(1 for j in jobs if j["rc"]),
        "stages": stages,
        "load_before": load0,
        "load_after": os.getloadavg(),
        "workdir": str(wd),
    }
    log(
        f"  {name}: {wall:.1f} s wall (+{sync_s:.1f} s sync), {nbytes['total'] / 1e9:.2f} GB, "
        f"{len(jobs)} imugen jobs, CPU {res['cpu_s']:.0f} s, max RSS {res['rss_max'] / 2**20:.0f} MiB"
    )
    return res


def job_fixed_cost(scratch: Path, truth: Path, grade: str) -> dict:
    """Wall/CPU/RSS of 1-sequence simulate and navigate jobs: the per-job fixed cost."""
    timelog = scratch / "fixed.timelog"
    timelog.unlink(missing_ok=True)
    env = tool_env(scratch, timelog)
    d = scratch / "fixed"
    d.mkdir(exist_ok=True)
    shard = d / "shard-000.parquet"
    imugen = str(scratch / "bin" / "imugen")
    for _ in range(2):
        subprocess.run(
            [imugen, "simulate", str(truth), "-o", str(shard), "--grade", grade,
             "--sequences", "1", "--seed", "1", "--shard", "0"],
            env=env, check=True, capture_output=True,
        )  # fmt: skip
        subprocess.run(
            [imugen, "navigate", str(truth), str(shard), "-o", str(d / "nav.parquet")],
            env=env, check=True, capture_output=True,
        )  # fmt: skip
    t0 = time.perf_counter()
    subprocess.run([str(VENV_BIN / "python"), "-c", "pass"], check=True)
    py = time.perf_counter() - t0
    jobs = parse_timelog(timelog)
    shutil.rmtree(d)
    out = {"python_startup_s": py}
    for stage in ("simulate", "navigate"):
        js = [j for j in jobs if j["stage"] == stage][1:]  # second call: warm caches
        out[stage] = {"wall_s": js[0]["wall"], "cpu_s": js[0]["cpu"], "rss": js[0]["rss"]}
    return out


def fit_line(x, y):
    """Least squares y = a + b x; returns a, b."""
    x, y = np.asarray(x, float), np.asarray(y, float)
    A = np.column_stack([np.ones_like(x), x])
    (a, b), *_ = np.linalg.lstsq(A, y, rcond=None)
    return float(a), float(b)


# --- storage ----------------------------------------------------------------------------------
def storage_bench(shard: Path, scratch: Path, rows: int = 1 << 22) -> list[dict]:
    """Write/read a real shard's first ``rows`` rows under several Parquet choices."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    pf = pq.ParquetFile(shard)
    names = pf.schema_arrow.names
    parts, have = [], 0
    for rb in pf.iter_batches(batch_size=1 << 16):
        parts.append(rb)
        have += rb.num_rows
        if have >= rows:
            break
    base = pa.Table.from_batches(parts).slice(0, rows).replace_schema_metadata(None)
    floats = [c for c in names if c not in ("sequence", "time_s")]
    f64 = base.cast(
        pa.schema(
            [pa.field(f.name, pa.float64() if f.name in floats else f.type) for f in base.schema]
        )
    )
    p = scratch / "storage.parquet"
    R = 1 << 20
    variants = [
        # (label, table, write options)
        ("float32, dict on floats (pyarrow default), none", base, dict(use_dictionary=True, compression="none")),
        ("float32, PLAIN floats, none (imugen)", base, dict(use_dictionary=["sequence"], compression="none")),
        ("float32, PLAIN floats, snappy", base, dict(use_dictionary=["sequence"], compression="snappy")),
        ("float32, PLAIN floats, lz4", base, dict(use_dictionary=["sequence"], compression="lz4")),
        ("float32, PLAIN floats, zstd(1)", base, dict(use_dictionary=["sequence"], compression="zstd", compression_level=1)),
        ("float32, BYTE_STREAM_SPLIT floats, none", base, dict(use_dictionary=["sequence"], use_byte_stream_split=floats, compression="none")),
        ("float32, BYTE_STREAM_SPLIT floats, zstd(1)", base, dict(use_dictionary=["sequence"], use_byte_stream_split=floats, compression="zstd", compression_level=1)),
        ("float32, PLAIN floats, dict on time_s, none", base, dict(use_dictionary=["sequence", "time_s"], compression="none")),
        ("float64, dict on floats, none", f64, dict(use_dictionary=True, compression="none")),
        ("float64, PLAIN floats, none", f64, dict(use_dictionary=["sequence"], compression="none")),
        ("float64, PLAIN floats, snappy", f64, dict(use_dictionary=["sequence"], compression="snappy")),
        ("float64, BYTE_STREAM_SPLIT floats, zstd(1)", f64, dict(use_dictionary=["sequence"], use_byte_stream_split=floats, compression="zstd", compression_level=1)),
    ]  # fmt: skip
    for rg in (1 << 14, 1 << 16, 1 << 18, 1 << 22):
        variants.append(
            (f"float32, PLAIN floats, none, row group 2^{rg.bit_length() - 1}", base,
             dict(use_dictionary=["sequence"], compression="none", row_group_size=rg))
        )  # fmt: skip
    out = []
    for label, tbl, opts in variants:
        opts = {"row_group_size": R, "write_statistics": ["sequence", "time_s"], **opts}
        wbest = rbest = math.inf
        for _ in range(2):
            p.unlink(missing_ok=True)
            t0 = time.perf_counter()
            pq.write_table(tbl, p, **opts)
            wbest = min(wbest, time.perf_counter() - t0)
            t0 = time.perf_counter()
            for rb in pq.ParquetFile(p).iter_batches(batch_size=1 << 16):
                for c in rb.columns:
                    c.to_numpy(zero_copy_only=False)
            rbest = min(rbest, time.perf_counter() - t0)
        size = p.stat().st_size
        raw = tbl.nbytes
        out.append(
            {
                "variant": label,
                "rows": tbl.num_rows,
                "bytes_per_row": size / tbl.num_rows,
                "file_over_raw": size / raw,
                "write_MB_per_s": raw / wbest / 1e6,
                "read_MB_per_s": raw / rbest / 1e6,
                "row_group_size": opts["row_group_size"],
                "footer_bytes": pq.ParquetFile(p).metadata.serialized_size,
            }
        )
        log(
            f"  storage {label:52s} {size / tbl.num_rows:5.1f} B/row  write "
            f"{out[-1]['write_MB_per_s']:6.0f} MB/s  read {out[-1]['read_MB_per_s']:6.0f} MB/s"
        )
    p.unlink(missing_ok=True)
    return out


# --- reporting --------------------------------------------------------------------------------
def floors(run: dict, rates: dict, cores: int) -> dict:
    N, K = run["sequences"], run["samples"]
    f = {
        "normals_s": N * K * rates["normals_per_sample"] / (rates["normals_per_s"] * cores),
        "mechanization_s": N * (K - 1) / (rates["mech_per_s"] * cores),
        "disk_s": run["bytes"]["total"] / rates["disk"]["bytes_per_s"],
    }
    f["sum_s"] = sum(f.values())
    f["wall_over_sum"] = run["wall_s"] / f["sum_s"]
    return f


def chart(runs: list[dict], fits: dict, out_stem: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(11, 4.5), layout="constrained")
    marks = {10.0: "s", 100.0: "o", 1000.0: "^"}
    x = np.array([r["work"] for r in runs], float)
    xx = np.geomspace(x.min() / 2, x.max() * 2, 100)
    for ax, key, label, fkey in (
        (axes[0], "wall_s", "wall time [s]", "wall"),
        (axes[1], "bytes", "bytes written", "bytes"),
    ):
        for r in runs:
            y = r["wall_s"] if key == "wall_s" else r["bytes"]["total"]
            ax.loglog(
                r["work"],
                y,
                marks.get(float(r["rate_hz"]), "o"),
                ms=8,
                mfc="none" if r.get("explicit_m") else None,
                label=f"{r['sequences']} seq. @ {r['rate_hz']:g} Hz, M={r['per_shard']}",
            )
        a, b = fits[fkey]
        ax.loglog(xx, a + b * xx, "k-", lw=1, label=f"fit {a:.3g} + {b:.3g} x work")
        ax.loglog(xx, b * xx, "k:", lw=1, label="linear part alone")
        ax.set_xlabel("work [sample-sequences = N x samples per sequence]")
        ax.set_ylabel(label)
        ax.grid(True, which="both", alpha=0.3)
    axes[0].set_title("snakemake -j2 wall time against work")
    axes[1].set_title("bytes written against work")
    axes[0].legend(fontsize=7, loc="upper left")
    for ext in ("png", "svg"):
        fig.savefig(out_stem.with_suffix(f".{ext}"), dpi=130)
    plt.close(fig)


def markdown(res: dict) -> str:
    L = []
    m = res["machine"]
    L.append(
        f"Machine: {m['cpu']}, {m['cpu_count']} cores, {m['memory_bytes'] / 2**30:.0f} GiB; "
        f"Python {m['python']}, NumPy {m['numpy']}, numba {m['numba']}, pyarrow {m['pyarrow']}, "
        f"Snakemake {m['snakemake']}."
    )
    r = res["rates"]
    L.append(
        f"\nFloors measured in this run: disk (dd 2 GiB, fdatasync) "
        f"{r['disk']['bytes_per_s'] / 1e6:.0f} MB/s; normals {r['normals_per_s']:.3g}/s per core "
        f"x {r['normals_per_sample']:g} per sample; mechanization kernel "
        f"{r['mech_per_s'] / 1e6:.1f} M sample-sequences/s per core."
    )
    main = res["main"]
    fl = main["floors"]
    L.append(
        f"\nMain run: {main['sequences']} sequences x {main['samples']} samples "
        f"({main['rate_hz']:g} Hz), {main['shards']} shards of {main['per_shard']}, "
        f"`snakemake -j{res['cores']}`, load average before {main['load_before'][0]:.1f}\n"
    )
    L.append("| quantity | value |\n|---|---|")
    L.append(
        f"| wall time (all jobs) | **{main['wall_s']:.0f} s** ({main['wall_s'] / 60:.1f} min) |"
    )
    L.append(f"| `sync` after the run | {main['sync_s']:.1f} s |")
    L.append(f"| CPU time of imugen jobs (user+sys) | {main['cpu_s']:.0f} s |")
    b = main["bytes"]
    L.append(
        f"| bytes written | {b['total'] / 1e9:.2f} GB (IMU shards {b['imu'] / 1e9:.2f}, labels "
        f"{b['labels'] / 1e6:.1f} MB, navigation {b['nav'] / 1e6:.0f} MB, other {b['other'] / 1e6:.0f} MB) |"
    )
    L.append(
        f"| write rate (bytes / wall) | {b['total'] / main['wall_s'] / 1e6:.0f} MB/s against dd "
        f"{r['disk']['bytes_per_s'] / 1e6:.0f} MB/s |"
    )
    L.append(
        f"| floors on {res['cores']} cores: normals + mechanization + disk | "
        f"{fl['normals_s']:.0f} + {fl['mechanization_s']:.0f} + {fl['disk_s']:.0f} = "
        f"{fl['sum_s']:.0f} s |"
    )
    L.append(f"| wall / sum of floors | **{fl['wall_over_sum']:.2f}** (goal <= 2) |")
    L.append(f"| peak RSS of any job | **{main['rss_max'] / 2**20:.0f} MiB** (target <= 1024) |")
    L.append("\nPer stage (from the timed `imugen` wrapper; span = first start to last end):\n")
    L.append("| stage | jobs | mean wall s | CPU s (sum) | sys s (sum) | span s | peak RSS MiB |")
    L.append("|---|--:|--:|--:|--:|--:|--:|")
    for k, s in sorted(main["stages"].items(), key=lambda kv: kv[1]["first_start"]):
        L.append(
            f"| {k} | {s['jobs']} | {s['wall_mean']:.2f} | {s['cpu_sum']:.0f} | {s['sys_sum']:.0f} | "
            f"{s['first_start']:.0f}-{s['last_end']:.0f} | {s['rss_max'] / 2**20:.0f} |"
        )
    fx = res.get("fixed")
    if fx:
        L.append(
            f"\nPer-job fixed cost (1-sequence job, warm caches): simulate "
            f"{fx['simulate']['wall_s']:.2f} s wall / {fx['simulate']['cpu_s']:.2f} s CPU, "
            f"navigate {fx['navigate']['wall_s']:.2f} s / {fx['navigate']['cpu_s']:.2f} s; "
            f"bare Python start {fx['python_startup_s']:.2f} s."
        )
    dr = res.get("dry_run")
    if dr:
        L.append("\nSnakemake DAG + dry-run (`snakemake -n`, whole process):\n")
        L.append("| configuration | jobs | s |\n|---|--:|--:|")
        for k, v in dr.items():
            L.append(f"| {k} | {v['jobs']} | {v['s']:.1f} |")
        if res.get("slurm_plugin_import_s") is not None:
            L.append(
                f"\n(Import of the SLURM executor plugin alone, paid by every Snakemake start: "
                f"{res['slurm_plugin_import_s']:.1f} s.)"
            )
    if res.get("growth"):
        L.append("\nCost growth (clean runs, target all):\n")
        L.append(
            "| N | rate Hz | M | shards | work (sample-seq.) | wall s | CPU s | bytes | "
            "peak RSS MiB | floors s | wall/floors |"
        )
        L.append("|--:|--:|--:|--:|--:|--:|--:|--:|--:|--:|--:|")
        for g in res["growth"]:
            L.append(
                f"| {g['sequences']} | {g['rate_hz']:g} | {g['per_shard']} | {g['shards']} | "
                f"{g['work']:.3g} | {g['wall_s']:.0f} | {g['cpu_s']:.0f} | "
                f"{g['bytes']['total'] / 1e9:.3g} GB | {g['rss_max'] / 2**20:.0f} | "
                f"{g['floors']['sum_s']:.0f} | {g['floors']['wall_over_sum']:.2f} |"
            )
        f = res["fits"]
        L.append(
            f"\nFit over these runs: wall = {f['wall'][0]:.1f} s + {f['wall'][1] * 1e9:.3g} s per "
            f"1e9 sample-sequences; bytes = {f['bytes'][0] / 1e6:.0f} MB + "
            f"{f['bytes'][1]:.2f} bytes per sample-sequence."
        )
    po = res.get("per_shard_overhead")
    if po:
        L.append(
            f"\nPer-shard overhead: {po['sequences']} sequences in {po['shards'][0]} then "
            f"{po['shards'][1]} shards: {po['wall_s'][0]:.0f} s then {po['wall_s'][1]:.0f} s wall, "
            f"{po['cpu_s'][0]:.0f} s then {po['cpu_s'][1]:.0f} s CPU: "
            f"{po['wall_per_extra_shard_s']:.2f} s wall and {po['cpu_per_extra_shard_s']:.2f} s CPU "
            "per extra shard (two jobs: simulate and navigate)."
        )
    if res.get("storage"):
        L.append("\nStorage choices on the first rows of a real shard (write to the page cache):\n")
        L.append(
            "| variant | bytes/row | size/raw | write MB/s | read MB/s |\n|---|--:|--:|--:|--:|"
        )
        for s in res["storage"]:
            L.append(
                f"| {s['variant']} | {s['bytes_per_row']:.1f} | {s['file_over_raw']:.3f} | "
                f"{s['write_MB_per_s']:.0f} | {s['read_MB_per_s']:.0f} |"
            )
    return "\n".join(L) + "\n"


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sequences", type=int, default=10_000)
    ap.add_argument("--per-shard", type=int, default=250)
    ap.add_argument("--grade", default="industrial")
    ap.add_argument("--scratch", default="/tmp/imugen-scale")
    ap.add_argument("--cores", type=int, default=2)
    ap.add_argument(
        "--growth",
        nargs="*",
        default=["100@100", "1000@100", "1000@100/50", "1000@10", "10000@10", "100@1000"],
        help="extra runs N@HZ[/M] (M default: the constant-work sizing rule)",
    )
    ap.add_argument("--skip-growth", action="store_true")
    ap.add_argument("--skip-storage", action="store_true")
    ap.add_argument("--keep", action="store_true", help="keep the working directories")
    ap.add_argument("--quick", action="store_true", help="smoke test: small N everywhere")
    ap.add_argument("--out", default=str(OUT))
    a = ap.parse_args()
    if a.quick:
        a.sequences = 200
        a.per_shard = 50
        a.growth = ["20@100", "100@10"]
    scratch = Path(a.scratch)
    scratch.mkdir(parents=True, exist_ok=True)
    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    t_start = time.time()
    res: dict = {"machine": machine(), "cores": a.cores, "grade": a.grade}
    log(f"machine: {res['machine']}")

    log("disk: dd 2 GiB conv=fdatasync ...")
    disk = dd_rate(scratch, 256 if a.quick else 2048)
    log(f"  {disk['bytes_per_s'] / 1e6:.0f} MB/s")

    log("dry runs ...")
    dr = {}
    for label, m in ((f"{a.sequences} seq., M={a.per_shard}", a.per_shard),
                     (f"{a.sequences} seq., M=10", max(10, math.ceil(a.sequences / 1000)))):  # fmt: skip
        wd = scratch / "dry"
        cfg = prepare(wd, a.sequences, m, 100.0, a.grade)
        dr[f"{label}, empty folder"] = dry_run(wd, cfg, a.cores)
        log(f"  {label}: {dr[f'{label}, empty folder']}")
    shutil.rmtree(scratch / "dry")

    # warm-up (not counted): a 2-sequence workflow fills the numba caches and gives the truth
    # of the scene for the floors and the per-job fixed cost
    warm = run_workflow(scratch, "warmup", 2, 1, 100.0, a.grade, a.cores)
    truth = Path(warm["workdir"]) / "results" / "paper" / "truth.parquet"
    log("floors: normals, mechanization ...")
    rates = {
        "disk": disk,
        "normals_per_s": normals_rate(),
        "normals_per_sample": normals_per_sample(truth, a.grade),
        "mech_per_s": mech_rate(truth),
    }
    res["rates"] = rates
    log(
        f"  normals {rates['normals_per_s']:.3g}/s/core x {rates['normals_per_sample']:g}/sample; "
        f"kernel {rates['mech_per_s'] / 1e6:.1f} M/s/core"
    )
    res["fixed"] = job_fixed_cost(scratch, truth, a.grade)
    log(f"  fixed per-job cost: {res['fixed']}")
    shutil.rmtree(warm["workdir"])

    main_run = run_workflow(scratch, "main", a.sequences, a.per_shard, 100.0, a.grade, a.cores)
    main_run["floors"] = floors(main_run, rates, a.cores)
    res["main"] = main_run
    cfg = Path(main_run["workdir"]) / "config.json"
    dr[f"{a.sequences} seq., M={a.per_shard}, finished (nothing to do)"] = dry_run(
        Path(main_run["workdir"]), cfg, a.cores
    )
    res["dry_run"] = dr
    log(f"  dry run of the finished folder: {dr}")
    # Snakemake imports its installed executor plugins at start; the SLURM plugin runs
    # `scontrol show config`, which waits ~9 s when SLURM's tools are installed but no
    # controller answers. Time that import alone, to tell it apart from the DAG.
    t0 = time.perf_counter()
    r = subprocess.run(
        [sys.executable, "-c", "import snakemake_executor_plugin_slurm"], capture_output=True
    )
    res["slurm_plugin_import_s"] = time.perf_counter() - t0 if r.returncode == 0 else None
    # partial results now, in case a later step fails
    (out / "scale.json").write_text(json.dumps(res, indent=1, default=float))

    if not a.skip_storage:
        log("storage choices ...")
        shard = (
            Path(main_run["workdir"]) / "results" / "paper" / "imu" / a.grade / "shard-000.parquet"
        )
        res["storage"] = storage_bench(shard, scratch, rows=1 << (20 if a.quick else 22))
    if not a.keep:
        shutil.rmtree(main_run["workdir"])

    runs = [main_run]
    if not a.skip_growth:
        growth = []
        for spec in a.growth:
            nhz, _, m = spec.partition("/")
            n, _, hz = nhz.partition("@")
            n, hz = int(n), float(hz)
            per = int(m) if m else nice_shard_size(n, round(619 * hz) + 1)
            name = f"n{n}_hz{hz:g}" + (f"_m{per}" if m else "")
            r = run_workflow(scratch, name, n, per, hz, a.grade, a.cores)
            r["floors"] = floors(r, rates, a.cores)
            r["explicit_m"] = bool(m)
            if not a.keep:
                shutil.rmtree(r["workdir"])
            growth.append(r)
        res["growth"] = sorted([main_run, *growth], key=lambda r: (r["work"], r["per_shard"]))
        runs = res["growth"]
        base = [r for r in runs if not r.get("explicit_m")]
        res["fits"] = {
            "wall": fit_line([r["work"] for r in base], [r["wall_s"] for r in base]),
            "bytes": fit_line([r["work"] for r in base], [r["bytes"]["total"] for r in base]),
        }
        # per-shard overhead: the same N and rate in more, smaller shards
        for r in runs:
            if r.get("explicit_m"):
                same = [
                    q
                    for q in base
                    if (q["sequences"], q["rate_hz"]) == (r["sequences"], r["rate_hz"])
                ]
                if same:
                    q = same[0]
                    extra = r["shards"] - q["shards"]
                    res["per_shard_overhead"] = {
                        "sequences": r["sequences"],
                        "shards": [q["shards"], r["shards"]],
                        "wall_s": [q["wall_s"], r["wall_s"]],
                        "cpu_s": [q["cpu_s"], r["cpu_s"]],
                        "wall_per_extra_shard_s": (r["wall_s"] - q["wall_s"]) / extra,
                        "cpu_per_extra_shard_s": (r["cpu_s"] - q["cpu_s"]) / extra,
                    }
        chart(runs, res["fits"], out / "scale_growth")
    res["benchmark_wall_s"] = time.time() - t_start
    (out / "scale.json").write_text(json.dumps(res, indent=1, default=float))
    md = markdown(res)
    (out / "scale.md").write_text(md)
    print(md)
    log(f"done in {res['benchmark_wall_s'] / 60:.1f} min; results in {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
