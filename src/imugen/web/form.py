"""The run form, generated from the workflow's JSON schema (so the page and the workflow agree)."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import yaml

from imugen.core.errors import InputError

SKIP = ("routes", "grades")
"""Top-level keys the page builds itself (the uploaded route, the grade checkboxes)."""
ROUTE_KEYS = ("vehicle", "path", "dt_s", "origin")


@dataclass
class Field:
    """One form field: ``name`` is ``section.key`` (``route.key`` for the route)."""

    name: str
    kind: str  # select | checkbox | number | integer | text | multi
    label: str
    help: str = ""
    default: object = None
    choices: list = field(default_factory=list)
    minimum: float | None = None
    maximum: float | None = None


def load_schema(repo: Path) -> dict:
    return yaml.safe_load((repo / "workflow" / "schemas" / "config.schema.yaml").read_text())


def _field(name: str, spec: dict) -> Field | None:
    t = spec.get("type")
    types = t if isinstance(t, list) else [t]
    help_ = " ".join(str(spec.get("description", "")).split())
    lo = spec.get("minimum", spec.get("exclusiveMinimum"))
    hi = spec.get("maximum", spec.get("exclusiveMaximum"))
    d = spec.get("default")
    if "enum" in spec:
        return Field(name, "select", name.split(".")[-1], help_, d, list(spec["enum"]))
    if "string" in types:  # e.g. path: a name or a 1-based index, both typed as text
        return Field(name, "text", name.split(".")[-1], help_, d)
    if "boolean" in types:
        return Field(name, "checkbox", name.split(".")[-1], help_, bool(d))
    if "integer" in types:
        return Field(name, "integer", name.split(".")[-1], help_, d, [], lo, hi)
    if "number" in types:
        return Field(name, "number", name.split(".")[-1], help_, d, [], lo, hi)
    if "array" in types and "enum" in spec.get("items", {}):
        return Field(
            name, "multi", name.split(".")[-1], help_, list(d or []), spec["items"]["enum"]
        )
    items = spec.get("items", {})
    tuple_items = spec.get("prefixItems") or []
    numeric = items.get("type") in ("number", "integer") or (
        tuple_items and all(t.get("type") in ("number", "integer") for t in tuple_items)
    )
    if "array" in types and numeric:  # e.g. origin (a [lat, lon, h] tuple), outages
        return Field(name, "numbers", name.split(".")[-1], help_ + " (comma-separated)", d)
    return None  # arrays of objects (declared scenario intervals): config files only


def route_fields(schema: dict) -> list[Field]:
    props = schema["properties"]["routes"]["additionalProperties"]["properties"]
    return [f for k in ROUTE_KEYS if k in props and (f := _field(f"route.{k}", props[k]))]


def section_fields(schema: dict) -> dict[str, list[Field]]:
    """Every object section of the schema but routes and grades, with its fields."""
    out = {}
    for sec, spec in schema["properties"].items():
        if sec in SKIP or "properties" not in spec:
            continue
        fields = [_field(f"{sec}.{k}", v) for k, v in spec.get("properties", {}).items()]
        out[sec] = [f for f in fields if f is not None]
    return out


def _coerce(f: Field, form) -> object:
    """The value of one field from a submitted form (``form``: a MultiDict), or None."""
    if f.kind == "checkbox":
        return f.name in form
    if f.kind == "multi":
        return [v for v in form.getlist(f.name) if v in f.choices]
    raw = (form.get(f.name) or "").strip()
    if raw == "":
        return None
    try:
        if f.kind == "integer":
            return int(raw)
        if f.kind == "number":
            return _finite(float(raw))
        if f.kind == "numbers":
            return [_finite(float(x)) for x in raw.split(",") if x.strip()]
        if f.name == "route.path" and raw.isdigit():
            return int(raw)
    except ValueError:
        what = {"integer": "an integer", "number": "a finite number"}.get(
            f.kind, "a comma-separated list of finite numbers"
        )
        raise InputError(f.name, f"{raw[:40]!r} is not {what}") from None
    if f.kind == "select" and raw not in map(str, f.choices):
        raise InputError(f.name, f"{raw!r} is not one of {', '.join(map(str, f.choices))}")
    return raw


def _finite(x: float) -> float:
    if not math.isfinite(x):
        raise ValueError(x)
    return x


def config_from_form(schema: dict, form, route_file: str, grades: dict) -> dict:
    """The workflow configuration a submitted form describes (validated against the schema)."""
    route = {"file": route_file}
    for f in route_fields(schema):
        v = _coerce(f, form)
        if v is not None:
            route[f.name.split(".", 1)[1]] = v
    cfg: dict = {"routes": {"route": route}, "grades": grades}
    for sec, fields in section_fields(schema).items():
        vals = {}
        for f in fields:
            v = _coerce(f, form)
            if v is not None and v != f.default:
                vals[f.name.split(".", 1)[1]] = v
        if vals:
            cfg[sec] = vals
    if not grades:
        raise InputError("grades", "choose at least one grade")
    return cfg


def validate(cfg: dict, repo: Path) -> None:
    """Refuse what the workflow would refuse before its first job: the schema (NaN and values
    out of range included) and the pre-flight's checks (custom grades, names of presets);
    one-line InputError naming the key."""
    import jsonschema

    from imugen import preflight

    schema = load_schema(repo)
    err = jsonschema.exceptions.best_match(jsonschema.Draft202012Validator(schema).iter_errors(cfg))
    if err is not None:
        where = ".".join(str(p) for p in err.absolute_path) or "configuration"
        raise InputError(where, " ".join(err.message.split())[:300])
    preflight.check_values(cfg)


def form_values(schema: dict, form) -> dict:
    """A submitted form as ``{field name: value}`` (lists for grades and multi fields)."""
    multi = {"grades"} | {
        f.name for fs in section_fields(schema).values() for f in fs if f.kind == "multi"
    }
    out = {k: form.getlist(k) if k in multi else form.get(k) for k in form.keys()}
    for f in (f for fs in section_fields(schema).values() for f in fs if f.kind == "checkbox"):
        out[f.name] = f.name in form
    return out


def config_values(schema: dict, cfg: dict) -> dict:
    """The form values that reproduce a configuration written by :func:`config_from_form`."""
    route = cfg.get("routes", {}).get("route", {})
    out = {f"route.{k}": v for k, v in route.items() if k != "file"}
    out["grades"] = [g for g, spec in cfg.get("grades", {}).items() if not spec]
    for sec, fields in section_fields(schema).items():
        for f in fields:
            key = f.name.split(".", 1)[1]
            if key in cfg.get(sec, {}):
                out[f.name] = cfg[sec][key]
    return out
