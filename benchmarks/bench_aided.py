"""Aided-INS filter throughput (loosely-coupled error-state KF), per core.

Scene: a car on a 400 m x 200 m rectangle (imugen truth, 100 Hz, about 178 s), consumer IMU
(nominal draw, every configured term), standalone GNSS at 10 Hz with a 0.6/0.3/1.2 m lever arm.
The batch is tiled to ``--sequences`` sequences. The filter starts at the first sample
(``initial_state`` at the truth), so every sample is filtered; the alignment and the Python
set-up are excluded. Reported: million sample-sequences per second (Msps) for each option set,
by wall clock and per CPU-second of this process (the per-core figure when other jobs share
the cores), with the size of the error state (the default estimates the gyro's six
cross-coupling elements):

* p, v, psi, b_g, b_a only (15 states), GNSS position + velocity;
* + GNSS Gauss-Markov bias, gyro cross-coupling (24 states), the default;
* the default + NHC + ZUPT (a car);
* + gyro and accelerometer scale factors + NHC + ZUPT;
* the default + odometer scale factor + barometer drift + the odometer's two tick residuals
  + NHC + ZUPT + odometer (``abs``, 10 Hz) and barometer (``bmp388``, 10 Hz) updates;
* the default + NHC + ZUPT in ``wgs84``.

``--compile`` instead measures the filter kernel's numba compilation from a cold cache: in
fresh processes with ``NUMBA_CACHE_DIR`` an empty folder, the CPU seconds of the first
:func:`imugen.aid.filter.run` call minus those of the second (a tiny synthetic batch; every
option set shares one compiled signature).

``--outage`` instead measures the horizontal error at the end of a 30 s and a 60 s GNSS outage
starting at t = 100 s on the same scene (consumer and industrial, every configured error term,
levels drawn in the grade ranges, standalone receiver drawn in its ranges, filter tuned with
the grade's upper levels): median and 5-95 % over the sequences, with and without NHC
(without NHC the outage is free inertial navigation started from the filter's state).

Usage::

    python benchmarks/bench_aided.py [--sequences 512] [--repeat 3] [--json out.json]
    python benchmarks/bench_aided.py --outage [--sequences 200]
    python benchmarks/bench_aided.py --compile [--repeat 3]
"""

from __future__ import annotations

import os

for _v in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "NUMBA_NUM_THREADS"):
    os.environ.setdefault(_v, "1")

import argparse  # noqa: E402
import json  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
from types import SimpleNamespace  # noqa: E402

import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402

from imugen import truth as T  # noqa: E402
from imugen.aid import companions as CP  # noqa: E402
from imugen.aid import filter as A  # noqa: E402
from imugen.aid import gnss as G  # noqa: E402
from imugen.core.earth import OriginFrame, earth_rate_n  # noqa: E402
from imugen.simulate import stage as SIM  # noqa: E402

if not hasattr(A, "run"):  # before the filter became a package (issue 23): one module
    from imugen.aid.filter import ekf as A

ORIGIN = (45.0, 7.0, 200.0)


def scene(earth: str, M: int):
    pts = np.array(
        [[0, 0, 0], [400, 0, 0], [400, 200, 0], [0, 200, 0], [0, 0, 0], [400, 0, 0], [400, 200, 0]],
        float,
    )
    enu = pd.DataFrame(pts, columns=["e_m", "n_m", "u_m"])
    meta = {"origin": dict(zip(("lat_deg", "lon_deg", "alt_m"), ORIGIN, strict=True))}
    df, _ = T.build_truth(enu, meta, rate_hz=100.0, earth=earth, vehicle="car", verbose=False)
    frame = OriginFrame.from_deg(*ORIGIN, model=earth)
    t = df["time_s"].to_numpy()
    p = df[["e_m", "n_m", "u_m"]].to_numpy()
    v = df[["v_e_mps", "v_n_mps", "v_u_mps"]].to_numpy()
    q = df[["q_w", "q_x", "q_y", "q_z"]].to_numpy()
    w = df[["gyro_x_radps", "gyro_y_radps", "gyro_z_radps"]].to_numpy()
    base = min(M, 64)
    sh = SIM.simulate(df, "consumer", sequences=base, seed=1, draw="nominal")
    gn = G.simulate_gnss(
        t, p, v, q, w, "standalone", base, seed=1, lever_arm_b_m=(0.6, 0.3, 1.2),
        omega_ie_n=earth_rate_n(frame),
    )  # fmt: skip
    reps = -(-M // base)

    def tile(a):
        return np.ascontiguousarray(np.concatenate([a] * reps)[:M])

    od = CP.simulate_odometer(t, v, q, w, "abs", base, seed=1)
    ba = CP.simulate_barometer(t, p, frame, "bmp388", base, seed=1)
    ce = CP.filter_input(gn.index, base, od, ba, h0_m=frame.h0_m)
    from dataclasses import replace as _r

    ce = _r(ce, z=tile(ce.z), lever_b_m=tile(ce.lever_b_m), odo_sf_sd=tile(ce.odo_sf_sd),
            baro_sd_m=tile(ce.baro_sd_m), baro_tau_s=tile(ce.baro_tau_s),
            odo_tick_m=tile(ce.odo_tick_m))  # fmt: skip

    dth, dv = tile(sh.data["dtheta"]), tile(sh.data["dv"])
    from dataclasses import replace

    gn = replace(
        gn,
        p_n=tile(gn.p_n),
        v_n=tile(gn.v_n),
        sigma_p_n=tile(gn.sigma_p_n),
        sigma_v_n=tile(gn.sigma_v_n),
        fix=tile(gn.fix),
        params=replace(
            gn.params,
            lever_arm_b_m=tile(gn.params.lever_arm_b_m),
            latency_s=tile(gn.params.latency_s),
        ),
    )
    return frame, dth, dv, gn, p, v, q, ce


def bench(frame, dth, dv, gn, p, v, q, ce, opts, repeat):
    from dataclasses import replace

    M, K = dth.shape[:2]
    tun = A.Tuning.from_grade("consumer")
    P0 = A.initial_covariance(tun, opts, 2.0, 0.1, [0.02, 0.02, 0.05], 1.0, 0.01, 0.66)
    init = A.initial_state(0, p[0], v[0], q[0], np.repeat(P0, M, 0))
    ce2 = replace(ce, z=ce.z[:2], lever_b_m=ce.lever_b_m[:2], odo_sf_sd=ce.odo_sf_sd[:2],
                  baro_sd_m=ce.baro_sd_m[:2], baro_tau_s=ce.baro_tau_s[:2],
                  odo_tick_m=ce.odo_tick_m[:2])  # fmt: skip
    A.run(dth[:2], dv[:2], 0.01, frame, _head(gn, 2), tun, opts, _init_head(init, 2),
          companions=ce2)  # fmt: skip
    best, best_cpu = np.inf, np.inf
    for _ in range(repeat):
        t0, c0 = time.perf_counter(), time.process_time()
        A.run(dth, dv, 0.01, frame, gn, tun, opts, init, companions=ce)
        best = min(best, time.perf_counter() - t0)
        best_cpu = min(best_cpu, time.process_time() - c0)
    return M * (K - 1) / best / 1e6, M * (K - 1) / best_cpu / 1e6


def _head(gn, n):
    from dataclasses import replace

    return replace(
        gn,
        p_n=gn.p_n[:n],
        v_n=gn.v_n[:n],
        sigma_p_n=gn.sigma_p_n[:n],
        sigma_v_n=gn.sigma_v_n[:n],
        fix=gn.fix[:n],
        params=replace(
            gn.params, lever_arm_b_m=gn.params.lever_arm_b_m[:n], latency_s=gn.params.latency_s[:n]
        ),
    )


def _init_head(init, n):
    return A.Initial(init.k0[:n], init.x0[:n], init.P0[:n])


def outage_table(M: int) -> dict:
    from imugen.aid import scenarios as SC

    frame, _, _, _, p, v, q, _ = scene("flat", 1)
    pts = np.array(
        [[0, 0, 0], [400, 0, 0], [400, 200, 0], [0, 200, 0], [0, 0, 0], [400, 0, 0], [400, 200, 0]],
        float,
    )
    enu = pd.DataFrame(pts, columns=["e_m", "n_m", "u_m"])
    meta = {"origin": dict(zip(("lat_deg", "lon_deg", "alt_m"), ORIGIN, strict=True))}
    df, _ = T.build_truth(enu, meta, rate_hz=100.0, earth="flat", vehicle="car", verbose=False)
    t = df["time_s"].to_numpy()
    w = df[["gyro_x_radps", "gyro_y_radps", "gyro_z_radps"]].to_numpy()
    out = {}
    for grade in ("consumer", "industrial"):
        sh = SIM.simulate(df, grade, sequences=M, seed=7)
        gn = G.simulate_gnss(t, p, v, q, w, "standalone", M, seed=7, lever_arm_b_m=(0.6, 0.3, 1.2))
        tun = A.Tuning.from_grade(grade, level="upper")
        for dur in (30.0, 60.0):
            sc = SC.apply(gn, [{"kind": "outage", "start_s": 100.0, "duration_s": dur}])
            j = int(np.searchsorted(gn.time_s, 100.0 + dur - 1e-9)) - 1
            for nhc in (False, True):
                res = A.run(sh.data["dtheta"], sh.data["dv"], 0.01, frame, sc.gnss, tun,
                            A.Options(nhc=nhc, zupt=True))  # fmt: skip
                e = res.p_n[:, j] - p[res.index[j]]
                h = np.hypot(e[:, 0], e[:, 1])
                lo, med, hi = np.percentile(h, [5, 50, 95])
                key = f"{grade} {dur:g} s {'NHC' if nhc else 'free inertial'}"
                out[key] = [round(med, 2), round(lo, 2), round(hi, 2)]
                print(f"{key:40s} median {med:8.2f} m   5-95 % {lo:8.2f} - {hi:8.2f} m")
    return out


def _compile_child():
    """First and second call of the filter on a tiny synthetic batch (no other kernel runs);
    prints the CPU seconds of the first minus the second."""
    S, K, J = 2, 201, 20
    dth = np.zeros((S, K, 3))
    dv = np.zeros((S, K, 3))
    dv[..., 2] = 9.81 * 0.01
    idx = np.arange(1, J + 1) * 10
    gn = SimpleNamespace(
        index=idx, time_s=idx * 0.01, p_n=np.zeros((S, J, 3)), v_n=np.zeros((S, J, 3)),
        sigma_p_n=np.ones((S, J, 3)), sigma_v_n=np.full((S, J, 3), 0.1),
        valid=np.ones((S, J), bool), receiver=None,
        params=SimpleNamespace(lever_arm_b_m=np.zeros((S, 3)), latency_s=np.zeros(S)),
    )  # fmt: skip
    frame = OriginFrame.from_deg(*ORIGIN, model="flat")
    tun = A.Tuning.from_grade("consumer")
    opts = A.Options(nhc=True, zupt=True)
    P0 = A.initial_covariance(tun, opts, 1.0, 0.1, 0.01)
    init = A.initial_state(0, np.zeros(3), np.zeros(3), [1.0, 0, 0, 0], np.repeat(P0, S, 0))
    T = A.tuning_matrix(tun, S)
    cpu = []
    for _ in range(2):
        c0 = time.process_time()
        A.run(dth, dv, 0.01, frame, gn, tun, opts, init, tuning_T=T)
        cpu.append(time.process_time() - c0)
    print(json.dumps({"compile_cpu_s": cpu[0] - cpu[1]}))


def compile_time(repeat: int) -> dict:
    """Cold-cache compilation of the filter kernel, in fresh processes (see the docstring)."""
    out = []
    for _ in range(repeat):
        with tempfile.TemporaryDirectory() as cache:
            env = dict(os.environ, NUMBA_CACHE_DIR=cache)
            t0 = time.perf_counter()
            r = subprocess.run(
                [sys.executable, __file__, "--compile-child"], env=env, check=True,
                capture_output=True, text=True,
            )  # fmt: skip
            wall = time.perf_counter() - t0
        cpu = json.loads(r.stdout.strip().splitlines()[-1])["compile_cpu_s"]
        out.append({"compile_cpu_s": round(cpu, 2), "process_wall_s": round(wall, 2)})
        print(f"compile {cpu:6.2f} CPU-s   (whole process {wall:6.2f} s wall)", flush=True)
    return {"runs": out, "min_compile_cpu_s": min(o["compile_cpu_s"] for o in out)}


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sequences", type=int, default=512)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--json")
    ap.add_argument("--outage", action="store_true")
    ap.add_argument("--compile", action="store_true")
    ap.add_argument("--compile-child", action="store_true", help=argparse.SUPPRESS)
    a = ap.parse_args()
    if a.compile_child:
        _compile_child()
        return
    if a.compile:
        out = compile_time(a.repeat)
        if a.json:
            with open(a.json, "w") as fh:
                json.dump(out, fh, indent=1)
        return
    if a.outage:
        out = outage_table(a.sequences)
        if a.json:
            with open(a.json, "w") as fh:
                json.dump(out, fh, indent=1)
        return
    configs = {
        "base": A.Options(gnss_bias=False, gyro_cross_coupling=False),
        "default": A.Options(),
        "NHC + ZUPT": A.Options(nhc=True, zupt=True),
        "scale factors + NHC + ZUPT": A.Options(scale_factors=True, nhc=True, zupt=True),
        "NHC + ZUPT + odometer + barometer": A.Options(
            nhc=True, zupt=True, odometer=True, baro=True
        ),
    }
    out = {}
    for earth in ("flat", "wgs84"):
        data = scene(earth, a.sequences)
        for name, opts in configs.items():
            if earth == "wgs84" and name != "NHC + ZUPT":
                continue
            wall, cpu = bench(*data, opts, a.repeat)
            key = f"{earth}: {name} ({opts.n} states)"
            out[key] = {"wall_msps": round(wall, 3), "cpu_msps": round(cpu, 3)}
            print(f"{key:50s} {wall:6.2f} Msps wall  {cpu:6.2f} Msps per CPU-second")
    if a.json:
        with open(a.json, "w") as fh:
            json.dump(out, fh, indent=1)


if __name__ == "__main__":
    main()
