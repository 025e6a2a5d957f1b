"""The network: a small 1-D CNN from a window of increments to its mean effective error.

Input ``(B, W, 6)``: measured ``dtheta`` (rad) and ``dv`` (m/s) per sample, divided by the
sample interval and by :data:`INPUT_SCALE` (about unit size for a moving vehicle). Output
``(B, 6)``: the window's mean effective error per sample divided by the sample interval
(rad/s, m/s^2), in units of the target scale stored with the model (the training batch's
per-channel RMS). About 11 k weights.
"""

from __future__ import annotations

import numpy as np

INPUT_SCALE = np.array([1.0, 1.0, 1.0, 10.0, 10.0, 10.0])
"""Per-channel divisor of the rates (rad/s, m/s^2) fed to the network."""


def build(width: int = 32):
    """The network (``torch.nn.Module``), ``(B, W, 6) -> (B, 6)``."""
    from torch import nn

    class WindowCNN(nn.Module):
        def __init__(self):
            super().__init__()
            self.body = nn.Sequential(
                nn.Conv1d(6, width, 5, stride=2, padding=2), nn.GELU(),
                nn.Conv1d(width, width, 5, stride=2, padding=2), nn.GELU(),
                nn.Conv1d(width, width, 5, stride=2, padding=2), nn.GELU(),
                nn.AdaptiveAvgPool1d(1),
            )  # fmt: skip
            self.head = nn.Linear(width, 6)

        def forward(self, x):
            return self.head(self.body(x.transpose(1, 2)).squeeze(-1))

    return WindowCNN()


def inputs(x: np.ndarray, dt: float) -> np.ndarray:
    """Network input from increments ``x`` (..., W, 6) [rad, m/s] at interval ``dt`` (s)."""
    return (np.asarray(x, np.float32) / np.float32(dt) / INPUT_SCALE.astype(np.float32)).astype(
        np.float32
    )


def save(path, net, meta: dict) -> None:
    """Write the weights and ``meta`` (window, dt, target scale, ...) to ``path`` atomically."""
    import os

    import torch

    tmp = f"{path}.tmp"
    torch.save({"state": net.state_dict(), "meta": meta}, tmp)
    os.replace(tmp, path)


def load(path):
    """``(net, meta)`` of a model file written by :func:`save` (eval mode)."""
    import torch

    from imugen.core.errors import InputError

    try:
        blob = torch.load(path, map_location="cpu", weights_only=True)
    except (OSError, RuntimeError, ValueError) as exc:
        raise InputError(path, f"not a model file of imugen learn train ({exc})") from None
    meta = blob["meta"]
    net = build(int(meta["width"]))
    net.load_state_dict(blob["state"])
    net.eval()
    return net, meta
