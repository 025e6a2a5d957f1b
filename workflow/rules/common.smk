# Helpers for every stage: config validation, routes/grades/shards, code tracking.
import ast
import functools
import hashlib
import json
import math
import shlex
import sys
from pathlib import Path

import yaml
from snakemake.exceptions import WorkflowError
from snakemake.io import report as report_flag  # a bare `report(` reads as `report:`
from snakemake.utils import validate

# the checks below use this checkout's package (the jobs call the installed `imugen`)
sys.path.insert(0, str(Path(workflow.basedir) / "src"))
from imugen import preflight
from imugen.core.errors import InputError
from imugen.tables import layout


# The schema first, one line per problem naming the key (Snakemake's `validate` would print
# the first problem with its whole sub-schema); then `validate` fills the defaults.
_problems = preflight.schema_problems(
    config, yaml.safe_load((Path(workflow.basedir) / "workflow/schemas/config.schema.yaml").read_text())
)
if _problems:
    raise WorkflowError("\n".join(f"imugen: error: {p}" for p in _problems))
_DRAWN_OUTAGES_GIVEN = "outages_s" in (config.get("scenarios") or {})
"""``scenarios.outages_s`` given by the user (its schema default applies only without declared
outages: see ``SCEN``)."""
validate(config, "../schemas/config.schema.yaml")


def expand_paths_all(routes):
    """``paths: all``: one route per path of the route's file, named ``<route>-<id>`` (the
    path's stable id, :func:`imugen.ingest.stage.route_ids`: its name's slug and a hash of its
    name and first point), each ingesting its path with ``--path=all:<id>``. The file's path
    list is read here, when the workflow is parsed (the file only, no cleaning); a path that
    the ingest job then refuses fails that route's jobs alone."""
    out = {}
    for name, r in routes.items():
        if r.get("paths") != "all":
            out[name] = r
            continue
        if r.get("path") is not None:
            raise WorkflowError(
                f"imugen: error: routes.{name}: give path or paths: all, not both"
            )
        from imugen.ingest.stage import path_ids

        try:
            ids = path_ids(r["file"])
        except InputError as exc:
            raise WorkflowError(f"imugen: error: routes.{name}: {exc}") from None
        for rid in ids:
            sub = f"{name}-{rid}"
            if sub in routes or sub in out:
                raise WorkflowError(
                    f"imugen: error: routes.{name}: path {rid!r} gives the route name {sub!r}, "
                    "which another route already has"
                )
            out[sub] = {**r, "paths": None, "path": f"all:{rid}"}
    return out


config["routes"] = expand_paths_all(config["routes"])
# Before any job: no NaN/inf, custom grades valid (not named like a preset), the run within
# the memory and disk budgets (estimates in the message; see src/imugen/preflight.py). The
# budget is checked in dry runs too, which is what we want: `snakemake -n` refuses a run that
# would not fit (Snakemake 9 cannot tell a dry run at parse time: `workflow.dryrun` is False
# until the executor is set up, after this file is read). Jobs re-reading this file on a
# cluster node skip the budget (it was checked where the run was started).
try:
    preflight.check_values(config)
    if workflow.is_main_process:
        preflight.check_budget(config, Path(layout.RESULTS))
except InputError as exc:
    raise WorkflowError(f"imugen: error: {exc}") from None

ROUTES = sorted(config["routes"])
GRADES = list(config["grades"])
SIM = config["simulate"]
N_SEQ = SIM["sequences"]
PER_SHARD = SIM["sequences_per_shard"]
# shard-000 ... shard-999, then shard-1000, ...: adding shards never renames existing ones
SHARDS = [layout.shard_label(k) for k in range(math.ceil(N_SEQ / PER_SHARD))]
WRITE_IMU = SIM["write_imu"]
MOUNTING = config.get("mounting", {})
MOUNTING_ARG = (
    f"--mounting={shlex.quote(json.dumps(MOUNTING))}" if MOUNTING.get("enabled") else ""
)
"""`imugen simulate --mounting JSON` when the config's mounting is enabled (else nothing)."""
# the IMU shard and its labels, when written (simulate.write_imu); without them the rules that
# read shards (export_mat, the figures' IMU panels) are not scheduled
IMU_OUTPUTS = (
    [layout.shard("imu"), layout.sidecar(layout.shard("imu"), "labels")] if WRITE_IMU else []
)
IMU_GRADES = GRADES if WRITE_IMU else []
FIG = config["figures"]


def figure_reports(stem, caption, figure, **labels):
    """One report item per figure format of ``layout.figure(stem, ext)``: each with its own
    labels (route, figure, the given extra labels such as the grade, and the format), since
    Snakemake's report keeps one item per set of labels within a category (items sharing
    labels hide each other; tests/system/test_workflow.py checks they are unique)."""
    return [
        report_flag(
            layout.figure(stem, ext),
            caption=caption,
            category="Figures",
            labels={"route": "{route}", "figure": figure, **labels, "format": ext.upper()},
        )
        for ext in FIG["formats"]
    ]


wildcard_constraints:
    route="|".join(ROUTES),
    grade="|".join(GRADES),
    shard=r"\d\d\d|[1-9]\d\d\d+",


SRC = Path(workflow.basedir) / "src"
"""The package source the jobs run (``imugen`` installed from this checkout)."""


@functools.cache
def _module_file(name):
    """Source file of mod ``name`` (``imugen.a.b``) under ``SRC``, or None (not imugen's)."""
    base = SRC.joinpath(*name.split("."))
    for path in (base.with_suffix(".py"), base / "__init__.py"):
        if path.is_file():
            return path
    return None


@functools.cache
def _imports(name, top_level_only=False, function=None):
    """The imugen modules mod ``name`` imports (``top_level_only``: only the imports run
    when it is imported, not those inside its functions; ``function``: those and the imports
    inside that one top-level function), with their parent packages."""
    path = _module_file(name)
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    found = set()

    def add(mod):
        if _module_file(mod) is None:
            return
        parts = mod.split(".")
        found.update(".".join(parts[:i]) for i in range(1, len(parts) + 1))

    def visit(node, skip_functions):
        for child in ast.iter_child_nodes(node):
            if skip_functions and isinstance(child, ast.FunctionDef | ast.AsyncFunctionDef):
                continue
            if isinstance(child, ast.Import):
                for alias in child.names:
                    add(alias.name)
            elif isinstance(child, ast.ImportFrom):
                base = child.module or ""
                if child.level:
                    parent = package.split(".")[: len(package.split(".")) - child.level + 1]
                    base = ".".join([*parent, base] if base else parent)
                add(base)
                for alias in child.names:  # `from package import mod`
                    add(f"{base}.{alias.name}")
            visit(child, skip_functions)

    tree = ast.parse(path.read_text(), str(path))
    visit(tree, top_level_only or function is not None)
    if function is not None:
        defs = [
            n
            for n in tree.body
            if isinstance(n, ast.FunctionDef | ast.AsyncFunctionDef) and n.name == function
        ]
        if not defs:
            raise WorkflowError(f"imugen: error: code_digest: {name} has no function {function}")
        visit(defs[0], False)
    found.discard(name)
    return frozenset(m for m in found if m == "imugen" or m.startswith("imugen."))


@functools.cache
def _closure(name):
    """Every imugen mod that importing and running mod ``name`` may execute; ``module:function``:
    that module's top-level imports and its function's, not its other functions' (a face
    holding several commands, each importing its own module inside its function)."""
    name, _, function = name.partition(":")
    parts = name.split(".")
    seen, todo = set(), [".".join(parts[:i]) for i in range(1, len(parts))]
    if function:
        seen.add(name)
        todo.extend(_imports(name, function=function))
    else:
        todo.append(name)
    while todo:
        mod = todo.pop()
        if mod not in seen:
            seen.add(mod)
            todo.extend(_imports(mod))
    return frozenset(seen)


def code_files(*modules):
    """Source files of the code a rule's command runs (sorted paths under ``SRC``).

    The transitive closure, computed from the code with ``ast``, of the imugen modules the
    command's modules import (``modules``: the stage's ``stage.py`` face, or whichever module
    the command dispatches to, or ``module:function`` for one command of a face that holds
    several; each imports its command's options module), anywhere in them,
    function-level imports included, plus what ``imugen.cli`` imports when it starts (it loads
    the one command's options module by name, so one stage's closure holds no other stage).
    """
    names = {"imugen.cli"}
    for m in (*_imports("imugen.cli", top_level_only=True), *modules):
        names |= _closure(m)
    return sorted(str(_module_file(m)) for m in names)


@functools.cache
def code_digest(*modules):
    """A digest of the contents of :func:`code_files`, given to a rule as its ``code`` param;
    editing one of its files reruns the rule's jobs, and what follows.

    Snakemake does not track imported code itself. A changed param reruns its jobs
    (Snakemake's ``params`` rerun trigger), and a mere timestamp change (a git checkout)
    reruns nothing. Computed once per rule when the workflow is parsed (closures cached per
    module); a static param costs a job nothing, where the same files as inputs of every shard
    job cost a fifth of a 10,000-shard dry run (benchmarks/bench_dryrun.py). Files are keyed
    by their path under ``SRC``, so a moved checkout reruns nothing.
    tests/system/test_code_inputs.py edits a module of each stage and checks the jobs a dry
    run schedules.
    """
    h = hashlib.sha256()
    for f in code_files(*modules):
        h.update(Path(f).relative_to(SRC).as_posix().encode() + b"\0")
        h.update(Path(f).read_bytes() + b"\0")
    return h.hexdigest()[:16]


PRESETS = str(Path(workflow.basedir) / "src" / "imugen" / "data" / "grades.yaml")


def is_custom(grade):
    """A grade with a definition in the config (an empty mapping selects the preset)."""
    return bool(config["grades"][grade])


def grade_files(wildcards):
    """The custom grade's YAML file, when the grade is custom."""
    g = wildcards.grade
    return [layout.grade_file(g)] if is_custom(g) else []


def grade_arg(wildcards):
    """`--grade` value: the preset name, or FILE.yaml:NAME for a custom grade."""
    g = wildcards.grade
    return f"{layout.grade_file(g)}:{g}" if is_custom(g) else g


def shard_sequences(wildcards):
    """Sequences in this shard: M, except a shorter last shard when M does not divide N."""
    k = int(wildcards.shard)
    return min(PER_SHARD, N_SEQ - k * PER_SHARD)


def ingest_opts(wildcards):
    """Command-line options of `imugen ingest` for this route (path, origin, dt, extent).

    Every value is written `--name=value`: a southern latitude (`--origin=-33.9,...`) or a
    path name starting with `-` would otherwise be taken for an option.
    """
    r = config["routes"][wildcards.route]
    opts = []
    if r.get("path") is not None:
        opts.append(f"--path={shlex.quote(str(r['path']))}")
    if r.get("origin") is not None:
        opts.append("--origin=" + ",".join(repr(float(x)) for x in r["origin"]))
    if r.get("dt_s") is not None:
        opts.append(f"--dt={float(r['dt_s'])!r}")
    if r.get("max_extent_km") is not None:
        opts.append(f"--max-extent-km={float(r['max_extent_km'])!r}")
    opts.append(f"--pose-world={shlex.quote(str(r.get('pose_world', 'enu')))}")
    opts.append(f"--pose-world-yaw-deg={float(r.get('pose_world_yaw_deg', 0.0))!r}")
    return " ".join(opts)


def truth_pose_opts(wildcards):
    """`imugen truth` options of a pose trajectory's frames and clock, and of the vehicle's
    suspension, for this route."""
    r = config["routes"][wildcards.route]
    opts = [f"--pose-body={shlex.quote(str(r.get('pose_body', 'flu')))}"]
    opts.append(f"--suspension={shlex.quote(str(r.get('suspension', 'auto')))}")
    for key in ("imu_rotation_deg", "lever_arm_m", "marker_offset_m"):
        xyz = ",".join(repr(float(x)) for x in r.get(key, (0.0, 0.0, 0.0)))
        opts.append(f"--{key.replace('_', '-')}={xyz}")
    opts.append(f"--time-offset-s={float(r.get('time_offset_s', 0.0))!r}")
    return " ".join(opts)


def ingest_clean_opts(wildcards):
    """`imugen ingest` options of the cleaning and gap rules for this route."""
    r = config["routes"][wildcards.route]
    opts = [f"--vehicle={shlex.quote(str(r.get('vehicle', 'car')))}"]
    if r.get("max_gap_s") is not None:
        opts.append(f"--max-gap-s={float(r['max_gap_s'])!r}")
    opts.append(f"--gaps={shlex.quote(str(r.get('gaps', 'auto')))}")
    return " ".join(opts)


def auto_grades():
    """`--grade` options of the truth: every configured grade (presets by name, custom grades
    as FILE.yaml:NAME) takes part in the `--earth auto` budget."""
    return " ".join(
        f"--grade={shlex.quote(f'{layout.grade_file(g)}:{g}' if is_custom(g) else g)}"
        for g in GRADES
    )


AUTO_EARTH = config["truth"]["earth"] == "auto"


def custom_grade_files():
    """YAML files of all custom grades (inputs of the truth's `--earth auto` budget)."""
    return [layout.grade_file(g) for g in GRADES if is_custom(g)]


def shard_paths(kind):
    """All shard tables of one kind (imu, nav, gnss, ...) of a route and grade."""
    return lambda wc: [layout.shard(kind, wc.route, wc.grade, s) for s in SHARDS]


def bench_shard(kind, shard="{shard}"):
    """A benchmark table of a route's shard (workflow/rules/learn.smk):
    results/<route>/benchmark/<kind>/<grade>/shard-<shard>.parquet."""
    return f"{layout.route_dir()}/benchmark/{kind}/{{grade}}/shard-{shard}.parquet"


def route_shards(kind):
    """All shard tables of one kind of a route, grade by grade (``GRADES`` order)."""
    return lambda wc: [layout.shard(kind, wc.route, g, s) for g in GRADES for s in SHARDS]


def grade_pairs(kind):
    """`--nav GRADE=PATH ...`-style options from the rule's named inputs."""

    def opts(wildcards, input):
        files = input[kind]
        per = len(files) // len(GRADES)
        return " ".join(
            f"--{kind}={shlex.quote(f'{g}={f}')}"
            for i, g in enumerate(GRADES)
            for f in files[i * per : (i + 1) * per]
        )

    return opts


def run_summary():
    """Where the results are and, per route, the Earth model the truth used and why."""
    from imugen.core.io import read_meta

    print("imugen: results in " + str(Path(layout.RESULTS).resolve()))
    for r in ROUTES:
        truth = Path(layout.truth(r))
        if not truth.exists():
            continue
        m = read_meta(truth)
        b = m.get("earth_budget") or {}
        why = "as configured"
        if b.get("terms_m") and b.get("grade_effect_m"):
            name, val = max(b["terms_m"].items(), key=lambda kv: kv[1])
            why = (
                f"earth: auto; largest term flat drops: {name}, "
                f"{val / b['grade_effect_m']:.1%} of the {b.get('grade')} grade's error effect "
                f"(limit {b.get('fraction', 0.1):.0%})"
            )
        print(f"  {r}: {layout.route_dir(r)}/ (rmse.csv, figures/); Earth model {m.get('earth')} ({why})")


def check_executor():
    """Before the first job of a SLURM run: refuse, in one line, a run that would wait for
    ever (a cluster without accounting; src/imugen/preflight.py, slurm_status_problem)."""
    plugin = workflow.executor_plugin
    if plugin is None or plugin.name != "slurm":
        return
    settings = workflow.executor_settings
    problem = preflight.slurm_status_problem(
        getattr(settings, "status_command", None),
        float(getattr(settings, "init_seconds_before_status_checks", None) or 40),
    )
    if problem:
        print(f"imugen: error: {problem}", file=sys.stderr)
        sys.exit(1)


ERROR_IN_RULE = "Error in rule "
"""How Snakemake's log starts the block of a failed job."""


def failed_job_reasons(snakemake_logs):
    """(rule, log file, reason) of each failed job in Snakemake's log files (a path or a
    list): the job's last line `imugen: error: ...` (without the prefix), else its log's
    last line, else Snakemake's message (a failed submission: `SLURM sbatch failed ...`)."""
    if isinstance(snakemake_logs, (str, Path)):
        snakemake_logs = [snakemake_logs]
    text = "\n".join(
        Path(f).read_text(errors="replace") for f in snakemake_logs or [] if Path(f).is_file()
    )
    out, failed, message = [], None, None
    for line in text.splitlines():
        s = line.strip()
        if line.startswith(ERROR_IN_RULE):
            failed, message = line[len(ERROR_IN_RULE) :].rstrip(":"), None
        elif failed and s.startswith("message: ") and s != "message: None":
            message = s[len("message: ") :]
        elif failed and s.startswith("log: ") and "(check log file" in s:
            for f in s[5:].split(" (check log file")[0].split(", "):
                out.append((failed, f, _last_reason(Path(f)) or message or "(no log written)"))
            failed = None
    return out


def _last_reason(path):
    try:
        lines = [ln.strip() for ln in path.read_text(errors="replace").splitlines() if ln.strip()]
    except OSError:
        return None
    errors = [ln for ln in lines if ln.startswith("imugen: error: ")]
    if errors:
        return errors[-1][len("imugen: error: ") :]
    return lines[-1][:300] if lines else None


def report_failures(snakemake_logs):
    """On a failed run: each failed job's one-line reason, on the terminal (not only in its log)."""
    for name, f, reason in failed_job_reasons(snakemake_logs):
        print(f"imugen: error: {name} failed: {reason} ({f})", file=sys.stderr)


# --- aid stage (GNSS-denied scenarios, aided baseline): workflow/rules/aid.smk ---
GNSS = config["gnss"]
SCEN = config["scenarios"]
if not _DRAWN_OUTAGES_GIVEN and any(iv["kind"] == "outage" for iv in SCEN["intervals"]):
    SCEN["outages_s"] = []  # declared outages are the outages; drawn ones only where asked
AIDED = config["aided"]
COMP = config["companions"]
AID_ON = bool(GNSS["enabled"])
OUTAGES = AID_ON and bool(
    SCEN["outages_s"] or any(iv["kind"] == "outage" for iv in SCEN["intervals"])
)
"""The aid stage runs with outage scenarios: the outage-drift table and figure are made."""


def aid_opts(wildcards):
    """`imugen aid` options from the gnss, scenarios and aided config blocks."""
    opts = [f"--receiver={GNSS['receiver']}", f"--gnss-draw={GNSS['draw']}"]
    if GNSS["rate_hz"] is not None:
        opts.append(f"--gnss-rate-hz={GNSS['rate_hz']!r}")
    opts.append("--lever-arm=" + ",".join(repr(float(x)) for x in GNSS["lever_arm_b_m"]))
    opts.append(f"--lever-arm-sd={float(GNSS['lever_arm_sd_m'])!r}")
    specs = [f"outage:{float(T)!r}" for T in SCEN["outages_s"]] + list(SCEN["draw"])
    for iv in SCEN["intervals"]:
        extra = "".join(
            f",{k}={float(v)!r}" for k, v in iv.items() if k not in ("kind", "start_s", "duration_s")
        )
        specs.append(f"{iv['kind']}:{float(iv['duration_s'])!r}@{float(iv['start_s'])!r}{extra}")
    opts += [f"--scenario={shlex.quote(s)}" for s in specs]
    opts.append(f"--settle-s={float(SCEN['settle_s'])!r}")
    opts.append(f"--tuning-level={AIDED['tuning_level']}")
    if not AIDED["gnss_bias_states"]:
        opts.append("--no-gnss-bias-states")
    if AIDED["scale_factors"]:
        opts.append("--scale-factors")
    if not AIDED["cross_coupling"]:
        opts.append("--no-cross-coupling")
    if AIDED["nhc"] is not None:
        opts.append("--nhc" if AIDED["nhc"] else "--no-nhc")
    slip = AIDED["nhc_slip_sd_mps"]
    if slip is not None:
        slip = slip if isinstance(slip, list) else [slip]
        opts.append("--nhc-slip-sd=" + ",".join(repr(float(x)) for x in slip))
    if not AIDED["zupt"]:
        opts.append("--no-zupt")
    opts.append(f"--gate-sigma={float(AIDED['gate_sigma'])!r}")
    opts.append(f"--align-speed={float(AIDED['align_speed_mps'])!r}")
    opts.append(f"--companion-draw={COMP['draw']}")
    if COMP["odometer"] is not None:
        opts.append(f"--odometer={COMP['odometer']}")
        if COMP["odometer_rate_hz"] is not None:
            opts.append(f"--odometer-rate-hz={float(COMP['odometer_rate_hz'])!r}")
        lever = ",".join(repr(float(x)) for x in COMP["odometer_lever_b_m"])
        opts.append(f"--odometer-lever={lever}")
        if not COMP["odometer_scale_state"]:
            opts.append("--no-odometer-scale-state")
    if COMP["barometer"] is not None:
        opts.append(f"--baro={COMP['barometer']}")
        if COMP["barometer_rate_hz"] is not None:
            opts.append(f"--baro-rate-hz={float(COMP['barometer_rate_hz'])!r}")
    return " ".join(opts)
