"""What the test folders share: the repository's paths and the tiny-workflow runner.

The suite runs with ``--import-mode=importlib`` and ``pythonpath = ["tests"]``, so a test
module imports these as ``from helpers import ...`` (and the shared oracles as
``from oracles.strapdown import ...``).
"""

import hashlib
import re
import subprocess
import sys
from pathlib import Path

import yaml

REPO = Path(__file__).resolve().parents[1]
"""The repository (or worktree) root."""
DATA = REPO / "tests" / "data"
"""Test inputs kept in the repository (hostile files, KML cases, licences)."""
SHARED = next(
    (d / "shared" for d in (REPO.parent, REPO.parent.parent) if (d / "shared").is_dir()),
    REPO.parent / "shared",
)
"""``../shared`` (the paper, real route files and recordings); tests that read it are marked
``shared`` and skip cleanly without it."""
SHARED_TRAJ = SHARED / "data" / "trajectories"
"""Real route files of ``../shared``."""

# --- the workflow on a tiny config --------------------------------------------------------------
ROUTE = REPO / "resources" / "example_route.kml"
PAPER = REPO / "resources" / "paper" / "seed_reference_trajectory_enu.txt"

TINY = {
    "routes": {
        "example": {"file": str(ROUTE)},
        "paper": {"file": str(PAPER), "origin": [31.63, -7.99, 480.6], "dt_s": 1.0},
    },
    "truth": {"rate_hz": 10, "earth": "wgs84"},
    "grades": {
        "consumer": {},
        "tactical": {},
        "mine": {
            "id": 101,
            "gyro": {"white_noise": {"value": 0.2, "unit": "deg_per_sqrt_h"}},
            "accel": {"white_noise": {"value": 0.05, "unit": "m_per_s_per_sqrt_h"}},
        },
    },
    "simulate": {"sequences": 4, "sequences_per_shard": 2, "seed": 7},
    "allan": {"static_s": 300, "rate_hz": 10, "sequences": 2},
}


def snakemake(workdir, *args, snakefile=None):
    """Run Snakemake on ``workdir`` (the repository's ``Snakefile`` unless ``snakefile``)."""
    bindir = Path(sys.executable).parent
    # the `imugen` the rules call runs this checkout's code, whatever the venv's install points to
    env = {"PATH": f"{bindir}:/usr/bin:/bin", "HOME": str(workdir), "PYTHONPATH": str(REPO / "src")}
    return subprocess.run(
        [
            sys.executable,
            "-m",
            "snakemake",
            "-s",
            str(snakefile or REPO / "Snakefile"),
            "-d",
            str(workdir),
            *args,
        ],
        capture_output=True,
        text=True,
        env=env,
        timeout=900,
    )


def write_config(workdir, cfg):
    (workdir / "config").mkdir(exist_ok=True)
    (workdir / "config" / "config.yaml").write_text(yaml.safe_dump(cfg, sort_keys=False))


def planned_jobs(workdir, snakefile=None) -> dict[str, int]:
    """Rule -> job count of a dry run (the `Job stats` table)."""
    proc = snakemake(workdir, "-n", "-j1", "--quiet", "rules", snakefile=snakefile)
    assert proc.returncode == 0, proc.stderr[-2000:]
    out = proc.stdout + proc.stderr
    if "Nothing to be done" in out:
        return {}
    jobs = dict(re.findall(r"^(\w+)\s+(\d+)$", out, flags=re.M))
    jobs.pop("total", None)
    return {k: int(v) for k, v in jobs.items()}


def digest(paths):
    h = hashlib.sha256()
    for p in sorted(paths):
        h.update(p.read_bytes())
    return h.hexdigest()


def dry_run_outputs(workdir, *args) -> list[str]:
    """Output paths of every job a dry run schedules."""
    proc = snakemake(workdir, "-n", "-j1", *args)
    assert proc.returncode == 0, proc.stderr[-2000:]
    lines = re.findall(r"^\s+output: (.+)$", proc.stdout + proc.stderr, flags=re.M)
    return [p for line in lines for p in line.split(", ")]


# --- the stages' faces with the options of a test as keywords ----------------------------------
def simulate_shard(truth, out, grade="consumer", sequences=1, seed=0, shard=0, *, navigate=None,
                   **options):  # fmt: skip
    """:func:`imugen.simulate.stage.run` with its options as keywords (those of
    :class:`imugen.simulate.options.SimulateOptions`); the metadata written."""
    from imugen.simulate.options import SimulateOptions
    from imugen.simulate.stage import run

    opts = SimulateOptions(grade=grade, sequences=sequences, seed=seed, shard=shard, **options)
    return run(truth, out, opts, navigate=navigate)
