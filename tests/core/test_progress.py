"""Progress of long jobs: quiet when short, counts and rate when long, a short console form."""

from __future__ import annotations

import os

from imugen.core.progress import CONSOLE_FD, Progress


def test_short_jobs_print_nothing(capsys):
    p = Progress("simulate x", 3, every_s=60.0)
    for k in range(1, 4):
        p.update(k)
    assert capsys.readouterr().err == ""


def test_long_jobs_report_counts_rate_and_time_left(capsys, monkeypatch, tmp_path):
    r, w = os.pipe()
    monkeypatch.setenv(CONSOLE_FD, str(w))
    p = Progress("navigate y", 4, every_s=0.0, console_s=0.0)
    p.update(1)
    p.update(4)
    os.close(w)
    err = capsys.readouterr().err.splitlines()
    assert err[0].startswith("navigate y: 1/4 sequences,") and "left" in err[0]
    assert err[-1].startswith("navigate y: 4/4 sequences,") and "left" not in err[-1]
    console = os.read(r, 4096).decode().splitlines()
    assert console[0].startswith("  navigate y: 25 %") and console[-1].startswith(
        "  navigate y: 100 %"
    )
