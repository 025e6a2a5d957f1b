# imugen workflow: route file -> CSV -> ENU -> truth -> IMU shards per grade -> navigation ->
# RMSE tables, figures, datasets and report. Rules live in workflow/rules/<stage>.smk and call
# the `imugen` command line (src/imugen); config/README.md documents every configuration key.
from snakemake.utils import min_version

min_version("9.0")


configfile: "config/config.yaml"


report: "workflow/report/workflow.rst"


include: "workflow/rules/common.smk"
include: "workflow/rules/ingest.smk"
include: "workflow/rules/truth.smk"
include: "workflow/rules/simulate.smk"
include: "workflow/rules/navigate.smk"
include: "workflow/rules/evaluate.smk"


rule all:
    default_target: True
    input:
        expand("results/{route}/rmse.csv", route=ROUTES),
        expand("results/allan/{grade}/allan.json", grade=GRADES),
