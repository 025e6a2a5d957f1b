"""Code tracking derived from the imports: editing a module of a stage reruns that stage and
what follows, and nothing else.

A complete run of a tiny config (one route, one grade, the aid stage, the Allan check, a
.mat and a TUM export) with a copy of the workflow and the package source; then one module
of each stage is edited in the copy and the dry run must schedule exactly the rules whose
command runs that module (``code_files`` in workflow/rules/common.smk) and those downstream.
The jobs run this checkout's code (``PYTHONPATH``, warm numba caches): only the copy's files
enter the rules' code digests (``params: code=``, ``code_digest``). Snakemake reruns a job
whose params changed, so the edit is a change of content (an appended comment): restoring
the content undoes it, and a mere touch reruns nothing.
"""

import shutil

import pytest

from helpers import REPO, ROUTE, planned_jobs, snakemake, write_config

CFG = {
    "routes": {"example": {"file": str(ROUTE)}},
    "truth": {"rate_hz": 10, "earth": "wgs84"},
    "grades": {"consumer": {}},
    "simulate": {"sequences": 2, "sequences_per_shard": 2, "seed": 7},
    "allan": {"static_s": 60, "rate_hz": 10, "sequences": 1},
    "gnss": {"enabled": True},
    "exports": {"mat": True, "formats": ["tum"]},
    "figures": {"formats": ["png"]},
}

AFTER_TRUTH = {
    "simulate", "aid", "evaluate", "rmse_table", "figures", "outage_figure", "outage_drift",
    "export_mat", "export_formats", "all",
}  # fmt: skip
"""Every rule downstream of the truth (with the aid stage and both exports on)."""
IMU = AFTER_TRUTH | {"allan_static", "allan"}
"""The rules of a change to the sensor model or the navigation: the shard jobs and what
follows, and the Allan check's still IMU (``imugen simulate --static`` is the same command,
so it runs the same code)."""

AFTER_AID = {
    "aid", "evaluate", "rmse_table", "figures", "outage_figure", "outage_drift", "export_formats",
    "all",
}  # fmt: skip
"""The aid jobs and what reads their tables (metrics, the outage figure, the TUM export)."""

EDITS = {
    "ingest/readers/kml.py": {"ingest_csv", "ingest_enu", "truth"} | AFTER_TRUTH,
    "truth/flight.py": {"truth"} | AFTER_TRUTH,
    "sensors/model.py": IMU,
    "navigate/_kernel.py": IMU,
    "aid/scenarios.py": AFTER_AID,
    "evaluate/stage.py": {"evaluate", "rmse_table", "figures", "outage_drift", "all"},
    "tables/metrics.py": {"evaluate", "rmse_table", "figures", "outage_drift", "all"},
    "figures/mapview.py": {"figures", "all"},
    "figures/outage.py": {"outage_figure", "all"},
    "figures/outage_drift.py": {"outage_drift", "all"},
    "export/tum.py": {"export_formats", "all"},
    "export/mat.py": {"export_mat", "all"},
    "allan/stage.py": {"allan", "all"},
}
"""Module edited (under src/imugen) -> the rules the dry run must schedule, exactly."""


@pytest.fixture(scope="module")
def done(tmp_path_factory):
    """``(snakefile, workdir)`` of a complete run with a copy of the workflow and the source."""
    base = tmp_path_factory.mktemp("code")
    repo = base / "repo"
    shutil.copytree(REPO / "workflow", repo / "workflow")
    shutil.copy2(REPO / "Snakefile", repo / "Snakefile")
    shutil.copytree(
        REPO / "src", repo / "src", ignore=shutil.ignore_patterns("__pycache__", "*.egg-info")
    )
    work = base / "work"
    work.mkdir()
    write_config(work, CFG)
    proc = snakemake(work, "-j2", snakefile=repo / "Snakefile")
    assert proc.returncode == 0, proc.stderr[-4000:]
    assert planned_jobs(work, repo / "Snakefile") == {}
    return repo / "Snakefile", work


@pytest.mark.parametrize("module", list(EDITS))
def test_editing_a_module_reruns_its_stage_and_what_follows(done, module):
    snakefile, work = done
    path = snakefile.parent / "src" / "imugen" / module
    text = path.read_text()
    try:
        path.write_text(text + "\n# edited\n")
        assert set(planned_jobs(work, snakefile)) == EDITS[module]
    finally:
        path.write_text(text)
    assert planned_jobs(work, snakefile) == {}  # the same content again: nothing to do


def test_a_touch_reruns_nothing(done):
    """A newer timestamp with the same content (a git checkout) reruns nothing."""
    snakefile, work = done
    for module in EDITS:
        (snakefile.parent / "src" / "imugen" / module).touch()
    assert planned_jobs(work, snakefile) == {}
