# GNSS-denied scenarios and the aided baseline: per route, grade and shard, GNSS fixes with the
# configured scenarios and the loosely-coupled filter on the shard's IMU (config `gnss.enabled`).


GNSS = config["gnss"]
SCEN = config["scenarios"]
AIDED = config["aided"]
AID_ON = bool(GNSS["enabled"])


def aid_opts(wildcards):
    """`imugen aid` options from the gnss, scenarios and aided config blocks."""
    opts = [f"--receiver {GNSS['receiver']}", f"--gnss-draw {GNSS['draw']}"]
    if GNSS["rate_hz"] is not None:
        opts.append(f"--gnss-rate-hz {GNSS['rate_hz']!r}")
    opts.append("--lever-arm " + ",".join(repr(float(x)) for x in GNSS["lever_arm_b_m"]))
    opts.append(f"--lever-arm-sd {float(GNSS['lever_arm_sd_m'])!r}")
    specs = [f"outage:{float(T)!r}" for T in SCEN["outages_s"]] + list(SCEN["draw"])
    for iv in SCEN["intervals"]:
        extra = "".join(
            f",{k}={float(v)!r}" for k, v in iv.items() if k not in ("kind", "start_s", "duration_s")
        )
        specs.append(f"{iv['kind']}:{float(iv['duration_s'])!r}@{float(iv['start_s'])!r}{extra}")
    opts += [f"--scenario {shlex.quote(s)}" for s in specs]
    opts.append(f"--settle-s {float(SCEN['settle_s'])!r}")
    opts.append(f"--tuning-level {AIDED['tuning_level']}")
    if not AIDED["gnss_bias_states"]:
        opts.append("--no-gnss-bias-states")
    if AIDED["scale_factors"]:
        opts.append("--scale-factors")
    if AIDED["nhc"] is not None:
        opts.append("--nhc" if AIDED["nhc"] else "--no-nhc")
    if not AIDED["zupt"]:
        opts.append("--no-zupt")
    opts.append(f"--gate-sigma {float(AIDED['gate_sigma'])!r}")
    return " ".join(opts)


rule aid:
    input:
        truth="results/{route}/truth.parquet",
        shard="results/{route}/imu/{grade}/shard-{shard}.parquet",
        grade=grade_files,
        code=stage_code("aid", "aided", "gnss", "scenarios", "mechanize", "earth"),
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
