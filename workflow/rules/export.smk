# Datasets for MATLAB users: one .mat per route and grade (truth, IMU, labels, errors).


rule export_mat:
    input:
        truth="results/{route}/truth.parquet",
        shards=shard_paths("imu"),
        nav=shard_paths("nav"),
        code=stage_code("export"),
    output:
        "results/{route}/datasets/{grade}.mat",
    log:
        "logs/{route}/export_mat/{grade}.log",
    shell:
        "imugen export-mat --truth {input.truth:q} --shards {input.shards:q} --nav {input.nav:q} "
        "--grade {wildcards.grade} --route {wildcards.route} -o {output:q} > {log:q} 2>&1"
