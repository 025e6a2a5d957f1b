"""What a user sees when the workflow refuses or fails (issue 22).

A failed job's one-line reason reaches the terminal; a configuration error is one line per
problem naming the key; a custom grade named like a preset is refused by the dry run; the
budget pre-flight speaks in human units.
"""

from __future__ import annotations

import subprocess

import pytest
import yaml

from imugen import preflight
from imugen.core.errors import InputError

from helpers import REPO, ROUTE, snakemake, write_config

CUSTOM = {
    "id": 101,
    "gyro": {"white_noise": {"value": 0.2, "unit": "deg_per_sqrt_h"}},
    "accel": {"white_noise": {"value": 0.05, "unit": "m_per_s_per_sqrt_h"}},
}


def test_a_failed_jobs_reason_reaches_the_terminal(tmp_path):
    bad = tmp_path / "bad.gpx"
    bad.write_text(
        '<gpx><trk><trkseg><trkpt lat="1" lon="-1230"/><trkpt lat="1" lon="2"/></trkseg></trk></gpx>'
    )
    write_config(tmp_path, {"routes": {"bad": {"file": str(bad)}}})
    proc = snakemake(tmp_path, "-j1", "results/bad/enu.parquet")
    assert proc.returncode != 0
    tail = (proc.stdout + proc.stderr).strip().splitlines()[-8:]
    reason = [ln for ln in tail if ln.startswith("imugen: error: ingest_csv failed: ")]
    assert len(reason) == 1, tail
    assert "longitude -1230 deg is outside" in reason[0]
    assert reason[0].endswith("(logs/bad/ingest_csv.log)")


def test_config_errors_are_one_line_per_problem_naming_the_key(tmp_path):
    write_config(
        tmp_path,
        {
            "routes": {"ex": {"file": str(ROUTE), "dt_s": -1, "vehicel": "car"}},
            "truht": {"rate_hz": 5},
            "simulate": {"sequences": "many"},
        },
    )
    proc = snakemake(tmp_path, "-n", "-j1")
    assert proc.returncode != 0
    out = (proc.stdout + proc.stderr).strip().splitlines()
    errors = [ln for ln in out if ln.startswith("imugen: error: ")]
    assert sorted(errors) == sorted(
        [
            "imugen: error: config.truht: unknown key (did you mean 'truth'?)",
            "imugen: error: config.routes.ex.vehicel: unknown key (did you mean 'vehicle'?)",
            "imugen: error: config.routes.ex.dt_s: -1 is less than or equal to the minimum of 0",
            "imugen: error: config.simulate.sequences: 'many' is not of type 'integer'",
        ]
    )
    assert len(out) <= len(errors) + 3, out  # Snakemake's own header and location lines


def test_schema_problems_are_capped():
    schema = yaml.safe_load((REPO / "workflow" / "schemas" / "config.schema.yaml").read_text())
    cfg = {"routes": {f"r{k}": {"file": "x", "dt_s": -1} for k in range(30)}}
    lines = preflight.schema_problems(cfg, schema, limit=20)
    assert len(lines) == 21 and lines[-1] == "config: and 10 more problems"


def test_a_custom_grade_named_like_a_preset_is_refused_by_the_dry_run(tmp_path):
    write_config(tmp_path, {"routes": {"ex": {"file": str(ROUTE)}}, "grades": {"consumer": CUSTOM}})
    proc = snakemake(tmp_path, "-n", "-j1")
    assert proc.returncode != 0
    assert (
        "imugen: error: config grades.consumer: is the name of a shipped preset"
        in proc.stdout + proc.stderr
    )


@pytest.mark.parametrize(
    "grades, message",
    [
        ({"mine": {**CUSTOM, "id": 3}}, r"id 3 is the preset 'tactical''s"),
        (
            {"mine": CUSTOM, "yours": CUSTOM},
            r"grades.yours: id 101 is already used by grade 'mine'",
        ),
    ],
)
def test_custom_grade_ids_are_checked_up_front(grades, message):
    with pytest.raises(InputError, match=message):
        preflight.check_values({"grades": grades})


@pytest.mark.parametrize(
    "n, text",
    [(50 * 2**20, "50 MiB"), (1.5 * 2**30, "1.5 GiB"), (3 * 2**10, "3 KiB"), (12, "12 bytes")],
)
def test_budget_sizes_in_human_units(n, text):
    assert preflight.human_bytes(n) == text


def test_disk_budget_of_50_mib_is_not_called_zero(tmp_path):
    cfg = {
        "routes": {"ex": {"file": str(ROUTE)}},
        "truth": {"rate_hz": 100},
        "grades": {"consumer": {}},
        "simulate": {"sequences": 100},
        "allan": {"static_s": 60, "rate_hz": 10, "sequences": 1},
        "exports": {"mat": False},
        "budget": {"disk_gib": 50 / 1024},
    }
    with pytest.raises(InputError, match=r"would write about [\d.]+ MiB but the budget is 50 MiB"):
        preflight.check_budget(cfg, tmp_path / "results")


def test_the_readme_report_leaves_nothing_untracked():
    """``snakemake --report`` as the README writes it lands in ``results/``; a bare
    ``report.html`` in the checkout is ignored by git."""
    import shutil

    if not shutil.which("git") or not (REPO / ".git").exists():
        pytest.skip("not a git checkout")
    readme = (REPO / "README.md").read_text()
    assert "snakemake --report results/report.html" in readme
    for name in ("report.html", "results/report.html"):
        proc = subprocess.run(["git", "-C", str(REPO), "check-ignore", "-q", name])
        assert proc.returncode == 0, name
