"""Helpers shared by the format writers: measured rates of a sequence, noise figures, text."""

from __future__ import annotations

import math

import numpy as np

from imugen.formats.source import INCREMENT_COLUMNS, RATE_COLUMNS, Sequence, TruthArrays


def measured_rates(seq: Sequence, truth: TruthArrays):
    """``(time_s (n,), gyro_b (n, 3), accel_b (n, 3), kind)`` of a sequence.

    With rate columns in the shard: the samples at the truth times (``kind="samples"``).
    Otherwise the interval means of the increments, ``dtheta / dt`` and ``dv / dt``, stamped at
    the interval midpoints ``t_k - dt / 2`` (``kind="interval means"``; a second-order
    estimate of the rate there).
    """
    if seq.has(RATE_COLUMNS):
        r = seq.stack(RATE_COLUMNS)
        return truth.time_s, r[:, :3], r[:, 3:], "samples"
    inc = seq.stack(INCREMENT_COLUMNS)[1:] / truth.dt
    return truth.time_s[1:] - 0.5 * truth.dt, inc[:, :3], inc[:, 3:], "interval means"


def _label(labels: dict, stem: str) -> float:
    vals = [labels.get(stem.format(a=a)) for a in "xyz"]
    vals = [float(v) for v in vals if v is not None and np.isfinite(v)]
    return float(np.mean(vals)) if vals else 0.0


def noise_figures(labels: dict) -> dict[str, float]:
    """Kalibr's four numbers for one sequence from its drawn parameters (SI, axis means).

    ``random_walk = sqrt(RRW^2 + 2 sigma_GM^2 / T_GM)`` as in
    :func:`imugen.grade_io.kalibr_figures`.
    """
    out = {}
    for sensor, prefix, dens, rw, rate in (
        ("gyro", "gyroscope", "rad_per_sqrt_s", "radps_per_sqrt_s", "radps"),
        ("accel", "accelerometer", "m_per_s_per_sqrt_s", "mps2_per_sqrt_s", "mps2"),
    ):
        w = _label(labels, f"{sensor}_white_noise_{{a}}_{dens}")
        k2 = _label(labels, f"{sensor}_rate_random_walk_{{a}}_{rw}") ** 2
        c = 0
        while f"{sensor}_bias_instability_tau{c}_s" in labels:
            T = float(labels[f"{sensor}_bias_instability_tau{c}_s"])
            s = _label(labels, f"{sensor}_bias_instability_sigma{c}_{{a}}_{rate}")
            if T > 0 and s > 0:
                k2 += 2.0 * s * s / T
            c += 1
        out[f"{prefix}_noise_density"] = w
        out[f"{prefix}_random_walk"] = math.sqrt(k2)
    return out


def write_rows(fh, array: np.ndarray, fmt: str) -> None:
    """Write a 2-D array as text rows with numpy's formatter (streams in blocks)."""
    for i in range(0, len(array), 65536):
        np.savetxt(fh, array[i : i + 65536], fmt=fmt)
