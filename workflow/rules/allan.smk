# Allan check per grade: a still IMU simulated for `allan.static_s` seconds, then its Allan
# deviation against the grade's figures (JSON report and plot, each written atomically).


rule allan_static:
    input:
        grade=grade_files,
        presets=PRESETS,
    output:
        layout.allan_static(),
    params:
        code=code_digest("imugen.simulate.stage"),
        grade=grade_arg,
        spec=lambda wc: config["grades"][wc.grade],
        static_s=config["allan"]["static_s"],
        rate_hz=config["allan"]["rate_hz"],
        sequences=config["allan"]["sequences"],
        seed=SIM["seed"],
    log:
        "logs/allan/{grade}/static.log",
    shell:
        "imugen simulate --static={params.static_s} --rate-hz={params.rate_hz} "
        "--output={output:q} --grade={params.grade:q} --sequences={params.sequences} "
        "--seed={params.seed} --shard=0 --draw=nominal > {log:q} 2>&1"


rule allan:
    input:
        static=rules.allan_static.output[0],
    output:
        json=layout.allan(ext="json"),
        plot=report(
            layout.allan(ext="png"),
            caption="../report/allan.rst",
            category="Allan deviation",
            labels={"grade": "{grade}"},
        ),
    params:
        code=code_digest("imugen.allan.stage"),
    log:
        "logs/allan/{grade}/allan.log",
    shell:
        "imugen allan {input.static:q} --plot={output.plot:q} --output={output.json:q} > {log:q} 2>&1"
