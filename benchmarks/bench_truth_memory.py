"""Peak memory and CPU of the truth job (``imugen truth``) per IMU sample (run on demand).

Each configuration runs in a fresh child process (``imugen truth`` itself, under this script's
``--child`` mode): peak RSS (``ru_maxrss``), CPU seconds (user + system) and wall time of the
child; the load average is printed before and after each run (the machine is shared). With
``--where``, a thread samples the child's RSS every 20 ms and records the main thread's stack at
the highest sample: where the peak is.

Routes: the ENU Parquet of any route (``--enu``), or a synthetic untimed drive
(``--synthetic-km``: a gently winding road of vertices 500 m apart heading north-east from
45 N 7 E, written by ``imugen.truth.build.enu_table``). The per-sample cost is the slope
between two sizes (``--rates``: the same route at two IMU rates), the base the intercept.

Usage::

    python benchmarks/bench_truth_memory.py --synthetic-km 500 --earth flat geodetic \
        --rates 20 100 [--vehicle car] [--where] [--json out.json]
    python benchmarks/bench_truth_memory.py --enu enu.parquet --earth geodetic --rates 2 20
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import tempfile
import threading
import time
import traceback
from pathlib import Path


def _rss_b() -> int:
    with open("/proc/self/statm") as fh:
        return int(fh.read().split()[1]) * os.sysconf("SC_PAGE_SIZE")


def _child(args) -> None:
    """Run one truth job in this process; print one JSON line of its figures."""
    from imugen.truth.options import TruthOptions
    from imugen.truth.stage import run

    peak = {"rss": 0, "stack": ""}
    main = threading.main_thread().ident
    stop = threading.Event()

    def sample():
        while not stop.wait(0.02):
            r = _rss_b()
            if r > peak["rss"]:
                peak["rss"] = r
                frame = sys._current_frames().get(main)
                peak["stack"] = "".join(traceback.format_stack(frame, limit=12)) if frame else ""

    th = threading.Thread(target=sample, daemon=True)
    if args.where:
        th.start()
    c0, w0 = time.process_time(), time.perf_counter()
    opts = TruthOptions(rate_hz=args.rate, earth=args.earth[0], vehicle=args.vehicle)
    meta = run(args.enu, args.out, opts)
    cpu, wall = time.process_time() - c0, time.perf_counter() - w0
    stop.set()
    ru = resource.getrusage(resource.RUSAGE_SELF)
    res = {
        "samples": meta["samples"],
        "earth": meta["earth"],
        "cpu_s": cpu,
        "user_s": ru.ru_utime,
        "sys_s": ru.ru_stime,
        "wall_s": wall,
        "peak_rss_b": ru.ru_maxrss * 1024,
        "file_b": Path(args.out).stat().st_size,
    }
    if args.where:
        res["sampled_peak_b"] = peak["rss"]
        res["peak_stack"] = peak["stack"]
    print("RESULT " + json.dumps(res))


def synthetic_enu(km: float, out: Path) -> Path:
    """A winding untimed road of ``km`` km (vertices 500 m apart) written as an ENU Parquet."""
    import numpy as np

    from imugen.tables import enu as tenu
    from imugen.truth.build import enu_table

    n = int(km * 2) + 1
    s = np.arange(n) * 500.0
    heading = np.radians(45.0) + 0.3 * np.sin(s / 7000.0)  # bends ~ 7 km apart
    step = 500.0 * np.c_[np.cos(heading), np.sin(heading)]
    en = np.vstack([[0.0, 0.0], np.cumsum(step[:-1], axis=0)])
    up = 40.0 * np.sin(s / 5000.0)
    df, meta = enu_table(np.c_[en, up], None, (45.0, 7.0, 300.0))
    tenu.write(df, meta, out)
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--enu", type=Path, help="ENU Parquet of the route")
    ap.add_argument("--synthetic-km", type=float, help="synthetic untimed road of this length")
    ap.add_argument("--earth", nargs="+", default=["flat", "geodetic"])
    ap.add_argument("--rates", nargs="+", type=float, default=[20.0, 100.0])
    ap.add_argument("--vehicle", default="car")
    ap.add_argument("--where", action="store_true", help="record the stack at the peak RSS")
    ap.add_argument("--keep", type=Path, help="keep the truth files in this folder")
    ap.add_argument("--json", type=Path, help="write the results here")
    ap.add_argument("--child", action="store_true", help=argparse.SUPPRESS)
    ap.add_argument("--rate", type=float, help=argparse.SUPPRESS)
    ap.add_argument("--out", type=Path, help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.child:
        _child(args)
        return
    tmp = Path(tempfile.mkdtemp(prefix="bench_truth_memory."))
    enu = args.enu or synthetic_enu(args.synthetic_km or 500.0, tmp / "enu.parquet")
    outdir = args.keep or tmp
    outdir.mkdir(parents=True, exist_ok=True)
    rows = []
    print(f"route {enu}; load average at start {os.getloadavg()[0]:.1f}")
    for earth in args.earth:
        for rate in args.rates:
            out = outdir / f"truth_{earth}_{rate:g}hz.parquet"
            cmd = [sys.executable, __file__, "--child", "--enu", str(enu), "--out", str(out)]
            cmd += ["--earth", earth, "--rate", str(rate), "--vehicle", args.vehicle]
            cmd += ["--where"] if args.where else []
            load0 = os.getloadavg()[0]
            p = subprocess.run(cmd, capture_output=True, text=True)
            line = [ln for ln in p.stdout.splitlines() if ln.startswith("RESULT ")]
            if p.returncode or not line:
                print(p.stderr[-2000:])
                raise SystemExit(f"{earth} {rate} Hz failed")
            r = json.loads(line[-1][7:])
            r.update(rate_hz=rate, earth_requested=earth, load_before=load0)
            r["load_after"] = os.getloadavg()[0]
            rows.append(r)
            print(
                f"{earth:9s} {rate:6g} Hz K={r['samples']:>10,d}  load {load0:4.1f}->"
                f"{r['load_after']:4.1f}  cpu {r['cpu_s']:7.1f} s (user {r['user_s']:.1f}, sys "
                f"{r['sys_s']:.1f})  wall {r['wall_s']:7.1f} s  peak RSS "
                f"{r['peak_rss_b'] / 1e6:8.1f} MB  ({r['peak_rss_b'] / r['samples']:6.0f} B/sample, "
                f"{1e6 * r['cpu_s'] / r['samples']:5.1f} us CPU/sample)  file "
                f"{r['file_b'] / r['samples']:.0f} B/sample",
                flush=True,
            )
            if args.where:
                print("  peak at:\n" + r["peak_stack"])
            if not args.keep:
                out.unlink(missing_ok=True)
        same = [r for r in rows if r["earth_requested"] == earth]
        if len(same) >= 2:
            a, b = same[0], same[-1]
            slope = (b["peak_rss_b"] - a["peak_rss_b"]) / (b["samples"] - a["samples"])
            base = a["peak_rss_b"] - slope * a["samples"]
            print(f"{earth}: peak RSS ~ {base / 1e6:.0f} MB + {slope:.0f} B per sample")
    if args.json:
        args.json.write_text(json.dumps(rows, indent=1))


if __name__ == "__main__":
    main()
