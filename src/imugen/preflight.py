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
    ``corner_m / 16``; ``corner_m`` is the one the truth job fits with,
    :func:`imugen.truth.flight.corner_length_m`: a dense logger flight is rounded at its own
    point spacing, 100 m - 2 km, not at the airliner's 2 km); ``benchmarks/bench_truth_memory.py``, car: the 7,602 km Pacific route,
    ``geodetic``, peaks at 10.57 GB at 2 Hz (1,093,818 samples, at the fit of the path) and
    12.87 GB at 20 Hz (10.9 M samples, ``/usr/bin/time``): ~1,355 bytes per metre + ~234 per
    sample; a synthetic 500 km road at 2 / 20 Hz (71,974 / 719,737 samples) peaks at 948 /
    1,236 MB (``flat``: 916 MB + 445 B per sample) and 1,075 / 1,285 MB (``geodetic``:
    1,051 MB + 325 B per sample). Disk: per sample-sequence of IMU shard, 4 bytes (8 with
    ``simulate.dtype: float64``) per stored column (:func:`imugen.tables.shard.groups` of
    ``simulate.outputs`` and ``simulate.series``: 6 for increments, 24 with the series) plus
    8.4 for the sequence ids and an explicit time column (measured with the implicit clock:
    24.1 bytes increments, 96.1 with ``series``, 48.1 / 144.1 for ``both``; none without
    ``write_imu``), 24 more for the MAT export, 200 per truth sample. The duration of a route is that of its truth when already
    computed, else the time span of the file, else its length at 80 % of the vehicle's cruise
    speed (untimed paths; the speed profile slows in corners).
"""

from __future__ import annotations

import math
import os
import re
import shutil
import subprocess
from pathlib import Path

from imugen.core.errors import InputError
from imugen.tables import layout
from imugen.tables.shard import groups

TRUTH_BASE_B = 300e6
TRUTH_PER_SAMPLE_B = 700.0
TRUTH_PATH_PER_M_B = 1600.0  # untimed path of a vehicle of corner_m = TRUTH_PATH_CORNER_M
TRUTH_PATH_CORNER_M = 10.0
SHARD_PER_SAMPLE_SEQUENCE_B = 32.4  # increments only, float32 (the Allan stage's shards)
SHARD_ROW_OVERHEAD_B = 8.4
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


def schema_problems(config: dict, schema: dict, limit: int = 20) -> list[str]:
    """Every way ``config`` breaks the JSON schema, one short line each naming the key.

    Snakemake's own validation prints the first error with the whole sub-schema (1,635 lines
    for a misspelt top-level key); this lists each problem as ``KEY: what is wrong`` (at most
    ``limit`` lines), an unknown key with the closest known one.
    """
    import difflib

    import jsonschema

    validator = jsonschema.Draft202012Validator(schema)
    errors = sorted(validator.iter_errors(config), key=lambda e: [str(p) for p in e.path])
    lines = []
    for e in errors:
        where = ".".join(["config", *map(str, e.absolute_path)])
        if e.validator == "additionalProperties" and isinstance(e.instance, dict):
            known = sorted(e.schema.get("properties", {}))
            for key in sorted(set(e.instance) - set(known), key=str):
                close = difflib.get_close_matches(str(key), known, n=1)
                hint = f"did you mean {close[0]!r}?" if close else f"known: {', '.join(known)}"
                lines.append(f"{where}.{key}: unknown key ({limit_text(hint, 160)})")
            continue
        if e.context:  # anyOf / oneOf: the branch that came closest
            e = jsonschema.exceptions.best_match(e.context)
        lines.append(f"{where}: {limit_text(' '.join(e.message.split()), 200)}")
    if len(lines) > limit:
        lines = [*lines[:limit], f"config: and {len(lines) - limit} more problems"]
    return lines


def limit_text(text: str, n: int) -> str:
    """``text`` cut to ``n`` characters (an ellipsis marks the cut)."""
    return text if len(text) <= n else text[: n - 3] + "..."


def check_values(config: dict) -> None:
    """Refuse NaN/inf anywhere and invalid custom grades (InputError naming the key).

    A custom grade is checked as the jobs will read it: fully valid, not named like a preset
    and not using a preset's id (``imugen.sensors.grades.load_grades`` refuses both in a job), and
    with an id no other grade of the run has (ids seed the random draws).
    """
    from imugen.sensors.grades import grade_from_config, presets

    hit = _non_finite(config)
    if hit:
        raise InputError(hit, "is not a finite number")
    pre = presets()
    ids = {g.id: f"the preset {n!r}" for n, g in pre.items() if n in config.get("grades", {})}
    pre_ids = {g.id: n for n, g in pre.items()}
    for name, spec in config.get("grades", {}).items():
        where = f"config grades.{name}"
        if spec:
            if name in pre:
                raise InputError(
                    where, "is the name of a shipped preset: give the custom grade another name"
                )
            g = grade_from_config(name, spec, origin=where)
            if g.id in pre_ids:
                raise InputError(
                    where, f"id {g.id} is the preset {pre_ids[g.id]!r}'s: choose another id"
                )
            if g.id in ids:
                raise InputError(where, f"id {g.id} is already used by {ids[g.id]}")
            ids[g.id] = f"grade {name!r}"
        elif name not in pre:
            raise InputError(
                where,
                f"is empty but no preset has this name (presets: {', '.join(pre)})",
            )


def human_bytes(n: float) -> str:
    """``n`` bytes in binary units with 3 significant digits: ``50.0 MiB``, ``1.25 GiB``."""
    for unit in ("bytes", "KiB", "MiB", "GiB", "TiB"):
        if abs(n) < 1024 or unit == "TiB":
            return f"{n:.0f} bytes" if unit == "bytes" else f"{n:.3g} {unit}"
        n /= 1024
    raise AssertionError  # pragma: no cover


def route_figures(name: str, route: dict, results: Path) -> tuple[float | None, float]:
    """A route's duration (s; None when its file cannot be read) and the truth memory of
    fitting its path (bytes; 0 for timed routes and computed truths).

    The duration is that of the route's truth when already computed (``route["_rate_hz"]``
    gives its rate), else that of its ingested file (time span, or length at 80 % of the
    vehicle's cruise speed for an untimed path).
    """
    from imugen.ingest.stage import ingest
    from imugen.tables import enu as tenu
    from imugen.tables import truth as ttruth
    from imugen.truth import VEHICLES
    from imugen.truth.flight import corner_length_m

    truth = Path(layout.truth(name, root=results))
    rate = route.get("_rate_hz")
    if rate and truth.is_file():
        try:
            return ttruth.samples(truth) / rate, 0.0
        except InputError:
            pass  # an unreadable truth is rebuilt: estimate from the route file
    try:
        ing = ingest(
            route["file"],
            path=route.get("path"),
            origin=None if route.get("origin") is None else ",".join(map(str, route["origin"])),
            dt=route.get("dt_s"),
            vehicle=route.get("vehicle", "car"),
        )
    except InputError:
        return None, 0.0  # the ingest job reports it in one line
    if ing.meta["timed"]:
        return float(ing.meta["duration_s"]), 0.0
    vp = VEHICLES[route.get("vehicle", "car")]
    length = ing.meta["length_3d_m"]
    corner = corner_length_m(ing.table[list(tenu.ENU)].to_numpy(float), vp)  # as the truth job
    path_b = TRUTH_PATH_PER_M_B * TRUTH_PATH_CORNER_M / corner * length
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


def shard_bytes(simulate: dict) -> float:
    """Disk bytes per sample-sequence of the IMU shards of a ``simulate`` config section."""
    if not simulate.get("write_imu", True):
        return 0.0
    width = 8 if simulate.get("dtype", "float32") == "float64" else 4
    cols = 3 * len(groups(simulate.get("outputs", "increments"), bool(simulate.get("series"))))
    return SHARD_ROW_OVERHEAD_B + width * cols


def estimate(config: dict, results: Path = Path(layout.RESULTS)) -> dict:
    """Largest job memory and total disk (bytes) of a run, with the terms behind them."""
    rate = float(config["truth"]["rate_hz"])
    n_seq = int(config["simulate"]["sequences"])
    n_grades = len(config["grades"])
    per_ss = shard_bytes(config["simulate"]) + (
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


def budgets(config: dict, results: Path = Path(layout.RESULTS)) -> tuple[float, float]:
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


def check_budget(config: dict, results: Path = Path(layout.RESULTS)) -> dict:
    """Refuse a run whose estimate exceeds a budget (InputError with the estimate)."""
    est = estimate(config, results)
    mem, disk = budgets(config, results)
    if est["memory_b"] > mem:
        raise InputError(
            "config",
            f"the largest truth job needs about {human_bytes(est['memory_b'])} of memory "
            f"(routes of {max(est['route_durations_s'].values()):.0f} s at "
            f"{config['truth']['rate_hz']:g} Hz) but the budget is {human_bytes(mem)} "
            "(budget.memory_gib); lower truth.rate_hz or split the route",
        )
    if est["disk_b"] > disk:
        raise InputError(
            "config",
            f"the run would write about {human_bytes(est['disk_b'])} but the budget is "
            f"{human_bytes(disk)} (budget.disk_gib, default the free space); lower "
            "simulate.sequences, truth.rate_hz or allan.static_s",
        )
    return est


SLURM_QUERY_TIMEOUT_S = 30


def slurm_status_problem(status_command: str | None, init_s: float = 40.0) -> str | None:
    """Why a run through snakemake-executor-plugin-slurm would never see its jobs end, or None.

    The plugin polls job states with ``sacct`` whenever the command exists (with ``squeue``
    only when asked, ``--slurm-status-command squeue``, and only while SLURM's ``MinJobAge``
    is at least 3 x ``--slurm-init-seconds-before-status-checks``; else it falls back to
    ``sacct``). On a cluster without accounting ``sacct`` exists but fails, and the run waits
    for ever after its jobs have finished.
    """
    if shutil.which("sacct") is None:
        return None  # the plugin uses squeue
    uses_sacct = status_command in (None, "", "sacct")
    if not uses_sacct:
        age = _slurm_min_job_age()
        if age is None or age >= 3 * init_s:
            return None
    try:
        p = subprocess.run(
            ["sacct", "-X", "-n", "-S", "now"],
            capture_output=True,
            text=True,
            timeout=SLURM_QUERY_TIMEOUT_S,
        )
    except subprocess.TimeoutExpired:
        why = f"sacct did not answer within {SLURM_QUERY_TIMEOUT_S} s"
    except OSError as exc:
        why = f"sacct cannot be run ({exc.strerror or exc})"
    else:
        if p.returncode == 0:
            return None
        lines = (p.stderr or p.stdout).strip().splitlines()
        why = f"sacct fails ({lines[-1][:160] if lines else f'exit status {p.returncode}'})"
    if uses_sacct:
        return (
            f"this SLURM cluster has no job accounting: {why}, and the executor plugin would "
            "wait for ever; add --slurm-status-command squeue (workflow/profiles/slurm/README.md)"
        )
    return (
        f"SLURM's MinJobAge ({age} s) is below 3 x --slurm-init-seconds-before-status-checks "
        f"({init_s:g} s): the executor plugin would fall back to sacct, and {why}; lower "
        "--slurm-init-seconds-before-status-checks (workflow/profiles/slurm/README.md)"
    )


def _slurm_min_job_age() -> int | None:
    """SLURM's ``MinJobAge`` in seconds (``scontrol show config``), None when unknown."""
    try:
        p = subprocess.run(
            ["scontrol", "show", "config"],
            capture_output=True,
            text=True,
            timeout=SLURM_QUERY_TIMEOUT_S,
        )
    except (OSError, subprocess.TimeoutExpired):
        return None
    m = re.search(r"^MinJobAge\s*=\s*(\d+)", p.stdout, flags=re.M)
    return int(m.group(1)) if m else None
