"""Shared fixtures: the real route files in ../shared (skipped when absent) and a CLI runner."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
SHARED_TRAJ = REPO.parent / "shared" / "data" / "trajectories"


@pytest.fixture
def shared_file():
    """Return a function giving the path of a shared trajectory file, skipping when absent."""

    def get(name: str) -> Path:
        p = SHARED_TRAJ / name
        if not p.exists():
            pytest.skip(f"shared trajectory {name} not available")
        return p

    return get


@pytest.fixture
def cli():
    """Run ``python -m imugen ARGS``; returns the CompletedProcess (text mode)."""

    def run(*args, check=None):
        proc = subprocess.run(
            [sys.executable, "-m", "imugen", *map(str, args)],
            capture_output=True,
            text=True,
            timeout=300,
        )
        if check is not None:
            assert proc.returncode == check, proc.stderr
        return proc

    return run
