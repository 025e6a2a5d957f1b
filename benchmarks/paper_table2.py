"""The paper's Table 2 beside ours, regenerated from the paper's workflow run.

1. Runs ``snakemake -j2 --configfile config/paper.yaml`` (unless ``--no-run``: then the results
   already in ``--results`` are read), recording its wall and CPU seconds (of every child
   process) and the load average before and after. ``--sequences=N`` runs N sequences per grade
   instead of the configuration's 300 (the first N of the full run: seeds name the sequence, not
   the shard count), in its own working folder ``benchmarks/results/paper-N/`` (its results in
   ``results/`` there), never in the user's ``results/``; the table states the number.
2. Closed loop (imugen's mechanization, the physics a real INS obeys): the workflow's own RMSE
   table, ``results/paper/rmse.csv``, for every grade of the run.
3. Open loop, as the paper's published code does it: the SAME shards
   (``results/paper/imu/<grade>/shard-*.parquet``) integrated with the TRUE attitude (its
   attitude loop never uses the gyros, bug B1 of the project's review), so only the
   accelerometer errors reach the position.

RMSE per axis over the 1 Hz epochs from the first one, Total = sqrt(E^2 + N^2 + U^2) (the
paper's definition), as median [5th-95th percentile] over the sequences.

Usage::

    python benchmarks/paper_table2.py [--no-run] [--results=results] [--sequences=N]
                                      [--write-docs | --out=FILE]

``--write-docs`` writes ``docs/data/paper_table2.md``, the one copy the documentation includes
(Validation page); without it the table goes to ``benchmarks/results/paper_table2.md``.
"""

from __future__ import annotations

import argparse
import datetime as dt
import os
import resource
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pandas as pd

from imugen.core.rotations import quat_to_dcm
from imugen.evaluate.stage import horizontal_distance_m, sequence_metrics
from imugen.tables import layout
from imugen.tables import shard as tshard
from imugen.tables import truth as ttruth

REPO = Path(__file__).resolve().parents[1]
CONFIG = "config/paper.yaml"
ROUTE = "paper"
DOCS_FILE = REPO / "docs" / "data" / "paper_table2.md"
TABLE2 = {  # the paper's Table 2, metres: East, North, Up, Total
    "paper_low_cost": (9.22, 16.94, 26.75, 32.98),
    "paper_industrial": (0.58, 1.28, 8.88, 8.99),
    "paper_tactical": (0.01, 0.13, 1.06, 1.07),
}
BATCH = 50
"""Sequences integrated at once (memory: about 50 x 62,000 x 3 x 8 x 3 bytes = 220 MB)."""


def workdir_of(sequences: int | None) -> Path:
    """The working folder of a run: the project's, or ``benchmarks/results/paper-N`` for
    ``--sequences=N`` (the configuration and route files linked into it)."""
    if sequences is None:
        return REPO
    work = REPO / "benchmarks" / "results" / f"paper-{sequences}"
    work.mkdir(parents=True, exist_ok=True)
    for name in ("config", "resources"):
        if not (work / name).exists():
            (work / name).symlink_to(REPO / name)
    (work / "sequences.yaml").write_text(f"simulate:\n  sequences: {sequences}\n")
    return work


def run_workflow(cores: int, sequences: int | None = None) -> dict:
    """Run the paper's workflow (``sequences`` per grade, default the configuration's); its
    cost: wall and CPU seconds, load average before/after."""
    work = workdir_of(sequences)
    load0 = os.getloadavg()
    ru0 = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    cmd = ["snakemake", f"-j{cores}", "--configfile", CONFIG]
    if sequences is not None:  # the Snakefile of this checkout, run in the scratch folder
        cmd = ["snakemake", "-s", str(REPO / "Snakefile"), "-d", str(work), f"-j{cores}"]
        cmd += ["--configfile", CONFIG, "sequences.yaml"]
    subprocess.run(cmd, cwd=work, check=True)
    wall = time.perf_counter() - t0
    ru1 = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (ru1.ru_utime - ru0.ru_utime) + (ru1.ru_stime - ru0.ru_stime)
    shown = " ".join(cmd).replace(str(REPO) + "/", "").replace(str(REPO), ".")
    return {
        "command": shown,
        "wall_s": wall,
        "cpu_s": cpu,
        "load": (load0, os.getloadavg()),
    }


def open_loop_errors(C: np.ndarray, dv_true: np.ndarray, dv_meas: np.ndarray, dt_s: float):
    """Position error of the paper's open attitude loop: true attitude, measured dv.

    With the true attitude, v_{k+1} - v_k = C_nb(t_k) dv_k + g dt exactly for the true dv, so
    the velocity error is the running sum of C_nb(t_k) (dv_meas - dv_true); position by the
    trapezoid rule.

    Parameters
    ----------
    C : (K-1, 3, 3) body-to-navigation rotations at the interval starts.
    dv_true : (K-1, 3) true increments of the intervals (rows 1.. of the truth), m/s.
    dv_meas : (S, K-1, 3) measured increments of the same intervals, m/s.
    dt_s : sample interval, s.

    Returns
    -------
    (S, K, 3) position error, m (zero at the first sample).
    """
    dv_n = np.einsum("kij,skj->ski", C, dv_meas - dv_true[None])
    S = dv_n.shape[0]
    v_err = np.concatenate([np.zeros((S, 1, 3)), np.cumsum(dv_n, axis=1)], axis=1)
    steps = 0.5 * dt_s * (v_err[:, 1:] + v_err[:, :-1])
    return np.concatenate([np.zeros((S, 1, 3)), np.cumsum(steps, axis=1)], axis=1)


def open_loop_metrics(results: Path, grade: str) -> pd.DataFrame:
    """Per-sequence RMSE of the open loop over every shard of ``grade`` (1 Hz epochs)."""
    truth_path = results / ROUTE / "truth.parquet"
    tr = ttruth.read(truth_path)
    K = tr.K
    every = round(tr.rate_hz)  # 1 Hz epochs from the first sample, as navigate's eval_rate_hz
    idx = np.arange(0, K, every)
    C = quat_to_dcm(tr.q_nb[:-1])
    dv_true = tr.dv[1:]
    distance = horizontal_distance_m(truth_path)
    shards = sorted(Path(results / ROUTE / "imu" / grade).glob("shard-*[0-9].parquet"))
    if not shards:
        raise SystemExit(f"no shards of {grade} under {results / ROUTE / 'imu'}: run the workflow")
    out = []
    for path in shards:
        for ids, _dth, dv in tshard.iter_blocks(path, tshard.INCREMENTS, K, BATCH, skip=1):
            err = open_loop_errors(C, dv_true, dv, tr.dt)[:, idx]
            S = len(ids)
            table = pd.DataFrame(
                {
                    "sequence": np.repeat(ids, len(idx)),
                    "time_s": np.tile(tr.time_s[idx], S),
                    "err_e_m": err[..., 0].ravel(),
                    "err_n_m": err[..., 1].ravel(),
                    "err_u_m": err[..., 2].ravel(),
                }
            )
            out.append(sequence_metrics(table, distance))
    return pd.concat(out)


def _num(x: float) -> str:
    """Three significant figures with thousands separators (1,726; 7.7; 0.043)."""
    if not np.isfinite(x):
        return "n/a"
    if abs(x) >= 100:
        return f"{float(f'{x:.3g}'):,.0f}"
    return f"{x:.2g}" if abs(x) < 1 else f"{x:.3g}"


def _cell(p50: float, p05: float, p95: float) -> str:
    return f"{_num(p50)} [{_num(p05)}-{_num(p95)}]"


def _md(rows: list[list[str]]) -> str:
    head, body = rows[0], rows[1:]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    lines += ["| " + " | ".join(r) + " |" for r in body]
    return "\n".join(lines)


def closed_loop_table(rmse_csv: Path) -> tuple[str, int]:
    """The workflow's RMSE table of every grade, the paper's figures beside its grades."""
    df = pd.read_csv(rmse_csv)
    rows = [["grade", "sequences", "East", "North", "Up", "Total", "paper (E / N / U / Total)"]]
    for r in df.itertuples(index=False):
        r = r._asdict()
        cells = [
            _cell(r[f"{a}_m"], r[f"{a}_p05_m"], r[f"{a}_p95_m"])
            for a in ("east", "north", "up", "total")
        ]
        paper = " / ".join(f"{x:g}" for x in TABLE2[r["grade"]]) if r["grade"] in TABLE2 else "-"
        rows.append([f"`{r['grade']}`", str(int(r["sequences"])), *cells, paper])
    return _md(rows), int(df["sequences"].max())


def open_loop_table(results: Path) -> str:
    rows = [["grade", "East", "North", "Up", "Total", "paper's Total", "its percentile"]]
    for grade, paper in TABLE2.items():
        m = open_loop_metrics(results, grade)
        cells = []
        for a in ("east", "north", "up", "total"):
            v = m[f"rmse_{a}_m"].to_numpy()
            p05, p50, p95 = np.percentile(v, [5, 50, 95])
            cells.append(_cell(p50, p05, p95))
        pct = (m["rmse_total_m"].to_numpy() < paper[3]).mean()
        rows.append([f"`{grade}`", *cells, f"{paper[3]:g}", f"{pct:.0%}"])
    return _md(rows)


def _git_version() -> str:
    def git(*args):
        r = subprocess.run(["git", *args], cwd=REPO, capture_output=True, text=True)
        return r.stdout.strip() if r.returncode == 0 else ""

    sha = git("rev-parse", "--short", "HEAD") or "unknown"
    dirty = git("status", "--porcelain", "--untracked-files=no", "--", "src", "workflow", "config")
    return sha + (" with uncommitted changes to src/workflow/config" if dirty else "")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--no-run", action="store_true", help="read the results already there")
    ap.add_argument(
        "--results", type=Path, help="results folder to read (default: the run's results/)"
    )
    ap.add_argument("--cores", type=int, default=2, help="snakemake -j (default 2)")
    ap.add_argument(
        "--sequences",
        type=int,
        help="sequences per grade instead of the configuration's, run in "
        "benchmarks/results/paper-N/ (default: the configuration's, in results/)",
    )
    ap.add_argument(
        "--write-docs", action="store_true", help=f"write {DOCS_FILE.relative_to(REPO)}"
    )
    ap.add_argument("--out", type=Path, help="write the table here instead")
    a = ap.parse_args(argv)
    if a.sequences is not None and a.sequences < 1:
        ap.error("--sequences must be at least 1")
    if a.results is None:
        a.results = workdir_of(a.sequences) / layout.RESULTS
    cost = None if a.no_run else run_workflow(a.cores, a.sequences)
    t0, c0 = time.perf_counter(), time.process_time()
    load0 = os.getloadavg()
    closed, n = closed_loop_table(a.results / ROUTE / "rmse.csv")
    opened = open_loop_table(a.results)
    own = (time.perf_counter() - t0, time.process_time() - c0, load0, os.getloadavg())
    when = dt.datetime.now(dt.UTC).strftime("%Y-%m-%d %H:%M UTC")
    command = "python benchmarks/paper_table2.py" + "".join(
        f" {arg}" for arg in sys.argv[1:] if not arg.startswith("--out")
    )
    lines = [
        f"<!-- written by `{command}`; do not edit by hand -->",
        "",
        f"Generated {when} by `{command}` at commit `{_git_version()}`, {os.cpu_count()} CPUs.",
    ]
    if a.sequences is not None:
        lines.append(
            f"**{a.sequences} sequences per grade** (`--sequences={a.sequences}`: the first "
            f"{a.sequences} of `{CONFIG}`'s 300, run in `benchmarks/results/paper-{a.sequences}/`)."
        )
    if cost is not None:
        l0, l1 = cost["load"]
        lines.append(
            f"Workflow `{cost['command']}`: {cost['wall_s']:.0f} s wall, {cost['cpu_s']:.0f} "
            f"CPU-s (all its jobs), load average {l0[0]:.1f} before and {l1[0]:.1f} after."
        )
    lines += [
        f"Open-loop integration of the shards: {own[0]:.0f} s wall, {own[1]:.0f} CPU-s, load "
        f"average {own[2][0]:.1f} before and {own[3][0]:.1f} after.",
        "",
        f"**Closed loop** (the workflow's `results/{ROUTE}/rmse.csv`): RMSE in metres, median "
        f"[5th-95th percentile] over {n} sequences per grade, 1 Hz epochs, "
        "Total = sqrt(E² + N² + U²) as in the paper.",
        "",
        closed,
        "",
        "**Open loop** (the same shards, position computed with the true attitude as the "
        "paper's code does): RMSE in metres, median [5th-95th percentile]; the last column is "
        "the share of our sequences whose Total lies below the paper's.",
        "",
        opened,
        "",
    ]
    text = "\n".join(lines)
    out = a.out or (
        DOCS_FILE if a.write_docs else REPO / "benchmarks" / "results" / "paper_table2.md"
    )
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = out.with_name(out.name + ".tmp")
    tmp.write_text(text)
    tmp.replace(out)
    print(text)
    print(f"-> {out}", file=sys.stderr)


if __name__ == "__main__":
    main()
