# Figures per route: the paper's Figure 8, 3-D trajectories, errors against time, IMU signals;
# with the aid stage, the error growth during GNSS outages.

rule figures:
    input:
        truth=rules.truth.output[0],
        nav=route_shards("nav"),
        metrics=expand(layout.metrics(grade="{grade}"), grade=GRADES, allow_missing=True),
        imu=[layout.shard("imu", grade=g, shard=layout.shard_label(0)) for g in IMU_GRADES],
    output:
        report(
            [layout.figure("figure8", ext) for ext in FIG["formats"]],
            caption="../report/figure8.rst",
            category="Figures",
            labels={"route": "{route}", "figure": "Figure 8 (paper)"},
        ),
        report(
            [layout.figure("trajectories_3d", ext) for ext in FIG["formats"]],
            caption="../report/trajectories_3d.rst",
            category="Figures",
            labels={"route": "{route}", "figure": "3-D trajectories"},
        ),
        report(
            [layout.figure("error_vs_time", ext) for ext in FIG["formats"]],
            caption="../report/error_vs_time.rst",
            category="Figures",
            labels={"route": "{route}", "figure": "errors against time"},
        ),
        report(
            [layout.figure(f"imu_{g}", ext) for g in IMU_GRADES for ext in FIG["formats"]],
            caption="../report/imu.rst",
            category="Figures",
            labels={"route": "{route}", "figure": "IMU signals"},
        ),
    params:
        code=code_digest("imugen.figures.stage"),
        outdir=lambda wc: layout.figures_dir(wc.route),
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
        "imugen figures {input.truth:q} --outdir={params.outdir:q} "
        "{params.nav} {params.metrics} {params.imu} --formats {params.formats} --dpi={params.dpi} "
        "--zoom-fraction={params.zoom} --representative={params.representative} > {log:q} 2>&1"


rule outage_figure:
    input:
        aided=route_shards("aided"),
        nav=route_shards("nav"),
    output:
        report(
            [layout.figure("outage_growth", ext) for ext in FIG["formats"]],
            caption="../report/outage_growth.rst",
            category="Figures",
            labels={"route": "{route}", "figure": "error growth during GNSS outages"},
        ),
    params:
        code=code_digest("imugen.figures.outage"),
        stem=lambda wc: layout.figure("outage_growth", "", wc.route).removesuffix("."),
        aided=grade_pairs("aided"),
        nav=grade_pairs("nav"),
        formats=" ".join(FIG["formats"]),
        dpi=FIG["dpi"],
    log:
        "logs/{route}/outage_figure.log",
    shell:
        "imugen outage-figure --output={params.stem:q} "
        "{params.aided} {params.nav} --formats {params.formats} --dpi={params.dpi} > {log:q} 2>&1"
