# imugen workflow: route file -> CSV -> ENU -> truth -> (later) IMU shards -> navigation -> RMSE.
# Rules live in workflow/rules/<stage>.smk and call the `imugen` CLI (src/imugen).
from snakemake.utils import min_version

min_version("9.0")


configfile: "config/config.yaml"


include: "workflow/rules/common.smk"
include: "workflow/rules/ingest.smk"


rule all:
    default_target: True
    input:
        expand("results/{route}/enu.parquet", route=ROUTES),
