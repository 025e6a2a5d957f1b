# Ingestion: route file (KML/KMZ/GPX/CSV/ENU text, NMEA, IGC, GeoJSON, ...) -> geodetic CSV
# -> ENU Parquet. Cleaning (vehicle limits) and gap handling happen in the first step; the CSV
# carries their report to the second.


rule ingest_csv:
    input:
        src=lambda wc: config["routes"][wc.route]["file"],
        code=stage_code(
            "ingest/stage", "core/frames", "ingest/route", "ingest/xmlsafe", "ingest/readers/__init__", "ingest/readers/kml",
            "ingest/readers/gpx", "ingest/readers/text", "ingest/readers/nmea", "ingest/readers/igc", "ingest/readers/geojson",
            "ingest/readers/gnsscsv", "ingest/readers/babel", "ingest/clean", "ingest/segments", "ingest/limits",
        ),
    output:
        "results/{route}/route.csv",
    params:
        opts=lambda wc: f"{ingest_opts(wc)} {ingest_clean_opts(wc)}",
    log:
        "logs/{route}/ingest_csv.log",
    shell:
        "imugen ingest {input.src:q} -o {output:q} {params.opts} > {log:q} 2>&1"


rule ingest_enu:
    input:
        csv="results/{route}/route.csv",
        code=stage_code("ingest/stage", "core/frames", "ingest/readers/text", "ingest/clean", "ingest/segments"),
    output:
        "results/{route}/enu.parquet",
    log:
        "logs/{route}/ingest_enu.log",
    shell:
        "imugen ingest {input.csv:q} -o {output:q} > {log:q} 2>&1"
