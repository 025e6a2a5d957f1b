"""``routes.<name>.paths: all``: one route file feeds one route per path (issue 27)."""

from __future__ import annotations

from imugen.ingest.stage import path_ids

from helpers import dry_run_outputs, snakemake, write_config

PLACES = {"North walk": 0, "River walk": 1, "Old town": 2, "New walk": 3}


def _kml(path, names):
    """A KML of 20-point LineStrings, each path at its own place (:data:`PLACES`)."""
    marks = "".join(
        f"<Placemark><name>{n}</name><LineString><coordinates>"
        + " ".join(f"{7.0 + 0.001 * k + 0.01 * PLACES[n]!r},46.0,500" for k in range(20))
        + "</coordinates></LineString></Placemark>"
        for n in names
    )
    path.write_text(
        '<kml xmlns="http://www.opengis.net/kml/2.2"><Document>' + marks + "</Document></kml>"
    )
    return path


def test_paths_all_gives_one_route_per_path_with_stable_ids(tmp_path):
    f = _kml(tmp_path / "walks.kml", ["North walk", "River walk", "Old town"])
    ids = path_ids(f)
    assert len(ids) == 3 and ids[0].startswith("north-walk-")
    # stable: the same path keeps its id when another is removed or added in front
    kept = path_ids(_kml(tmp_path / "fewer.kml", ["River walk", "Old town"]))
    assert kept == ids[1:]
    more = path_ids(
        _kml(tmp_path / "more.kml", ["New walk", "North walk", "River walk", "Old town"])
    )
    assert more[1:] == ids and more[0] not in ids
    write_config(
        tmp_path,
        {
            "routes": {"walks": {"file": str(f), "paths": "all", "vehicle": "pedestrian"}},
            "grades": {"consumer": {}},
            "simulate": {"sequences": 1},
        },
    )
    outs = dry_run_outputs(tmp_path)
    enus = sorted(o for o in outs if o.endswith("/enu.parquet"))
    assert enus == sorted(f"results/walks-{rid}/enu.parquet" for rid in ids)
    # a tiny run of one of them: the ingest job reads that path alone
    rid = ids[1]
    proc = snakemake(tmp_path, "-j1", f"results/walks-{rid}/enu.parquet")
    assert proc.returncode == 0, proc.stderr[-3000:]
    log = (tmp_path / "logs" / f"walks-{rid}" / "ingest_csv.log").read_text()
    assert "'River walk'" in log


def test_paths_all_with_path_is_refused(tmp_path):
    f = _kml(tmp_path / "walks.kml", ["North walk", "Old town"])
    write_config(tmp_path, {"routes": {"w": {"file": str(f), "paths": "all", "path": 1}}})
    proc = snakemake(tmp_path, "-n", "-j1")
    assert proc.returncode != 0
    assert "imugen: error: routes.w: give path or paths: all, not both" in proc.stdout + proc.stderr
