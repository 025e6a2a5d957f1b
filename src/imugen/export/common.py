"""Helpers shared by the format writers: measured rates of a sequence, noise figures, text,
the train/val/test split lists."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from imugen.core.errors import InputError
from imugen.export.source import INCREMENT_COLUMNS, RATE_COLUMNS, Sequence, TruthArrays


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


def gm_components(labels: dict, sensor: str) -> list[tuple[str, str]]:
    """Label stems ``(tau, sigma)`` (after ``<sensor>_``) of a sensor's Gauss-Markov bias
    components: the bias instability's ``tau<c>_s`` / ``sigma<c>``, then the grade's second,
    slow one (``slow_bias_tau_s`` / ``slow_bias_sigma``) where the labels hold it."""
    comps = []
    c = 0
    while f"{sensor}_bias_instability_tau{c}_s" in labels:
        comps.append((f"bias_instability_tau{c}_s", f"bias_instability_sigma{c}"))
        c += 1
    if f"{sensor}_slow_bias_tau_s" in labels:
        comps.append(("slow_bias_tau_s", "slow_bias_sigma"))
    return comps


def noise_figures(labels: dict) -> dict[str, float]:
    """Kalibr's four numbers for one sequence from its drawn parameters (SI, axis means).

    ``random_walk = sqrt(RRW^2 + sum 2 sigma_GM^2 / T_GM)`` (every GM, the slow bias's too) as in
    :func:`imugen.sensors.grade_io.kalibr_figures`.
    """
    out = {}
    for sensor, prefix, dens, rw, rate in (
        ("gyro", "gyroscope", "rad_per_sqrt_s", "radps_per_sqrt_s", "radps"),
        ("accel", "accelerometer", "m_per_s_per_sqrt_s", "mps2_per_sqrt_s", "mps2"),
    ):
        w = _label(labels, f"{sensor}_white_noise_{{a}}_{dens}")
        k2 = _label(labels, f"{sensor}_rate_random_walk_{{a}}_{rw}") ** 2
        for tau, sig in gm_components(labels, sensor):
            T = float(labels[f"{sensor}_{tau}"])
            s = _label(labels, f"{sensor}_{sig}_{{a}}_{rate}")
            if T > 0 and s > 0:
                k2 += 2.0 * s * s / T
        out[f"{prefix}_noise_density"] = w
        out[f"{prefix}_random_walk"] = math.sqrt(k2)
    return out


def write_rows(fh, array: np.ndarray, fmt: str) -> None:
    """Write a 2-D array as text rows with numpy's formatter (streams in blocks)."""
    for i in range(0, len(array), 65536):
        np.savetxt(fh, array[i : i + 65536], fmt=fmt)


SPLIT_BY = ("sequence", "route")


def split_parts(
    keys,
    *,
    seed=0,
    by: str = "sequence",
    holdout_routes=None,
    val_fraction: float = 0.1,
    test_fraction: float = 0.1,
    warn=None,
) -> dict[str, list[tuple[str, int]]]:
    """Train/val/test parts of one export's ``(route, sequence)`` keys, consistent across the
    exports of a dataset (one per route and grade).

    The sequences of ``holdout_routes`` form the test part, whole, in every export; the other
    routes' then go to train and val only (fractions renormalized), as in
    :func:`imugen.dataset.split`. ``by="sequence"``: each sequence id hashed with ``seed``
    (:func:`imugen.dataset.split`; ids are unique across routes and grades, so a draw is in one
    part in every export); too few sequences for the non-empty parts put all in train (with a
    warning). ``by="route"``: every sequence of a route in the part the route's hash gives it
    (:func:`imugen.dataset.hashed_part`), the same in every export, whatever other routes
    exist (an export holds one route, so parts may be empty).

    Returns ``{"train": [...], "val": [...], "test": [...]}`` (keys in input order).
    """
    from imugen.dataset import hashed_part, split

    if by not in SPLIT_BY:
        raise InputError("--split-by", f"must be one of {', '.join(SPLIT_BY)}, got {by!r}")
    fr = {"val": float(val_fraction), "test": float(test_fraction)}
    for name, f in fr.items():
        if not (0.0 <= f < 1.0):
            raise InputError(f"--{name}-fraction", f"must be in [0, 1), got {f!r}")
    if fr["val"] + fr["test"] >= 1.0:
        raise InputError("--val-fraction", "val and test fractions must leave some for train")
    hold = {str(r) for r in (holdout_routes or ())}
    if hold:
        fr["test"] = 0.0
    fractions = {"train": 1.0 - fr["val"] - fr["test"], **fr}
    total = sum(fractions.values())  # below 1 with holdout routes: renormalized
    fractions = {n: f / total for n, f in fractions.items()}
    keys = [(str(r), int(s)) for r, s in keys]
    parts = {"train": [], "val": [], "test": []}
    rest = [k for k in keys if k[0] not in hold]
    if by == "route":
        for r in dict.fromkeys(r for r, _ in rest):
            parts[hashed_part(r, fractions, seed=seed)].extend(k for k in rest if k[0] == r)
    elif rest:
        try:
            for name, ks in split(rest, fractions, seed=seed, by="sequence").items():
                parts[name].extend(ks)
        except InputError:  # too few sequences for the non-empty parts
            if warn is not None:
                warn(f"{len(rest)} sequences: every one in the train list")
            parts["train"].extend(rest)
    parts["test"].extend(k for k in keys if k[0] in hold)
    order = {k: i for i, k in enumerate(keys)}
    return {name: sorted(ks, key=order.__getitem__) for name, ks in parts.items()}


def write_split_lists(folder, parts: dict, names: dict, pattern: str = "{part}_list.txt"):
    """Write one list file per part (``pattern`` formatted with ``part``) in ``folder``: the
    folder names ``names[key]`` of its keys, one a line. Returns the paths written."""
    out = []
    for part, ks in parts.items():
        path = Path(folder) / pattern.format(part=part)
        path.write_text("".join(f"{names[k]}\n" for k in ks))
        out.append(path)
    return out
