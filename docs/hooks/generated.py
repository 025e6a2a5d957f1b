"""MkDocs hook: the parts of the documentation that are generated from the code at every build.

A page asks for a part with a line ``<!-- generated: NAME -->``; the hook replaces the line with
the part, so the documentation cannot drift from the code:

- ``cli``: every ``imugen`` command's usage and options, from ``imugen.cli.build_parser()`` and
  the options dataclasses it is made from (meaning, unit, default and config key of each);
- ``config``: every configuration key (path, type, default, bounds, description), from
  ``workflow/schemas/config.schema.yaml``;
- ``files``: every file that passes between stages, its columns and units, from ``imugen.tables``;
- ``readers``: the route formats ingestion reads, from the registry ``imugen.ingest.formats``;
- ``rulegraph``: ``snakemake --rulegraph`` turned from DOT into a Mermaid diagram;
- ``house``: stage -> rule -> rule file -> package -> command -> tests -> files in and out, from
  the rule files, the command line and a dry run of the workflow;
- ``packages``: every package and top-level module of ``src/imugen`` with the first sentence of
  its docstring, and its test folder.

The rule graph and the map come from the workflow run on ``config/config.yaml`` plus
``docs/hooks/house.yaml`` (every optional rule on), in a scratch directory. An unknown part, or
one that cannot be generated, fails the build.
"""

from __future__ import annotations

import argparse
import ast
import inspect
import json
import re
import subprocess
import sys
import tempfile
import textwrap
from functools import cache
from pathlib import Path

import yaml

REPO = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(REPO / "src"))  # this checkout's code, whatever the environment installed

MARKER = re.compile(r"^<!-- generated: ([a-z]+) -->$", re.M)
HOUSE_CONFIG = REPO / "docs" / "hooks" / "house.yaml"


def on_pre_build(config):
    for fn in (*GENERATORS.values(), _workflow):
        fn.cache_clear()  # `mkdocs serve` rebuilds after an edit: regenerate


def on_page_markdown(markdown, page, config, files):
    def part(m):
        name = m.group(1)
        if name not in GENERATORS:
            raise ValueError(f"{page.file.src_path}: unknown generated part {name!r}")
        return GENERATORS[name]()

    return MARKER.sub(part, markdown)


# --- helpers ------------------------------------------------------------------------------------
def _cell(text) -> str:
    """Text fit for one Markdown table cell."""
    return " ".join(str(text).split()).replace("|", "\\|")


def _markdown(text: str) -> str:
    """A docstring's reStructuredText roles and literals as Markdown code spans."""

    def role(m):
        return f"`{m.group(1).lstrip('~')}`"

    text = re.sub(r":\w+:`([^`]+)`", role, text)
    return re.sub(r"``([^`]+)``", r"`\1`", text).replace("`~", "`")


def _code(value) -> str:
    text = json.dumps(value) if not isinstance(value, str) else value
    return f"`{_cell(text)}`"


def _table(head: list[str], rows: list[list[str]]) -> str:
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    lines += ["| " + " | ".join(r) + " |" for r in rows]
    return "\n".join(lines)


# --- the command line ---------------------------------------------------------------------------
def _subcommands(parser, prefix=()):
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            helps = {a.dest: a.help for a in action._choices_actions}
            for name, sub in action.choices.items():
                yield (*prefix, name), sub, helps.get(name, "")
                yield from _subcommands(sub, (*prefix, name))


def _names(action, value=None) -> str:
    """An argument as the house writes it: ``--name=VALUE`` for an option taking a value."""
    plain = argparse.HelpFormatter("imugen")
    value = value or action.metavar or action.dest.upper()
    if not action.option_strings:
        return f"`{plain._format_args(action, action.metavar or action.dest)}`"
    if action.nargs == 0:
        return ", ".join(f"`{o}`" for o in action.option_strings)
    if action.choices:
        value = "{" + ",".join(str(c) for c in action.choices) + "}"
    spelled = plain._format_args(action, value)

    def one(o):  # a long option takes its value after "=", a short one or a list after a space
        sep = "=" if o.startswith("--") and action.nargs not in ("+", "*") else " "
        return f"`{o}{sep}{spelled}`"

    return ", ".join(one(o) for o in action.option_strings)


def _io_row(action) -> list[str]:
    """An input or output of a command (positional files, ``-o``)."""
    shown = "required" if action.required or action.nargs not in ("?", "*") else ""
    if action.option_strings and not action.required:
        shown = "" if action.default in (None, []) else _code(action.default)
    return [_names(action), _cell(action.help or ""), shown, ""]


def _option_row(action, f) -> list[str]:
    """An option, from its dataclass field (help, unit, default, config key written once)."""
    from imugen.core.options import help_text

    m = f.metadata
    meaning = m["help"] + (f" [{m['unit']}]" if m.get("unit") else "")
    shown = help_text(f).removeprefix(meaning).strip()
    shown = shown.removeprefix("(default: ").removesuffix(")")
    if action.required:
        shown = "required"
    elif shown and m.get("shown") is None:  # a value, as written on the command line
        shown = f"`{shown}`"
    config = f"`{m['config']}`" if m.get("config") else ""
    return [_names(action), _cell(meaning), _cell(shown), config]


@cache
def cli() -> str:
    from imugen.cli import build_parser
    from imugen.core.options import cli_fields

    out = []
    for path, sub, summary in _subcommands(build_parser()):
        if any(isinstance(a, argparse._SubParsersAction) for a in sub._actions):
            out += [f"## imugen {' '.join(path)}", "", _cell(summary), ""]
            continue
        command = sub.get_default("_command")
        out += [f"## imugen {' '.join(path)}", "", _cell(summary) + ".", ""]
        usage = " ".join(sub.format_usage().split()).removeprefix("usage: ")
        out += ["```text", usage, "```", ""]
        fields = {f.name: f for f in cli_fields(command.options)}
        rows = [
            _option_row(a, fields[a.dest]) if a.dest in fields else _io_row(a)
            for a in sub._actions
            if a.dest != "help"
        ]
        out += [_table(["argument", "meaning", "default", "config key"], rows), ""]
    return "\n".join(out)


# --- the configuration --------------------------------------------------------------------------
def _type(spec: dict) -> str:
    if "enum" in spec:
        return "one of " + ", ".join(_code(v) for v in spec["enum"])
    if "oneOf" in spec:
        return " or ".join(_type(s) for s in spec["oneOf"])
    t = spec.get("type", "any")
    kinds = t if isinstance(t, list) else [t]
    text = " or ".join(k for k in kinds)
    if "array" in kinds:
        items = spec.get("items") or {}
        if "prefixItems" in spec:
            text = "array [" + ", ".join(_type(s) for s in spec["prefixItems"]) + "]"
        elif items:
            text = text.replace("array", f"array of {_type(items)}")
    return text


def _bounds(spec: dict) -> str:
    parts = []
    for key, sign in (
        ("minimum", ">="),
        ("exclusiveMinimum", ">"),
        ("maximum", "<="),
        ("exclusiveMaximum", "<"),
    ):
        if key in spec:
            parts.append(f"{sign} {spec[key]:g}")
    for key, what in (("minItems", "at least {} items"), ("maxItems", "at most {} items")):
        if key in spec and not (spec.get("minItems") == spec.get("maxItems") and key == "maxItems"):
            n = spec[key]
            parts.append(
                f"exactly {n} items"
                if spec.get("minItems") == spec.get("maxItems")
                else what.format(n)
            )
    if spec.get("uniqueItems"):
        parts.append("no repeats")
    items = spec.get("items") or {}
    if isinstance(items, dict) and items.get("type") in ("number", "integer"):
        inner = _bounds(items)
        if inner:
            parts.append(f"each {inner}")
    for i, s in enumerate(spec.get("prefixItems", [])):
        inner = _bounds(s)
        if inner:
            parts.append(f"item {i + 1} {inner}")
    if "pattern" in spec:
        parts.append(f"matches `{spec['pattern']}`")
    return "; ".join(parts)


def _rows(spec: dict, path: str, required=()) -> list[list[str]]:
    rows = []
    for key, sub in spec.get("properties", {}).items():
        p = f"{path}.{key}" if path else key
        if sub.get("type") == "object" and "properties" in sub:
            rows += _rows(sub, p, sub.get("required", ()))
            continue
        default = (
            "required" if key in required else (_code(sub["default"]) if "default" in sub else "")
        )
        rows.append(
            [f"`{p}`", _type(sub), default, _bounds(sub), _cell(sub.get("description", ""))]
        )
    return rows


@cache
def config() -> str:
    schema = yaml.safe_load((REPO / "workflow" / "schemas" / "config.schema.yaml").read_text())
    head = ["key", "type", "default", "bounds", "meaning"]
    out = []
    for section, spec in schema["properties"].items():
        out += [f"## `{section}`", ""]
        if spec.get("description"):
            out += [_cell(spec["description"]), ""]
        if section in ("routes", "grades"):  # a mapping of names: one entry's keys
            entry = spec.get("additionalProperties") or {}
            name = {"routes": "<route>", "grades": "<grade>"}[section]
            out += [f"Names: {_bounds(spec.get('propertyNames', {}))}.", ""]
            if "default" in spec:
                out += [f"Default: {_code(spec['default'])}.", ""]
            rows = _rows(entry, f"{section}.{name}", entry.get("required", ()))
            if rows:
                out += [_table(head, rows), ""]
            continue
        out += [_table(head, _rows(spec, section, spec.get("required", ()))), ""]
    return "\n".join(out)


# --- the files between stages -------------------------------------------------------------------
_SUFFIX_UNITS = (
    ("_radps", "rad/s"),
    ("_mps2", "m/s²"),
    ("_mps", "m/s"),
    ("_rad", "rad"),
    ("_deg", "deg"),
    ("_m", "m"),
    ("_s", "s"),
)


def _unit(column: str, units: dict) -> str:
    if column in units:
        return units[column]
    return next((u for s, u in _SUFFIX_UNITS if column.endswith(s)), "")


def _columns(mod) -> list[tuple[str, str, str]]:
    """(column, unit, note) of a contract module, from its column constants and units."""
    from imugen.tables import SEQUENCE, TIME

    units = dict(getattr(mod, "UNITS", {}))
    if hasattr(mod, "COLUMNS"):
        cols = [(c, _unit(c, units), "") for c in mod.COLUMNS]
        seen = {c for c, _, _ in cols}
        cols += [(c, u, "optional") for c, u in units.items() if c not in seen]
        return cols
    if hasattr(mod, "GROUPS"):  # the shard: column groups of three axes
        cols = [(SEQUENCE, "1", ""), (TIME, "s", "or the metadata's clock")]
        for group, (names, unit) in mod.GROUPS.items():
            note = "" if group in ("dtheta", "dv", "gyro", "accel") else "with `series`"
            cols += [(c, unit, note) for c in names]
        return cols
    names = [
        v
        for k, v in vars(mod).items()
        if k.isupper() and not k.startswith("_") and k not in ("WHAT", "FORMAT", "AXES")
    ]
    flat = []
    for v in names:
        for c in v if isinstance(v, tuple) else (v,):
            if isinstance(c, str) and re.fullmatch(r"[a-z][a-z0-9_]*", c) and c not in flat:
                flat.append(c)
    return [(SEQUENCE, "1", "")] + [(c, _unit(c, units), "") for c in flat if c != SEQUENCE]


@cache
def files() -> str:
    import importlib

    import imugen.tables as tables
    from imugen.tables import layout

    out = [
        "Where each file lies (`imugen.tables.layout`):",
        "",
        "```text",
        textwrap.dedent(inspect.getdoc(layout).split("::", 1)[1].split("\n\n", 2)[1]).rstrip(),
        "```",
        "",
    ]
    for name in tables._SUBMODULES:
        if name == "layout":
            continue
        mod = importlib.import_module(f"imugen.tables.{name}")
        doc = _markdown(inspect.getdoc(mod) or "")
        out += [f"## `imugen.tables.{name}`", "", doc, ""]
        rows = [[f"`{c}`", u, n] for c, u, n in _columns(mod)]
        out += [_table(["column", "unit", "note"], rows), ""]
    return "\n".join(out)


# --- route formats -----------------------------------------------------------------------------
@cache
def readers() -> str:
    from imugen.ingest.formats import FORMATS

    rows = [
        [
            _cell(f.name),
            _cell(f.what),
            ", ".join(f"`{s}`" for s in f.suffixes),
            f"`imugen.ingest.readers.{f.reader}`",
        ]
        for f in FORMATS
    ]
    return _table(["format", "what is read", "usual file names", "reader"], rows)


# --- the workflow: rule graph and the map of the house ---------------------------------------------
@cache
def _workflow() -> tuple[str, str]:
    """(DOT of ``snakemake --rulegraph``, text of ``snakemake -n --forceall``), one scratch dir."""
    with tempfile.TemporaryDirectory(prefix="imugen-docs-") as tmp:
        for name in ("config", "resources"):
            (Path(tmp) / name).symlink_to(REPO / name)
        base = [sys.executable, "-m", "snakemake", "-s", str(REPO / "Snakefile"), "-d", tmp]
        base += ["--nolock", "--configfile", str(HOUSE_CONFIG)]
        run = {"cwd": tmp, "capture_output": True, "text": True}
        graph = subprocess.Popen(
            [*base, "--rulegraph"],
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
            cwd=tmp,
        )
        dry = subprocess.run([*base, "-n", "--forceall"], **run)
        g_out, g_err = graph.communicate()
    if graph.returncode or dry.returncode:
        raise RuntimeError(f"snakemake failed:\n{g_err[-2000:]}\n{dry.stderr[-2000:]}")
    return g_out, dry.stdout + dry.stderr


def _rule_graph() -> tuple[dict[str, str], list[tuple[str, str]]]:
    dot, _ = _workflow()
    nodes = dict(re.findall(r'^\s*(\d+)\[label = "(\w+)"', dot, flags=re.M))
    edges = [(nodes[a], nodes[b]) for a, b in re.findall(r"^\s*(\d+) -> (\d+)", dot, flags=re.M)]
    return nodes, edges


@cache
def rulegraph() -> str:
    nodes, edges = _rule_graph()
    lines = ["```mermaid", "flowchart TB"]
    lines += [f"    {name}([{name}])" for name in nodes.values()]
    lines += [f"    {a} --> {b}" for a, b in edges]
    return "\n".join([*lines, "```"])


def _jobs() -> dict[str, dict[str, set[str]]]:
    """Rule -> {"in": paths, "out": paths} over every job of the dry run, generalized."""
    _, text = _workflow()
    cfg = yaml.safe_load((REPO / "config" / "config.yaml").read_text())
    routes = set(cfg["routes"])
    grades = set(yaml.safe_load(HOUSE_CONFIG.read_text())["grades"])

    def general(path: str) -> str:
        path = path.strip()
        path = path.removeprefix(str(REPO) + "/")
        parts = path.split("/")
        parts = ["{route}" if p in routes and i == 1 else p for i, p in enumerate(parts)]
        parts = ["{grade}" if p in grades else p for p in parts]
        path = "/".join(parts)
        path = re.sub(r"shard-\d+", "shard-{K}", path)
        for g in grades:
            path = re.sub(rf"\b{g}\.(\w+)$", r"{grade}.\1", path)
            path = path.replace(f"imu_{g}.", "imu_{grade}.")
        return path

    jobs: dict[str, dict[str, set[str]]] = {}
    for block in re.split(r"^\[.*\]\n", text, flags=re.M):
        m = re.match(r"(?:local)?rule (\w+):\n", block)
        if not m:
            continue
        job = jobs.setdefault(m.group(1), {"in": set(), "out": set()})
        for kind, key in (("input", "in"), ("output", "out")):
            f = re.search(rf"^\s+{kind}: (.+)$", block, flags=re.M)
            if f:
                paths = (general(p) for p in f.group(1).split(", "))
                job[key].update(p for p in paths if p)
    return jobs


def _commands() -> dict[str, tuple[str, str]]:
    """Rule -> (rule file, shell command) from the rule files."""
    out = {}
    for smk in sorted((REPO / "workflow" / "rules").glob("*.smk")):
        text = smk.read_text()
        for m in re.finditer(r"^rule (\w+):\n(.*?)(?=^rule |\Z)", text, flags=re.M | re.S):
            cmd = re.search(r'"(?:IMUGEN_\w+=\S+ )?(imugen [a-z-]+(?: --static)?)', m.group(2))
            out[m.group(1)] = (smk.name, cmd.group(1) if cmd else "shell")
    return out


def _command_modules() -> dict[str, str]:
    """``imugen COMMAND`` -> the module it runs (the stage's face), from its declaration."""
    from imugen.cli import build_parser

    out = {}
    for path, sub, _ in _subcommands(build_parser()):
        command = sub.get_default("_command")
        if command is not None:
            out["imugen " + " ".join(path)] = command.run.partition(":")[0]
    return out


def _pipeline_order(nodes, edges) -> list[str]:
    """Rules in pipeline order: a topological order of the graph, ties in the graph's order."""
    names = list(nodes.values())
    before = {n: {a for a, b in edges if b == n} for n in names}
    order = []
    while len(order) < len(names):
        ready = [n for n in names if n not in order and before[n] <= set(order)]
        order.append(ready[0])
    return order


def _files(paths: set[str]) -> str:
    def label(p):
        if p.startswith("resources/"):
            return "the route file (`routes.<route>.file`)"
        if p == "src/imugen/data/grades.yaml":
            return "`src/imugen/data/grades.yaml` (presets)"
        return f"`{p}`"

    return "<br>".join(dict.fromkeys(label(p) for p in sorted(paths))) or "the configuration"


@cache
def house() -> str:
    nodes, edges = _rule_graph()
    jobs = _jobs()
    commands = _commands()
    modules = _command_modules()
    rows = []
    for rule in _pipeline_order(nodes, edges):
        if rule == "all" or rule not in commands:
            continue
        smk, cmd = commands[rule]
        stage = smk.removesuffix(".smk")
        module = modules.get(cmd.removesuffix(" --static"), "")
        tests = REPO / "tests" / stage
        n = len(list(tests.glob("test_*.py"))) if tests.is_dir() else 0
        job = jobs.get(rule, {"in": set(), "out": set()})
        rows.append(
            [
                f"`{stage}`",
                f"`{rule}`",
                f"`workflow/rules/{smk}`",
                f"`{module}`" if module else "",
                f"`{cmd}`" if cmd != "shell" else "(shell: writes the config's grade)",
                f"`tests/{stage}/` ({n} file{'s' if n != 1 else ''})" if n else "",
                _files(job["in"]),
                _files(job["out"]),
            ]
        )
    head = ["stage", "rule", "rule file", "package (face)", "command", "tests"]
    return _table([*head, "files in", "files out"], rows)


@cache
def packages() -> str:
    root = REPO / "src" / "imugen"
    rows = []
    for path in sorted(root.iterdir()):
        if path.name.startswith(("_", ".")) or not (path.suffix == ".py" or path.is_dir()):
            continue
        init = path / "__init__.py" if path.is_dir() else path
        if not init.is_file():
            continue
        doc = ast.get_docstring(ast.parse(init.read_text())) or ""
        first = " ".join(doc.split("\n\n")[0].split())
        name = path.stem
        tests = REPO / "tests" / name
        where = f"`tests/{name}/`" if tests.is_dir() else ""
        if not where and (REPO / "tests" / f"test_{name}.py").is_file():
            where = f"`tests/test_{name}.py`"
        kind = "package" if path.is_dir() else "module"
        rows.append([f"`imugen.{name}`", kind, _cell(_markdown(first)), where])
    return _table(["name", "kind", "what it is (its docstring)", "tests"], rows)


GENERATORS = {
    "cli": cli,
    "config": config,
    "files": files,
    "readers": readers,
    "rulegraph": rulegraph,
    "house": house,
    "packages": packages,
}
