# Ingestion: route file (KML/KMZ/GPX/CSV/ENU text, NMEA, IGC, GeoJSON, ...) -> geodetic CSV
# -> ENU Parquet. Cleaning (vehicle limits) and gap handling happen in the first step; the CSV
# carries their report to the second.


def ingest_clean_opts(wildcards):
    """`imugen ingest` options of the cleaning and gap rules for this route."""
    r = config["routes"][wildcards.route]
    opts = ["--vehicle", shlex.quote(str(r.get("vehicle", "car")))]
    if r.get("max_gap_s") is not None:
        opts += ["--max-gap-s", repr(float(r["max_gap_s"]))]
    opts += ["--gaps", shlex.quote(str(r.get("gaps", "split")))]
    return " ".join(opts)


rule ingest_csv:
    input:
        src=lambda wc: config["routes"][wc.route]["file"],
        code=stage_code(
            "ingest", "frames", "route", "xmlsafe", "readers/__init__", "readers/kml",
            "readers/gpx", "readers/text", "readers/nmea", "readers/igc", "readers/geojson",
            "readers/gnsscsv", "readers/babel", "clean", "segments",
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
        code=stage_code("ingest", "frames", "readers/text", "clean", "segments"),
    output:
        "results/{route}/enu.parquet",
    log:
        "logs/{route}/ingest_enu.log",
    shell:
        "imugen ingest {input.csv:q} -o {output:q} > {log:q} 2>&1"
