# Datasets for MATLAB users: one .mat per route and grade (truth, IMU, labels, errors).


rule export_mat:
    input:
        truth=rules.truth.output[0],
        shards=shard_paths("imu"),
        nav=shard_paths("nav"),
    output:
        layout.dataset_mat(),
    params:
        code=code_digest("imugen.export.mat"),
    log:
        "logs/{route}/export_mat/{grade}.log",
    shell:
        "imugen export-mat --truth={input.truth:q} --shards {input.shards:q} --nav {input.nav:q} "
        "--grade={wildcards.grade} --route={wildcards.route} --output={output:q} > {log:q} 2>&1"


# the companion sensors (aid stage, config `companions`) go to the ROS 2 bags
COMPANION_EXPORT = (
    AID_ON
    and "ros2" in config["exports"]["formats"]
    and (COMP["odometer"] is not None or COMP["barometer"] is not None)
)

# the split lists (config `exports.split`), the same in every route's and grade's export
SPLIT = config["exports"]["split"]
_unknown = sorted(set(SPLIT["holdout_routes"]) - set(ROUTES))
if _unknown:
    raise WorkflowError(
        f"imugen: error: exports.split.holdout_routes: {', '.join(_unknown)} not among the routes"
    )
if SPLIT["val_fraction"] + SPLIT["test_fraction"] >= 1:
    raise WorkflowError(
        "imugen: error: exports.split: val_fraction + test_fraction must leave some for train"
    )
SPLIT_OPTS = (
    f"--split-by={SPLIT['by']} --split-seed={int(SPLIT['seed'])} "
    f"--val-fraction={float(SPLIT['val_fraction'])!r} "
    f"--test-fraction={float(SPLIT['test_fraction'])!r}"
    + (f" --holdout-routes={shlex.quote(','.join(SPLIT['holdout_routes']))}" if SPLIT["holdout_routes"] else "")
)
"""`imugen export` options of the split lists (config `exports.split`)."""


rule export_formats:
    input:
        truth=rules.truth.output[0],
        shards=shard_paths("imu"),
        gnss=shard_paths("gnss") if AID_ON else [],
        aided=shard_paths("aided") if AID_ON and "tum" in config["exports"]["formats"] else [],
        companions=shard_paths("companions") if COMPANION_EXPORT else [],
    output:
        directory(layout.datasets_dir()),
    params:
        code=code_digest("imugen.export.stage"),
        formats=",".join(config["exports"]["formats"]),
        nav_rate_hz=config["exports"]["nav_rate_hz"],
        split=SPLIT_OPTS,
        gnss=lambda wc, input: ("--gnss " + " ".join(map(shlex.quote, input.gnss))) if input.gnss else "",
        aided=lambda wc, input: ("--aided " + " ".join(map(shlex.quote, input.aided))) if input.aided else "",
        companions=lambda wc, input: (
            ("--companions " + " ".join(map(shlex.quote, input.companions))) if input.companions else ""
        ),
    log:
        "logs/{route}/export_formats/{grade}.log",
    shell:
        "imugen export {input.truth:q} {input.shards:q} --output={output:q} --format={params.formats} "
        "--route={wildcards.route} --grade={wildcards.grade} --nav-rate-hz={params.nav_rate_hz} "
        "{params.split} "
        "--overwrite {params.gnss} {params.aided} {params.companions} > {log:q} 2>&1"
