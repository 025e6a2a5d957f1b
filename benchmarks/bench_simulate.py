"""Benchmark of error injection and shard writing (run on demand, not a test).

Measures in one run:
* the normal-variate rate of NumPy's Generator (PCG64, ``standard_normal`` into a reused
  buffer of the injection's chunk shape, float64 and float32);
* the injection throughput of a shard (default 1,000 sequences x 62,000 samples, the paper
  scene at 100 Hz, grade ``industrial``) into a null sink, and its ratio to the bound set by the
  normals each sample needs (``normals/s / normals_per_sample``);
* the full ``simulate.run`` write of the same shard (wall time, bytes) and the peak RSS;
* Parquet write rates of random float data with/without dictionary encoding, float32/float64,
  no compression / snappy.

Usage: python benchmarks/bench_simulate.py [--sequences 1000] [--samples 62000]
       [--grade industrial] [--out-dir DIR] [--skip-write]
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import tempfile
import time
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from imugen.simulate import stage as S
from imugen.simulate.options import SimulateOptions
from imugen.simulate.plan import plan_shard
from imugen.simulate.sources import StaticTruth
from imugen.tables import shard as tshard


class _Null:
    def put(self, *a):
        pass


def rss_mb() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def normals_rate(dtype=np.float64, seconds=2.0, shape=(S.CHUNK, 3)) -> float:
    rng = np.random.default_rng(0)
    buf = np.empty(shape, dtype)
    rng.standard_normal(out=buf, dtype=dtype)
    n = 0
    t0 = time.perf_counter()
    while time.perf_counter() - t0 < seconds:
        rng.standard_normal(out=buf, dtype=dtype)
        n += buf.size
    return n / (time.perf_counter() - t0)


def injection(grade, M, K, rate_hz=100.0):
    tr = StaticTruth((K - 1) / rate_hz, rate_hz)
    S._loop(plan_shard(tr, SimulateOptions(grade=grade, sequences=2, seed=1, shard=0)), _Null())
    plan = plan_shard(tr, SimulateOptions(grade=grade, sequences=M, seed=1, shard=0))
    t0 = time.perf_counter()
    nps = S._loop(plan, _Null())
    el = time.perf_counter() - t0
    return M * tr.K / el, nps, el


def parquet_rates(rows=4_000_000, reps=2):
    out = {}
    rng = np.random.default_rng(1)
    d = tempfile.mkdtemp()
    for dt in (np.float32, np.float64):
        cols = {f"c{i}": rng.standard_normal(rows).astype(dt) for i in range(6)}
        tbl = pa.table(cols)
        nbytes = tbl.nbytes
        for dic in (True, False):
            for comp in ("none", "snappy"):
                best = 1e9
                for _ in range(reps):
                    p = os.path.join(d, "x.parquet")
                    t0 = time.perf_counter()
                    pq.write_table(
                        tbl, p, use_dictionary=dic, compression=comp, row_group_size=1 << 20
                    )
                    best = min(best, time.perf_counter() - t0)
                size = os.path.getsize(p)
                out[f"{np.dtype(dt).name} dict={dic} {comp}"] = {
                    "MB_per_s": nbytes / best / 1e6,
                    "file_over_raw": size / nbytes,
                }
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sequences", type=int, default=1000)
    ap.add_argument("--samples", type=int, default=62000)
    ap.add_argument("--grade", default="industrial")
    ap.add_argument("--out-dir", default=None)
    ap.add_argument("--skip-write", action="store_true")
    a = ap.parse_args()
    res = {"cpu_count": os.cpu_count()}
    res["normals_per_s_float64"] = normals_rate(np.float64)
    res["normals_per_s_float32"] = normals_rate(np.float32)
    sps, nps, el = injection(a.grade, a.sequences, a.samples)
    bound = res["normals_per_s_float64"] / nps
    res.update(
        {
            "grade": a.grade,
            "sequences": a.sequences,
            "samples": a.samples,
            "normals_per_sample": nps,
            "injection_samples_per_s": sps,
            "injection_s": el,
            "bound_samples_per_s": bound,
            "ratio": sps / bound,
            "peak_rss_mb_after_injection": rss_mb(),
        }
    )
    print(
        f"normals/s float64 {res['normals_per_s_float64']:.3e}  float32 {res['normals_per_s_float32']:.3e}"
    )
    print(
        f"injection {a.sequences} x {a.samples} ({a.grade}): {el:.1f} s, {sps:.3e} samples/s, "
        f"{nps:g} normals/sample, bound {bound:.3e} samples/s, ratio {sps / bound:.2f}"
    )
    if not a.skip_write:
        d = Path(a.out_dir or tempfile.mkdtemp())
        out = d / "bench_shard.parquet"
        t0 = time.perf_counter()
        opts = SimulateOptions(
            grade=a.grade, sequences=a.sequences, seed=1, shard=0,
            static_s=(a.samples - 1) / 100.0, rate_hz=100.0,
        )  # fmt: skip
        S.run(None, out, opts)
        el = time.perf_counter() - t0
        size = out.stat().st_size
        res.update(
            {
                "run_s": el,
                "shard_bytes": size,
                "run_MB_per_s_file": size / el / 1e6,
                "peak_rss_mb_after_write": rss_mb(),
            }
        )
        print(
            f"run (inject + write float32, no dictionary on floats): {el:.1f} s, "
            f"{size / 1e9:.2f} GB, peak RSS {rss_mb():.0f} MB"
        )
        out.unlink()
        tshard.labels_path(out).unlink()
    res["parquet"] = parquet_rates()
    for k, v in res["parquet"].items():
        print(f"parquet {k:28s} {v['MB_per_s']:7.0f} MB/s  size/raw {v['file_over_raw']:.3f}")
    print(json.dumps(res))


if __name__ == "__main__":
    main()
