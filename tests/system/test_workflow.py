"""The Snakemake workflow end to end on a tiny config in a temporary directory.

Covers: a full run then nothing to do; edits rerun only what they affect (asserted on the
dry-run job list); -j1 and -j2 give identical tables and bit-identical datasets; clean failures.
"""

import copy
import re
import shutil

import pandas as pd
import pytest
import yaml

from imugen.core.io import read_meta
from imugen.tables.shard import route_id

from helpers import (
    REPO,
    TINY,
    digest,
    dry_run_outputs,
    planned_jobs,
    snakemake,
    write_config,
)


@pytest.fixture(scope="module")
def done(tmp_path_factory):
    """A complete run of the tiny config (shared by the tests below, which copy it)."""
    workdir = tmp_path_factory.mktemp("wf")
    write_config(workdir, TINY)
    proc = snakemake(workdir, "-j2")
    assert proc.returncode == 0, proc.stderr[-4000:]
    return workdir


def copy_run(src, dst):
    shutil.copytree(src, dst, symlinks=True)
    return dst


def test_full_run_outputs_then_nothing_to_do(done):
    for route in ("example", "paper"):
        table = pd.read_csv(done / "results" / route / "rmse.csv")
        assert list(table.grade) == ["consumer", "tactical", "mine"]
        for c in ("east_m", "north_m", "up_m", "total_m", "total_p05_m", "total_p95_m"):
            assert (table[c] > 0).all()
        # RMSE total is the paper's sqrt(E^2 + N^2 + U^2) per sequence; medians are ordered
        assert (table.total_p05_m <= table.total_m).all() and (
            table.total_m <= table.total_p95_m
        ).all()
    meta = read_meta(done / "results" / "paper" / "truth.parquet")
    assert meta["rate_hz"] == 10 and meta["earth"] in ("flat", "wgs84")
    shards = sorted((done / "results" / "paper" / "imu" / "mine").glob("shard-*[0-9].parquet"))
    assert [p.name for p in shards] == ["shard-000.parquet", "shard-001.parquet"]
    assert (done / "results" / "allan" / "consumer" / "allan.png").stat().st_size > 1000
    for stem in ("figure8", "trajectories_3d", "error_vs_time", "imu_mine"):
        for ext in ("png", "svg"):
            assert (done / "results" / "paper" / "figures" / f"{stem}.{ext}").stat().st_size > 1000
    assert planned_jobs(done) == {}


def test_edit_one_grade_reruns_only_that_grade(done, tmp_path):
    wd = copy_run(done, tmp_path / "wd")
    cfg = copy.deepcopy(TINY)
    cfg["grades"]["mine"]["gyro"]["white_noise"]["value"] = 0.3
    write_config(wd, cfg)
    jobs = planned_jobs(wd)
    # 2 routes x 2 shards of "mine" (one job each: synthesis + navigation) + its Allan check;
    # gathers of each route; nothing else
    assert jobs == {
        "custom_grade": 1,
        "simulate": 4,
        "evaluate": 2,
        "rmse_table": 2,
        "allan_static": 1,
        "allan": 1,
        "figures": 2,
        "export_mat": 2,
        "all": 1,
    }


def test_under_auto_a_custom_grade_feeds_the_truth(tmp_path):
    # `earth: auto` budgets every configured grade: editing a custom grade reruns the truth
    cfg = copy.deepcopy(TINY)
    cfg["truth"]["earth"] = "auto"
    write_config(tmp_path, cfg)
    proc = snakemake(tmp_path, "-n", "-j1", "--quiet", "rules")
    assert proc.returncode == 0, proc.stderr[-2000:]
    out = snakemake(tmp_path, "-n", "-j1", "results/example/truth.parquet")
    assert "results/grades/mine.yaml" in out.stdout + out.stderr


def test_raising_n_runs_only_new_shards_and_gathers(done, tmp_path):
    wd = copy_run(done, tmp_path / "wd")
    cfg = copy.deepcopy(TINY)
    cfg["simulate"]["sequences"] = 5
    write_config(wd, cfg)
    jobs = planned_jobs(wd)
    # one new (short) shard per route and grade: 2 routes x 3 grades
    assert jobs == {
        "simulate": 6,
        "evaluate": 6,
        "rmse_table": 2,
        "figures": 2,
        "export_mat": 6,
        "all": 1,
    }


def test_short_last_shard_keeps_sequence_ids_unique(done, tmp_path):
    wd = copy_run(done, tmp_path / "wd")
    cfg = copy.deepcopy(TINY)
    cfg["simulate"]["sequences"] = 5  # shards of 2, 2 and 1
    write_config(wd, cfg)
    proc = snakemake(wd, "-j2", "results/paper/metrics/mine.parquet")
    assert proc.returncode == 0, proc.stderr[-3000:]
    shards = sorted((wd / "results" / "paper" / "imu" / "mine").glob("shard-*[0-9].parquet"))
    base = route_id("paper") << 31  # ids route_id << 31 | index (the workflow passes --route)
    ids = [
        (pd.read_parquet(p, columns=["sequence"]).sequence.unique() - base).tolist() for p in shards
    ]
    assert ids == [[0, 1], [2, 3], [4]]
    metrics = pd.read_parquet(wd / "results" / "paper" / "metrics" / "mine.parquet")
    assert sorted(metrics.sequence - base) == [0, 1, 2, 3, 4]


def test_figure_option_reruns_only_figures(done, tmp_path):
    wd = copy_run(done, tmp_path / "wd")
    cfg = copy.deepcopy(TINY)
    cfg["figures"] = {"zoom_fraction": 0.3}
    write_config(wd, cfg)
    assert planned_jobs(wd) == {"figures": 2, "all": 1}


def test_without_imu_shards_errors_only(done, tmp_path):
    """simulate.write_imu: false keeps the navigation errors and drops every rule that needs
    shards; the errors do not depend on it, so a finished run's shard jobs do not rerun."""
    wd = copy_run(done, tmp_path / "wd")
    cfg = copy.deepcopy(TINY)
    cfg["simulate"]["write_imu"] = False
    write_config(wd, cfg)
    jobs = planned_jobs(wd)
    assert "export_mat" not in jobs and "simulate" not in jobs, jobs
    fresh = tmp_path / "fresh"
    fresh.mkdir()
    write_config(fresh, cfg)
    proc = snakemake(fresh, "-j2", "results/paper/rmse.csv")
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert not (fresh / "results" / "paper" / "imu").exists()
    a = pd.read_csv(done / "results" / "paper" / "rmse.csv")
    b = pd.read_csv(fresh / "results" / "paper" / "rmse.csv")
    # relative drift re-navigates the shards, so it is absent without them; the rest is equal
    assert not any(c.startswith("drift_") for c in b.columns)
    assert any(c.startswith("drift_") for c in a.columns)
    pd.testing.assert_frame_equal(a[list(b.columns)], b, check_exact=True)


def test_report_has_figures_and_tables(done, tmp_path):
    wd = copy_run(done, tmp_path / "wd")
    proc = snakemake(wd, "--report", "report.html")
    assert proc.returncode == 0, proc.stderr[-2000:]
    html = (wd / "report.html").read_text(errors="replace")
    for name in ("figure8", "error_vs_time", "rmse", "allan"):
        assert name in html, name
    # the report keeps one item per set of labels: every figure file of every route has its
    # own (route, figure, grade, format), so none hides another (6 IMU figures, not 1)
    items = set(re.findall(r'"filename": "([^"]+)", "labels": (\{[^}]*\})', html))
    figures = sorted(p.name for p in (wd / "results").glob("*/figures/*"))
    assert len(figures) == 2 * 2 * (3 + len(TINY["grades"])), figures
    labels = [lab for name, lab in items if name in figures]
    assert len(labels) == len(figures), labels
    assert len(set(labels)) == len(labels), sorted(labels)
    imu = [lab for name, lab in items if name.startswith("imu_")]
    assert len(set(imu)) == 2 * 2 * len(TINY["grades"]), imu


def test_j1_and_j2_identical(done, tmp_path):
    wd = tmp_path / "j1"
    wd.mkdir()
    write_config(wd, TINY)
    proc = snakemake(wd, "-j1", "results/paper/rmse.csv")
    assert proc.returncode == 0, proc.stderr[-3000:]
    a = pd.read_csv(done / "results" / "paper" / "rmse.csv")
    b = pd.read_csv(wd / "results" / "paper" / "rmse.csv")
    pd.testing.assert_frame_equal(a, b, check_exact=True)
    for grade in TINY["grades"]:
        ga = sorted((done / "results" / "paper" / "imu" / grade).glob("*.parquet"))
        gb = sorted((wd / "results" / "paper" / "imu" / grade).glob("*.parquet"))
        assert [p.name for p in ga] == [p.name for p in gb]
        assert digest(ga) == digest(gb), grade


def test_bad_route_fails_cleanly(tmp_path):
    bad = tmp_path / "bad.gpx"
    bad.write_text(
        '<gpx><trk><trkseg><trkpt lat="1" lon="-1230"/><trkpt lat="1" lon="2"/></trkseg></trk></gpx>'
    )
    write_config(tmp_path, {"routes": {"bad": {"file": str(bad)}}})
    proc = snakemake(tmp_path, "-j1", "results/bad/enu.parquet")
    assert proc.returncode != 0
    log = (tmp_path / "logs" / "bad" / "ingest_csv.log").read_text()
    assert "longitude -1230" in log and "Traceback" not in log
    assert not (tmp_path / "results" / "bad" / "route.csv").exists()


def test_max_extent_km_is_a_route_limit(tmp_path):
    """``max_extent_km`` in a route's config is accepted by the schema and reaches ingestion as
    ``--max-extent-km``: a 222 km path beyond a 100 km limit is refused (without a limit it is
    accepted: tests/ingest/test_stage.py)."""
    far = tmp_path / "far.gpx"
    far.write_text(
        '<gpx><trk><trkseg><trkpt lat="0" lon="0"/><trkpt lat="0" lon="2"/></trkseg></trk></gpx>'
    )
    write_config(tmp_path, {"routes": {"far": {"file": str(far), "max_extent_km": 100}}})
    proc = snakemake(tmp_path, "-j1", "results/far/enu.parquet")
    assert proc.returncode != 0
    log = (tmp_path / "logs" / "far" / "ingest_csv.log").read_text()
    assert "beyond --max-extent-km 100" in log and "Traceback" not in log


def test_schema_refuses_bad_config(tmp_path):
    write_config(tmp_path, {"routes": {"ex": {"file": "x.kml", "dt_s": -1}}})
    proc = snakemake(tmp_path, "-n", "-j1")
    assert proc.returncode != 0 and "dt_s" in proc.stdout + proc.stderr


def test_lint_only_the_documented_conda_lint(tmp_path):
    write_config(tmp_path, TINY)
    proc = snakemake(tmp_path, "--lint")
    text = proc.stdout + proc.stderr
    lints = re.findall(r"^\s+\* (.+?):$", text, flags=re.M)
    assert lints, text[-2000:]
    assert set(lints) == {"Specify a conda environment or container for each rule."}


def test_configfile_replaces_the_shipped_routes_and_grades(tmp_path):
    # a working directory like the repository: the shipped config/ and resources/
    (tmp_path / "config").symlink_to(REPO / "config")
    (tmp_path / "resources").symlink_to(REPO / "resources")
    shipped = yaml.safe_load((REPO / "config" / "config.yaml").read_text())
    paper = yaml.safe_load((REPO / "config" / "paper.yaml").read_text())
    outs = dry_run_outputs(tmp_path, "--configfile", str(tmp_path / "config" / "paper.yaml"))
    routes = {p.split("/")[1] for p in outs if p.startswith("results/") and "allan" not in p}
    assert routes == set(paper["routes"]) and "example" not in routes
    nav = [p for p in outs if "/nav/" in p]
    shards = paper["simulate"]["sequences"] // paper["simulate"]["sequences_per_shard"]
    assert len(nav) == len(paper["grades"]) * shards
    # a user's file naming other grades: only those, and the shipped value of every other key
    mine = {"routes": paper["routes"], "grades": {"tactical": {}}}
    (tmp_path / "mine.yaml").write_text(yaml.safe_dump(mine))
    outs = dry_run_outputs(tmp_path, "--configfile", str(tmp_path / "mine.yaml"))
    grades = {p.split("/")[3] for p in outs if re.match(r"results/\w+/(imu|nav)/", p)}
    assert grades == {"tactical"} and not any("example" in p or "consumer" in p for p in outs)
    sim = shipped["simulate"]
    nav = [p for p in outs if "/nav/" in p]
    assert len(nav) == sim["sequences"] // sim["sequences_per_shard"]
    # without --configfile, the shipped example as before
    outs = dry_run_outputs(tmp_path)
    assert {p.split("/")[1] for p in outs if "/nav/" in p} == set(shipped["routes"])
    assert {p.split("/")[3] for p in outs if "/nav/" in p} == set(shipped["grades"])
    # the shipped example shows the GNSS-denied result: the aid stage with declared outages,
    # their drift table and figure beside the error growth
    assert shipped["gnss"]["enabled"] and shipped["scenarios"]["intervals"]
    for f in ("outage_drift.csv", "outage_drift.md", "figures/outage_drift.png",
              "figures/outage_growth.png", "aided/consumer/shard-000.parquet"):  # fmt: skip
        assert f"results/example/{f}" in outs, f


def test_export_formats_planned_per_route_and_grade(tmp_path):
    cfg = {**TINY, "exports": {"mat": False, "formats": ["tum", "euroc"]}}
    write_config(tmp_path, cfg)
    jobs = planned_jobs(tmp_path)
    assert jobs.get("export_formats") == len(cfg["routes"]) * len(cfg["grades"])
    write_config(tmp_path, {**cfg, "exports": {"mat": False, "formats": ["kitti"]}})
    proc = snakemake(tmp_path, "-n", "-j1")
    assert proc.returncode != 0 and "kitti" in proc.stdout + proc.stderr


def test_export_formats_without_imu_shards_are_not_scheduled(tmp_path):
    """``exports.formats`` with ``simulate.write_imu: false``: the dry run succeeds and plans no
    export (nothing to export: the shards are not stored), as for ``exports.mat``."""
    cfg = copy.deepcopy(TINY)
    cfg["simulate"]["write_imu"] = False
    cfg["exports"] = {"mat": True, "formats": ["tum", "ros2"]}
    write_config(tmp_path, cfg)
    jobs = planned_jobs(tmp_path)
    assert "export_formats" not in jobs and "export_mat" not in jobs, jobs
    assert "evaluate" in jobs, jobs


def test_export_formats_pass_the_split_and_the_companions(tmp_path):
    """``exports.split`` reaches every export as the same options; with the aid stage and an
    odometer the ROS 2 export gets the companion tables of its route and grade; a held-out
    route that is not a route is refused before any job."""
    cfg = copy.deepcopy(TINY)
    cfg["exports"] = {
        "mat": False,
        "formats": ["tlio", "ros2"],
        "split": {"by": "route", "holdout_routes": ["paper"], "val_fraction": 0.2},
    }
    cfg["gnss"] = {"enabled": True}
    cfg["companions"] = {"odometer": "abs"}
    write_config(tmp_path, cfg)
    proc = snakemake(tmp_path, "-n", "-j1", "-p", "results/example/datasets/consumer")
    assert proc.returncode == 0, proc.stderr[-2000:]
    out = (proc.stdout + proc.stderr).splitlines()
    (cmd,) = [ln for ln in out if ln.startswith("Shell command: imugen export ")]
    assert "--split-by=route --split-seed=0 --val-fraction=0.2 --test-fraction=0.1" in cmd
    assert "--holdout-routes=paper" in cmd
    shards = [f"results/example/companions/consumer/shard-{k:03d}.parquet" for k in (0, 1)]
    assert "--companions " + " ".join(shards) in cmd
    cfg["exports"]["split"]["holdout_routes"] = ["nowhere"]
    write_config(tmp_path, cfg)
    proc = snakemake(tmp_path, "-n", "-j1")
    assert proc.returncode != 0 and "nowhere not among the routes" in proc.stdout + proc.stderr
