"""The tables the documentation includes, as a benchmark writes them: ``docs/data/<name>.md``.

A script that measures a table the docs show takes ``--write-docs`` and calls :func:`write`,
which puts a provenance line above the table (when, which commit, the machine's CPUs, the load
average at the script's start and end, its wall and CPU seconds, the command that regenerates
it), so the page never shows a number nobody can reproduce. The pages include these files with
``--8<-- "data/<name>.md"``.
"""

from __future__ import annotations

import datetime as dt
import os
import resource
import subprocess
import sys
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
DATA = REPO / "docs" / "data"
_START = (time.perf_counter(), os.getloadavg())


def _cpu_seconds() -> float:
    own = resource.getrusage(resource.RUSAGE_SELF)
    kids = resource.getrusage(resource.RUSAGE_CHILDREN)
    return own.ru_utime + own.ru_stime + kids.ru_utime + kids.ru_stime


def commit() -> str:
    """Short commit of the checkout, marked when src/, workflow/ or config/ has changes."""

    def git(*args):
        r = subprocess.run(["git", *args], cwd=REPO, capture_output=True, text=True)
        return r.stdout.strip() if r.returncode == 0 else ""

    sha = git("rev-parse", "--short", "HEAD") or "unknown"
    dirty = git("status", "--porcelain", "--untracked-files=no", "--", "src", "workflow", "config")
    return sha + (" with uncommitted changes" if dirty else "")


def provenance(command: str | None = None) -> str:
    """One line: when, commit, CPUs, load average at start and now, wall and CPU seconds."""
    command = command or "python " + " ".join([Path(sys.argv[0]).as_posix(), *sys.argv[1:]])
    wall = time.perf_counter() - _START[0]
    when = dt.datetime.now(dt.UTC).strftime("%Y-%m-%d %H:%M UTC")
    return (
        f"Measured {when} by `{command}` at commit `{commit()}`, {os.cpu_count()} CPUs, load "
        f"average {_START[1][0]:.1f} at the start and {os.getloadavg()[0]:.1f} at the end; "
        f"{wall:.0f} s wall, {_cpu_seconds():.0f} CPU-s (the script and its child processes)."
    )


def write(name: str, body: str, command: str | None = None) -> Path:
    """Write ``docs/data/<name>.md``: a do-not-edit comment, the provenance, ``body``."""
    path = DATA / f"{name}.md"
    text = (
        f"<!-- written by a benchmark's --write-docs ({Path(sys.argv[0]).name}); do not edit -->\n\n"
        f"{provenance(command)}\n\n{body.strip()}\n"
    )
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(path.name + ".tmp")
    tmp.write_text(text)
    tmp.replace(path)
    return path
