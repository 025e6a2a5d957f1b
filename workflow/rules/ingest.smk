# Ingestion: route file (KML/KMZ/GPX/CSV/ENU text, NMEA, IGC, GeoJSON, ...) -> geodetic CSV
# -> ENU Parquet. Cleaning (vehicle limits) and gap handling happen in the first step; the CSV
# carries their report to the second.


rule ingest_csv:
    input:
        src=lambda wc: config["routes"][wc.route]["file"],
    output:
        layout.route_csv(),
    params:
        code=code_digest("imugen.ingest.stage"),
        opts=lambda wc: f"{ingest_opts(wc)} {ingest_clean_opts(wc)}",
    log:
        "logs/{route}/ingest_csv.log",
    shell:
        "imugen ingest --output={output:q} {params.opts} -- {input.src:q} > {log:q} 2>&1"


rule ingest_enu:
    input:
        csv=rules.ingest_csv.output[0],
    output:
        layout.enu(),
    params:
        code=code_digest("imugen.ingest.stage"),
    log:
        "logs/{route}/ingest_enu.log",
    shell:
        "imugen ingest {input.csv:q} --output={output:q} > {log:q} 2>&1"
