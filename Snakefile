# imugen workflow: route file -> CSV -> ENU -> truth -> IMU shards per grade -> navigation ->
# RMSE tables, figures, datasets and report. Rules live in workflow/rules/<stage>.smk and call
# the `imugen` command line (src/imugen); config/README.md documents every configuration key.
# `snakemake --lint` reports one remaining lint per rule, "Specify a conda environment or
# container": deliberate. imugen is a pip package; every rule calls its `imugen` command from
# the environment Snakemake itself runs in (README: one `pip install`), so a per-rule conda
# environment would only duplicate that environment. tests/test_workflow.py asserts that no
# other lint appears.
from snakemake.utils import min_version

min_version("9.0")


configfile: "config/config.yaml"


report: "workflow/report/workflow.rst"


localrules:
    all,
    ingest_csv,
    ingest_enu,
    custom_grade,
    tables,


include: "workflow/rules/common.smk"
include: "workflow/rules/ingest.smk"
include: "workflow/rules/truth.smk"
include: "workflow/rules/simulate.smk"
include: "workflow/rules/evaluate.smk"
include: "workflow/rules/figures.smk"
include: "workflow/rules/export.smk"


rule all:
    default_target: True
    input:
        expand("results/{route}/rmse.csv", route=ROUTES),
        expand("results/{route}/figures/figure8.{ext}", route=ROUTES, ext=FIG["formats"]),
        expand("results/allan/{grade}/allan.json", grade=GRADES),
        expand(
            "results/{route}/datasets/{grade}.mat",
            route=ROUTES,
            grade=GRADES if config["exports"]["mat"] and WRITE_IMU else [],
        ),
