"""The tutorials run as written: each page of docs/tutorials/ is executed block by block.

The pages run in the order of the site's navigation (``mkdocs.yml``), in one scratch copy of
the project (the ``Snakefile``, ``workflow/``, ``config/``, ``resources/``, ``benchmarks/`` and
``src/`` linked into a temporary folder, which is the working directory, as the project's
folder is for a user who works through the tutorials one after the other: later pages reuse
the route and results of the first). A page's fenced code blocks are taken in order:

- a block titled with a file name (```` ```yaml title="my_route.yaml" ````) is written to that
  file;
- a ``bash`` block is run with ``bash -euo pipefail``, a ``python`` block with this Python;
- a block titled "Not run: ..." is shown on the page and skipped here (its title says why);
- any other block (``text``: an output shown) is skipped.

A page that needs an optional extra says so in a comment ``<!-- needs: torch -->``; it is
skipped where that module is missing (CI installs every extra).

The tutorials use tiny configurations (a few sequences at 20 Hz), so that all the pages run
in about four minutes.
"""

from __future__ import annotations

import importlib.util
import os
import re
import resource
import subprocess
import sys
import time
from pathlib import Path

import pytest

from helpers import REPO

NAV = re.findall(r"tutorials/([\w-]+\.md)", (REPO / "mkdocs.yml").read_text())
PAGES = [REPO / "docs" / "tutorials" / name for name in NAV if name != "index.md"]
FENCE = re.compile(r"^```(\w+)([^\n]*)\n(.*?)^```[ \t]*$", re.M | re.S)
FILE_TITLE = re.compile(r"[\w.-]+(/[\w.-]+)*\.\w+")
LINKED = ("Snakefile", "workflow", "config", "resources", "benchmarks", "src")


def blocks(page: Path) -> list[tuple[str, str, str]]:
    """``(language, title, body)`` of every fenced code block of ``page``, in order."""
    out = []
    for m in FENCE.finditer(page.read_text()):
        title = re.search(r'title="([^"]*)"', m.group(2))
        out.append((m.group(1), title.group(1) if title else "", m.group(3)))
    return out


def action(lang: str, title: str) -> str:
    if title.startswith("Not run"):
        return "skip"
    if FILE_TITLE.fullmatch(title):
        return "write"
    return "run" if lang in ("bash", "python") else "skip"


def project(tmp: Path) -> dict[str, str]:
    """Link the project into ``tmp``; the environment its commands run in."""
    for name in LINKED:
        (tmp / name).symlink_to(REPO / name)
    bindir = Path(sys.executable).parent
    env = dict(os.environ)
    env.update(
        PATH=f"{bindir}:{env.get('PATH', '/usr/bin:/bin')}",
        PYTHONPATH=str(REPO / "src"),  # the `imugen` of this checkout
        MPLBACKEND="Agg",
    )
    return env


def _children_cpu() -> float:
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


def run_page(page: Path, tmp: Path, env: dict[str, str]) -> None:
    for i, (lang, title, body) in enumerate(blocks(page), 1):
        what = action(lang, title)
        where = f"{page.name}, block {i} ({lang}{' ' + title if title else ''})"
        if what == "write":
            (tmp / title).parent.mkdir(parents=True, exist_ok=True)
            (tmp / title).write_text(body)
        elif what == "run":
            cmd = (
                ["bash", "-euo", "pipefail", "-c", body]
                if lang == "bash"
                else [sys.executable, "-c", body]
            )
            t0, c0 = time.perf_counter(), _children_cpu()
            r = subprocess.run(cmd, cwd=tmp, env=env, capture_output=True, text=True, timeout=600)
            assert r.returncode == 0, (
                f"{where} failed:\n{body}\n{r.stdout[-3000:]}\n{r.stderr[-3000:]}"
            )
            # with -s: the cost of each block (tutorials must stay quick)
            print(f"{where}: {time.perf_counter() - t0:.1f} s, {_children_cpu() - c0:.1f} CPU-s")


def test_every_tutorial_is_a_page_with_blocks_that_run():
    """The newcomer's six tasks and the further tutorials, each in the navigation and with
    blocks this test runs; a block that is not run says why in its title."""
    files = {p.name for p in (REPO / "docs" / "tutorials").glob("*.md")} - {"index.md"}
    assert len(PAGES) >= 6 and {p.name for p in PAGES} == files, (NAV, files)
    for page in PAGES:
        kinds = [action(lang, title) for lang, title, _ in blocks(page)]
        assert "run" in kinds, page.name
        for _, title, _ in blocks(page):
            if title.startswith("Not run"):
                assert len(title) > len("Not run: ") + 10, (page.name, title)


@pytest.fixture(scope="module")
def scratch(tmp_path_factory):
    """One project folder for the tutorials, and the pages already run in it."""
    tmp = tmp_path_factory.mktemp("tutorials")
    return tmp, project(tmp), []


@pytest.mark.parametrize("page", PAGES, ids=[p.stem for p in PAGES])
def test_tutorial_runs(page, scratch):
    """The page runs after the pages before it (run here first when selected alone)."""
    tmp, env, done = scratch
    for module in re.findall(r"<!-- needs: ([\w.]+) -->", page.read_text()):
        if importlib.util.find_spec(module) is None:  # an optional extra (CI installs them)
            pytest.skip(f"{page.name} needs {module}")
    for earlier in PAGES[: PAGES.index(page) + 1]:
        if earlier not in done:
            run_page(earlier, tmp, env)
            done.append(earlier)
