# Figures per route: the paper's Figure 8, 3-D trajectories, errors against time, IMU signals;
# with the aid stage, the error growth during GNSS outages.

rule figures:
    input:
        truth=rules.truth.output[0],
        nav=route_shards("nav"),
        metrics=expand(layout.metrics(grade="{grade}"), grade=GRADES, allow_missing=True),
        imu=[layout.shard("imu", grade=g, shard=layout.shard_label(0)) for g in IMU_GRADES],
    output:
        figure_reports("figure8", "../report/figure8.rst", "Figure 8 (paper)"),
        figure_reports("trajectories_3d", "../report/trajectories_3d.rst", "3-D trajectories"),
        figure_reports("error_vs_time", "../report/error_vs_time.rst", "errors against time"),
        [
            figure_reports(f"imu_{g}", "../report/imu.rst", "IMU signals", grade=g)
            for g in IMU_GRADES
        ],
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
        figure_reports(
            "outage_growth", "../report/outage_growth.rst", "error growth during GNSS outages"
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


rule outage_drift:
    input:
        metrics=expand(layout.metrics(grade="{grade}"), grade=GRADES, allow_missing=True),
    output:
        csv=report(
            f"{layout.route_dir()}/outage_drift.csv",
            caption="../report/outage_drift.rst",
            category="Outages",
            labels={"route": "{route}", "format": "CSV"},
        ),
        md=f"{layout.route_dir()}/outage_drift.md",
        figures=figure_reports(
            "outage_drift", "../report/outage_drift.rst", "drift at the end of each GNSS outage"
        ),
    params:
        code=code_digest("imugen.figures.outage_drift"),
        stem=lambda wc: layout.figure("outage_drift", "", wc.route).removesuffix("."),
        metrics=grade_pairs("metrics"),
        formats=" ".join(FIG["formats"]),
        dpi=FIG["dpi"],
    log:
        "logs/{route}/outage_drift.log",
    shell:
        "imugen outage-drift --output={params.stem:q} --table={output.csv:q} "
        "{params.metrics} --formats {params.formats} --dpi={params.dpi} > {log:q} 2>&1"
