# Sensor errors: per route, grade and shard, M sequences of measured IMU with their labels.


rule custom_grade:
    output:
        layout.grade_file(),
    params:
        doc=lambda wc: json.dumps({"grades": {wc.grade: config["grades"][wc.grade]}}),
    log:
        "logs/grades/{grade}.log",
    shell:
        "printf '%s\\n' {params.doc:q} > {output:q} 2> {log:q}"


# One job per shard from noise to navigation errors: the shard is synthesized, written (unless
# simulate.write_imu is false) and navigated in the same process, never re-read.
rule simulate:
    input:
        truth=rules.truth.output[0],
        grade=grade_files,
        presets=PRESETS,
        vibration=[SIM["vibration"]] if str(SIM["vibration"]).endswith((".yaml", ".yml")) else [],
    output:
        nav=layout.shard("nav"),
        imu=IMU_OUTPUTS,
    # few function params: Snakemake calls each one for each job; the grade's definition
    # reaches the job through its file (input grade), the shard number through its wildcard
    params:
        code=code_digest("imugen.simulate.stage"),
        grade=grade_arg,
        sequences=shard_sequences,
        shard_size=PER_SHARD,
        seed=SIM["seed"],
        draw=SIM["draw"],
        dtype=SIM["dtype"],
        outputs=SIM["outputs"],
        series="--series" if SIM["series"] else "",
        increments=SIM["increments"],
        vibration=SIM["vibration"] or "off",
        mounting=MOUNTING_ARG,
        imu=lambda wc, output: f"--output={shlex.quote(output.imu[0])}" if WRITE_IMU else "",
        eval_rate_hz=config["navigate"]["eval_rate_hz"],
        vertical=config["navigate"]["vertical"],
    log:
        "logs/{route}/simulate/{grade}/shard-{shard}.log",
    shell:
        "IMUGEN_CONSOLE_FD=3 "
        "imugen simulate {input.truth:q} {params.imu} --navigate={output.nav:q} "
        "--eval-rate-hz={params.eval_rate_hz} --vertical={params.vertical[mode]} "
        "--vertical-order={params.vertical[order]} "
        "--vertical-time-constant-s={params.vertical[time_constant_s]} "
        "--vertical-reference={params.vertical[reference]} "
        "--route={wildcards.route:q} --grade={params.grade:q} "
        "--sequences={params.sequences} --shard-size={params.shard_size} --seed={params.seed} "
        "--shard={wildcards.shard} --draw={params.draw} --dtype={params.dtype} --outputs={params.outputs} --increments={params.increments} {params.series} "
        "--vibration={params.vibration} {params.mounting} "
        "3>&2 > {log:q} 2>&1"
