# Ingestion: route file (KML/KMZ/GPX/CSV/ENU text, NMEA, IGC, GeoJSON, ...) -> geodetic CSV
# -> ENU Parquet. Cleaning (vehicle limits) and gap handling happen in the first step; the CSV
# carries their report to the second.


rule ingest_csv:
    input:
        src=lambda wc: config["routes"][wc.route]["file"],
        code=code_inputs("imugen.ingest.stage"),
    output:
        layout.route_csv(),
    params:
        opts=lambda wc: f"{ingest_opts(wc)} {ingest_clean_opts(wc)}",
    log:
        "logs/{route}/ingest_csv.log",
    shell:
        "imugen ingest {input.src:q} -o {output:q} {params.opts} > {log:q} 2>&1"


rule ingest_enu:
    input:
        csv=rules.ingest_csv.output[0],
        code=code_inputs("imugen.ingest.stage"),
    output:
        layout.enu(),
    log:
        "logs/{route}/ingest_enu.log",
    shell:
        "imugen ingest {input.csv:q} -o {output:q} > {log:q} 2>&1"
