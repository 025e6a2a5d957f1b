"""``imugen learn correct``: the reference network's IMU correction of a shard.

The network predicts the mean effective error of each window of ``W`` samples (non-overlapping,
from sample 1); a causal running mean of the predictions over the last ``smooth_s`` seconds
(the effective error is mostly slow bias) gives each window's correction rate, spread evenly
over its samples (times the sample interval: a correction of the increments). The last partial
window takes the previous window's rate; sample 0 (no interval) is zero. Written as an IMU
correction table (:mod:`imugen.tables.imu_correction`, ``what = "reference-cnn"``), the input
of ``imugen aid --correction-in``.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from imugen.core.errors import InputError
from imugen.learn import model as M
from imugen.learn.options import CorrectOptions
from imugen.tables import SEQUENCE
from imugen.tables import imu_correction as tcorr
from imugen.tables import shard as tshard


def predict(net, meta: dict, x: np.ndarray, smooth_s: float) -> np.ndarray:
    """Correction ``(S, K, 6)`` of increments ``x`` (S, K, 6) (row 0: no interval)."""
    import torch

    W, dt = int(meta["window"]), float(meta["dt_s"])
    S, K = x.shape[:2]
    n = (K - 1) // W
    out = np.zeros((S, K, 6))
    if n == 0:
        return out
    win = x[:, 1 : 1 + n * W].reshape(S * n, W, 6)
    with torch.no_grad():
        rate = net(torch.from_numpy(M.inputs(win, dt))).numpy().astype(np.float64)
    rate = rate.reshape(S, n, 6) * np.asarray(meta["target_scale"])
    m = max(round(smooth_s / (W * dt)), 1)
    c = np.cumsum(rate, axis=1)
    lo = np.r_[0, np.arange(1, n) - m + 1].clip(0)  # first window of each running mean
    prev = np.concatenate([np.zeros((S, 1, 6)), c], axis=1)
    mean = (c - prev[:, lo]) / (np.arange(n) - lo + 1)[None, :, None]
    out[:, 1 : 1 + n * W] = np.repeat(mean, W, axis=1) * dt
    out[:, 1 + n * W :] = mean[:, -1:] * dt
    return out


def correct(model, shard, out, options: CorrectOptions) -> Path:
    """Write the network's correction of every sequence of ``shard`` to ``out``."""
    net, meta = M.load(model)
    t = tshard.read(shard, columns=[SEQUENCE, *tshard.INCREMENTS]).to_pandas()
    if t.empty:
        raise InputError(shard, "no IMU rows")
    seq = t[SEQUENCE].to_numpy()
    ids, counts = np.unique(seq, return_counts=True)
    if np.ptp(counts):
        raise InputError(shard, "sequences differ in length")
    order = np.argsort(seq, kind="stable")
    x = t[list(tshard.INCREMENTS)].to_numpy(np.float64)[order].reshape(len(ids), counts[0], 6)
    dt = float(meta["dt_s"])
    step = float(np.diff(tshard.times(shard)[:2])[0])
    if abs(step - dt) > 1e-6 * dt:
        raise InputError(shard, f"sample interval {step:g} s, the model's is {dt:g} s")
    corr = predict(net, meta, x, options.smooth_s)
    info = {"stage": "learn-correct", "shard": Path(shard).name, "what": "reference-cnn",
            "model": Path(model).name}  # fmt: skip
    return tcorr.write(tcorr.frame(ids, corr), info, out)
