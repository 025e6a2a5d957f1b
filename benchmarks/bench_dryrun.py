"""Cost of planning a run with many shards: ``snakemake -n`` (run on demand, not a test).

Scene: the shipped example route, ``--grades`` preset grades, ``--shards`` shards of one
sequence (``simulate.sequences_per_shard: 1``), everything else the schema's defaults; a scratch
working folder. Each pass runs ``snakemake -n --quiet rules`` with the given ``Snakefile``
(default this checkout's; ``--snakefile`` another checkout's, for before/after) and reports
wall seconds, CPU seconds of Snakemake (children's user + system time) and the load average;
``--calls`` also counts Python function calls under cProfile (slow, but the same on a busy
machine). Per-job figures subtract a 2-shard run of the same scene (start-up and parsing).

Usage: python benchmarks/bench_dryrun.py [--shards 10000] [--grades 1] [--repeat 3]
       [--snakefile PATH] [--calls]
"""

from __future__ import annotations

import argparse
import os
import pstats
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
PRESETS = ["consumer", "industrial", "tactical", "navigation"]


def config(shards: int, grades: int) -> str:
    return (
        f"routes:\n  example: {{file: {REPO / 'resources' / 'example_route.kml'}}}\n"
        f"grades: {{{', '.join(f'{g}: {{}}' for g in PRESETS[:grades])}}}\n"
        f"simulate: {{sequences: {shards}, sequences_per_shard: 1}}\n"
    )


def one_pass(workdir: Path, snakefile: Path, calls: bool) -> dict:
    cmd = [sys.executable]
    prof = workdir / "prof.out"
    if calls:
        cmd += ["-m", "cProfile", "-o", str(prof)]
    cmd += ["-m", "snakemake", "-s", str(snakefile), "-d", str(workdir), "-n", "--quiet", "rules"]
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    proc = subprocess.run(cmd, capture_output=True, text=True)
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if proc.returncode != 0:
        sys.exit(proc.stderr[-2000:])
    out = {
        "wall_s": wall,
        "cpu_s": (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime),
        "load": os.getloadavg()[0],
    }
    if calls:
        out["calls"] = pstats.Stats(str(prof)).total_calls
    return out


def scene(shards: int, grades: int, snakefile: Path, repeat: int, calls: bool) -> list[dict]:
    with tempfile.TemporaryDirectory(prefix="imugen-dryrun-") as d:
        wd = Path(d)
        (wd / "config").mkdir()
        (wd / "config" / "config.yaml").write_text(config(shards, grades))
        return [one_pass(wd, snakefile, calls) for _ in range(repeat)]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--shards", type=int, default=10000)
    ap.add_argument("--grades", type=int, default=1, choices=range(1, len(PRESETS) + 1))
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--snakefile", type=Path, default=REPO / "Snakefile")
    ap.add_argument("--calls", action="store_true", help="count function calls (cProfile)")
    a = ap.parse_args()
    base = min(scene(2, a.grades, a.snakefile, a.repeat, a.calls), key=lambda r: r["cpu_s"])
    runs = scene(a.shards, a.grades, a.snakefile, a.repeat, a.calls)
    jobs = a.shards * a.grades
    for r in runs:
        line = (
            f"{a.snakefile}: {a.shards} shards x {a.grades} grades: wall {r['wall_s']:.1f} s, "
            f"CPU {r['cpu_s']:.1f} s ({1e3 * (r['cpu_s'] - base['cpu_s']) / jobs:.2f} CPU-ms per "
            f"shard job beyond the {base['cpu_s']:.1f} s of a 2-shard run), load {r['load']:.1f}"
        )
        if a.calls:
            line += f", {(r['calls'] - base['calls']) / jobs:,.0f} calls per shard job"
        print(line, flush=True)


if __name__ == "__main__":
    main()
