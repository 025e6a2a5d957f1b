# Truth: ENU route -> smooth 6-DoF motion and the ideal IMU at the IMU rate.


rule truth:
    input:
        enu=rules.ingest_enu.output[0],
        # the grades feed only the `earth: auto` budget: with an explicit Earth model the truth
        # does not depend on them (editing a grade then reruns only that grade's jobs)
        grade_files=custom_grade_files() if AUTO_EARTH else [],
        presets=PRESETS if AUTO_EARTH else [],
    output:
        layout.truth(),
    params:
        code=code_digest("imugen.truth.stage"),
        rate_hz=config["truth"]["rate_hz"],
        earth=config["truth"]["earth"],
        vehicle=lambda wc: config["routes"][wc.route]["vehicle"],
        grades=auto_grades() if AUTO_EARTH else "",
        pose=truth_pose_opts,
    log:
        "logs/{route}/truth.log",
    shell:
        "imugen truth {input.enu:q} --output={output:q} --rate-hz={params.rate_hz} "
        "--earth={params.earth} --vehicle={params.vehicle} {params.pose} {params.grades} "
        "> {log:q} 2>&1"
