"""One options object per command: its dataclass is the one place an option's default lives.

Every option that corresponds to a key of the workflow's config (field metadata ``config``)
has the same default in the schema (workflow/schemas/config.schema.yaml), on the command line
and in the dataclass, and the same choices; every key of the schema is either such an
option's or named below as the workflow's own; and a dry run of a config that sets every such
key to a value other than its default shows each rule passing it: the options object the
job's command line gives holds the config's value.
"""

from __future__ import annotations

import argparse
import dataclasses
import importlib
import re
import shlex

import pytest
import yaml

from imugen.cli import COMMANDS, build_parser, command_of
from imugen.core.options import cli_fields, flag_of, from_namespace

from helpers import REPO, ROUTE, snakemake, write_config

SCHEMA = yaml.safe_load((REPO / "workflow" / "schemas" / "config.schema.yaml").read_text())

DIFFERENT = {
    ("simulate", "shard_size"): "None: the shard alone (--sequences); the workflow's M is 10",
    ("simulate", "static_s"): "None: a truth table; the Allan check's still IMU lasts an hour",
    ("simulate", "mounting"): "None and the block's enabled: false both mean no mounting",
    ("evaluate", "segments_s"): "no drift unless asked; the workflow asks for 30, 60, 120 s",
}
"""(command, field) whose default is not the schema's, and why."""
WORKFLOW_ONLY = {
    "routes.*.file": "the input of ingest",
    "routes.*.paths": "all: one route per path of the file, each ingested with --path=all:ID",
    "grades": "one job per grade (--grade)",
    "simulate.sequences": "N, split into shards of sequences_per_shard (--sequences per job)",
    "simulate.write_imu": "whether the shard job is given -o",
    "gnss.enabled": "whether the aid jobs run",
    "aided.estimates": "whether the aid job is given --estimates-out",
    "aided.learned_in": "the aid job's --learned-in, a path with wildcards",
    "allan.sequences": "--sequences of the still IMU's simulate job",
    "exports.mat": "whether the export-mat jobs run",
    "budget.memory_gib": "the preflight's",
    "budget.disk_gib": "the preflight's",
    "benchmark.train": "the truths given to learn train",
    "benchmark.validation": "the routes whose metrics the benchmark table reads",
    "benchmark.test": "the routes whose metrics the benchmark table reads",
}
"""Keys of the schema that are no command's option, and what the workflow does with them."""
NOT_PASSED = {("allan_static", "draw"): "the Allan check's still IMU is drawn nominal"}
"""(rule, field) whose value in the job is not the config key's, and why."""


def _commands():
    for name, (module, _) in COMMANDS.items():
        yield name, importlib.import_module(module).COMMANDS[name]


def _schema_node(key: str) -> dict:
    node = SCHEMA
    for part in key.split("."):
        node = node["additionalProperties"] if part == "*" else node["properties"][part]
    return node


def _config_value(cfg: dict, key: str, route: str):
    node = cfg
    for part in key.split("."):
        node = node[route if part == "*" else part]
    return node


def _leaves(node: dict, prefix: str = ""):
    """Dotted keys of the schema's leaves (``*`` for any route)."""
    if "properties" in node and node.get("type") == "object" and prefix != "mounting":
        for k, v in node["properties"].items():
            yield from _leaves(v, f"{prefix}.{k}" if prefix else k)
    elif isinstance(node.get("additionalProperties"), dict) and "properties" in node.get(
        "additionalProperties"
    ):
        yield from _leaves(node["additionalProperties"], f"{prefix}.*")
    else:
        yield prefix


def _plain(value):
    """Lists as tuples, numbers as floats, ``"a,b"`` text of numbers as a tuple of floats."""
    if isinstance(value, list | tuple):
        return tuple(_plain(v) for v in value)
    if isinstance(value, dict):
        return {k: _plain(v) for k, v in value.items()}
    if isinstance(value, bool) or value is None:
        return value
    if isinstance(value, int | float):
        return float(value)
    if isinstance(value, str) and re.fullmatch(r"-?[\d.eE+-]+(,-?[\d.eE+-]+)+", value):
        return tuple(float(x) for x in value.split(","))
    if isinstance(value, str) and re.fullmatch(r"-?\d+(\.\d*)?", value):
        return float(value)
    return value


def _minimal_argv(name: str) -> list[str]:
    """``name``'s command line with its required inputs and options only."""
    sub = build_parser([name])
    for word in name.split():
        subparsers = next(a for a in sub._actions if isinstance(a, argparse._SubParsersAction))
        sub = subparsers.choices[word]
    argv = name.split()
    for a in sub._actions:
        if a.required or (not a.option_strings and a.nargs != "?"):
            value = str(a.choices[0]) if a.choices else "1"
            argv += [a.option_strings[0], value] if a.option_strings else [value]
    return argv


@pytest.mark.parametrize("name", list(COMMANDS))
def test_schema_cli_and_dataclass_defaults_agree(name):
    cmd = dict(_commands())[name]
    argv = _minimal_argv(name)
    parsed = from_namespace(cmd.options, build_parser([name]).parse_args(argv))
    for f in dataclasses.fields(cmd.options):
        if f.default is dataclasses.MISSING or not f.metadata.get("help"):
            continue
        if f.metadata["cli"]:
            assert getattr(parsed, f.name) == f.default, (name, f.name)
        key = f.metadata.get("config")
        if key is None:
            continue
        node = _schema_node(key)
        if (name, f.name) not in DIFFERENT:
            assert _plain(node.get("default")) == _plain(f.default), (name, f.name, key)
        choices = f.metadata.get("choices")
        if choices is not None and "enum" in node:
            assert set(choices) == set(node["enum"]) - {False, None}, (name, f.name)


def test_every_schema_key_is_an_option_or_the_workflows():
    mapped = {
        f.metadata["config"]
        for _, cmd in _commands()
        for f in dataclasses.fields(cmd.options)
        if f.metadata.get("config")
    }
    leaves = set(_leaves(SCHEMA))
    assert leaves == mapped | set(WORKFLOW_ONLY), leaves - mapped - set(WORKFLOW_ONLY)
    assert not mapped & set(WORKFLOW_ONLY)
    for name, field in DIFFERENT:
        assert field in {f.name for f in dataclasses.fields(dict(_commands())[name].options)}


CFG = {
    "routes": {
        "r1": {
            "file": str(ROUTE), "vehicle": "bicycle", "origin": [33.9, 151.2, 10.0],
            "dt_s": 2.0, "max_gap_s": 30.0, "gaps": "bridge", "max_extent_km": 500.0, "path": 1,
            "pose_world": "flu", "pose_world_yaw_deg": 10.0, "pose_body": "frd",
            "imu_rotation_deg": [1.0, 2.0, 3.0], "lever_arm_m": [0.1, 0.0, 0.0],
            "marker_offset_m": [0.0, 0.1, 0.0], "time_offset_s": 0.5, "suspension": "damped",
        },
    },
    "truth": {"rate_hz": 50, "earth": "wgs84"},
    "grades": {"consumer": {}},
    "simulate": {
        "sequences": 3, "sequences_per_shard": 2, "seed": 5, "draw": "nominal",
        "dtype": "float64", "outputs": "both", "series": True, "increments": "raw",
        "vibration": "car",
    },
    "mounting": {
        "enabled": True, "misalignment_sd_deg": [2.0, 2.0, 3.0], "lever_arm_m": [0.1, 0.2, 0.3],
        "lever_arm_sd_m": [0.01, 0.01, 0.01],
    },
    "navigate": {
        "eval_rate_hz": 2.0,
        "vertical": {"mode": "damped", "order": 2, "time_constant_s": 50.0, "reference": "truth"},
    },
    "evaluate": {"segments_s": [20, 40]},
    "gnss": {
        "enabled": True, "receiver": "rtk", "rate_hz": 5.0, "draw": "nominal",
        "lever_arm_b_m": [0.1, 0.2, 0.3], "lever_arm_sd_m": 0.05,
    },
    "scenarios": {
        "outages_s": [10, 20], "draw": ["jamming"], "settle_s": 30.0,
        "intervals": [{"kind": "outage", "start_s": 5.0, "duration_s": 3.0}],
    },
    "aided": {
        "tuning_level": "nominal", "gnss_bias_states": False, "scale_factors": True,
        "cross_coupling": False, "nhc": True, "nhc_slip_sd_mps": [0.2, 0.1], "zupt": False,
        "gate_sigma": 3.0, "align_speed_mps": 2.0,
    },
    "companions": {
        "odometer": "abs", "odometer_rate_hz": 10.0, "odometer_lever_b_m": [1.0, 0.0, 0.1],
        "odometer_scale_state": False, "barometer": "bmp388", "barometer_rate_hz": 5.0,
        "draw": "nominal",
    },
    "allan": {"static_s": 100, "rate_hz": 50, "sequences": 2},
    "exports": {
        "mat": True, "formats": ["tum", "tlio", "ros2"], "nav_rate_hz": 5.0,
        "split": {
            "by": "route", "holdout_routes": ["r1"], "val_fraction": 0.2, "test_fraction": 0.3,
            "seed": 3,
        },
    },
    "figures": {"formats": ["png", "pdf"], "dpi": 80, "zoom_fraction": 0.3, "representative": "worst"},
}  # fmt: skip
"""Every key an option corresponds to, away from its default."""


def _job_commands(workdir) -> list[tuple[str, list[str]]]:
    """(rule, ``imugen`` arguments) of every job of a dry run."""
    proc = snakemake(workdir, "-n", "-p", "-j1")
    assert proc.returncode == 0, proc.stderr[-3000:]
    out, rule = [], None
    for line in (proc.stdout + proc.stderr).splitlines():
        m = re.match(r"^(?:local)?rule (\w+):", line)
        if m:
            rule = m.group(1)
        elif line.startswith("Shell command: ") and " imugen " in f" {line}":
            words = shlex.split(line[len("Shell command: ") :])
            words = words[words.index("imugen") + 1 :]
            end = next((i for i, w in enumerate(words) if re.match(r"^\d*>", w)), len(words))
            out.append((rule, words[:end]))
    return out


def test_the_rules_pass_every_option_of_the_config(tmp_path):
    assert {
        k
        for k in _leaves(SCHEMA)
        if k not in WORKFLOW_ONLY and k != "mounting" and not k.startswith("benchmark.")
    } <= {
        f"{s}.{k}" if s != "routes" else f"routes.*.{k}"
        for s, block in CFG.items()
        if isinstance(block, dict) and s != "mounting"
        for k in (block["r1"] if s == "routes" else block)
        for k in ([f"{k}.{j}" for j in block[k]] if k in ("split", "vertical") else [k])
    } | {"scenarios.intervals"}, "the test's config sets every key away from its default"
    _check_passed(tmp_path, CFG)


CFG_BENCH = {
    "routes": {"r1": CFG["routes"]["r1"], "r2": {"file": str(ROUTE)}},
    "grades": {"consumer": {}},
    "gnss": {"enabled": True},
    "figures": {"formats": ["png", "pdf"], "dpi": 80},
    "benchmark": {
        "train": ["r2"], "test": ["r1"], "outages_s": [10, 20],
        "model": {"steps": 7, "batch_size": 12, "windows_per_sequence": 3, "window": 30,
                  "width": 5, "learning_rate": 0.01, "smooth_s": 9.0},
    },
}  # fmt: skip
"""The benchmark's keys (a benchmark config builds only the benchmark), away from defaults."""


def test_the_benchmark_rules_pass_every_option_of_its_config(tmp_path):
    assert {k for k in _leaves(SCHEMA) if k.startswith("benchmark.")} - set(WORKFLOW_ONLY) <= {
        "benchmark.outages_s",
        *(f"benchmark.model.{k}" for k in CFG_BENCH["benchmark"]["model"]),
    }
    commands = _check_passed(tmp_path, CFG_BENCH, prefix="learn")
    assert commands == {"learn train", "learn correct", "learn table"}


def _check_passed(tmp_path, cfg, prefix="") -> set:
    """Every option of the commands (those starting with ``prefix``) a dry run of ``cfg``
    schedules is passed its config value; returns the commands."""
    write_config(tmp_path, cfg)
    given, commands = set(), set()
    for rule, argv in _job_commands(tmp_path):
        name = command_of(argv)
        if not name.startswith(prefix):
            continue
        cmd = dict(_commands())[name]
        commands.add(name)
        o = from_namespace(cmd.options, build_parser([name]).parse_args(argv))
        for f in cli_fields(cmd.options):
            key = f.metadata.get("config")
            flag = flag_of(f)
            flags = {flag, f"--no-{flag[2:]}"}  # --nhc / --no-nhc
            if key is None or not any(w.split("=")[0] in flags for w in argv):
                continue
            given.add((name, f.name))
            if (rule, f.name) not in NOT_PASSED:
                want = _config_value(cfg, key, "r1")
                assert _plain(getattr(o, f.name)) == _plain(want), (rule, f.name)
        if name == "aid" and "scenarios" in cfg:
            scen = cfg["scenarios"]
            assert _plain(o.intervals) == _plain(tuple(scen["intervals"]))
            assert _plain(o.outage_durations_s) == _plain(scen["outages_s"])
            assert set(o.draw_kinds) == {*scen["draw"], "outage"}
    missing = {
        (name, f.name)
        for name, cmd in _commands()
        if name in commands
        for f in cli_fields(cmd.options)
        if f.metadata.get("config") and (name, f.name) not in given
    }
    assert not missing, missing
    return commands
