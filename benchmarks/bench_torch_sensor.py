"""Throughput of the sensor model on torch (imugen.sensors.torch_model): samples x sequences / s.

A prepared script for a machine with a GPU (it runs on CPU too, with smaller defaults): one
consumer-grade IMU (both triads: turn-on bias, Gauss-Markov bias, white noise, scale factor,
cross-coupling, g-sensitivity, quantization and saturation where the grade has them) applied to
``--sequences`` windows of ``--samples`` ideal increments, ``--repeat`` times after a warm-up;
the device is synchronized around the timed loop. Prints the device name, the figure and the
peak memory. The goal on one H100-class GPU is >= 1e9 sample-sequences per second.

Usage: python benchmarks/bench_torch_sensor.py [--device cuda] [--sequences 4096]
       [--samples 2000] [--repeat 20] [--dtype float32] [--json FILE]
"""

from __future__ import annotations

import argparse
import json
import os
import time

import numpy as np
import torch

from imugen.sensors.grades import TERMS, get_grade
from imugen.sensors.model import SensorParams, draw_sensor
from imugen.sensors.torch_model import TorchSensor, imu
from imugen.simulate.plan import enabled_terms


def main(argv=None) -> dict:
    cuda = torch.cuda.is_available()
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--device", default="cuda" if cuda else "cpu")
    ap.add_argument("--sequences", type=int, default=4096 if cuda else 256)
    ap.add_argument("--samples", type=int, default=2000 if cuda else 1000)
    ap.add_argument("--repeat", type=int, default=20 if cuda else 3)
    ap.add_argument("--grade", default="consumer")
    ap.add_argument("--dtype", default="float32", choices=["float32", "float64"])
    ap.add_argument("--json", default=None)
    a = ap.parse_args(argv)
    dev = torch.device(a.device)
    name = (
        torch.cuda.get_device_name(dev) if dev.type == "cuda" else f"CPU ({os.cpu_count()} cores)"
    )
    grade = get_grade(a.grade)
    # every term of the grade but temperature (not on the torch path)
    en = enabled_terms(grade, [t for t in TERMS if not t.startswith("temperature")])
    rng = np.random.default_rng(0)
    gp, apar = [], []
    for _ in range(a.sequences):
        gp.append(draw_sensor(grade.gyro, rng, en["gyro"]))
        apar.append(draw_sensor(grade.accel, rng, en["accel"]))
    dt = 0.01
    dtype = getattr(torch, a.dtype)
    bands = [
        None if grade.sensor(s).bandwidth is None
        else grade.sensor(s).bandwidth.output_filter(s, 1.0 / dt)
        for s in ("gyro", "accel")
    ]  # fmt: skip
    g = TorchSensor(SensorParams.stack(gp), dt, dev, dtype, band=bands[0])
    acc = TorchSensor(SensorParams.stack(apar), dt, dev, dtype, band=bands[1])
    L = a.samples
    t = torch.arange(L, device=dev, dtype=torch.float64) * dt
    dth = torch.stack([0.01 * torch.sin(t), 0 * t, 0.002 + 0 * t], dim=1) * dt
    dv = torch.stack([0.1 * torch.cos(t), 0 * t, 9.81 + 0 * t], dim=1) * dt
    gen = torch.Generator(device=dev).manual_seed(0)

    def step():
        return imu(g, acc, dth, dv, generator=gen, outputs=("inc", "err_inc"))

    step()  # warm-up
    if dev.type == "cuda":
        torch.cuda.synchronize(dev)
        torch.cuda.reset_peak_memory_stats(dev)
    w0, c0 = time.perf_counter(), time.process_time()
    for _ in range(a.repeat):
        step()
    if dev.type == "cuda":
        torch.cuda.synchronize(dev)
    wall, cpu = time.perf_counter() - w0, time.process_time() - c0
    n = a.repeat * a.sequences * L
    out = {
        "device": name,
        "torch": torch.__version__,
        "grade": a.grade,
        "dtype": a.dtype,
        "sequences": a.sequences,
        "samples": L,
        "repeat": a.repeat,
        "wall_s": wall,
        "cpu_s": cpu,
        "sample_sequences_per_s": n / wall,
        "peak_memory_b": torch.cuda.max_memory_allocated(dev) if dev.type == "cuda" else None,
        "load_1min": os.getloadavg()[0],
    }
    print(f"{name}: {n / wall:,.3g} sample-sequences/s (IMU, both triads, increments + effective "
          f"error), {a.sequences} x {L} x {a.repeat} in {wall:.3f} s wall, {cpu:.2f} CPU-s, "
          f"load {out['load_1min']:.2f}")  # fmt: skip
    if a.json:
        with open(a.json, "w") as fh:
            json.dump(out, fh, indent=1)
    return out


if __name__ == "__main__":
    main()
