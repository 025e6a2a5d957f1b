"""Option values that start with ``-`` (issue 22): a southern origin, a path named ``-...``.

The workflow passes every option value as ``--name=value``; the command line also takes
``--origin -33.9,...`` (a negative number list) and says how to write any other value that
starts with ``-``.
"""

from __future__ import annotations

import argparse
import itertools
import re
import shlex
from pathlib import Path

import numpy as np

from imugen.cli import build_parser
from imugen.core.io import read_meta

from helpers import ROUTE
from helpers import snakemake as _snakemake
from helpers import write_config as _config

SOUTH = (-33.9, 151.2, 10.0)


def _gpx(path: Path) -> Path:
    """Two tracks in Sydney; the one to use is named ``-harbour``."""

    def trk(name, lat0, n):
        pts = "".join(
            f'<trkpt lat="{lat0 + 1e-4 * k:.6f}" lon="{151.2 + 2e-4 * k:.6f}"><ele>10</ele></trkpt>'
            for k in range(n)
        )
        return f"<trk><name>{name}</name><trkseg>{pts}</trkseg></trk>"

    path.write_text(
        f'<gpx version="1.1">{trk("-harbour", -33.86, 40)}{trk("other", -33.80, 5)}</gpx>'
    )
    return path


def _enu(path: Path) -> Path:
    """An untimed E N U square of 400 m (metres from an origin the config gives)."""
    side = np.linspace(0, 400, 41)
    zero, top = np.zeros_like(side), np.full_like(side, 400.0)
    e = np.concatenate([side, top, side[::-1], zero])
    n = np.concatenate([zero, side, top, side[::-1]])
    path.write_text("".join(f"{a:.1f} {b:.1f} 5.0\n" for a, b in zip(e, n, strict=True)))
    return path


def test_cli_takes_a_southern_origin_written_either_way(tmp_path, cli):
    for origin in (["--origin", "-33.9,151.2,10"], ["--origin=-33.9,151.2,10"]):
        out = tmp_path / "r.parquet"
        cli("ingest", ROUTE, "-o", out, *origin, check=0)
        assert read_meta(out)["origin"]["lat_deg"] == -33.9
        out.unlink()


def test_cli_hint_for_another_value_starting_with_a_dash(tmp_path, cli):
    gpx = _gpx(tmp_path / "two.gpx")
    proc = cli("ingest", gpx, "-o", tmp_path / "r.parquet", "--path", "-harbour", check=2)
    last = proc.stderr.strip().splitlines()[-1]
    assert "--path=VALUE" in last and "expected one argument" in last
    cli("ingest", gpx, "-o", tmp_path / "r.parquet", "--path=-harbour", check=0)
    assert read_meta(tmp_path / "r.parquet")["path"] == "-harbour"


def test_negative_values_join_only_options_with_one_value():
    from imugen.cli import _join_negative_values

    p = build_parser()
    assert _join_negative_values(p, ["aid", "t", "s", "--lever-arm", "-1,0,0.5"]) == [
        "aid",
        "t",
        "s",
        "--lever-arm=-1,0,0.5",
    ]
    # a flag never takes the next word; a word after `--` stays as it is
    assert _join_negative_values(p, ["ingest", "--utm", "-1"]) == ["ingest", "--utm", "-1"]
    assert _join_negative_values(p, ["ingest", "--", "--origin", "-1"])[-2:] == ["--origin", "-1"]


def _single_valued() -> dict[str, set[str]]:
    """Per subcommand, its options that take one value."""
    p = build_parser()
    sub = next(a for a in p._actions if isinstance(a, argparse._SubParsersAction))
    return {
        name: {
            s
            for a in sp._actions
            if a.nargs is None and isinstance(a, (argparse._StoreAction, argparse._AppendAction))
            for s in a.option_strings
        }
        for name, sp in sub.choices.items()
    }


def test_every_rule_passes_option_values_as_name_equals_value(tmp_path):
    """The dry run's shell commands of a config using every optional stage: no option that
    takes one value is followed by its value as a separate word."""
    cfg = {
        "routes": {"south": {"file": str(_gpx(tmp_path / "two.gpx")), "path": "-harbour",
                             "origin": list(SOUTH), "max_gap_s": 30, "max_extent_km": 50}},
        "truth": {"rate_hz": 10, "earth": "auto"},
        "grades": {"consumer": {}, "mine": {
            "id": 101, "gyro": {"white_noise": {"value": 0.2, "unit": "deg_per_sqrt_h"}},
            "accel": {"white_noise": {"value": 0.05, "unit": "m_per_s_per_sqrt_h"}}}},
        "simulate": {"sequences": 2, "sequences_per_shard": 2},
        "allan": {"static_s": 60, "rate_hz": 10, "sequences": 1},
        "gnss": {"enabled": True, "lever_arm_b_m": [-0.5, 0, 1]},
        "companions": {"odometer": "abs", "barometer": "bmp388"},
        "evaluate": {"segments_s": [30]},
        "exports": {"mat": True, "formats": ["tum", "ros2"],
                    "split": {"by": "route", "holdout_routes": ["south"]}},
        "mounting": {"enabled": True},
    }  # fmt: skip
    _config(tmp_path, cfg)
    proc = _snakemake(tmp_path, "-n", "-j1", "-p")
    assert proc.returncode == 0, proc.stderr[-3000:]
    text = proc.stdout + proc.stderr
    commands = [c for c in re.findall(r"^Shell command: (.+)$", text, flags=re.M) if "imugen " in c]
    stages = {c.split("imugen ", 1)[1].split()[0] for c in commands}
    assert len(stages) >= 10, stages
    single = _single_valued()
    for cmd in commands:
        words = shlex.split(cmd.split(" > ")[0])
        stage = words[words.index("imugen") + 1]
        for w, nxt in itertools.pairwise(words):
            assert w not in single[stage], f"{w} {nxt}: in {cmd}"
    assert any("--origin=-33.9,151.2,10.0" in c for c in commands)
    assert any("--path=-harbour" in c for c in commands)


def test_workflow_runs_a_southern_route_and_a_path_named_with_a_dash(tmp_path):
    """A GPX route whose chosen path is named ``-harbour`` with a southern origin, and an E N U
    file placed by a southern origin: both reach their truth."""
    cfg = {
        "routes": {
            "harbour": {"file": str(_gpx(tmp_path / "two.gpx")), "path": "-harbour",
                        "origin": list(SOUTH)},
            "square": {"file": str(_enu(tmp_path / "square.txt")), "origin": list(SOUTH),
                       "dt_s": 1.0},
        },
        "truth": {"rate_hz": 10, "earth": "wgs84"},
        "grades": {"consumer": {}},
    }  # fmt: skip
    _config(tmp_path, cfg)
    proc = _snakemake(
        tmp_path, "-j2", "results/harbour/truth.parquet", "results/square/truth.parquet"
    )
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    for route in ("harbour", "square"):
        meta = read_meta(tmp_path / "results" / route / "enu.parquet")
        assert meta["origin"]["lat_deg"] == SOUTH[0] and meta["origin"]["lon_deg"] == SOUTH[1]
        assert (tmp_path / "results" / route / "truth.parquet").is_file()
    assert read_meta(tmp_path / "results" / "harbour" / "enu.parquet")["path"] == "-harbour"
