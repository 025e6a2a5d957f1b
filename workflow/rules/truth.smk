# Truth: ENU route -> smooth 6-DoF motion and the ideal IMU at the IMU rate.


rule truth:
    input:
        enu="results/{route}/enu.parquet",
        # the grades feed only the `earth: auto` budget: with an explicit Earth model the truth
        # does not depend on them (editing a grade then reruns only that grade's jobs)
        grade_files=custom_grade_files() if AUTO_EARTH else [],
        presets=PRESETS if AUTO_EARTH else [],
    output:
        "results/{route}/truth.parquet",
    params:
        code=stage_code(
            "truth/__init__",
            "truth/budget",
            "truth/build",
            "truth/fit",
            "truth/profile",
            "truth/attitude",
            "truth/increments",
            "truth/report",
            "truth/stage",
            "truth/vehicles",
            "earth",
            "rotations",
            "tables/__init__",
            "tables/_parquet",
            "tables/enu",
            "tables/truth",
            "grades",
        ),
        rate_hz=config["truth"]["rate_hz"],
        earth=config["truth"]["earth"],
        vehicle=lambda wc: config["routes"][wc.route]["vehicle"],
        grades=auto_grades() if AUTO_EARTH else "",
    log:
        "logs/{route}/truth.log",
    shell:
        "imugen truth {input.enu:q} --output={output:q} --rate-hz={params.rate_hz} "
        "--earth={params.earth} --vehicle={params.vehicle} {params.grades} > {log:q} 2>&1"
