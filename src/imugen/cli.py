"""Command line: ``imugen <command> ...``, a dispatcher onto the stages.

Each command is declared by its stage, in a light ``options`` module
(:class:`imugen.core.options.Command`: the options dataclass, the inputs and outputs, the
function it runs); this module lists the commands and loads only the one asked for, so that
starting a command imports its options and its stage and nothing of the others (the rules'
code inputs, workflow/rules/common.smk, rely on it).

A user's mistake (bad file, bad option) prints one line ``imugen: error: FILE: problem``
and exits with status 2; no traceback, no partial output. A warning a stage raises
(``warnings.warn``, a UserWarning) prints one line ``imugen: warning: message``; other
categories (a library's RuntimeWarning) keep their category and origin on that one line.
Control characters that a file could smuggle into a message (terminal escapes, carriage
returns) are printed escaped.
"""

from __future__ import annotations

import argparse
import importlib
import re
import sys
import warnings

from imugen import __version__
from imugen.core.errors import InputError, printable

COMMANDS = {
    "ingest": ("imugen.ingest.options", "route file -> geodetic table + local ENU (.parquet/.csv)"),
    "truth": ("imugen.truth.options", "ENU route -> 6-DoF truth and ideal IMU at the IMU rate"),
    "closure": ("imugen.closure", "ingest -> truth -> mechanize the ideal IMU; print errors"),
    "simulate": ("imugen.simulate.options", "truth (or a still IMU) -> one shard of erroneous IMU"),
    "navigate": (
        "imugen.navigate.options",
        "shard of IMU sequences -> strapdown -> errors vs truth",
    ),
    "aid": ("imugen.aid.options", "shard + GNSS with scenarios -> aided (GNSS/INS) nav errors"),
    "evaluate": (
        "imugen.evaluate.options",
        "navigation errors of one grade -> per-sequence RMSE",
    ),
    "tables": ("imugen.evaluate.options", "per-grade metrics -> RMSE table (CSV, MD, TeX, HTML)"),
    "figures": ("imugen.figures.options", "route figures: Figure 8, 3-D, errors vs time, IMU"),
    "outage-figure": (
        "imugen.figures.options",
        "aided error growth during GNSS outages per grade, free inertial beside",
    ),
    "outage-drift": (
        "imugen.figures.options",
        "per-grade metrics -> drift at the end of each GNSS outage (table, figure)",
    ),
    "export-mat": (
        "imugen.export.options",
        "one grade's truth, IMU, labels, errors -> MATLAB .mat",
    ),
    "serve": ("imugen.web.options", "local web page: upload a route, pick grades, run, download"),
    "export": (
        "imugen.export.options",
        "shards -> EuRoC, TUM, TLIO, RoNIN, KF-GINS or ROS 2 bag datasets",
    ),
    "grade import": ("imugen.sensors.options", "IMU description -> imugen custom grade (YAML)"),
    "grade export": (
        "imugen.sensors.options",
        "grade -> Kalibr imu.yaml (white noise + random walk)",
    ),
    "grade fit": (
        "imugen.sensors.options",
        "still IMU log -> fitted grade (YAML) + Allan figure",
    ),
    "allan": ("imugen.allan.options", "Allan deviation of a static shard against its grade"),
    "vibration fit": (
        "imugen.sensors.options",
        "IMU recording (minus its truth) -> vibration model: broadband + rotation harmonics",
    ),
    "learn train": (
        "imugen.learn.options",
        "truth of training routes -> reference network (.pt; the optional torch extra)",
    ),
    "learn correct": ("imugen.learn.options", "network + IMU shard -> IMU correction Parquet"),
    "learn table": (
        "imugen.learn.options",
        "metrics of the GNSS-denied benchmark -> its table (CSV, MD) and figure",
    ),
}
"""Command -> (module declaring it in its ``COMMANDS``, one-line help)."""
GROUPS = {
    "grade": "import a Kalibr/VINS/i2Nav/datasheet IMU description; export Kalibr; fit a log",
    "vibration": "fit a vibration model to a recording",
    "learn": "the GNSS-denied benchmark's reference network: train, correct a shard, table",
}
"""Commands of two words: the first word's help."""


class _Parser(argparse.ArgumentParser):
    """argparse, with a hint when an option's value was taken for an option (``-33.9,...``)."""

    def error(self, message: str):
        m = re.match(r"argument ([-\w/]+)(?:/(--[-\w]+))?: expected one argument", message)
        if m:
            name = m.group(2) or m.group(1).split("/")[-1]
            message += (
                f" (a value starting with '-' is written {name}=VALUE, "
                f"e.g. --origin=-33.9,151.2,10)"
            )
        super().error(message)


_NEGATIVE = re.compile(r"^-(?:\d|\.\d)[\d.,eE+-]*$")
"""A value that looks like a negative number or a comma-separated list starting with one."""


def _valued_options(parser: argparse.ArgumentParser) -> set[str]:
    """Option strings of ``parser`` that take exactly one value."""
    return {
        s
        for a in parser._actions
        if a.nargs is None and isinstance(a, (argparse._StoreAction, argparse._AppendAction))
        for s in a.option_strings
    }


def _join_negative_values(parser: argparse.ArgumentParser, argv: list[str]) -> list[str]:
    """``--origin -33.9,151.2,10`` -> ``--origin=-33.9,151.2,10`` (argparse would take the
    value for an option); only for options that take one value, only for number-like values."""
    sub = next((a for a in parser._actions if isinstance(a, argparse._SubParsersAction)), None)
    out: list[str] = []
    valued = _valued_options(parser)
    i = 0
    while i < len(argv):
        tok = argv[i]
        if sub is not None and tok in sub.choices:
            return [*out, tok, *_join_negative_values(sub.choices[tok], argv[i + 1 :])]
        if tok == "--":
            return [*out, *argv[i:]]
        if tok in valued and i + 1 < len(argv) and _NEGATIVE.match(argv[i + 1]):
            out.append(f"{tok}={argv[i + 1]}")
            i += 2
            continue
        out.append(tok)
        i += 1
    return out


def build_parser(commands=None) -> argparse.ArgumentParser:
    """The parser of ``imugen``; ``commands``: the commands whose options it loads (names of
    :data:`COMMANDS`; default all), the others listed by name and help only."""
    parser = _Parser(prog="imugen", description=__doc__.splitlines()[0])
    parser.add_argument("--version", action="version", version=f"imugen {__version__}")
    sub = parser.add_subparsers(dest="command", required=True)
    groups = {}
    for name, (module, help) in COMMANDS.items():
        group, _, word = name.rpartition(" ")
        where = sub
        if group:
            if group not in groups:
                g = sub.add_parser(group, help=GROUPS[group])
                groups[group] = g.add_subparsers(dest=f"{group}_command", required=True)
            where = groups[group]
        p = where.add_parser(word, help=help, description=help)
        if commands is None or name in commands:
            importlib.import_module(module).COMMANDS[name].add_to(p)
    return parser


def command_of(argv: list[str]) -> str | None:
    """The command ``argv`` names (``"grade import"`` for two words), or None."""
    words = [a for a in argv if not a.startswith("-")]
    if words and words[0] in GROUPS and len(words) > 1:
        return f"{words[0]} {words[1]}"
    return words[0] if words and words[0] in COMMANDS else None


def _show_warning(message, category, filename, lineno, file=None, line=None) -> None:
    """``warnings.showwarning`` of the command line: one line on stderr, no source line."""
    text = f"imugen: warning: {message}"
    if category is not UserWarning:
        text = f"imugen: warning: {category.__name__}: {message} ({filename}:{lineno})"
    print(printable(text), file=sys.stderr if file is None else file)


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else list(argv)
    name = command_of(argv)
    parser = build_parser([name] if name else [])
    args = parser.parse_args(_join_negative_values(parser, argv))
    try:
        with warnings.catch_warnings():
            warnings.showwarning = _show_warning
            return args._command(args) or 0
    except InputError as exc:
        print(printable(f"imugen: error: {exc}"), file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("imugen: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
