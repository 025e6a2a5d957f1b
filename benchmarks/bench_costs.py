"""Costs a user must plan for: disk and memory per sequence, measured on a small run, projected.

Runs the workflow in a scratch folder on the paper's trajectory (620 s) at ``--rate-hz``
(100 Hz), one grade (``consumer``), ``--sequences`` sequences (20, shards of 10) with
``simulate.series: true`` and ``exports.mat: true``, GNSS off, and measures:

- the bytes each kind of output takes per sample-sequence (IMU shards with their series and
  labels, MATLAB files), per sequence-second (navigation errors) and per sample (truth);
- the training loader's peak memory above its imports (``WindowDataset(in_memory=True)``, the
  ``effective_error`` target, windows of 200: what tutorial 2 does), in a child process, per
  sample-sequence;
- the run's wall and CPU seconds (all its jobs), and the machine's load.

It then projects these to ``--project-sequences`` sequences of a ``--project-minutes`` route
(1,000 of 8.5 minutes by default), with and without the series, and writes the table
(``--write-docs``: ``docs/data/costs.md``, which the Costs page includes; else
``benchmarks/results/costs.md``). The time per sequence comes from ``bench_cost.py``'s fit,
quoted on the page.

Usage: python benchmarks/bench_costs.py [--sequences 20] [--rate-hz 100] [--write-docs]
"""

from __future__ import annotations

import argparse
import datetime as dt
import json
import os
import resource
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
DOCS_FILE = REPO / "docs" / "data" / "costs.md"
ROUTE = "paper"
LOADER = """
import resource, sys
from imugen.dataset import WindowDataset, find_routes
base = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
ds = WindowDataset(find_routes(sys.argv[1], grade="consumer"), window=200, stride=200,
                   target="effective_error", in_memory=True)
x, y = ds.get_batch(list(range(8)))
peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
print(base * 1024, peak * 1024)
"""


def config(n: int, per_shard: int, rate_hz: float) -> dict:
    return {
        "routes": {
            ROUTE: {
                "file": str(REPO / "resources" / "paper" / "seed_reference_trajectory_enu.txt"),
                "origin": [31.63, -7.99, 480.6],
                "dt_s": 1.0,
            }
        },
        "truth": {"rate_hz": rate_hz, "earth": "flat"},
        "grades": {"consumer": {}},
        "simulate": {"sequences": n, "sequences_per_shard": per_shard, "series": True},
        "allan": {"static_s": 60, "rate_hz": rate_hz, "sequences": 1},
        "exports": {"mat": True},
    }


def size(paths) -> int:
    return sum(p.stat().st_size for p in paths if p.is_file())


def human(n_bytes: float) -> str:
    for unit, scale in (("TB", 1e12), ("GB", 1e9), ("MB", 1e6), ("kB", 1e3)):
        if n_bytes >= scale:
            return f"{n_bytes / scale:.3g} {unit}"
    return f"{n_bytes:.0f} B"


def git_version() -> str:
    r = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=REPO, capture_output=True)
    return r.stdout.decode().strip() or "unknown"


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sequences", type=int, default=20)
    ap.add_argument("--per-shard", type=int, default=10)
    ap.add_argument("--rate-hz", type=float, default=100.0)
    ap.add_argument("--project-sequences", type=int, default=1000)
    ap.add_argument("--project-minutes", type=float, default=8.5)
    ap.add_argument("--scratch", type=Path, help="keep the run here (default: a temporary one)")
    ap.add_argument("--write-docs", action="store_true", help=f"write {DOCS_FILE.name}")
    a = ap.parse_args(argv)
    work = a.scratch or Path(tempfile.mkdtemp(prefix="imugen-costs-"))
    work.mkdir(parents=True, exist_ok=True)
    (work / "config.json").write_text(json.dumps(config(a.sequences, a.per_shard, a.rate_hz)))
    env = {**os.environ, "PYTHONPATH": str(REPO / "src")}
    load0 = os.getloadavg()
    ru0 = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    cmd = [sys.executable, "-m", "snakemake", "-s", str(REPO / "Snakefile"), "-d", str(work)]
    cmd += ["--configfile", str(work / "config.json"), "-j2", "--quiet"]
    subprocess.run(cmd, check=True, env=env, cwd=work)
    wall = time.perf_counter() - t0
    ru1 = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (ru1.ru_utime - ru0.ru_utime) + (ru1.ru_stime - ru0.ru_stime)
    load1 = os.getloadavg()

    import pyarrow.parquet as pq

    route = work / "results" / ROUTE
    truth = route / "truth.parquet"
    K = pq.ParquetFile(truth).metadata.num_rows
    work_ss = a.sequences * K  # sample-sequences
    seconds = a.sequences * (K - 1) / a.rate_hz  # sequence-seconds
    imu = size((route / "imu").rglob("*.parquet"))
    nav = size((route / "nav").rglob("*.parquet"))
    mat = size((route / "datasets").rglob("*.mat"))
    out = subprocess.run(
        [sys.executable, "-c", LOADER, str(work / "results")],
        check=True,
        capture_output=True,
        text=True,
        env=env,
    )
    base, peak = (int(x) for x in out.stdout.split())
    loader = (peak - base) / work_ss
    per = {
        "imu": imu / work_ss,
        "mat": mat / work_ss,
        "nav": nav / seconds,
        "truth": truth.stat().st_size / K,
        "loader": loader,
    }
    # the projection: N sequences of a route of T minutes at the same rate
    N = a.project_sequences
    Kp = round(a.project_minutes * 60 * a.rate_hz) + 1
    Wp = N * Kp
    no_series = (
        24.0  # bytes per sample-sequence of a shard without series: 6 float32, implicit clock
    )
    rows = [
        ("IMU shards with `series: true` (+ labels)", per["imu"], "sample-sequence", per["imu"] * Wp),
        ("IMU shards without series", no_series, "sample-sequence", no_series * Wp),
        ("MATLAB files (`exports.mat`, with series)", per["mat"], "sample-sequence", per["mat"] * Wp),
        ("navigation errors (1 Hz)", per["nav"], "sequence-second", per["nav"] * N * (Kp - 1) / a.rate_hz),
        ("truth (once per route)", per["truth"], "sample", per["truth"] * Kp),
        ("training loader in memory (`effective_error` target)", per["loader"], "sample-sequence", per["loader"] * Wp),
    ]  # fmt: skip
    total = per["imu"] * Wp + per["mat"] * Wp + rows[3][3] + rows[4][3]
    when = dt.datetime.now(dt.UTC).strftime("%Y-%m-%d %H:%M UTC")
    lines = [
        "<!-- written by `python benchmarks/bench_costs.py --write-docs`; do not edit by hand -->",
        "",
        f"Measured {when} by `python benchmarks/bench_costs.py --write-docs` at commit "
        f"`{git_version()}`, {os.cpu_count()} CPUs: the paper's trajectory at "
        f"{a.rate_hz:g} Hz ({K} samples), `consumer`, {a.sequences} sequences in shards of "
        f"{a.per_shard}, `series: true`, `exports.mat: true`; the run took {wall:.0f} s wall "
        f"and {cpu:.0f} CPU-s (all its jobs, Allan check included), load average "
        f"{load0[0]:.1f} before and {load1[0]:.1f} after. Projected to {N:,} sequences of a "
        f"{a.project_minutes:g}-minute route at {a.rate_hz:g} Hz ({Wp:.3g} sample-sequences):",
        "",
        "| what | measured | per | projected |",
        "|---|---|---|---|",
    ]
    lines += [f"| {w} | {v:.3g} bytes | {u} | {human(p)} |" for w, v, u, p in rows]
    lines += [
        "",
        f"Written in all, with the series and the MATLAB files: **{human(total)}**; the "
        f"training loader holds **{human(per['loader'] * Wp)}** in memory "
        "(`in_memory=False` reads memory-mapped caches instead: the page cache holds what fits).",
        "",
    ]
    text = "\n".join(lines)
    dest = DOCS_FILE if a.write_docs else REPO / "benchmarks" / "results" / "costs.md"
    dest.parent.mkdir(parents=True, exist_ok=True)
    tmp = dest.with_name(dest.name + ".tmp")
    tmp.write_text(text)
    tmp.replace(dest)
    print(text)
    if a.scratch is None:
        shutil.rmtree(work, ignore_errors=True)


if __name__ == "__main__":
    main()
