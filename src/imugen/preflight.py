"""Checks of a workflow configuration before any job starts: values, custom grades, budgets.

The schema (``workflow/schemas/config.schema.yaml``) bounds each key; this module adds what a
schema cannot state: no NaN or infinity anywhere, custom grades fully validated, and an
estimate of the largest job's memory and of the run's disk use against the budgets
(``budget.memory_gib``, default the machine's memory; ``budget.disk_gib``, default the free
space of the working directory plus what ``results/`` already holds).

Estimates (measured, README "Security and limits")
    truth job memory: 300 MB + 700 bytes per IMU sample (``bench``: 268 MB at 31,207 samples,
    414 MB at 249,649) + 1,600 bytes per metre of an untimed path for a vehicle of
    ``corner_m = 10`` (scaled by ``10 / corner_m``: the path is fitted on a grid of
    ``corner_m / 16``); ``benchmarks/bench_truth_memory.py``, car: the 7,602 km Pacific route,
    ``geodetic``, peaks at 10.57 GB at 2 Hz (1,093,818 samples, at the fit of the path) and
    12.87 GB at 20 Hz (10.9 M samples, ``/usr/bin/time``): ~1,355 bytes per metre + ~234 per
    sample; a synthetic 500 km road at 2 / 20 Hz (71,974 / 719,737 samples) peaks at 948 /
    1,236 MB (``flat``: 916 MB + 445 B per sample) and 1,075 / 1,285 MB (``geodetic``:
    1,051 MB + 325 B per sample). Disk: 32.4 bytes per sample-sequence of IMU shard, 24 more for the MAT
    export, 200 per truth sample. The duration of a route is that of its truth when already
    computed, else the time span of the file, else its length at 80 % of the vehicle's cruise
    speed (untimed paths; the speed profile slows in corners).
"""

from __future__ import annotations

import math
import os
import shutil
from pathlib import Path

from imugen.core.errors import InputError

TRUTH_BASE_B = 300e6
TRUTH_PER_SAMPLE_B = 700.0
TRUTH_PATH_PER_M_B = 1600.0  # untimed path of a vehicle of corner_m = TRUTH_PATH_CORNER_M
TRUTH_PATH_CORNER_M = 10.0
SHARD_PER_SAMPLE_SEQUENCE_B = 32.4
MAT_PER_SAMPLE_SEQUENCE_B = 24.0
TRUTH_FILE_PER_SAMPLE_B = 200.0


def _non_finite(node, where: str = "config"):
    """Path of the first NaN/inf number in a nested config, else None."""
    if isinstance(node, float) and not math.isfinite(node):
        return where
    if isinstance(node, dict):
        items = node.items()
    elif isinstance(node, list):
        items = enumerate(node)
    else:
        return None
    for k, v in items:
        hit = _non_finite(v, f"{where}.{k}")
        if hit:
            return hit
    return None


def check_values(config: dict) -> None:
    """Refuse NaN/inf anywhere and invalid custom grades (InputError naming the key)."""
    from imugen.sensors.grades import grade_from_config, presets

    hit = _non_finite(config)
    if hit:
        raise InputError(hit, "is not a finite number")
    for name, spec in config.get("grades", {}).items():
        if spec:
            grade_from_config(name, spec, origin=f"config grades.{name}")
        elif name not in presets():
            raise InputError(
                f"config grades.{name}",
                f"is empty but no preset has this name (presets: {', '.join(presets())})",
            )


def route_duration_s(name: str, route: dict, results: Path) -> float | None:
    """Best estimate of a route's duration (s); None when the file cannot be read."""
    return route_figures(name, route, results)[0]


def route_figures(name: str, route: dict, results: Path) -> tuple[float | None, float]:
    """A route's duration (s, :func:`route_duration_s`; None when the file cannot be read)
    and the truth memory of fitting its path (bytes; 0 for timed routes and computed
    truths)."""
    import pyarrow.parquet as pq

    from imugen.ingest.stage import ingest
    from imugen.truth import VEHICLES

    truth = results / name / "truth.parquet"
    if truth.is_file():
        try:
            md = pq.ParquetFile(truth).metadata
            rate = route.get("_rate_hz")
            if rate:
                return md.num_rows / rate, 0.0
        except (OSError, ValueError):
            pass
    try:
        ing = ingest(
            route["file"],
            path=route.get("path"),
            origin=None if route.get("origin") is None else ",".join(map(str, route["origin"])),
            dt=route.get("dt_s"),
        )
    except InputError:
        return None, 0.0  # the ingest job reports it in one line
    if ing.meta["timed"]:
        return float(ing.meta["duration_s"]), 0.0
    vp = VEHICLES[route.get("vehicle", "car")]
    length = ing.meta["length_3d_m"]
    path_b = TRUTH_PATH_PER_M_B * TRUTH_PATH_CORNER_M / vp.corner_m * length
    return length / (0.8 * vp.cruise_mps), path_b


def _tree_bytes(root: Path) -> int:
    total = 0
    for dirpath, _dirs, files in os.walk(root):
        for f in files:
            try:
                total += os.lstat(os.path.join(dirpath, f)).st_size
            except OSError:
                pass
    return total


def estimate(config: dict, results: Path = Path("results")) -> dict:
    """Largest job memory and total disk (bytes) of a run, with the terms behind them."""
    rate = float(config["truth"]["rate_hz"])
    n_seq = int(config["simulate"]["sequences"])
    n_grades = len(config["grades"])
    per_ss = SHARD_PER_SAMPLE_SEQUENCE_B + (
        MAT_PER_SAMPLE_SEQUENCE_B if config["exports"]["mat"] else 0.0
    )
    memory = 0.0
    disk = 0.0
    routes = {}
    for name, route in config["routes"].items():
        dur, path_b = route_figures(name, {**route, "_rate_hz": rate}, results)
        if dur is None:
            continue
        samples = dur * rate + 1
        routes[name] = dur
        memory = max(memory, TRUTH_BASE_B + TRUTH_PER_SAMPLE_B * samples + path_b)
        disk += samples * (n_seq * n_grades * per_ss + TRUTH_FILE_PER_SAMPLE_B)
    allan = config["allan"]
    allan_samples = allan["static_s"] * allan["rate_hz"] + 1
    disk += n_grades * allan["sequences"] * allan_samples * SHARD_PER_SAMPLE_SEQUENCE_B
    return {"memory_b": memory, "disk_b": disk, "route_durations_s": routes}


def budgets(config: dict, results: Path = Path("results")) -> tuple[float, float]:
    """Memory and disk budgets in bytes (configured, else this machine's)."""
    b = config.get("budget", {})
    if b.get("memory_gib") is not None:
        mem = b["memory_gib"] * 2**30
    else:
        mem = os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
    if b.get("disk_gib") is not None:
        disk = b["disk_gib"] * 2**30
    else:
        here = results if results.exists() else Path(".")
        disk = shutil.disk_usage(here).free + (_tree_bytes(results) if results.exists() else 0)
    return float(mem), float(disk)


def check_budget(config: dict, results: Path = Path("results")) -> dict:
    """Refuse a run whose estimate exceeds a budget (InputError with the estimate)."""
    est = estimate(config, results)
    mem, disk = budgets(config, results)
    gib = 2**30
    if est["memory_b"] > mem:
        raise InputError(
            "config",
            f"the largest truth job needs about {est['memory_b'] / gib:.1f} GiB of memory "
            f"(routes of {max(est['route_durations_s'].values()):.0f} s at "
            f"{config['truth']['rate_hz']:g} Hz) but the budget is {mem / gib:.1f} GiB "
            "(budget.memory_gib); lower truth.rate_hz or split the route",
        )
    if est["disk_b"] > disk:
        raise InputError(
            "config",
            f"the run would write about {est['disk_b'] / gib:.1f} GiB but the budget is "
            f"{disk / gib:.1f} GiB (budget.disk_gib, default the free space); lower "
            "simulate.sequences, truth.rate_hz or allan.static_s",
        )
    return est
