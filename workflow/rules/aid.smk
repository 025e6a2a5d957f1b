# GNSS-denied scenarios and the aided baseline: per route, grade and shard, GNSS fixes with the
# configured scenarios and the loosely-coupled filter on the shard's IMU (config `gnss.enabled`).


rule aid:
    input:
        truth="results/{route}/truth.parquet",
        shard="results/{route}/imu/{grade}/shard-{shard}.parquet",
        grade=grade_files,
        code=stage_code(
            "aid", "aided", "gnss", "scenarios", "mechanize", "earth", "local_errors"
        ),
    output:
        gnss="results/{route}/gnss/{grade}/shard-{shard}.parquet",
        labels="results/{route}/gnss/{grade}/shard-{shard}.labels.parquet",
        intervals="results/{route}/gnss/{grade}/shard-{shard}.intervals.parquet",
        aided="results/{route}/aided/{grade}/shard-{shard}.parquet",
    params:
        opts=aid_opts,
        grade=grade_arg,
        eval_rate_hz=config["navigate"]["eval_rate_hz"],
    log:
        "logs/{route}/aid/{grade}/shard-{shard}.log",
    shell:
        "imugen aid {input.truth:q} {input.shard:q} --gnss-out {output.gnss:q} -o {output.aided:q} "
        "--grade {params.grade:q} --eval-rate-hz {params.eval_rate_hz} {params.opts} > {log:q} 2>&1"
