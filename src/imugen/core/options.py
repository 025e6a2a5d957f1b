"""Options of the commands: one frozen dataclass per command, its fields the command's options.

A field made by :func:`option` carries in its metadata what the command line and the workflow
need: the help text, the flag (``--rate-hz`` from ``rate_hz`` unless given), the choices, the
unit, the config key it corresponds to (in workflow/schemas/config.schema.yaml, e.g.
``"simulate.draw"``; ``"routes.*.vehicle"`` for a key of every route) and, for a value the
command line spells as text (``X,Y,Z``, JSON, ``NAME=VALUE``), the function that parses it.
The field's default is the one default of the option: :func:`add_options` writes it into the
help (once), :func:`from_namespace` takes it when the option is not given, and
tests/system/test_options.py checks that the schema has the same.

A :class:`Command` pairs an options class with the command's inputs and outputs (positional
files, ``-o``), declared as argparse takes them, and names the function it runs:
``module:function``, called as ``function(options, **inputs_and_outputs)``.

Kinds of option, from the field's type and default:

- a value (``int``, ``float``, ``str``; or any type with ``parse``): ``--name VALUE``; no
  default makes it required;
- ``bool`` defaulting to False: a switch ``--name``; defaulting to True: a switch whose flag
  starts with ``--no-`` (``flag="--no-zupt"``); ``bool | None``: ``--name`` / ``--no-name``;
- ``many="append"`` (repeatable ``--name V``) or ``many="+"`` (``--name V [V ...]``): a tuple.

This module imports only the standard library: the parser of a command loads the command's
options module and nothing of its stage (tests/system/test_cli.py).
"""

from __future__ import annotations

import argparse
import dataclasses
import importlib
import types
import typing
from collections.abc import Callable

from imugen.core.errors import InputError

VEHICLES = ("car", "bicycle", "pedestrian", "aircraft", "airliner", "multirotor")
"""Vehicle classes: the cleaning limits of ``ingest`` and the motion models of ``truth``
(tests/system/test_cli.py checks that both stages define exactly these)."""
DRAWS = ("ranges", "nominal")
"""How a sequence's error levels are drawn: within the preset's ranges, or nominal."""


def option(
    default=dataclasses.MISSING,
    *,
    help: str,
    flag: str | None = None,
    metavar: str | None = None,
    choices: tuple | None = None,
    unit: str | None = None,
    config: str | None = None,
    parse: Callable | None = None,
    many: str | None = None,
    shown: str | None = None,
    cli: bool = True,
) -> dataclasses.Field:
    """A field of an options dataclass (``dataclasses.field`` with the option's metadata).

    Parameters
    ----------
    default
        The option's default (none: the option is required). Tuples for ``many`` options.
    help : str
        What the option does, without its default or unit (both are added).
    flag : str, optional
        Command-line flag; default ``--`` + the field name with ``-`` for ``_``.
    metavar, choices
        As argparse takes them.
    unit : str, optional
        Unit of the value (``"Hz"``, ``"s"``, ``"m"``), shown in the help.
    config : str, optional
        Key of the workflow config this option corresponds to, dotted (``"gnss.rate_hz"``;
        ``"routes.*.vehicle"``): the rules pass that key's value as this option.
    parse : callable, optional
        Text (or tuple of texts, for ``many``) -> value, raising ValueError with a one-line
        message (printed as ``imugen: error: --flag: message``).
    many : {"append", "+"}, optional
        A repeatable option, or one taking one or more values.
    shown : str, optional
        What the help says the default is, when the default value alone does not say it
        (``"the receiver's"`` for None).
    cli : bool
        False: an option of the Python API only (no flag).
    """
    meta = {
        "help": help, "flag": flag, "metavar": metavar, "choices": choices, "unit": unit,
        "config": config, "parse": parse, "many": many, "shown": shown, "cli": cli,
    }  # fmt: skip
    return dataclasses.field(default=default, metadata=meta)


def same_as(cls: type, name: str, **changes) -> dataclasses.Field:
    """A new field with the default and metadata of ``cls``'s field ``name`` (with
    ``changes`` to its metadata): one option shared by two commands, written once."""
    f = next(f for f in dataclasses.fields(cls) if f.name == name)
    return dataclasses.field(default=f.default, metadata={**f.metadata, **changes})


def flag_of(f: dataclasses.Field) -> str:
    """The command-line flag of field ``f``."""
    return f.metadata.get("flag") or "--" + f.name.replace("_", "-")


def cli_fields(cls: type) -> list[dataclasses.Field]:
    """The fields of options class ``cls`` that are command-line options."""
    return [f for f in dataclasses.fields(cls) if f.metadata.get("cli")]


def _scalar(tp) -> type:
    """The argparse ``type`` of annotation ``tp``: int, float or str (None dropped, the
    element type of a tuple)."""
    if isinstance(tp, types.UnionType) or typing.get_origin(tp) is typing.Union:
        args = [a for a in typing.get_args(tp) if a is not type(None)]
        tp = args[0] if len(args) == 1 else str
    if typing.get_origin(tp) is tuple:
        tp = typing.get_args(tp)[0]
    return tp if tp in (int, float, str) else str


def _show(value, sep: str) -> str:
    if isinstance(value, tuple):
        return sep.join(_show(v, sep) for v in value)
    return f"{value:g}" if isinstance(value, float) else str(value)


def _unshown(default) -> bool:
    """A default the help does not state: none, a switch's, an empty tuple."""
    return (
        default is dataclasses.MISSING
        or default is None
        or isinstance(default, bool)
        or (default == ())
    )


def help_text(f: dataclasses.Field) -> str:
    """The help of field ``f``'s option: its text, unit and default (once)."""
    m = f.metadata
    text = m["help"] + (f" [{m['unit']}]" if m.get("unit") else "")
    shown = m.get("shown")
    if shown is None and not _unshown(f.default):
        shown = _show(f.default, " " if m.get("many") == "+" else ",")
    return text + (f" (default: {shown})" if shown else "")


def add_options(parser: argparse.ArgumentParser, cls: type) -> None:
    """Add the options of dataclass ``cls`` to ``parser`` (dest: the field name)."""
    hints = typing.get_type_hints(cls)
    for f in cli_fields(cls):
        m = f.metadata
        flag = flag_of(f)
        kw = {"dest": f.name, "help": help_text(f).replace("%", "%%")}
        tp = hints[f.name]
        if tp is bool or tp == bool | None:
            if f.default is None:
                kw.update(action=argparse.BooleanOptionalAction, default=None)
            elif f.default is True:
                if not flag.startswith("--no-"):
                    raise TypeError(f"{cls.__name__}.{f.name}: a True switch is --no-...")
                kw.update(action="store_false", default=True)
            else:
                kw.update(action="store_true", default=False)
            parser.add_argument(flag, **kw)
            continue
        kw.update(
            type=str if m.get("parse") else _scalar(tp),
            default=None,
            required=f.default is dataclasses.MISSING,
        )
        if m.get("many") == "append":
            kw["action"] = "append"
        elif m.get("many") == "+":
            kw["nargs"] = "+"
        if m.get("choices") is not None:
            kw["choices"] = m["choices"]
        else:
            kw["metavar"] = m.get("metavar") or flag.lstrip("-").replace("-", "_").upper()
        parser.add_argument(flag, **kw)


def from_namespace(cls: type, ns: argparse.Namespace):
    """The options object of ``cls`` from parsed arguments: an option not given takes the
    field's default; ``parse`` turns text into the value (its ValueError -> InputError
    naming the flag)."""
    kw = {}
    for f in cli_fields(cls):
        value = getattr(ns, f.name)
        if value is None:
            continue
        if isinstance(value, list):
            value = tuple(value)
        parse = f.metadata.get("parse")
        if parse is not None:
            try:
                value = parse(value)
            except ValueError as exc:
                raise InputError(flag_of(f), str(exc)) from None
        kw[f.name] = value
    return cls(**kw)


@dataclasses.dataclass(frozen=True)
class Command:
    """A command of ``imugen``.

    Attributes
    ----------
    options : type
        Its options dataclass.
    run : str
        ``"module:function"``, called as ``function(options, **inputs_and_outputs)``.
    arguments : tuple of (tuple of str, dict)
        Its inputs and outputs, as ``parser.add_argument(*flags, **kwargs)`` takes them
        (:func:`argument`), passed to ``run`` by their argparse ``dest``.
    """

    options: type
    run: str
    arguments: tuple = ()

    def add_to(self, parser: argparse.ArgumentParser) -> None:
        """Declare the command's inputs, outputs and options on ``parser``."""
        dests = [parser.add_argument(*flags, **kw).dest for flags, kw in self.arguments]
        add_options(parser, self.options)
        parser.set_defaults(_command=self, _io=tuple(dests))

    def __call__(self, ns: argparse.Namespace):
        """Run the command on parsed arguments ``ns``."""
        options = from_namespace(self.options, ns)
        module, _, name = self.run.partition(":")
        func = getattr(importlib.import_module(module), name)
        return func(options, **{d: getattr(ns, d) for d in ns._io})


def argument(*flags: str, **kwargs) -> tuple:
    """An input or output of a command, as ``parser.add_argument`` takes it."""
    return flags, kwargs


def pairs(items, flag: str) -> dict[str, list]:
    """``GRADE=PATH`` values of option ``flag`` -> ``{grade: [paths]}`` in the given order
    (None: no values); InputError naming ``flag`` for a value without ``=``."""
    out: dict[str, list] = {}
    for item in items or ():
        key, sep, value = item.partition("=")
        if not sep or not key or not value:
            raise InputError(flag, f"{item!r} is not GRADE=PATH")
        out.setdefault(key, []).append(value)
    return out


def floats(text: str, n: int | None = None, what: str = "comma-separated numbers") -> tuple:
    """``"A,B,..."`` -> floats (``n`` of them when given; ``parse`` of ``X,Y,Z`` options)."""
    try:
        out = tuple(float(x) for x in text.split(","))
    except ValueError:
        out = ()
    if not out or (n is not None and len(out) != n):
        raise ValueError(f"expected {what}, got {text!r}")
    return out
