"""The README's recovery recipe, run as written, after the Snakemake process alone is killed.

Scenario (issue 16): ``snakemake`` gets SIGKILL while a shard job runs; the job is orphaned and
finishes on its own. A plain rerun then stops (the lock, then Snakemake's record of the
incomplete job, even after ``--unlock``); the recipe ``snakemake --unlock`` then
``snakemake --rerun-incomplete``
completes the run, and the output the orphan wrote is reproduced bit for bit by the rerun.
"""

from __future__ import annotations

import hashlib
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import yaml

REPO = Path(__file__).resolve().parents[2]
PAPER = REPO / "resources" / "paper" / "seed_reference_trajectory_enu.txt"
# one shard's navigation: ingest, truth, simulate, navigate (the whole run adds minutes)
TARGET = "results/paper/nav/consumer/shard-000.parquet"
CONFIG = {
    "routes": {"paper": {"file": str(PAPER), "origin": [31.63, -7.99, 480.6], "dt_s": 1.0}},
    "truth": {"rate_hz": 10, "earth": "flat"},
    "grades": {"consumer": {}},
    "simulate": {"sequences": 2, "sequences_per_shard": 1, "seed": 7},
    "allan": {"static_s": 60, "rate_hz": 10, "sequences": 1},
    "exports": {"mat": False},
    "figures": {"formats": ["png"], "dpi": 30},
}


def command(workdir: Path, *args: str) -> list[str]:
    return [sys.executable, "-m", "snakemake", "-s", str(REPO / "Snakefile"), "-d", str(workdir),
            *args]  # fmt: skip


def env(workdir: Path) -> dict:
    bindir = Path(sys.executable).parent
    out = {"PATH": f"{bindir}:/usr/bin:/bin", "HOME": str(workdir)}
    if "PYTHONPATH" in os.environ:
        out["PYTHONPATH"] = os.environ["PYTHONPATH"]
    return out


def run(workdir: Path, *args: str) -> subprocess.CompletedProcess:
    return subprocess.run(command(workdir, *args), capture_output=True, text=True,
                          env=env(workdir), timeout=900)  # fmt: skip


def descendants(pid: int) -> set[int]:
    out: set[int] = set()
    todo = [pid]
    while todo:
        p = todo.pop()
        for task in Path(f"/proc/{p}/task").glob("*"):
            try:
                kids = (task / "children").read_text().split()
            except OSError:
                continue
            for k in map(int, kids):
                if k not in out:
                    out.add(k)
                    todo.append(k)
    return out


def alive(pid: int) -> bool:
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return False
    return stat.rsplit(")", 1)[1].split()[0] != "Z"


def sha(p: Path) -> str:
    return hashlib.sha256(p.read_bytes()).hexdigest()


def test_recipe_after_snakemake_is_killed_with_an_orphaned_job(tmp_path):
    wd = tmp_path
    (wd / "config").mkdir()
    (wd / "config" / "config.yaml").write_text(yaml.safe_dump(CONFIG))
    proc = subprocess.Popen(command(wd, "-j1", TARGET),
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, env=env(wd))  # fmt: skip
    log = wd / "logs" / "paper" / "simulate" / "consumer" / "shard-000.log"
    deadline = time.monotonic() + 600
    jobs: set[int] = set()
    try:
        while time.monotonic() < deadline and proc.poll() is None:
            if log.exists():
                jobs = descendants(proc.pid)
                if jobs:
                    break
            time.sleep(0.05)
    finally:
        proc.send_signal(signal.SIGKILL)  # Snakemake only: its job runs on as an orphan
        proc.wait()
    assert jobs, "the shard job was not seen running"
    while any(alive(p) for p in jobs) and time.monotonic() < deadline:
        time.sleep(0.1)
    shard = wd / "results" / "paper" / "imu" / "consumer" / "shard-000.parquet"
    assert shard.exists()  # the orphan finished its output
    orphan_sha = sha(shard)

    r = run(
        wd, "-j1", TARGET
    )  # a plain rerun stops (lock or incomplete record, per Snakemake version)
    assert r.returncode != 0
    assert (
        "LockException" in r.stdout + r.stderr or "IncompleteFilesException" in r.stdout + r.stderr
    )
    r = run(wd, "--unlock")
    assert r.returncode == 0, r.stderr[-2000:]
    r = run(wd, "-j1", TARGET)  # without the recipe's second step
    assert r.returncode != 0 and "IncompleteFilesException" in r.stdout + r.stderr
    r = run(wd, "--rerun-incomplete", "-j1", TARGET)
    assert r.returncode == 0, (r.stdout + r.stderr)[-3000:]
    assert sha(shard) == orphan_sha
    r = run(wd, "-n", "-j1", TARGET)
    assert r.returncode == 0 and "Nothing to be done" in r.stdout + r.stderr
