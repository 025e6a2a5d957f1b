"""The documentation site builds strictly: a broken link, a missing page, a table file the
pages include or a generated part that cannot be made fails the build, and so this test.

`mkdocs build --strict` runs the hooks of docs/hooks/generated.py, which generate the CLI,
configuration, file and API reference and the rule graph from the code (the rule graph and the
map of the house from a dry run of the workflow). The README is checked too: the front door
links only to files that exist.
"""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from helpers import REPO

pytest.importorskip("mkdocs")
pytest.importorskip("material")
pytest.importorskip("mkdocstrings")


def build(root: Path, site: Path) -> subprocess.CompletedProcess:
    """``mkdocs build --strict`` of the project at ``root`` (its mkdocs.yml), into ``site``."""
    env = {**os.environ, "NO_MKDOCS_2_WARNING": "1", "PYTHONPATH": str(REPO / "src")}
    bindir = Path(sys.executable).parent
    env["PATH"] = f"{bindir}:{env.get('PATH', '/usr/bin:/bin')}"
    cmd = [sys.executable, "-m", "mkdocs", "build", "--strict", "-d", str(site)]
    return subprocess.run(cmd, cwd=root, capture_output=True, text=True, env=env, timeout=300)


def test_docs_build_strictly(tmp_path):
    r = build(REPO, tmp_path / "site")
    assert r.returncode == 0, r.stdout[-3000:] + r.stderr[-5000:]
    site = tmp_path / "site"
    cli = (site / "reference" / "cli" / "index.html").read_text()
    assert "imugen ingest" in cli and "--max-speed-kmh" in cli  # generated from the parser
    config = (site / "reference" / "config" / "index.html").read_text()
    assert "simulate.sequences_per_shard" in config  # generated from the schema
    files = (site / "reference" / "files" / "index.html").read_text()
    assert "dtheta_x_rad" in files and "err_att_rad" in files  # generated from imugen.tables
    house = (site / "house" / "index.html").read_text()
    assert 'class="mermaid"' in house and "simulate --&gt; evaluate" in house  # the rule graph
    api = (site / "reference" / "api" / "index.html").read_text()
    assert "navigate_arrays" in api and "WindowDataset" in api  # mkdocstrings


def test_a_broken_link_fails_the_build(tmp_path):
    """The same site with one page linking to a page that does not exist: the build fails."""
    root = tmp_path / "project"
    root.mkdir()
    for name in ("src", "workflow", "config", "resources", "Snakefile", "mkdocs.yml"):
        (root / name).symlink_to(REPO / name)
    shutil.copytree(REPO / "docs", root / "docs")
    page = root / "docs" / "getting-started.md"
    page.write_text(page.read_text() + "\nSee [a page that is not there](no-such-page.md).\n")
    r = build(root, tmp_path / "site")
    assert r.returncode != 0
    assert "no-such-page.md" in r.stdout + r.stderr


def test_readme_is_a_front_door_whose_links_exist():
    text = (REPO / "README.md").read_text()
    assert len(text.splitlines()) <= 200
    assert text.startswith(
        "```bash\n"
        'python3 -m venv .venv && . .venv/bin/activate && pip install -e ".[test]" && snakemake -j2\n'
        ". .venv/bin/activate && pytest\n```\n"
    )
    links = re.findall(r"\]\(((?:docs|config|resources)/[^)#]+)", text)
    assert len(links) >= 10
    missing = [link for link in links if not (REPO / link).exists()]
    assert not missing, missing
    for page in ("own-route", "training", "gnss-outages", "paper", "rerun", "slurm"):
        assert f"docs/tutorials/{page}.md" in text


def test_docs_code_blocks_are_ruff_formatted():
    """The pages' Python code blocks are formatted as the package is (``ruff format``, which
    formats Markdown code blocks, as ruff 0.17 does; skipped where the installed ruff cannot)."""
    ruff = shutil.which("ruff", path=str(Path(sys.executable).parent)) or shutil.which("ruff")
    if ruff is None:
        pytest.skip("ruff is not installed")
    pages = sorted(str(p.relative_to(REPO)) for p in (REPO / "docs").rglob("*.md"))
    cmd = [ruff, "format", "--check", *pages]
    r = subprocess.run(cmd, cwd=REPO, capture_output=True, text=True, timeout=120)
    if r.returncode == 2:  # an error, not a finding (1)
        pytest.skip(f"this ruff formats no Markdown: {r.stderr.strip()[:200]}")
    assert r.returncode == 0, r.stdout[-3000:]
