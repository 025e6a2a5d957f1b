"""CI fails, in one line, when a program it installs for tests is missing (issue 22); it no
longer lets their tests turn into skips. Stand-ins for apt-get and the programs play the machine."""

from __future__ import annotations

import subprocess
import sys

import pytest

from helpers import REPO

SCRIPT = REPO / ".ci" / "test-tools"


def _run(tmp_path, tools=(), apt_ok=False):
    bindir = tmp_path / "bin"
    bindir.mkdir()
    apt = f": > {tmp_path / 'apt-called'}; exit {0 if apt_ok else 100}"
    python = f'exec {sys.executable} "$@"'
    for name, body in {"apt-get": apt, "python": python, **dict.fromkeys(tools, "exit 0")}.items():
        (bindir / name).write_text(f"#!/bin/sh\n{body}\n")
        (bindir / name).chmod(0o755)
    return subprocess.run(
        ["/bin/bash", str(SCRIPT)], capture_output=True, text=True, env={"PATH": str(bindir)}
    )


@pytest.mark.parametrize("apt_ok", [False, True])
def test_missing_tools_fail_ci(tmp_path, apt_ok):
    proc = _run(tmp_path, tools=("chromedriver",), apt_ok=apt_ok)
    assert proc.returncode == 1 and (tmp_path / "apt-called").exists()
    (line,) = proc.stderr.strip().splitlines()
    assert line.startswith("CI: error: could not install chromium gpsbabel ")


def test_present_tools_pass_without_apt(tmp_path):
    for module in ("selenium", "mkdocs", "material", "mkdocstrings"):
        pytest.importorskip(module)
    proc = _run(tmp_path, tools=("chromium", "chromedriver", "gpsbabel"))
    assert proc.returncode == 0, proc.stderr
    assert not (tmp_path / "apt-called").exists()
