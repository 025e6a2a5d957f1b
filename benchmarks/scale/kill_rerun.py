"""Kill a whole ``snakemake -j2`` run mid-write, re-run it, compare with a clean run (on demand).

The unit test ``tests/system/test_faults.py`` kills one ``imugen simulate`` job; this script does it at
the workflow level, as a lost node or an out-of-memory kill would: it starts the workflow on a
small configuration, waits until a shard is being written (a ``.shard-*.tmp`` file is growing),
SIGKILLs Snakemake and its jobs (the whole process group), then runs Snakemake again in the same
folder (``--unlock`` first: a killed Snakemake leaves its lock behind) and compares every result
file, byte for byte, with those of an uninterrupted run in another folder.

Usage: python benchmarks/scale/kill_rerun.py [--scratch DIR] [--sequences 60] [--per-shard 20]
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent))

from bench_scale import config, snakemake_cmd  # noqa: E402


def digests(results: Path) -> dict[str, str]:
    out = {}
    for p in sorted(results.rglob("*")):
        if p.is_file() and p.suffix in (".parquet", ".csv", ".json"):
            out[str(p.relative_to(results))] = hashlib.sha256(p.read_bytes()).hexdigest()
    return out


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scratch", default="/tmp/imugen-kill")
    ap.add_argument("--sequences", type=int, default=60)
    ap.add_argument("--per-shard", type=int, default=20)
    a = ap.parse_args()
    scratch = Path(a.scratch)
    shutil.rmtree(scratch, ignore_errors=True)
    cfg_doc = config(a.sequences, a.per_shard, 100.0, "industrial")
    cfg_doc["grades"]["consumer"] = {}
    target = "results/paper/rmse.csv"
    runs = {}
    for name in ("clean", "killed"):
        wd = scratch / name
        wd.mkdir(parents=True)
        (wd / "config.json").write_text(json.dumps(cfg_doc))
        runs[name] = wd
    env = dict(os.environ, PATH=f"{Path(sys.executable).parent}:{os.environ.get('PATH', '')}")

    def snake(wd, *extra, **kw):
        return snakemake_cmd(wd, wd / "config.json", 2, *extra, target)

    t0 = time.time()
    subprocess.run(snake(runs["clean"]), env=env, check=True, capture_output=True)
    print(f"clean run: {time.time() - t0:.1f} s")

    wd = runs["killed"]
    proc = subprocess.Popen(
        snake(wd), env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
        start_new_session=True,
    )  # fmt: skip
    imu = wd / "results" / "paper" / "imu"
    seen = None
    deadline = time.time() + 600
    while proc.poll() is None and time.time() < deadline:
        try:
            tmps = list(imu.rglob(".shard-*.tmp")) if imu.exists() else []
            big = [p for p in tmps if p.stat().st_size > 1 << 20]  # a row group is on disk
        except FileNotFoundError:  # renamed while looking
            continue
        if big:
            done = list(imu.rglob("shard-*.labels.parquet"))
            seen = (sorted(str(p.relative_to(wd)) for p in big), len(done))
            break
        time.sleep(0.01)
    os.killpg(proc.pid, signal.SIGKILL)
    proc.wait()
    if seen is None:
        print("the workflow finished before it could be killed mid-write")
        return 1
    time.sleep(0.5)
    left = sorted(str(p.relative_to(wd)) for p in imu.rglob("*") if p.is_file())
    print(f"killed while writing {seen[0]} ({seen[1]} shards complete); files left: {len(left)}")
    stray = [p for p in left if Path(p).name.startswith(".") and not p.endswith(".tmp")]
    print(f"  temporaries left: {sum(p.endswith('.tmp') for p in left)}; other hidden: {stray}")
    r = subprocess.run(snake(wd), env=env, capture_output=True, text=True)
    if r.returncode:
        print("rerun without --unlock failed as expected:", "LockException" in r.stdout + r.stderr)
        subprocess.run(snake(wd, "--unlock"), env=env, check=True, capture_output=True)
        t1 = time.time()
        r = subprocess.run(snake(wd), env=env, capture_output=True, text=True)
        print(f"rerun after --unlock: exit {r.returncode}, {time.time() - t1:.1f} s")
    if r.returncode:
        print(r.stdout[-3000:], r.stderr[-3000:])
        return 1
    import pyarrow.parquet as pq

    a_, b_ = digests(runs["clean"] / "results"), digests(wd / "results")
    tmps = [p for p in (wd / "results").rglob("*.tmp")]
    print(f"result files compared: {len(a_)}; same set of files: {set(a_) == set(b_)}")
    same = set(a_) == set(b_)
    for k in sorted(set(a_) & set(b_)):
        if a_[k] == b_[k]:
            continue
        pa_, pb_ = runs["clean"] / "results" / k, wd / "results" / k
        data_same = k.endswith(".parquet") and pq.read_table(pa_).equals(pq.read_table(pb_))
        same &= data_same
        meta = ""
        if data_same:
            ma = json.loads(pq.read_schema(pa_).metadata[b"imugen"])
            mb = json.loads(pq.read_schema(pb_).metadata[b"imugen"])
            meta = ", ".join(x for x in ma if ma[x] != mb.get(x))
        print(f"  bytes differ: {k}; data identical: {data_same}; metadata keys differing: {meta}")
    print(f"all data identical to the clean run: {same}")
    print(f"temporaries left after the rerun: {len(tmps)}")
    shutil.rmtree(scratch, ignore_errors=True)
    return 0 if same and not tmps else 1


if __name__ == "__main__":
    sys.exit(main())
