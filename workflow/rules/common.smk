# Helpers shared by the rule files: config validation, route list, code tracking.
from pathlib import Path

from snakemake.utils import validate


validate(config, "../schemas/config.schema.yaml")

ROUTES = sorted(config["routes"])


wildcard_constraints:
    route="|".join(ROUTES),


def route_cfg(wildcards):
    """This route's slice of the config (only what the rule needs is tracked as params)."""
    return config["routes"][wildcards.route]


def stage_code(*modules):
    """Source files of the stage modules, as inputs: editing one reruns the stage.

    Snakemake does not track imported code; these files are small, so their checksums are
    recorded and a mere timestamp change (git checkout) does not rerun anything.
    """
    return [str(Path(workflow.basedir) / "src" / "imugen" / f"{m}.py") for m in modules]


def ingest_opts(wildcards):
    """Command-line options of `imugen ingest` for this route (path, origin, dt)."""
    r = route_cfg(wildcards)
    opts = []
    if r.get("path") is not None:
        opts += ["--path", shlex_quote(str(r["path"]))]
    if r.get("origin") is not None:
        opts += ["--origin", ",".join(repr(float(x)) for x in r["origin"])]
    if r.get("dt_s") is not None:
        opts += ["--dt", repr(float(r["dt_s"]))]
    return " ".join(opts)


def shlex_quote(text):
    import shlex

    return shlex.quote(text)
