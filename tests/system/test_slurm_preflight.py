"""A SLURM run that would wait for ever is refused in one line before its first job (issue 22).

Without accounting, ``sacct`` exists but fails, and snakemake-executor-plugin-slurm (which polls
with ``sacct`` by default, and falls back to it when ``MinJobAge`` is short) never sees a job
end. Stand-ins for ``sacct`` and ``scontrol`` on the PATH play the clusters.
"""

from __future__ import annotations

import stat
import sys

import pytest

from imugen import preflight

NO_ACCOUNTING = (
    "print('sacct: error: Slurm accounting storage is disabled', file=sys.stderr); sys.exit(1)"
)


def _tools(tmp_path, monkeypatch, sacct: str | None, min_job_age: int | None = 300):
    bindir = tmp_path / "bin"
    bindir.mkdir()
    if sacct is not None:
        exe = bindir / "sacct"
        exe.write_text(f"#!{sys.executable}\nimport sys\n{sacct}\n")
        exe.chmod(exe.stat().st_mode | stat.S_IEXEC)
    if min_job_age is not None:
        exe = bindir / "scontrol"
        exe.write_text(
            f"#!/bin/sh\necho 'MaxJobCount = 10000'\necho 'MinJobAge = {min_job_age} sec'\n"
        )
        exe.chmod(exe.stat().st_mode | stat.S_IEXEC)
    monkeypatch.setenv("PATH", str(bindir))


def test_no_accounting_with_the_default_status_command_is_refused(tmp_path, monkeypatch):
    _tools(tmp_path, monkeypatch, NO_ACCOUNTING)
    why = preflight.slurm_status_problem(None)
    assert why.startswith("this SLURM cluster has no job accounting: sacct fails (sacct: error: ")
    assert "add --slurm-status-command squeue" in why and "\n" not in why
    assert preflight.slurm_status_problem("sacct") == why


def test_squeue_is_fine_while_min_job_age_covers_the_polling(tmp_path, monkeypatch):
    _tools(tmp_path, monkeypatch, NO_ACCOUNTING, min_job_age=300)
    assert preflight.slurm_status_problem("squeue", init_s=40) is None
    assert preflight.slurm_status_problem("squeue", init_s=5) is None


def test_squeue_with_a_short_min_job_age_falls_back_to_a_failing_sacct(tmp_path, monkeypatch):
    _tools(tmp_path, monkeypatch, NO_ACCOUNTING, min_job_age=60)
    why = preflight.slurm_status_problem("squeue", init_s=40)
    assert why.startswith("SLURM's MinJobAge (60 s) is below 3 x")
    assert preflight.slurm_status_problem("squeue", init_s=10) is None


@pytest.mark.parametrize(
    "sacct, ok",
    [
        ("sys.exit(0)", True),  # accounting answers
        (None, True),  # no sacct at all: the plugin polls with squeue
        ("import time; time.sleep(60)", False),  # hangs
    ],
)
def test_working_missing_or_hanging_sacct(tmp_path, monkeypatch, sacct, ok):
    monkeypatch.setattr(preflight, "SLURM_QUERY_TIMEOUT_S", 2)
    _tools(tmp_path, monkeypatch, sacct)
    why = preflight.slurm_status_problem(None)
    assert (why is None) is ok, why
    if not ok:
        assert "sacct did not answer within 2 s" in why


def test_the_readme_slurm_command_refuses_in_one_line(tmp_path):
    """The README's command on a cluster without accounting: one line, no submission (with
    the executor plugin installed; stand-ins for the SLURM commands)."""
    import subprocess
    from pathlib import Path

    pytest.importorskip("snakemake_executor_plugin_slurm")
    from helpers import REPO as repo

    bindir = tmp_path / "bin"
    bindir.mkdir()
    scripts = {
        "sacct": "echo 'sacct: error: Slurm accounting storage is disabled' >&2; exit 1",
        "scontrol": "echo 'MinJobAge = 300 sec'",
        "sbatch": f"touch {tmp_path / 'submitted'}; exit 1",
        "sinfo": "exit 0",
        "squeue": "exit 0",
    }
    for name, body in scripts.items():
        (bindir / name).write_text(f"#!/bin/sh\n{body}\n")
        (bindir / name).chmod(0o755)
    wd = tmp_path / "wd"
    (wd / "config").mkdir(parents=True)
    (wd / "config" / "config.yaml").write_text(
        f"routes:\n  ex: {{file: {repo / 'resources' / 'example_route.kml'}}}\n"
        "grades: {consumer: {}}\n"
    )
    bin_py = Path(sys.executable).parent
    proc = subprocess.run(
        [sys.executable, "-m", "snakemake", "-s", str(repo / "Snakefile"), "--workflow-profile",
         str(repo / "workflow" / "profiles" / "slurm"), "--cores", "2",
         "--default-resources", "slurm_partition=debug"],
        cwd=wd, capture_output=True, text=True, timeout=300,
        env={"PATH": f"{bindir}:{bin_py}:/usr/bin:/bin", "HOME": str(tmp_path),
             "PYTHONPATH": str(repo / "src")},
    )  # fmt: skip
    last = (proc.stdout + proc.stderr).strip().splitlines()[-1]
    assert proc.returncode != 0
    assert last.startswith("imugen: error: this SLURM cluster has no job accounting"), last
    assert not (tmp_path / "submitted").exists()
