# Evaluation: per-grade per-sequence RMSE and relative drift, then the RMSE table of each route
# (rule rmse_table; command `imugen tables`).


# relative drift re-navigates the IMU shards from true starts: without shards
# (simulate.write_imu: false) it is skipped (config/README.md says so)
SEGMENTS = config["evaluate"]["segments_s"] if WRITE_IMU else []


rule evaluate:
    input:
        truth=rules.truth.output[0],
        nav=shard_paths("nav"),
        imu=shard_paths("imu") if SEGMENTS else [],
        aided=shard_paths("aided") if AID_ON else [],
    output:
        layout.metrics(),
    params:
        code=code_digest("imugen.evaluate.stage"),
        segments=(
            "--segments=" + ",".join(f"{T:g}" for T in SEGMENTS) + " --imu" if SEGMENTS else ""
        ),
        aided="--aided" if AID_ON else "",
    log:
        "logs/{route}/evaluate/{grade}.log",
    shell:
        "imugen evaluate {input.truth:q} {input.nav:q} --output={output:q} --grade={wildcards.grade} "
        "{params.segments} {input.imu:q} {params.aided} {input.aided:q} > {log:q} 2>&1"


rule rmse_table:
    input:
        metrics=expand(rules.evaluate.output[0], grade=GRADES, allow_missing=True),
    output:
        csv=report(
            layout.rmse(ext="csv"),
            caption="../report/rmse.rst",
            category="RMSE",
            labels={"route": "{route}", "format": "CSV"},
        ),
        md=layout.rmse(ext="md"),
        tex=layout.rmse(ext="tex"),
        html=report(
            layout.rmse(ext="html"),
            caption="../report/rmse.rst",
            category="RMSE",
            labels={"route": "{route}", "format": "table"},
        ),
    params:
        code=code_digest("imugen.evaluate.stage"),
    log:
        "logs/{route}/rmse_table.log",
    shell:
        "imugen tables {input.metrics:q} --output={output.csv:q} > {log:q} 2>&1"
