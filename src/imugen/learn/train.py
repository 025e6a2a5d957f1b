"""``imugen learn train``: fit the reference network on the stream of the training routes.

Each step draws a fresh batch of :class:`imugen.stream.Stream` (new sequences, new parameter
draws, keys in the stream's reserved shard namespace: never a written validation or test
sequence) and takes one Adam step on the mean squared error of the window's mean effective
error, each channel in units of its RMS over the first batch. A grade with an output bandwidth
(``phone``) is streamed without it: the stream's window mode runs the output filter window by
window in Python (585 windows per CPU-second for ``adis16405``, against about 11,000 without
it), beyond this model's ten-minute training budget. The filter shapes the noise the network
sees, so a phone model trained this way meets different inputs on the written shards (the
benchmark page's phone rows show the cost).
"""

from __future__ import annotations

import dataclasses
import time
from pathlib import Path

import numpy as np

from imugen.core.errors import InputError
from imugen.core.seeding import learn_seed
from imugen.learn import model as M
from imugen.learn.options import TrainOptions


def streamable(grade):
    """``grade`` (a :class:`~imugen.sensors.grades.Grade`) without its output bandwidth and
    rounding quantization (see the module docstring)."""

    def plain(s):
        return dataclasses.replace(s, bandwidth=None, quantization_mode="carry")

    return dataclasses.replace(grade, gyro=plain(grade.gyro), accel=plain(grade.accel))


def train(truths, grade: str, out, options: TrainOptions, log=None) -> dict:
    """Train on the truth tables ``truths`` for ``grade``; write the model to ``out``.

    Returns the model's metadata (also stored in the file): window, dt, target scale, steps,
    final training loss, and the loss of predicting zero on the same batches.
    """
    import torch

    from imugen.sensors.grades import get_grade

    if log is None:

        def log(msg):
            print(msg, flush=True)

    from imugen.stream import Stream, load_truths

    g = get_grade(grade)
    torch.manual_seed(learn_seed(options.seed, g.id))
    torch.set_num_threads(options.threads)
    stream = Stream(
        load_truths([Path(t) for t in truths]), streamable(g), window=options.window,
        batch_size=options.batch_size, windows_per_sequence=options.windows_per_sequence,
        seed=options.seed, targets=["effective_error"],
    )  # fmt: skip
    dt = stream.dt

    def batch(n):
        b = stream.batch(n)
        x = torch.from_numpy(M.inputs(b["x"], dt))
        y = b["effective_error"].mean(axis=1) / dt  # (B, 6) rad/s, m/s^2
        return x, y

    _, y0 = batch(0)
    scale = np.sqrt(np.mean(y0.astype(np.float64) ** 2, axis=0)) + 1e-12
    net = M.build(options.width)
    opt = torch.optim.Adam(net.parameters(), lr=options.learning_rate)
    sched = torch.optim.lr_scheduler.CosineAnnealingLR(opt, max(options.steps, 1))
    t0, c0 = time.time(), time.process_time()
    recent, zero = [], []
    for n in range(options.steps):
        x, y = batch(n)
        target = torch.from_numpy((y / scale).astype(np.float32))
        loss = torch.mean((net(x) - target) ** 2)
        opt.zero_grad()
        loss.backward()
        opt.step()
        sched.step()
        recent = [*recent[-19:], loss.item()]
        zero = [*zero[-19:], float(torch.mean(target**2))]
        if n % max(options.steps // 10, 1) == 0 or n == options.steps - 1:
            log(f"step {n}: loss {np.mean(recent):.4f} (zero prediction {np.mean(zero):.4f})")
    if not options.steps:
        raise InputError("--steps", "must be >= 1")
    meta = {
        "stage": "learn-train", "grade": g.name, "window": options.window, "dt_s": dt,
        "width": options.width, "target_scale": scale.tolist(), "steps": options.steps,
        "batch_size": options.batch_size, "seed": options.seed,
        "truths": [Path(t).as_posix() for t in truths], "target": "effective_error",
        "loss": float(np.mean(recent)), "zero_loss": float(np.mean(zero)),
        "wall_s": time.time() - t0, "cpu_s": time.process_time() - c0,
    }  # fmt: skip
    M.save(out, net, meta)
    log(f"wrote {out}: loss {meta['loss']:.4f} against {meta['zero_loss']:.4f} for zero, "
        f"{meta['wall_s']:.0f} s wall, {meta['cpu_s']:.0f} CPU-s")  # fmt: skip
    return meta
