"""The command line: every option explained with its default, defaults equal to the workflow's."""

from __future__ import annotations

import argparse
from pathlib import Path

import pytest
import yaml

from imugen.cli import build_parser

REPO = Path(__file__).resolve().parents[2]


def _subparsers(parser, prefix=()):
    for a in parser._actions:
        if isinstance(a, argparse._SubParsersAction):
            for name, sp in a.choices.items():
                yield (*prefix, name), sp
                yield from _subparsers(sp, (*prefix, name))


def test_every_option_has_help():
    missing = []
    for name, sp in _subparsers(build_parser()):
        for a in sp._actions:
            if not a.option_strings or a.dest == "help" or isinstance(a, argparse._VersionAction):
                continue
            if not a.help:
                missing.append(f"imugen {' '.join(name)} {a.option_strings[0]}")
    assert not missing, missing


def _option(path, dest):
    p = build_parser()
    for name, sp in _subparsers(p):
        if name == path:
            return next(a.default for a in sp._actions if a.dest == dest)
    raise KeyError(path)


@pytest.mark.parametrize(
    "command, dest, section, key",
    [
        (("truth",), "earth", "truth", "earth"),
        (("truth",), "rate_hz", "truth", "rate_hz"),
        (("navigate",), "eval_rate_hz", "navigate", "eval_rate_hz"),
        (("simulate",), "outputs", "simulate", "outputs"),
        (("simulate",), "draw", "simulate", "draw"),
        (("simulate",), "dtype", "simulate", "dtype"),
        (("figures",), "dpi", "figures", "dpi"),
        (("figures",), "zoom_fraction", "figures", "zoom_fraction"),
        (("figures",), "representative", "figures", "representative"),
    ],
)
def test_cli_defaults_agree_with_the_workflow(command, dest, section, key):
    schema = yaml.safe_load((REPO / "workflow" / "schemas" / "config.schema.yaml").read_text())
    default = schema["properties"][section]["properties"][key]["default"]
    assert _option(command, dest) == default


def test_vehicle_classes_are_those_of_both_stages():
    """The parser lists the vehicle classes itself (it imports no stage); ingest's cleaning
    limits and truth's motion models define exactly these."""
    from imugen.cli import VEHICLES
    from imugen.ingest.clean import VEHICLE_LIMITS
    from imugen.truth.vehicles import VEHICLES as MODELS

    assert list(VEHICLES) == list(VEHICLE_LIMITS) == list(MODELS)


def test_the_parser_imports_no_stage():
    """`imugen --help` loads no stage package: each command imports its own inside the
    dispatch, so a rule's code inputs are its stage's closure (workflow/rules/common.smk)."""
    import subprocess
    import sys

    code = "import sys, imugen.cli; print(sorted(m for m in sys.modules if m.startswith('imugen')))"
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert r.stdout.strip() == "['imugen', 'imugen.cli', 'imugen.core', 'imugen.core.errors']"


def _option_helps(sp):
    """Each option's rendered help text, as ``imugen COMMAND -h`` prints it."""
    fmt = sp._get_formatter()
    for a in sp._actions:
        if a.option_strings and a.help and a.dest != "help":
            yield a, " ".join(fmt._expand_help(a).split())


def test_each_default_is_printed_once():
    """One formatter prints the defaults: an option's help never states its default twice (the
    argparse formatter's ``(default: X)`` beside a hand-written "default ..."), and every option
    with a default value shows it as ``(default: X)``."""
    twice, missing = [], []
    for name, sp in _subparsers(build_parser()):
        for a, text in _option_helps(sp):
            where = f"imugen {' '.join(name)} {a.option_strings[-1]}: {text}"
            if text.lower().count("default") > 1:
                twice.append(where)
            shown = a.default not in (None, argparse.SUPPRESS, []) and not isinstance(
                a.default, bool
            )
            if shown and f"(default: {a.default})" not in text:
                missing.append(where)
    assert not twice, twice
    assert not missing, missing


def test_ingest_help_lists_every_format_of_the_reader_registry():
    from imugen.ingest.readers import FORMATS
    from imugen.ingest.readers.babel import FORMATS as BABEL

    p = next(sp for name, sp in _subparsers(build_parser()) if name == ("ingest",))
    text = " ".join(p.format_help().split())
    assert len(FORMATS) >= 9 + len(BABEL)
    for f in FORMATS:
        assert f.name in text, f.name
    assert {s for f in FORMATS if f.module == "babel" for s in f.suffixes} == set(BABEL)
