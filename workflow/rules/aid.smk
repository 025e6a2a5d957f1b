# GNSS-denied scenarios and the aided baseline: per route, grade and shard, GNSS fixes with the
# configured scenarios, the companion sensors (config `companions`) and the loosely-coupled
# filter on the shard's IMU (config `gnss.enabled`). The figure of error growth during outages
# is in figures.smk.


rule aid:
    input:
        truth=rules.truth.output[0],
        shard=layout.shard("imu"),
        grade=grade_files,
        # a learner's measurements per shard (config aided.learned_in, a path with {route},
        # {grade}, {shard}; imugen.tables.learned)
        **({"learned": AIDED["learned_in"]} if AIDED["learned_in"] else {}),
    output:
        gnss=layout.shard("gnss"),
        labels=layout.sidecar(layout.shard("gnss"), "labels"),
        intervals=layout.sidecar(layout.shard("gnss"), "intervals"),
        aided=layout.shard("aided"),
        companions=layout.shard("companions"),
        companion_labels=layout.sidecar(layout.shard("companions"), "labels"),
        # the filter's per-epoch state and sigmas (config aided.estimates; off by default: about
        # 1.6 times the IMU shard's size on disk at a 10 Hz receiver)
        **({"estimates": layout.shard("estimates")} if AIDED["estimates"] else {}),
    params:
        code=code_digest("imugen.aid.stage"),
        opts=aid_opts,
        grade=grade_arg,
        eval_rate_hz=config["navigate"]["eval_rate_hz"],
        learned=lambda wildcards, input: (
            f"--learned-in={shlex.quote(input.learned)}" if AIDED["learned_in"] else ""
        ),
        estimates=lambda wildcards, output: (
            f"--estimates-out={shlex.quote(output.estimates)}" if AIDED["estimates"] else ""
        ),
    log:
        "logs/{route}/aid/{grade}/shard-{shard}.log",
    shell:
        "imugen aid {input.truth:q} {input.shard:q} --gnss-out={output.gnss:q} --output={output.aided:q} "
        "--companions-out={output.companions:q} --grade={params.grade:q} "
        "--eval-rate-hz={params.eval_rate_hz} {params.estimates} {params.learned} {params.opts} > {log:q} 2>&1"
