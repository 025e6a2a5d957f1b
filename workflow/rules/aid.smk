# GNSS-denied scenarios and the aided baseline: per route, grade and shard, GNSS fixes with the
# configured scenarios, the companion sensors (config `companions`) and the loosely-coupled
# filter on the shard's IMU (config `gnss.enabled`); per route, the figure of error growth during
# outages.


rule aid:
    input:
        truth="results/{route}/truth.parquet",
        shard="results/{route}/imu/{grade}/shard-{shard}.parquet",
        grade=grade_files,
    output:
        gnss="results/{route}/gnss/{grade}/shard-{shard}.parquet",
        labels="results/{route}/gnss/{grade}/shard-{shard}.labels.parquet",
        intervals="results/{route}/gnss/{grade}/shard-{shard}.intervals.parquet",
        aided="results/{route}/aided/{grade}/shard-{shard}.parquet",
        companions="results/{route}/companions/{grade}/shard-{shard}.parquet",
        companion_labels="results/{route}/companions/{grade}/shard-{shard}.labels.parquet",
    params:
        code=stage_code(
            "aid", "aided", "gnss", "scenarios", "companions", "mechanize", "earth", "mounting",
            "local_errors",
        ),
        opts=aid_opts,
        grade=grade_arg,
        eval_rate_hz=config["navigate"]["eval_rate_hz"],
    log:
        "logs/{route}/aid/{grade}/shard-{shard}.log",
    shell:
        "imugen aid {input.truth:q} {input.shard:q} --gnss-out={output.gnss:q} --output={output.aided:q} "
        "--companions-out={output.companions:q} --grade={params.grade:q} "
        "--eval-rate-hz={params.eval_rate_hz} {params.opts} > {log:q} 2>&1"


rule outage_figure:
    input:
        aided=lambda wc: [
            f"results/{wc.route}/aided/{g}/shard-{s}.parquet" for g in GRADES for s in SHARDS
        ],
        nav=lambda wc: [
            f"results/{wc.route}/nav/{g}/shard-{s}.parquet" for g in GRADES for s in SHARDS
        ],
    output:
        report(
            expand("results/{{route}}/figures/outage_growth.{ext}", ext=FIG["formats"]),
            caption="../report/outage_growth.rst",
            category="Figures",
            labels={"route": "{route}", "figure": "error growth during GNSS outages"},
        ),
    params:
        code=stage_code("figures_outage", "figures", "plotting"),
        aided=grade_pairs("aided"),
        nav=grade_pairs("nav"),
        formats=" ".join(FIG["formats"]),
        dpi=FIG["dpi"],
    log:
        "logs/{route}/outage_figure.log",
    shell:
        "imugen outage-figure --output=results/{wildcards.route}/figures/outage_growth "
        "{params.aided} {params.nav} --formats {params.formats} --dpi={params.dpi} > {log:q} 2>&1"
