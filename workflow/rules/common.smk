# Helpers for every stage: config validation, routes/grades/shards, code tracking.
import functools
import hashlib
import json
import math
import shlex
import sys
from pathlib import Path

import yaml
from snakemake.exceptions import WorkflowError
from snakemake.utils import validate

# the checks below use this checkout's package (the jobs call the installed `imugen`)
sys.path.insert(0, str(Path(workflow.basedir) / "src"))
from imugen import preflight
from imugen.errors import InputError


# The schema first, one line per problem naming the key (Snakemake's `validate` would print
# the first problem with its whole sub-schema); then `validate` fills the defaults.
_problems = preflight.schema_problems(
    config, yaml.safe_load((Path(workflow.basedir) / "workflow/schemas/config.schema.yaml").read_text())
)
if _problems:
    raise WorkflowError("\n".join(f"imugen: error: {p}" for p in _problems))
validate(config, "../schemas/config.schema.yaml")
# Before any job: no NaN/inf, custom grades valid (not named like a preset), the run within
# the memory and disk budgets (estimates in the message; see src/imugen/preflight.py). Jobs
# re-reading this file on a cluster node skip the budget (it was checked where the run was
# started).
try:
    preflight.check_values(config)
    if workflow.is_main_process and not workflow.dryrun:
        preflight.check_budget(config)
except InputError as exc:
    raise WorkflowError(f"imugen: error: {exc}") from None

ROUTES = sorted(config["routes"])
GRADES = list(config["grades"])
SIM = config["simulate"]
N_SEQ = SIM["sequences"]
PER_SHARD = SIM["sequences_per_shard"]
# shard-000 ... shard-999, then shard-1000, ...: at least three digits, no other leading
# zeros, so adding shards never renames existing ones
SHARDS = [f"{k:03d}" for k in range(math.ceil(N_SEQ / PER_SHARD))]
WRITE_IMU = SIM["write_imu"]
MOUNTING = config.get("mounting", {})
MOUNTING_ARG = (
    f"--mounting={shlex.quote(json.dumps(MOUNTING))}" if MOUNTING.get("enabled") else ""
)
"""`imugen simulate --mounting JSON` when the config's mounting is enabled (else nothing)."""
# the IMU shard and its labels, when written (simulate.write_imu); without them the rules that
# read shards (export_mat, the figures' IMU panels) are not scheduled
IMU_OUTPUTS = (
    [
        "results/{route}/imu/{grade}/shard-{shard}.parquet",
        "results/{route}/imu/{grade}/shard-{shard}.labels.parquet",
    ]
    if WRITE_IMU
    else []
)
IMU_GRADES = GRADES if WRITE_IMU else []
FIG = config["figures"]


wildcard_constraints:
    route="|".join(ROUTES),
    grade="|".join(GRADES),
    shard=r"\d\d\d|[1-9]\d\d\d+",


@functools.cache
def stage_code(*modules):
    """A digest of the stage modules' source, a param of the stage's rules: editing one reruns
    the stage.

    Snakemake does not track imported code. A changed param reruns its jobs (Snakemake's
    `params` rerun trigger; a mere timestamp change, such as a git checkout, reruns nothing),
    and a static param costs a job nothing, where the same files as inputs of every shard job
    cost a fifth of a 10,000-shard dry run (benchmarks/bench_dryrun.py).
    """
    h = hashlib.sha256()
    for m in modules:
        h.update(m.encode() + b"\0")
        h.update((Path(workflow.basedir) / "src" / "imugen" / f"{m}.py").read_bytes())
    return h.hexdigest()[:16]


PRESETS = str(Path(workflow.basedir) / "src" / "imugen" / "data" / "grades.yaml")


def is_custom(grade):
    """A grade with a definition in the config (an empty mapping selects the preset)."""
    return bool(config["grades"][grade])


def grade_files(wildcards):
    """The custom grade's YAML file, when the grade is custom."""
    g = wildcards.grade
    return [f"results/grades/{g}.yaml"] if is_custom(g) else []


def grade_arg(wildcards):
    """`--grade` value: the preset name, or FILE.yaml:NAME for a custom grade."""
    g = wildcards.grade
    return f"results/grades/{g}.yaml:{g}" if is_custom(g) else g


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
    return " ".join(opts)


def ingest_clean_opts(wildcards):
    """`imugen ingest` options of the cleaning and gap rules for this route."""
    r = config["routes"][wildcards.route]
    opts = [f"--vehicle={shlex.quote(str(r.get('vehicle', 'car')))}"]
    if r.get("max_gap_s") is not None:
        opts.append(f"--max-gap-s={float(r['max_gap_s'])!r}")
    opts.append(f"--gaps={shlex.quote(str(r.get('gaps', 'split')))}")
    return " ".join(opts)


def auto_grades():
    """`--grade` options of the truth: every configured grade (presets by name, custom grades
    as FILE.yaml:NAME) takes part in the `--earth auto` budget."""
    return " ".join(
        f"--grade={shlex.quote(f'results/grades/{g}.yaml:{g}' if is_custom(g) else g)}"
        for g in GRADES
    )


AUTO_EARTH = config["truth"]["earth"] == "auto"


def custom_grade_files():
    """YAML files of all custom grades (inputs of the truth's `--earth auto` budget)."""
    return [f"results/grades/{g}.yaml" for g in GRADES if is_custom(g)]


def shard_paths(kind):
    """Per-grade list of all shard files of one kind (imu or nav) for a route."""
    return lambda wc: expand(
        f"results/{{route}}/{kind}/{{grade}}/shard-{{shard}}.parquet",
        route=wc.route,
        grade=wc.grade,
        shard=SHARDS,
    )


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
    from imugen.io import read_meta

    print("imugen: results in " + str(Path("results").resolve()))
    for r in ROUTES:
        truth = Path("results") / r / "truth.parquet"
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
        print(f"  {r}: results/{r}/ (rmse.csv, figures/); Earth model {m.get('earth')} ({why})")


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
AIDED = config["aided"]
COMP = config["companions"]
AID_ON = bool(GNSS["enabled"])


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
