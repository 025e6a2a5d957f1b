"""Faults at scale: a shard job killed mid-write, a full disk, a path that cannot be written.

Guarantees checked (issue 6): a killed job never leaves a file at its output path (only a
``.NAME.*.tmp`` temporary, which no reader or Snakemake pattern takes for an output, and which
the next successful write of that output removes), and re-running the job gives bit-identical
files; a write error (no space, file too large, not a directory) ends the command with one line
``imugen: error: PATH: ...`` and exit status 2, no traceback and no partial output.
"""

from __future__ import annotations

import errno
import hashlib
import resource
import signal
import subprocess
import sys
import time
from pathlib import Path

import pyarrow.parquet as pq
import pytest

from imugen import cli
from imugen.core.errors import InputError
from imugen.evaluate.options import EvaluateOptions
from imugen.ingest.stage import run as ingest_run
from imugen.navigate.stage import run as navigate_run
from imugen.simulate import stage as S
from imugen.tables import shard as tshard
from imugen.tables import truth as ttruth
from imugen.truth.options import TruthOptions
from imugen.truth.stage import run as truth_run

from helpers import simulate_shard

REPO = Path(__file__).resolve().parents[2]
EXAMPLE = REPO / "resources" / "example_route.kml"

# 50 still sequences of 600 s at 100 Hz: 3 M rows, three 2^20-row groups written one by one
KILL_ARGS = ["--static", "600", "--rate-hz", "100", "--grade", "industrial"]
KILL_ARGS += ["--sequences", "50", "--seed", "7", "--shard", "3"]


def sha(p: Path) -> str:
    return hashlib.sha256(p.read_bytes()).hexdigest()


def one_error_line(err: str, path) -> str:
    """The stderr of a failed command: exactly one ``imugen: error:`` line naming ``path``."""
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith("imugen: error: ") and str(path) in lines[0], err
    assert "Traceback" not in err
    return lines[0]


@pytest.fixture(scope="module")
def route(tmp_path_factory):
    """ENU table, a 10 Hz truth and a 2-sequence shard of the example route.

    Built in this process, which also fills the numba caches the subprocesses then load.
    """
    d = tmp_path_factory.mktemp("route")
    enu = d / "enu.parquet"
    ingest_run(EXAMPLE, enu)
    truth = d / "truth.parquet"
    truth_run(enu, truth, TruthOptions(rate_hz=10.0, earth="flat"))
    shard = d / "shard-000.parquet"
    simulate_shard(truth, shard, "industrial", sequences=2, seed=1)
    navigate_run(truth, shard, d / "nav.parquet")
    return {"enu": enu, "truth": truth, "shard": shard}


# --- a shard job killed mid-write -----------------------------------------------------------------
def test_killed_shard_job_leaves_no_output_and_rerun_is_bit_identical(route, tmp_path):
    a = tmp_path / "killed"
    a.mkdir()
    out = a / "shard-003.parquet"
    cmd = [sys.executable, "-m", "imugen", "simulate", *KILL_ARGS, "-o", str(out)]
    proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    tmp = None
    deadline = time.monotonic() + 120
    try:
        while proc.poll() is None and time.monotonic() < deadline:
            tmps = list(a.glob(".shard-003.parquet.*.tmp"))
            if tmps and tmps[0].stat().st_size > 1 << 20:  # a row group is being written
                tmp = tmps[0]
                break
            time.sleep(0.002)
    finally:
        proc.kill()
        proc.wait()
    assert tmp is not None, "the job ended before it was seen writing: enlarge KILL_ARGS"
    assert proc.returncode == -signal.SIGKILL
    # nothing at the output paths; only temporaries, which the shard patterns do not match
    assert not out.exists() and not tshard.labels_path(out).exists()
    left = sorted(p.name for p in a.iterdir())
    assert left and all(n.startswith(".shard-003.") and n.endswith(".tmp") for n in left), left
    assert not list(a.glob("shard-*.parquet")) and not list(a.glob("*.parquet"))
    assert 0 < tmp.stat().st_size  # a truncated file exists, but only under the temporary name
    # a downstream stage refuses the missing shard with one line (it never sees the temporary)
    r = subprocess.run(
        [sys.executable, "-m", "imugen", "navigate", str(route["truth"]), str(out), "-o", "n.pq"],
        capture_output=True,
        text=True,
    )
    assert r.returncode == 2
    one_error_line(r.stderr, out)

    # the rerun completes, removes the stale temporary, and equals an uninterrupted run
    r = subprocess.run(cmd, capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    assert sorted(p.name for p in a.iterdir()) == [tshard.labels_path(out).name, out.name]
    b = tmp_path / "clean"
    b.mkdir()
    ref = b / out.name
    simulate_shard(
        None, ref, "industrial", sequences=50, seed=7, shard=3, static_s=600.0, rate_hz=100.0
    )
    assert sha(out) == sha(ref)
    assert sha(tshard.labels_path(out)) == sha(tshard.labels_path(ref))


def test_truncated_shard_is_refused_in_one_line(route, tmp_path):
    """A truncated file put at a shard path by hand is refused, never read as data."""
    bad = tmp_path / "shard-000.parquet"
    data = route["shard"].read_bytes()
    bad.write_bytes(data[: len(data) // 2])
    out = tmp_path / "nav.parquet"
    r = subprocess.run(
        [sys.executable, "-m", "imugen", "navigate", str(route["truth"]), str(bad), "-o", str(out)],
        capture_output=True,
        text=True,
    )
    assert r.returncode == 2
    one_error_line(r.stderr, bad)
    assert not out.exists()


# --- write errors through the command line ------------------------------------------------------
def stage_argv(stage: str, route: dict, out: Path) -> list[str]:
    if stage == "truth":
        return ["truth", str(route["enu"]), "-o", str(out), "--rate-hz", "10"]
    if stage == "simulate":
        return ["simulate", str(route["truth"]), "-o", str(out), "--grade", "industrial",
                "--sequences", "2", "--seed", "1", "--shard", "0"]  # fmt: skip
    return ["navigate", str(route["truth"]), str(route["shard"]), "-o", str(out)]


STAGES = ("truth", "simulate", "navigate")


@pytest.mark.parametrize("stage", STAGES)
def test_output_under_a_regular_file(stage, route, tmp_path, capsys):
    """A directory that cannot be created (works as root too, unlike chmod)."""
    blocker = tmp_path / "not_a_dir"
    blocker.write_text("x")
    out = blocker / "sub" / "out.parquet"
    assert cli.main(stage_argv(stage, route, out)) == 2
    line = one_error_line(capsys.readouterr().err, out)
    assert "cannot write" in line
    assert blocker.read_text() == "x"


@pytest.mark.parametrize("stage", STAGES)
def test_disk_full_during_write(stage, route, tmp_path, monkeypatch, capsys):
    """ENOSPC after part of the file is written: one line, no output, no temporary left."""

    def full(*args, **kwargs):
        raise OSError(errno.ENOSPC, "No space left on device")

    def partial_then_full(table, where, *args, **kwargs):
        Path(where).write_bytes(b"PAR1" + b"\0" * 1000)
        full()

    if stage in ("simulate", "navigate"):  # both stream row groups through a ParquetWriter
        monkeypatch.setattr(pq.ParquetWriter, "write_table", full)
    else:
        monkeypatch.setattr(pq, "write_table", partial_then_full)
    d = tmp_path / "out"
    d.mkdir()
    out = d / "x.parquet"
    assert cli.main(stage_argv(stage, route, out)) == 2
    line = one_error_line(capsys.readouterr().err, out)
    assert "No space left on device" in line
    assert list(d.iterdir()) == []


def _small_files():
    signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
    resource.setrlimit(resource.RLIMIT_FSIZE, (16 << 10, 16 << 10))


@pytest.mark.parametrize("stage", STAGES)
def test_real_write_failure_in_a_subprocess(stage, route, tmp_path):
    """A real failing write() (RLIMIT_FSIZE 16 KiB: EFBIG, as a full quota), no monkeypatching.

    Every output here is larger than 16 KiB (truth 0.8 MB, shard 0.2 MB, errors 36 kB).
    """
    d = tmp_path / "out"
    d.mkdir()
    out = d / "x.parquet"
    r = subprocess.run(
        [sys.executable, "-m", "imugen", *stage_argv(stage, route, out)],
        capture_output=True,
        text=True,
        preexec_fn=_small_files,
    )
    assert r.returncode == 2, r.stderr
    line = one_error_line(r.stderr, out)
    assert "too large" in line.lower()
    assert list(d.iterdir()) == []


# --- bounded-memory streaming and ids at scale ----------------------------------------------------
def test_short_last_shard_keeps_global_ids_unique():
    """N = 5 in shards of 3: the last shard holds 2 sequences with ids 3, 4 (not 2, 3)."""
    kw = {"static_s": 2.0, "rate_hz": 10.0, "seed": 5}
    full = S.simulate(None, "consumer", sequences=3, shard=0, **kw)
    last = S.simulate(None, "consumer", sequences=2, shard=1, shard_size=3, **kw)
    base = tshard.route_id("static") << 31
    assert full.labels["index"].tolist() == [0, 1, 2]
    assert (full.labels["sequence"] - base).tolist() == [0, 1, 2]
    assert (last.labels["sequence"] - base).tolist() == [3, 4]
    assert last.meta["sequence_ids"] == [base + 3, base + 4]
    # the data of sequence j of shard K do not depend on the shard size
    alone = S.simulate(None, "consumer", sequences=2, shard=1, **kw)
    assert (alone.labels["sequence"] - base).tolist() == [2, 3]  # default: this shard's size
    for name in last.data:
        assert (last.data[name] == alone.data[name]).all()
    with pytest.raises(InputError, match="fewer than"):
        S.simulate(None, "consumer", sequences=4, shard=1, shard_size=3, **kw)


def test_cli_shard_size(tmp_path):
    out = tmp_path / "shard-001.parquet"
    argv = ["simulate", "--static", "2", "--rate-hz", "10", "-o", str(out), "--grade", "consumer"]
    assert (
        cli.main([*argv, "--sequences", "2", "--seed", "5", "--shard", "1", "--shard-size", "3"])
        == 0
    )
    base = tshard.route_id("static") << 31
    ids = pq.read_table(out, columns=["sequence"]).column(0).to_numpy() - base
    assert sorted(set(ids.tolist())) == [3, 4]
    lab = pq.read_table(tshard.labels_path(out)).column("sequence").to_numpy() - base
    assert lab.tolist() == [3, 4]


def _nav_table(ids, epochs=5, offset=0.0):
    import numpy as np
    import pandas as pd

    rng = np.random.default_rng(len(ids) + int(offset))
    n = len(ids) * epochs
    return pd.DataFrame(
        {
            "sequence": np.repeat(np.asarray(ids, np.int32), epochs),
            "time_s": np.tile(np.arange(epochs, dtype=float), len(ids)),
            "err_e_m": rng.normal(size=n) + offset,
            "err_n_m": rng.normal(size=n),
            "err_u_m": rng.normal(size=n),
            "err_att_rad": rng.random(n),
        }
    )


def test_evaluate_streams_files_and_refuses_repeated_ids(route, tmp_path):
    import pandas as pd

    from imugen.core.io import write_parquet
    from imugen.evaluate.stage import horizontal_distance_m, sequence_metrics
    from imugen.evaluate.stage import run as evaluate_run

    frames = [_nav_table([4, 5, 6]), _nav_table([0, 1], offset=1.0), _nav_table([2, 3])]
    paths = [write_parquet(f, {"stage": "navigate"}, tmp_path / f"n{i}.parquet") for i, f in
             enumerate(frames)]  # fmt: skip
    out = evaluate_run(route["truth"], paths, tmp_path / "m.parquet", EvaluateOptions(grade="g"))
    got = pd.read_parquet(out).set_index("sequence")
    want = sequence_metrics(pd.concat(frames), horizontal_distance_m(route["truth"]))
    pd.testing.assert_frame_equal(got, want, check_index_type=False)
    dup = write_parquet(_nav_table([6, 7]), {"stage": "navigate"}, tmp_path / "dup.parquet")
    with pytest.raises(InputError, match="sequence 6 appears in more than one"):
        evaluate_run(
            route["truth"], [*paths, dup], tmp_path / "m2.parquet", EvaluateOptions(grade="g")
        )
    assert not (tmp_path / "m2.parquet").exists()


def test_navigate_reader_is_independent_of_batching(route, tmp_path, monkeypatch):
    """Sequences straddling record batches, one per batch or all together: identical errors,
    and identical to mechanizing the float32 shard data held in memory."""
    import numpy as np

    from imugen.core.io import read_meta
    from imugen.navigate import stage as N
    from imugen.navigate.mechanize import mechanize
    from imugen.navigate.navigator import BATCH_BYTES, batch_size

    shard = tmp_path / "shard-000.parquet"
    simulate_shard(route["truth"], shard, "consumer", sequences=5, seed=3)
    ref = N.navigate(route["truth"], shard)
    monkeypatch.setattr(tshard, "READ_ROWS", 777)  # not a divisor of the samples per sequence
    for b in (1, 2, 5, 64):
        assert N.navigate(route["truth"], shard, batch=b).equals(ref)
    # oracle: the same increments, rounded to float32 as stored, mechanized directly
    mem = S.simulate(route["truth"], "consumer", sequences=5, seed=3)
    tr = pq.read_table(route["truth"]).to_pandas()
    from imugen.tables import truth as col

    dth = mem.data["dtheta"].astype(np.float32).astype(np.float64)[:, 1:]
    dv = mem.data["dv"].astype(np.float32).astype(np.float64)[:, 1:]
    meta = read_meta(route["truth"])
    nav = mechanize(
        np.ascontiguousarray(dth),
        np.ascontiguousarray(dv),
        1.0 / meta["rate_hz"],
        tr[list(col.POS)].to_numpy()[0],
        tr[list(col.VEL)].to_numpy()[0],
        tr[list(col.QUAT)].to_numpy()[0],
        ttruth.origin_frame(meta),
        every=round(meta["rate_hz"]),
        outputs=("p",),
    )
    err = nav.p_n - tr[list(col.POS)].to_numpy()[nav.index][None]
    assert np.array_equal(ref["err_e_m"].to_numpy(), err[..., 0].ravel())
    assert np.array_equal(ref["err_u_m"].to_numpy(), err[..., 2].ravel())
    assert batch_size(620_001) * 2 * 3 * 8 * 620_001 <= BATCH_BYTES  # bounded at 1 kHz


def test_navigate_refuses_stray_rows(route, tmp_path):
    bad = tmp_path / "bad.parquet"
    t = pq.read_table(route["shard"])
    pq.write_table(t.slice(0, t.num_rows - 3).replace_schema_metadata(t.schema.metadata), bad)
    r = cli.main(["navigate", str(route["truth"]), str(bad), "-o", str(tmp_path / "n.parquet")])
    assert r == 2
    assert not (tmp_path / "n.parquet").exists()
