"""One job per shard: `imugen simulate --navigate` synthesizes, writes and navigates a shard in
one pass; the oracle is the two-step path (`simulate` then `navigate` on the written file)."""

import hashlib

import numpy as np
import pytest

from imugen import truth as T
from imugen.core.errors import InputError
from imugen.navigate import navigator
from imugen.navigate import stage as nv
from imugen.navigate.options import NavigateOptions
from imugen.simulate import stage as S
from imugen.tables import nav as tnav
from imugen.tables import truth as ttruth

from helpers import simulate_shard


def sha(path):
    return hashlib.sha256(path.read_bytes()).hexdigest()


@pytest.fixture(scope="module")
def truth_path(tmp_path_factory):
    """A timed, curvy car track (40 s) -> truth at 20 Hz, in results/<route>/truth.parquet."""
    t = np.arange(0.0, 41.0, 1.0)
    enu = np.column_stack([150 * np.sin(t / 12.0), 9 * t - 100 * np.cos(t / 8.0), 2 * np.sin(t)])
    df, meta = T.enu_table(enu, t, (45.0, 7.0, 300.0))
    tdf, tmeta = T.build_truth(df, meta, rate_hz=20.0, earth="flat", verbose=False)
    p = tmp_path_factory.mktemp("wf") / "route" / "truth.parquet"
    ttruth.write(tdf, tmeta, p)
    return p


@pytest.mark.parametrize(
    "kw",
    [
        {},
        {"increments": "raw", "series": True},
        {"outputs": "rates"},
        {"outputs": "both", "dtype": "float64"},
    ],
)
def test_fused_equals_simulate_then_navigate(truth_path, tmp_path, monkeypatch, kw):
    # batches of 2 over 5 sequences: a full batch, another, and a short last one
    for module in (nv, navigator):  # the navigate stage's and simulate --navigate's batches
        monkeypatch.setattr(module, "batch_size", lambda samples: 2)
    args = dict(grade="consumer", sequences=5, seed=3, shard=1, shard_size=5, **kw)
    two = tmp_path / "two"
    simulate_shard(truth_path, two / "shard-001.parquet", **args)
    nv.run(
        truth_path,
        two / "shard-001.parquet",
        two / "nav.parquet",
        NavigateOptions(eval_rate_hz=2.0),
    )
    one = tmp_path / "one"
    simulate_shard(truth_path, one / "shard-001.parquet", navigate=one / "nav.parquet",
          eval_rate_hz=2.0, **args)  # fmt: skip
    for name in ("shard-001.parquet", "shard-001.labels.parquet", "nav.parquet"):
        assert sha(one / name) == sha(two / name), name
    nav = tnav.read(one / "nav.parquet")
    assert nav.sequence.nunique() == 5 and len(nav) == 5 * 81  # 40 s at 2 Hz, t_0 included
    assert tnav.read_meta(one / "nav.parquet")["shard"] == "shard-001.parquet"


def test_errors_only_without_shard(truth_path, tmp_path):
    args = dict(grade="tactical", sequences=3, seed=1)
    simulate_shard(truth_path, tmp_path / "s.parquet", navigate=tmp_path / "a.parquet", **args)
    simulate_shard(truth_path, None, navigate=tmp_path / "b.parquet", **args)
    assert sorted(p.name for p in tmp_path.iterdir()) == [
        "a.parquet", "b.parquet", "s.labels.parquet", "s.parquet",
    ]  # fmt: skip
    a, b = tnav.read(tmp_path / "a.parquet"), tnav.read(tmp_path / "b.parquet")
    assert a.equals(b) and (a.err_e_m.abs() > 0).any()
    assert tnav.read_meta(tmp_path / "b.parquet")["shard"] is None


def test_refusals_leave_nothing(truth_path, tmp_path):
    with pytest.raises(InputError, match="and/or --navigate"):
        simulate_shard(truth_path, None, grade="consumer")
    with pytest.raises(InputError, match="needs a truth file"):
        simulate_shard(None, None, grade="consumer", static_s=2.0, navigate=tmp_path / "n.parquet")
    with pytest.raises(InputError, match="> 0"):
        simulate_shard(truth_path, tmp_path / "s.parquet", grade="consumer",
              navigate=tmp_path / "n.parquet", eval_rate_hz=0.0)  # fmt: skip
    assert not list(tmp_path.iterdir())


def test_cli(truth_path, tmp_path, cli):
    nav = tmp_path / "nav.parquet"
    r = cli("simulate", str(truth_path), "--navigate", str(nav), "--grade", "consumer",
            "--sequences", "2", "--seed", "0", "--shard", "0")  # fmt: skip
    assert r.returncode == 0, r.stderr
    assert tnav.read(nav).sequence.nunique() == 2 and list(tmp_path.iterdir()) == [nav]
    r = cli("simulate", str(truth_path), "--grade", "consumer", "--sequences", "2",
            "--seed", "0", "--shard", "0")  # fmt: skip
    assert r.returncode == 2 and r.stderr.startswith("imugen: error: -o:")


def test_float32_outputs_are_the_rounded_float64_results(truth_path, tmp_path):
    """The kernel writes float32 straight into the output buffers: the stored values must be
    the float64 results of the in-memory generator rounded once to float32."""
    from imugen.tables import shard as tshard

    kw = dict(grade="consumer", sequences=2, seed=5, outputs="both", series=True)
    mem = S.simulate(str(truth_path), **kw)
    simulate_shard(truth_path, tmp_path / "s.parquet", dtype="float32", **kw)
    tbl = tshard.read(tmp_path / "s.parquet")
    for group, (cols, _) in tshard.GROUPS.items():
        if group in mem.data:
            for i, c in enumerate(cols):
                want = mem.data[group][..., i].astype(np.float32).ravel()
                np.testing.assert_array_equal(tbl.column(c).to_numpy(), want, err_msg=c)
