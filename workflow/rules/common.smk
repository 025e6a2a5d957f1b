# Helpers for every stage: config validation, routes/grades/shards, code tracking.
import json
import math
import shlex
from pathlib import Path

from snakemake.utils import validate


validate(config, "../schemas/config.schema.yaml")

ROUTES = sorted(config["routes"])
GRADES = list(config["grades"])
SIM = config["simulate"]
N_SEQ = SIM["sequences"]
PER_SHARD = SIM["sequences_per_shard"]
SHARDS = [f"{k:03d}" for k in range(math.ceil(N_SEQ / PER_SHARD))]
WRITE_IMU = SIM["write_imu"]
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
    shard=r"\d{3}",


def stage_code(*modules):
    """Source files of the stage modules, as inputs: editing one reruns the stage.

    Snakemake does not track imported code; these files are small, so their checksums are
    recorded and a mere timestamp change (git checkout) does not rerun anything.
    """
    return [str(Path(workflow.basedir) / "src" / "imugen" / f"{m}.py") for m in modules]


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
    """Command-line options of `imugen ingest` for this route (path, origin, dt)."""
    r = config["routes"][wildcards.route]
    opts = []
    if r.get("path") is not None:
        opts += ["--path", shlex.quote(str(r["path"]))]
    if r.get("origin") is not None:
        opts += ["--origin", ",".join(repr(float(x)) for x in r["origin"])]
    if r.get("dt_s") is not None:
        opts += ["--dt", repr(float(r["dt_s"]))]
    return " ".join(opts)


def auto_grades():
    """`--grade` options of the truth: the configured preset grades decide `--earth auto`."""
    names = [g for g in GRADES if not is_custom(g)]
    return " ".join(f"--grade {g}" for g in names)


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
            f"--{kind} {g}={shlex.quote(f)}"
            for i, g in enumerate(GRADES)
            for f in files[i * per : (i + 1) * per]
        )

    return opts
