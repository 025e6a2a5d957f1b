"""Benchmark of the training loader against the ceiling (run on demand, not a test).

Scene: ``--routes`` routes, each a truth of ``--samples`` rows and ``--shards`` shards of
``--sequences`` sequences (float32 increments, row groups of 2^20 rows as ``imugen simulate``
writes them; random values, which decode like real ones). Windows of 200 x 6 float32, target
the true increments (200 x 6), batches of 64 drawn i.i.d. (a fresh permutation of all windows),
one core, page cache warm (every figure is the best of ``--repeat`` passes after a first one).

Measured:
* ceiling: the same Parquet read with pyarrow into one array (its time reported), then each
  batch sliced window by window and stacked (``ceiling``), or gathered by one fancy index per
  batch and array (``ceiling_fancy``): what a hand-written in-memory loader reaches;
* ``WindowDataset(in_memory=True)`` and the disk-backed ``WindowDataset`` (memory-mapped
  ``.npy`` caches), through ``get_batch`` and ``batches()``;
* the one-time cache conversion.
Wall and CPU seconds (``time.process_time``) and the load average are printed beside each.

Usage: python benchmarks/bench_loader.py [--routes 2] [--shards 2] [--sequences 25]
       [--samples 60000] [--batches 2000] [--out-dir DIR] [--json FILE]
"""

from __future__ import annotations

import argparse
import json
import os
import tempfile
import time
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from imugen import columns as col
from imugen.dataset import WindowDataset, find_routes

WINDOW, BATCH = 200, 64
X_COLS = [*col.DTHETA, *col.DV]


def make_scene(root: Path, routes: int, shards: int, seqs: int, K: int) -> None:
    """Truth and shards with the layout of the workflow's (random values)."""
    rng = np.random.default_rng(0)
    for r in range(routes):
        d = root / f"route{r}"
        d.mkdir(parents=True, exist_ok=True)
        truth = {c: rng.standard_normal(K) for c in col.TRUTH_COLUMNS}
        pq.write_table(pa.table(truth), d / "truth.parquet", row_group_size=1 << 20)
        for s in range(shards):
            ids = (r * shards + s) * seqs + np.arange(seqs)
            cols = {"sequence": np.repeat(ids, K).astype(np.int32)}
            cols[col.TIME] = np.tile(np.arange(K) * 0.01, seqs)
            for c in X_COLS:
                cols[c] = rng.standard_normal(seqs * K).astype(np.float32)
            p = d / "imu" / "consumer" / f"shard-{s:03d}.parquet"
            p.parent.mkdir(parents=True, exist_ok=True)
            pq.write_table(pa.table(cols), p, row_group_size=1 << 20)


def timed(fn, repeat: int) -> tuple[float, float]:
    """Best wall and CPU seconds of ``repeat`` calls after one warm-up call."""
    fn()
    best = (np.inf, np.inf)
    for _ in range(repeat):
        w, c = time.perf_counter(), time.process_time()
        fn()
        best = min(best, (time.perf_counter() - w, time.process_time() - c))
    return best


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--routes", type=int, default=2)
    ap.add_argument("--shards", type=int, default=2)
    ap.add_argument("--sequences", type=int, default=25)
    ap.add_argument("--samples", type=int, default=60_000)
    ap.add_argument("--batches", type=int, default=2000)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--out-dir", type=Path)
    ap.add_argument("--json", type=Path)
    a = ap.parse_args()
    os.environ.setdefault("OMP_NUM_THREADS", "1")
    pa.set_cpu_count(1)
    pa.set_io_thread_count(1)

    with tempfile.TemporaryDirectory(dir=a.out_dir) as tmp:
        root = Path(tmp)
        make_scene(root, a.routes, a.shards, a.sequences, a.samples)
        routes = find_routes(root, "consumer")
        nbytes = sum(p.stat().st_size for r in routes for p in r.shards)
        res = {"load_before": os.getloadavg()[0], "shard_bytes": nbytes}

        # ceiling: pyarrow reads everything into one array, then one fancy index per batch
        w, c = time.perf_counter(), time.process_time()
        xs, ts = [], []
        for r in routes:
            t = pq.read_table(r.truth, columns=X_COLS)
            ts.append(np.column_stack([x.to_numpy() for x in t.columns]).astype(np.float32))
            for p in r.shards:
                t = pq.read_table(p, columns=X_COLS)
                xs.append(np.column_stack([x.to_numpy() for x in t.columns]))
        X, T = np.concatenate(xs), np.concatenate(ts)
        res["ceiling_read_s"] = (time.perf_counter() - w, time.process_time() - c)
        K = a.samples
        nw = (K - 1) // WINDOW  # windows per sequence, stride = window
        nseq = len(X) // K
        seq_route = np.repeat(np.arange(a.routes), a.shards * a.sequences)
        total = nseq * nw
        rng = np.random.default_rng(1)
        offs = np.arange(WINDOW)

        def orders():
            reps = -(-a.batches * BATCH // total)
            order = np.concatenate([rng.permutation(total) for _ in range(reps)])
            for idx in order[: a.batches * BATCH].reshape(-1, BATCH):
                s, k0 = idx // nw, 1 + idx % nw * WINDOW
                yield s * K + k0, seq_route[s] * K + k0

        def ceiling():  # slices stacked
            for xr, tr in orders():
                np.stack([X[r : r + WINDOW] for r in xr]), np.stack([T[r : r + WINDOW] for r in tr])

        def ceiling_fancy():  # one fancy index per batch and array
            for xr, tr in orders():
                X[xr[:, None] + offs], T[tr[:, None] + offs]

        w, c = time.perf_counter(), time.process_time()
        WindowDataset(routes, window=WINDOW)  # converts each shard once
        res["cache_build_s"] = (time.perf_counter() - w, time.process_time() - c)
        res["cache_build_mb_per_s"] = nbytes / 1e6 / res["cache_build_s"][0]

        def loader(d):
            def run():
                done, epoch = 0, 0
                while done < a.batches:  # whole epochs of i.i.d. batches
                    for idx in d.batches(BATCH, seed=epoch, drop_last=True)[: a.batches - done]:
                        d.get_batch(idx)
                        done += 1
                    epoch += 1

            return run

        disk = WindowDataset(routes, window=WINDOW)
        mem = WindowDataset(routes, window=WINDOW, in_memory=True)
        assert len(disk) == total
        n = a.batches * BATCH
        runs = {
            "ceiling": ceiling,
            "ceiling_fancy": ceiling_fancy,
            "in_memory": loader(mem),
            "disk": loader(disk),
        }
        for name, fn in runs.items():
            wall, cpu = timed(fn, a.repeat)
            res[name] = {"windows_per_s": n / wall, "wall_s": wall, "cpu_s": cpu}
        res["load_after"] = os.getloadavg()[0]

    print(f"shards: {nbytes / 1e6:.0f} MB; {total:,} windows of {WINDOW} x 6, batch {BATCH}")
    print(f"load average {res['load_before']:.2f} -> {res['load_after']:.2f}")
    w, c = res["ceiling_read_s"]
    print(f"pyarrow read into one array: {w:.2f} s wall, {c:.2f} s CPU")
    w, c = res["cache_build_s"]
    print(f"cache build (once): {w:.2f} s wall, {c:.2f} s CPU")
    for name in ("ceiling", "ceiling_fancy", "in_memory", "disk"):
        r = res[name]
        print(
            f"{name:10s} {r['windows_per_s']:>10,.0f} windows/s  "
            f"({r['wall_s']:.2f} s wall, {r['cpu_s']:.2f} s CPU for {n:,} windows)"
        )
    if a.json:
        a.json.write_text(json.dumps(res, indent=1))


if __name__ == "__main__":
    main()
