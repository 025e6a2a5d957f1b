# imugen workflow: route file -> CSV -> ENU -> truth -> IMU shards per grade -> navigation ->
# RMSE tables, figures, datasets and report. Rules live in workflow/rules/<stage>.smk and call
# the `imugen` command line (src/imugen); config/README.md documents every configuration key.
# `snakemake --lint` reports one remaining lint per rule, "Specify a conda environment or
# container": deliberate. imugen is a pip package; every rule calls its `imugen` command from
# the environment Snakemake itself runs in (README: one `pip install`), so a per-rule conda
# environment would only duplicate that environment. tests/system/test_workflow.py asserts that no
# other lint appears.
import copy
from pathlib import Path

import yaml
from snakemake.utils import min_version, update_config

min_version("9.0")

# Configuration: config/config.yaml of the working directory (the shipped example) gives every
# key; a --configfile or --config that names `routes` or `grades` REPLACES those two mappings
# instead of merging into them (Snakemake's `configfile:` directive would merge, adding the
# example route and the default grades to every user's run), and merges every other key as
# usual. `config` holds the command line's files and overrides at this point.
# tests/system/test_workflow.py checks it on the dry-run job list.
_cli_config = copy.deepcopy(config)
_shipped = Path("config/config.yaml")
if _shipped.is_file():
    config.clear()
    config.update(yaml.safe_load(_shipped.read_text()) or {})
    for _key in ("routes", "grades"):
        if _key in _cli_config:
            config.pop(_key, None)
    update_config(config, _cli_config)


report: "workflow/report/workflow.rst"


localrules:
    all,
    ingest_csv,
    ingest_enu,
    custom_grade,
    rmse_table,


include: "workflow/rules/common.smk"
include: "workflow/rules/ingest.smk"
include: "workflow/rules/truth.smk"
include: "workflow/rules/simulate.smk"
include: "workflow/rules/aid.smk"
include: "workflow/rules/evaluate.smk"
include: "workflow/rules/figures.smk"
include: "workflow/rules/export.smk"
include: "workflow/rules/allan.smk"
include: "workflow/rules/learn.smk"


onstart:
    check_executor()


onsuccess:
    run_summary()


onerror:
    report_failures(log)


rule all:
    # a benchmark config (config/benchmark.yaml) builds the benchmark instead (rule benchmark)
    default_target: not BENCH
    input:
        expand(rules.rmse_table.output.csv, route=ROUTES),
        expand(layout.figure("figure8"), route=ROUTES, ext=FIG["formats"]),
        expand(layout.figure("outage_growth"), route=ROUTES if AID_ON else [], ext=FIG["formats"]),
        expand(
            layout.figure("outage_drift"), route=ROUTES if OUTAGES else [], ext=FIG["formats"]
        ),
        expand(rules.allan.output.json, grade=GRADES),
        expand(
            rules.export_mat.output[0],
            route=ROUTES,
            grade=GRADES if config["exports"]["mat"] and WRITE_IMU else [],
        ),
        expand(
            layout.datasets_dir(),
            route=ROUTES,
            grade=GRADES if config["exports"]["formats"] and WRITE_IMU else [],
        ),
        expand(
            layout.shard("estimates"),
            route=ROUTES,
            grade=GRADES if AID_ON and AIDED["estimates"] else [],
            shard=SHARDS,
        ),


if BENCH:  # default target of a benchmark config (an included file cannot set one)

    rule benchmark:
        default_target: True
        input:
            rules.benchmark_table.output,
