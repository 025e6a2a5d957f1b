# Figures per route: the paper's Figure 8, 3-D trajectories, errors against time, IMU signals.

rule figures:
    input:
        truth="results/{route}/truth.parquet",
        nav=lambda wc: [
            f"results/{wc.route}/nav/{g}/shard-{s}.parquet" for g in GRADES for s in SHARDS
        ],
        metrics=expand("results/{{route}}/metrics/{grade}.parquet", grade=GRADES),
        imu=expand("results/{{route}}/imu/{grade}/shard-000.parquet", grade=IMU_GRADES),
    output:
        report(
            expand("results/{{route}}/figures/figure8.{ext}", ext=FIG["formats"]),
            caption="../report/figure8.rst",
            category="Figures",
            labels={"route": "{route}", "figure": "Figure 8 (paper)"},
        ),
        report(
            expand("results/{{route}}/figures/trajectories_3d.{ext}", ext=FIG["formats"]),
            caption="../report/trajectories_3d.rst",
            category="Figures",
            labels={"route": "{route}", "figure": "3-D trajectories"},
        ),
        report(
            expand("results/{{route}}/figures/error_vs_time.{ext}", ext=FIG["formats"]),
            caption="../report/error_vs_time.rst",
            category="Figures",
            labels={"route": "{route}", "figure": "errors against time"},
        ),
        report(
            expand(
                "results/{{route}}/figures/imu_{grade}.{ext}", grade=IMU_GRADES, ext=FIG["formats"]
            ),
            caption="../report/imu.rst",
            category="Figures",
            labels={"route": "{route}", "figure": "IMU signals"},
        ),
    params:
        code=stage_code("figures", "mapview"),
        nav=grade_pairs("nav"),
        metrics=grade_pairs("metrics"),
        imu=grade_pairs("imu"),
        formats=" ".join(FIG["formats"]),
        dpi=FIG["dpi"],
        zoom=FIG["zoom_fraction"],
        representative=FIG["representative"],
    log:
        "logs/{route}/figures.log",
    shell:
        "imugen figures {input.truth:q} --outdir=results/{wildcards.route}/figures "
        "{params.nav} {params.metrics} {params.imu} --formats {params.formats} --dpi={params.dpi} "
        "--zoom-fraction={params.zoom} --representative={params.representative} > {log:q} 2>&1"
