"""The Snakemake workflow end to end on a tiny config in a temporary directory."""

import subprocess
import sys
from pathlib import Path

import pandas as pd
import pytest

from imugen.io import read_meta

REPO = Path(__file__).resolve().parents[1]


def snakemake(workdir, *args):
    bindir = Path(sys.executable).parent
    env = {"PATH": f"{bindir}:/usr/bin:/bin", "HOME": str(workdir)}
    return subprocess.run(
        [
            sys.executable,
            "-m",
            "snakemake",
            "-s",
            str(REPO / "Snakefile"),
            "--directory",
            str(workdir),
            *args,
        ],
        capture_output=True,
        text=True,
        env=env,
        timeout=600,
    )


@pytest.fixture
def workdir(tmp_path):
    (tmp_path / "config").mkdir()
    route = REPO / "resources" / "example_route.kml"
    paper = REPO / "resources" / "paper" / "seed_reference_trajectory_enu.txt"
    (tmp_path / "config" / "config.yaml").write_text(
        "routes:\n"
        f"  example:\n    file: {route}\n"
        f"  paper:\n    file: {paper}\n    origin: [31.63, -7.99, 480.6]\n    dt_s: 1.0\n"
    )
    return tmp_path


def test_full_run_then_nothing_to_do(workdir):
    proc = snakemake(workdir, "-j2")
    assert proc.returncode == 0, proc.stderr[-3000:]
    for route in ("example", "paper"):
        enu = pd.read_parquet(workdir / "results" / route / "enu.parquet")
        assert {"e_m", "n_m", "u_m", "lat_deg", "lon_deg", "alt_m"} <= set(enu.columns)
    meta = read_meta(workdir / "results" / "paper" / "enu.parquet")
    assert meta["timed"] and meta["points_out"] == 620
    assert meta["origin"] == {"lat_deg": 31.63, "lon_deg": -7.99, "alt_m": 480.6}
    dry = snakemake(workdir, "-n", "-j2")
    assert dry.returncode == 0
    assert "Nothing to be done" in dry.stdout + dry.stderr


def test_bad_route_fails_cleanly(workdir):
    bad = workdir / "bad.gpx"
    bad.write_text(
        '<gpx><trk><trkseg><trkpt lat="1" lon="-1230"/><trkpt lat="1" lon="2"/></trkseg></trk></gpx>'
    )
    (workdir / "config" / "config.yaml").write_text(f"routes:\n  bad:\n    file: {bad}\n")
    proc = snakemake(workdir, "-j1")
    assert proc.returncode != 0
    log = (workdir / "logs" / "bad" / "ingest_csv.log").read_text()
    assert "longitude -1230" in log and "Traceback" not in log
    assert not (workdir / "results" / "bad" / "route.csv").exists()


def test_schema_refuses_bad_config(workdir):
    (workdir / "config" / "config.yaml").write_text(
        "routes:\n  ex:\n    file: x.kml\n    dt_s: -1\n"
    )
    proc = snakemake(workdir, "-n", "-j1")
    assert proc.returncode != 0 and "dt_s" in proc.stdout + proc.stderr
