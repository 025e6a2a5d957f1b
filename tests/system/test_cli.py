"""The command line: every option explained with its default written once; the parser loads
no stage (each command loads its own options module, then its stage when it runs)."""

from __future__ import annotations

import argparse
import dataclasses
import importlib
import importlib.util
import re
import subprocess
import sys

import pytest

from imugen.cli import COMMANDS, build_parser, command_of
from imugen.core.options import cli_fields, flag_of


def _subparsers(parser, prefix=()):
    for a in parser._actions:
        if isinstance(a, argparse._SubParsersAction):
            for name, sp in a.choices.items():
                yield (*prefix, name), sp
                yield from _subparsers(sp, (*prefix, name))


def _command(name):
    module, _ = COMMANDS[name]
    return importlib.import_module(module).COMMANDS[name]


def test_every_option_has_help():
    missing = [
        f"imugen {' '.join(name)} {a.option_strings[0]}"
        for name, sp in _subparsers(build_parser())
        for a in sp._actions
        if a.option_strings and a.dest != "help" and not a.help
    ]
    assert not missing, missing


@pytest.mark.parametrize("name", list(COMMANDS))
def test_help_shows_each_default_once(name):
    """An option with a default says it once, ``(default: X)`` from its dataclass field;
    argparse adds nothing (the help said defaults twice before)."""
    cmd = _command(name)
    p = build_parser([name])
    sub = dict(_subparsers(p))[tuple(name.split())]
    text = " ".join(sub.format_help().split())
    for f in cli_fields(cmd.options):
        action = next(a for a in sub._actions if a.dest == f.name)
        assert action.option_strings[0] == flag_of(f)
        assert action.help.count("(default:") <= 1 and "(default" not in f.metadata["help"], f
        if not (f.default in (None, (), dataclasses.MISSING) or isinstance(f.default, bool)):
            shown = re.escape(" ".join(action.help.replace("%%", "%").split()))
            assert len(re.findall(shown, text)) == 1, (name, f.name)
            assert "(default: " in action.help, (name, f.name)
    assert text.count("(default: ") == sum(
        a.help is not None and "(default: " in a.help for a in sub._actions
    )


def test_ingest_help_lists_every_format():
    """``imugen ingest --help`` names every format of the reader registry."""
    from imugen.ingest.formats import FORMATS

    sub = dict(_subparsers(build_parser(["ingest"])))[("ingest",)]
    text = " ".join(sub.format_help().split())
    for f in FORMATS:
        assert f.name in text, f.name


def test_vehicle_classes_are_those_of_both_stages():
    """The options list the vehicle classes themselves (they import no stage); ingest's
    cleaning limits and truth's motion models define exactly these."""
    from imugen.core.options import VEHICLES
    from imugen.ingest.clean import VEHICLE_LIMITS
    from imugen.truth.vehicles import VEHICLES as MODELS

    assert list(VEHICLES) == list(VEHICLE_LIMITS) == list(MODELS)


def test_the_command_of_argv():
    assert command_of(["simulate", "--grade", "x"]) == "simulate"
    assert command_of(["grade", "export", "consumer"]) == "grade export"
    assert command_of(["--version"]) is None and command_of(["nope"]) is None


def test_the_parser_imports_no_stage():
    """`imugen --help` loads no stage package: each command imports its own inside the
    dispatch, so a rule's code inputs are its stage's closure (workflow/rules/common.smk)."""
    code = "import sys, imugen.cli; print(sorted(m for m in sys.modules if m.startswith('imugen')))"
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert r.stdout.strip() == "['imugen', 'imugen.cli', 'imugen.core', 'imugen.core.errors']"


def test_the_commands_parsers_import_no_stage():
    """Every command's options (the whole parser) load no stage module and none of the
    numerical libraries (numpy only for ``closure``, whose check lives in the same module)."""
    code = (
        "import sys; from imugen.cli import build_parser; build_parser(); "
        "print(sorted(m for m in sys.modules if m.startswith('imugen'))); "
        "print([m for m in ('numba', 'pandas', 'pyarrow', 'scipy', 'pyproj', 'matplotlib', "
        "'flask') if m in sys.modules])"
    )
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    modules, heavy = r.stdout.splitlines()
    assert heavy == "[]"
    loaded = eval(modules)
    assert not [m for m in loaded if m.endswith((".stage", ".app", ".grade_io", ".mat"))], loaded
    assert {module for module, _ in COMMANDS.values()} <= set(loaded)


def test_an_option_value_is_refused_in_one_line(cli):
    """A value the options' parse refuses: one line naming the flag, status 2, no traceback."""
    r = cli("aid", "t.parquet", "s.parquet", "--gnss-out", "g.parquet", "-o", "a.parquet",
            "--lever-arm", "1,2")  # fmt: skip
    assert r.returncode == 2 and r.stderr == (
        "imugen: error: --lever-arm: expected X,Y,Z in metres, got '1,2'\n"
    )
    r = cli("simulate", "--static", "1", "--grade", "consumer", "--sequences", "1", "--seed",
            "1", "--shard", "0", "-o", "x.parquet", "--mounting", "{")  # fmt: skip
    assert r.returncode == 2 and r.stderr.startswith("imugen: error: --mounting: is not JSON")


@pytest.mark.parametrize("name", list(COMMANDS))
def test_each_command_runs_a_module_that_imports_its_options(name):
    """The function a command runs lives in a module that imports the command's options
    module at its top: the options are then in the code inputs of the rule that runs it
    (workflow/rules/common.smk: the closure of that module), although the parser loads them
    by name."""
    import ast

    options_module = COMMANDS[name][0]
    module = _command(name).run.partition(":")[0]
    if module == options_module:
        return
    spec = importlib.util.find_spec(module)
    tree = ast.parse(open(spec.origin).read())
    top = [n.module for n in tree.body if isinstance(n, ast.ImportFrom)]
    assert options_module in top or module == "imugen.web", (name, module)
