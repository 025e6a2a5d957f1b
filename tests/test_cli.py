"""The command line: every option explained with its default, defaults equal to the workflow's."""

from __future__ import annotations

import argparse
from pathlib import Path

import pytest
import yaml

from imugen.cli import build_parser

REPO = Path(__file__).resolve().parents[1]


def _subparsers(parser, prefix=()):
    for a in parser._actions:
        if isinstance(a, argparse._SubParsersAction):
            for name, sp in a.choices.items():
                yield (*prefix, name), sp
                yield from _subparsers(sp, (*prefix, name))


def test_every_option_has_help_and_shows_its_default():
    missing = []
    for name, sp in _subparsers(build_parser()):
        text = sp.format_help()
        for a in sp._actions:
            if not a.option_strings or a.dest == "help" or isinstance(a, argparse._VersionAction):
                continue
            if not a.help:
                missing.append(f"imugen {' '.join(name)} {a.option_strings[0]}")
            elif a.default not in (None, False, argparse.SUPPRESS) and not isinstance(
                a, argparse._StoreTrueAction
            ):
                assert "(default:" in text, (name, a.option_strings)
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
