"""Configurations the code cannot run are refused before any job starts (issue 16).

Oracles: the schema's ranges against values that failed at job time (seed 2**70, rate 1e9 Hz,
dpi 100,000, NaN rates, a day-long Allan check x 1e4), custom grades checked up front, the
budget estimate against its closed form, and the shard wildcard beyond 1,000 shards.
"""

from __future__ import annotations

import copy
import math
import re
import subprocess
import sys
from pathlib import Path

import pytest
import yaml
from snakemake.utils import validate

from imugen import preflight
from imugen.core.errors import InputError

REPO = Path(__file__).resolve().parents[1]
SCHEMA = REPO / "workflow" / "schemas" / "config.schema.yaml"
PAPER = REPO / "resources" / "paper" / "seed_reference_trajectory_enu.txt"
BASE = {
    "routes": {"paper": {"file": str(PAPER), "origin": [31.63, -7.99, 480.6], "dt_s": 1.0}},
    "truth": {"rate_hz": 10},
    "grades": {"consumer": {}},
    "simulate": {"sequences": 2, "sequences_per_shard": 1, "seed": 7},
    "allan": {"static_s": 60, "rate_hz": 10, "sequences": 1},
    "exports": {"mat": False},
}


def snakemake(workdir, *args):
    bindir = Path(sys.executable).parent
    env = {"PATH": f"{bindir}:/usr/bin:/bin", "HOME": str(workdir)}
    cmd = [sys.executable, "-m", "snakemake", "-s", str(REPO / "Snakefile"), "-d", str(workdir)]
    return subprocess.run([*cmd, *args], capture_output=True, text=True, env=env, timeout=600)


def write_config(workdir, cfg):
    (workdir / "config").mkdir(exist_ok=True)
    (workdir / "config" / "config.yaml").write_text(yaml.safe_dump(cfg, sort_keys=False))


def planned_jobs(workdir) -> dict[str, int]:
    """Rule -> job count of a dry run."""
    proc = snakemake(workdir, "-n", "-j1", "--quiet", "rules")
    assert proc.returncode == 0, proc.stderr[-2000:]
    jobs = dict(re.findall(r"^(\w+)\s+(\d+)$", proc.stdout + proc.stderr, flags=re.M))
    return {k: int(v) for k, v in jobs.items() if k != "total"}


def config(**edits) -> dict:
    """BASE with ``section__key=value`` edits, validated (defaults filled) by the schema."""
    cfg = copy.deepcopy(BASE)
    for key, value in edits.items():
        section, _, name = key.partition("__")
        cfg.setdefault(section, {})[name] = value
    validate(cfg, str(SCHEMA))
    return cfg


@pytest.mark.parametrize(
    "edits",
    [
        {"simulate__seed": 2**70},
        {"simulate__seed": -1},
        {"truth__rate_hz": 1e9},
        {"truth__rate_hz": 0},
        {"figures__dpi": 100_000},
        {"allan__static_s": 1e9},
        {"allan__rate_hz": 1e6},
        {"navigate__eval_rate_hz": 1e7},
        {"simulate__sequences_per_shard": 10**9},
    ],
)
def test_schema_refuses_what_the_code_cannot_run(edits):
    with pytest.raises(Exception, match=r"(greater|less) than"):
        config(**edits)


def test_largest_seed_is_accepted():
    assert config(simulate__seed=2**63 - 1)["simulate"]["seed"] == 2**63 - 1


@pytest.mark.parametrize("value", [math.nan, math.inf, -math.inf])
def test_non_finite_values_refused(value):
    cfg = config()
    cfg["truth"]["rate_hz"] = value  # a YAML .nan passes JSON-schema ranges (NaN compares False)
    with pytest.raises(InputError, match=r"config\.truth\.rate_hz: is not a finite number"):
        preflight.check_values(cfg)


def test_custom_grades_checked_up_front():
    cfg = config()
    cfg["grades"]["mine"] = {"gyro": {}, "accel": {}}
    with pytest.raises(InputError, match=r"grade 'mine'.*integer 'id'"):
        preflight.check_values(cfg)
    cfg["grades"] = {"no_such_preset": {}}
    with pytest.raises(InputError, match="no preset has this name"):
        preflight.check_values(cfg)


def test_budget_estimate_and_refusal(tmp_path):
    cfg = config()
    est = preflight.estimate(cfg, tmp_path / "results")
    # the paper file: 620 rows at dt 1 s -> 619 s; 10 Hz -> 6,191 samples
    dur = est["route_durations_s"]["paper"]
    assert dur == pytest.approx(619.0)
    samples = 619 * 10 + 1
    disk = samples * (2 * 1 * 32.4 + 200) + 1 * 1 * (60 * 10 + 1) * 32.4
    assert est["disk_b"] == pytest.approx(disk)
    assert est["memory_b"] == pytest.approx(300e6 + 700 * samples)
    small = config(budget__disk_gib=disk / 2**30 / 2)
    with pytest.raises(InputError, match=r"would write about 1\.58 MiB but the budget is 810 KiB"):
        preflight.check_budget(small, tmp_path / "results")
    hungry = config(truth__rate_hz=10_000, budget__memory_gib=1)
    with pytest.raises(InputError, match=r"needs about 4\.31 GiB of memory .*619 s at 10000 Hz"):
        preflight.check_budget(hungry, tmp_path / "results")
    assert preflight.check_budget(config(budget__memory_gib=1), tmp_path / "results") == est


def test_workflow_refuses_before_any_job(tmp_path):
    cfg = copy.deepcopy(BASE)
    cfg["budget"] = {"disk_gib": 1e-6}
    write_config(tmp_path, cfg)
    proc = snakemake(tmp_path, "-j1")
    assert proc.returncode != 0
    assert "imugen: error: config: the run would write about" in proc.stdout + proc.stderr
    assert not (tmp_path / "results").exists() and not (tmp_path / "logs").exists()
    proc = snakemake(tmp_path, "-n", "-j1")  # a dry run checks the budget too
    assert proc.returncode != 0
    assert "imugen: error: config: the run would write about" in proc.stdout + proc.stderr
    cfg = copy.deepcopy(BASE)
    cfg["truth"]["rate_hz"] = float("nan")
    write_config(tmp_path, cfg)
    proc = snakemake(tmp_path, "-n", "-j1")
    assert proc.returncode != 0
    assert "config.truth.rate_hz: is not a finite number" in proc.stdout + proc.stderr


def test_more_than_1000_shards(tmp_path):
    cfg = copy.deepcopy(BASE)
    cfg["simulate"] = {"sequences": 1001, "sequences_per_shard": 1, "seed": 7}
    write_config(tmp_path, cfg)
    jobs = planned_jobs(tmp_path)  # ran into MissingInputException on shard-1000
    assert jobs["simulate"] == 1001  # one job per shard: synthesis and navigation


def test_untimed_path_memory_term(tmp_path):
    """An untimed path adds its fitting memory: 1,600 B per metre at corner_m 10 m, scaled by
    10 / corner_m (the fit grid is corner_m / 16), on top of the per-sample term."""
    from imugen.ingest.stage import ingest
    from imugen.truth import VEHICLES

    kml = REPO / "resources" / "example_route.kml"
    length = ingest(str(kml)).meta["length_3d_m"]
    for vehicle in ("car", "pedestrian"):
        cfg = config()
        cfg["routes"] = {"ex": {"file": str(kml), "vehicle": vehicle}}
        est = preflight.estimate(cfg, tmp_path / "results")
        vp = VEHICLES[vehicle]
        dur = length / (0.8 * vp.cruise_mps)
        path_b = 1600.0 * 10.0 / vp.corner_m * length
        assert est["route_durations_s"]["ex"] == pytest.approx(dur)
        assert est["memory_b"] == pytest.approx(300e6 + 700 * (dur * 10 + 1) + path_b)


def test_disk_estimate_counts_the_stored_columns(tmp_path):
    """Bytes per sample-sequence: 4 per float32 column stored + 8.4 (measured 24.1 / 96.1)."""
    samples = 619 * 10 + 1
    allan = 1 * 1 * (60 * 10 + 1) * 32.4
    for edits, per in (
        ({}, 8.4 + 4 * 6),
        ({"simulate__series": True}, 8.4 + 4 * 24),
        ({"simulate__outputs": "both", "simulate__series": True}, 8.4 + 4 * 36),
        ({"simulate__dtype": "float64"}, 8.4 + 8 * 6),
        ({"simulate__write_imu": False}, 0.0),
    ):
        est = preflight.estimate(config(**edits), tmp_path / "results")
        assert est["disk_b"] == pytest.approx(samples * (2 * 1 * per + 200) + allan), edits


def test_untimed_flight_memory_at_the_fit_s_own_corner(tmp_path):
    """A dense untimed flight is fitted with the corner rounding of its own point spacing (10th
    percentile, 100 m - 2 km), not the airliner's 2 km: the path term is sized with the same
    rule (``truth.flight.corner_length_m``), checked against the corner the truth job records
    (the 429 km logger flight was estimated ~20x low)."""
    import numpy as np

    from imugen import truth
    from imugen.core.frames import LocalFrame, Origin
    from imugen.ingest.stage import ingest
    from imugen.truth import VEHICLES

    s = np.arange(0.0, 12_001.0, 250.0)  # a logger's fixes every 250 m: taxi-less run, climb
    enu = np.column_stack([s, 400.0 * np.sin(s / 3000.0), 600.0 * (s / s[-1]) ** 2])
    lat, lon, alt = LocalFrame(Origin(48.35, 11.78, 450.0)).to_geodetic(enu)
    coords = " ".join(
        f"{float(b)!r},{float(a)!r},{float(h)!r}" for a, b, h in zip(lat, lon, alt, strict=True)
    )
    kml = tmp_path / "flight.kml"
    kml.write_text(
        '<kml xmlns="http://www.opengis.net/kml/2.2"><Placemark><name>f</name><LineString>'
        f"<altitudeMode>absolute</altitudeMode><coordinates>{coords}</coordinates></LineString>"
        "</Placemark></kml>"
    )
    ing = ingest(str(kml), vehicle="airliner")
    length = ing.meta["length_3d_m"]
    _, m = truth.build_truth(ing.table, ing.meta, rate_hz=10.0, vehicle="airliner", verbose=False)
    corner = m["fit"]["corner_m"]
    assert 240.0 < corner < 260.0 and VEHICLES["airliner"].corner_m == 2000.0
    cfg = config()
    cfg["routes"] = {"fl": {"file": str(kml), "vehicle": "airliner"}}
    est = preflight.estimate(cfg, tmp_path / "results")
    dur = length / (0.8 * VEHICLES["airliner"].cruise_mps)
    path_b = 1600.0 * 10.0 / corner * length  # 8x what the class's 2 km would give
    assert est["memory_b"] == pytest.approx(300e6 + 700 * (dur * 10 + 1) + path_b)
