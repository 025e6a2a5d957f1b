"""Benchmark of the stream (imugen.stream) against the NumPy normal-variate floor (on demand).

Scene: one synthetic route (a turning, accelerating body, ``--seconds`` at 100 Hz), grade
``--grade``; windows of 200 x 6 (``dtheta, dv``) with the target ``effective_error`` (200 x 6),
batches of ``--batch`` windows, ``--per-seq`` windows per fresh sequence, window mode (the
default: slow states drawn from their law at each window's start). One core: numba kernels are
single-threaded and BLAS threads are set to 1.

Measured in the same run, on the same windows:
* ``stream``: ``Stream.batch(n)`` for ``--batches`` batches (parameters drawn, seeds spawned,
  noise drawn, kernel run, float32 cast);
* ``floor``: only the standard normals those windows consume (float64, the stream's count
  per window), drawn by NumPy from the stream's bit generator
  (``Generator(SFC64).standard_normal(out=...)`` into a reused buffer: the same algorithm
  and the same numbers as the stream's, :mod:`imugen.core.sfc64`), one call per sequence:
  what drawing these normals through NumPy costs. ``floor_pcg64`` is the same with the shard
  path's PCG64;
* ``exact``: the exact mode (each sequence generated from turn-on), a few batches.
Windows per CPU-second (``time.process_time``) are the figure that does not depend on the
machine's other users; wall time and the 1-minute load average are printed beside.

Usage: python benchmarks/bench_stream.py [--grade consumer] [--batches 200] [--batch 256]
       [--per-seq 16] [--seconds 3600] [--json FILE]
"""

from __future__ import annotations

import argparse
import json
import os
import time

for _v in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "NUMBA_NUM_THREADS"):
    os.environ.setdefault(_v, "1")

import numpy as np  # noqa: E402

from imugen.stream import Stream  # noqa: E402
from imugen.stream.windows import normals_per_window  # noqa: E402


def truth(seconds: float, dt: float = 0.01) -> dict:
    t = np.arange(int(seconds / dt) + 1) * dt
    w = np.column_stack([0.3 * np.sin(0.07 * t), 0.05 * np.cos(0.5 * t), 0.1 * np.sin(0.01 * t)])
    f = np.column_stack([1.5 * np.sin(0.03 * t), 0.8 * np.cos(0.9 * t), 9.8 + 0.5 * np.sin(t)])
    dth = np.vstack([np.zeros(3), 0.5 * (w[1:] + w[:-1]) * dt])
    dv = np.vstack([np.zeros(3), 0.5 * (f[1:] + f[:-1]) * dt])
    return {"time_s": t, "omega_ib_b": w, "f_b": f, "dtheta": dth, "dv": dv}


def clock(fn):
    w0, c0 = time.perf_counter(), time.process_time()
    out = fn()
    return out, time.perf_counter() - w0, time.process_time() - c0


def main(argv=None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--grade", default="consumer")
    ap.add_argument("--batches", type=int, default=200)
    ap.add_argument("--batch", type=int, default=256)
    ap.add_argument("--per-seq", type=int, default=16)
    ap.add_argument("--seconds", type=float, default=3600.0)
    ap.add_argument("--json", default=None)
    a = ap.parse_args(argv)
    s = Stream({"bench": truth(a.seconds)}, a.grade, window=200, batch_size=a.batch,
               windows_per_sequence=a.per_seq, targets=["effective_error"], seed=1)  # fmt: skip
    s.batch(0)  # compile / load the kernels
    n = a.batches
    B = n * a.batch
    _, w_s, c_s = clock(lambda: [s.batch(i) for i in range(1, n + 1)])
    # the floor: the same number of normals (each window's, module imugen.stream.windows)
    from imugen.stream.windows import draw_params

    d = draw_params(1, 0, s.grades[0], s.enabled[0], False, 0, 0)
    per_window = normals_per_window(d.gyro, 200) + normals_per_window(d.accel, 200)
    buf = np.empty(per_window * a.per_seq)

    def floor(bitgen):
        rng = np.random.Generator(bitgen(1))
        for _ in range(B // a.per_seq):
            rng.standard_normal(out=buf)

    _, w_f, c_f = clock(lambda: floor(np.random.SFC64))
    _, w_p, c_p = clock(lambda: floor(np.random.PCG64))
    ne = max(2, n // 20)
    se = Stream({"bench": truth(a.seconds)}, a.grade, window=200, batch_size=a.batch,
                windows_per_sequence=a.per_seq, targets=["effective_error"], seed=1,
                exact=True)  # fmt: skip
    se.batch(0)
    _, w_e, c_e = clock(lambda: [se.batch(i) for i in range(1, ne + 1)])
    out = {
        "grade": a.grade,
        "batch": a.batch,
        "windows_per_sequence": a.per_seq,
        "normals_per_window": per_window,
        "load_1min": os.getloadavg()[0],
        "cpu_count": os.cpu_count(),
        "stream": {"windows": B, "wall_s": w_s, "cpu_s": c_s, "windows_per_cpu_s": B / c_s},
        "floor": {"windows": B, "wall_s": w_f, "cpu_s": c_f, "windows_per_cpu_s": B / c_f},
        "floor_pcg64": {"windows": B, "wall_s": w_p, "cpu_s": c_p, "windows_per_cpu_s": B / c_p},
        "exact": {
            "windows": ne * a.batch,
            "wall_s": w_e,
            "cpu_s": c_e,
            "windows_per_cpu_s": ne * a.batch / c_e,
            "route_s": a.seconds,
        },
    }
    out["stream_over_floor"] = c_s / c_f
    for k in ("stream", "floor", "floor_pcg64", "exact"):
        r = out[k]
        print(f"{k:11s} {r['windows']:8d} windows  {r['cpu_s']:7.2f} CPU-s  {r['wall_s']:7.2f} s  "
              f"{r['windows_per_cpu_s']:10,.0f} windows/CPU-s")  # fmt: skip
    print(f"normals per window {per_window}; stream / floor CPU = {out['stream_over_floor']:.2f}; "
          f"load {out['load_1min']:.2f} on {out['cpu_count']} cores")  # fmt: skip
    if a.json:
        with open(a.json, "w") as fh:
            json.dump(out, fh, indent=1)
    return out


if __name__ == "__main__":
    main()
