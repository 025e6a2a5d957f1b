"""Fixtures of every test folder: the real route files in ../shared (skipped when absent, marked
``shared``) and a CLI runner. Paths and the tiny-workflow runner: ``tests/helpers.py``."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from helpers import SHARED_TRAJ


def pytest_collection_modifyitems(items):
    """Tests that read ``../shared`` through the ``shared_file`` fixture carry the ``shared``
    marker (``pytest -m "not shared"`` leaves them out); the others are marked by hand."""
    for item in items:
        if "shared_file" in getattr(item, "fixturenames", ()):
            item.add_marker(pytest.mark.shared)


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
