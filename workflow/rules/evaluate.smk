# Evaluation: per-grade per-sequence RMSE and relative drift, then the RMSE table of each route.


# relative drift re-navigates the IMU shards from true starts: without shards
# (simulate.write_imu: false) it is skipped (config/README.md says so)
SEGMENTS = config["evaluate"]["segments_s"] if WRITE_IMU else []


rule evaluate:
    input:
        truth="results/{route}/truth.parquet",
        nav=shard_paths("nav"),
        imu=shard_paths("imu") if SEGMENTS else [],
        aided=shard_paths("aided") if AID_ON else [],
    output:
        "results/{route}/metrics/{grade}.parquet",
    params:
        code=stage_code("evaluate", "navigate", "mechanize", "earth", "rotations"),
        segments=(
            "--segments=" + ",".join(f"{T:g}" for T in SEGMENTS) + " --imu" if SEGMENTS else ""
        ),
        aided="--aided" if AID_ON else "",
    log:
        "logs/{route}/evaluate/{grade}.log",
    shell:
        "imugen evaluate {input.truth:q} {input.nav:q} --output={output:q} --grade={wildcards.grade} "
        "{params.segments} {input.imu:q} {params.aided} {input.aided:q} > {log:q} 2>&1"


rule tables:
    input:
        metrics=expand("results/{{route}}/metrics/{grade}.parquet", grade=GRADES),
    output:
        csv=report(
            "results/{route}/rmse.csv",
            caption="../report/rmse.rst",
            category="RMSE",
            labels={"route": "{route}", "format": "CSV"},
        ),
        md="results/{route}/rmse.md",
        tex="results/{route}/rmse.tex",
        html=report(
            "results/{route}/rmse.html",
            caption="../report/rmse.rst",
            category="RMSE",
            labels={"route": "{route}", "format": "table"},
        ),
    params:
        code=stage_code("evaluate"),
    log:
        "logs/{route}/tables.log",
    shell:
        "imugen tables {input.metrics:q} --output={output.csv:q} > {log:q} 2>&1"
