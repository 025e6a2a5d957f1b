# Navigation: every shard mechanized back into trajectories; errors against the truth.


rule navigate:
    input:
        truth="results/{route}/truth.parquet",
        shard="results/{route}/imu/{grade}/shard-{shard}.parquet",
        code=stage_code("navigate", "mechanize", "earth", "rotations"),
    output:
        "results/{route}/nav/{grade}/shard-{shard}.parquet",
    params:
        eval_rate_hz=config["navigate"]["eval_rate_hz"],
    log:
        "logs/{route}/navigate/{grade}/shard-{shard}.log",
    shell:
        "IMUGEN_CONSOLE_FD=3 imugen navigate {input.truth:q} {input.shard:q} -o {output:q} "
        "--eval-rate-hz {params.eval_rate_hz} 3>&2 > {log:q} 2>&1"
