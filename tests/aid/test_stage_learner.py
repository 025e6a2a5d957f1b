"""The aid stage's learner files (issue 26): the filter-estimates table it writes
(``--estimates-out``) and the learned-measurements table it reads (``--learned-in``).

Oracles: every estimates row is the filter's output at its epoch (the aided table's state
columns at the shared epochs); the increments corrected with the held estimates reproduce what
the filter removed from each increment (``--correction-out``), so the filter-aware target the
loader forms from the table is the filter's own; a perfect learned body velocity (the truth's,
with its stated noise) through the file shrinks the drift at the end of the outage; bad files
are refused in one line with no output left.
"""

import numpy as np
import pandas as pd
import pytest

from imugen import truth as T
from imugen.aid import stage as AID
from imugen.core.errors import InputError
from imugen.core.rotations import quat_to_dcm
from imugen.dataset import RouteFiles, WindowDataset
from imugen.tables import aided as taided
from imugen.tables import filter_estimates as test_
from imugen.tables import gnss as tgnss
from imugen.tables import imu_correction as tcorr
from imugen.tables import layout
from imugen.tables import learned as tlearned
from imugen.tables import shard as tshard
from imugen.tables import truth as ttruth

from helpers import simulate_shard

OUTAGE = {"kind": "outage", "start_s": 80.0, "duration_s": 30.0}


@pytest.fixture(scope="module")
def scene(tmp_path_factory):
    """A 180 s car truth (flat), a consumer shard of 3 sequences, the stage run on it with the
    estimates and the correction written."""
    d = tmp_path_factory.mktemp("aidl")
    pts = np.array(
        [[0, 0, 0], [400, 0, 0], [400, 200, 0], [0, 200, 0], [0, 0, 0], [400, 0, 0], [400, 200, 0]],
        float,
    )
    enu = pd.DataFrame(pts, columns=["e_m", "n_m", "u_m"])
    meta = {"origin": {"lat_deg": 45.0, "lon_deg": 7.0, "alt_m": 200.0}, "timed": False}
    # a rigid car (no dive and squat on a suspension): the learner plumbing is the subject,
    # and the perfect learner's drift oracle was measured on it (with the car's
    # suspension one of three sequences drifted more with the perfect learner: open)
    df, tm = T.build_truth(
        enu, meta, rate_hz=100.0, earth="flat", vehicle="car", verbose=False,
        vehicle_params={"suspension": "rigid"},
    )  # fmt: skip
    ttruth.write(df, tm, d / "truth.parquet")
    # the results layout (imugen.tables.layout), so that the loader finds the estimates
    shard = d / "car" / "imu" / "consumer" / "shard-001.parquet"
    shard.parent.mkdir(parents=True)
    simulate_shard(d / "truth.parquet", shard, "consumer", sequences=3, seed=5,
                   shard=1, shard_size=3, route="car", dtype="float64", series=True)  # fmt: skip
    est = layout.beside(shard, "estimates")
    est.parent.mkdir(parents=True)
    (d / "e.parquet").symlink_to(est)
    params = AID.AidOptions(intervals=(OUTAGE,))
    AID.run(d / "truth.parquet", shard, d / "g.parquet", d / "a.parquet", params,
            out_correction=d / "c.parquet", out_estimates=est)  # fmt: skip
    return d


def _shard(d):
    return d / "car" / "imu" / "consumer" / "shard-001.parquet"


def test_estimates_are_the_filter_state_at_every_epoch(scene):
    e = test_.read(scene / "e.parquet")
    a = taided.read(scene / "a.parquet")
    g = tgnss.read(scene / "g.parquet")
    assert list(e.columns) == list(test_.COLUMNS)
    meta = test_.read_meta(scene / "e.parquet")
    assert meta["stage"] == "aid-estimates" and meta["units"]["sd_p_e_m"] == "m"
    # every epoch from the start: as many rows per sequence as GNSS epochs from the first
    for sid, rows in e.groupby("sequence"):
        t = g.loc[g["sequence"] == sid, "time_s"].to_numpy()
        np.testing.assert_allclose(rows["time_s"].to_numpy(), t[t >= rows["time_s"].min()])
    m = a.merge(e, on=["sequence", "time_s"], suffixes=("", "_e"))
    assert len(m) == len(a)
    for c in (*ttruth.POS, *ttruth.QUAT, *taided.GYRO_BIAS, *taided.ACCEL_BIAS):
        np.testing.assert_allclose(m[c + "_e"], m[c], rtol=1e-6, atol=1e-12)
    np.testing.assert_allclose(m[list(test_.SD["att"])], m[list(taided.SD_ATT)], rtol=1e-6)
    # the stage's defaults: cross-coupling states on, scale factors off
    assert e[list(test_.GYRO_CC + test_.ACCEL_CC + test_.SIGMAS[:15])].notna().all().all()
    assert e[list(test_.GYRO_SF + test_.SD["sg"] + test_.SD["odo_sf"])].isna().all().all()


def test_held_estimates_reproduce_the_filter_correction(scene):
    """raw - corrected(raw, estimate held since the last epoch) = the filter's correction."""
    e = test_.read(scene / "e.parquet")
    sh = tshard.read(_shard(scene)).to_pandas()
    ids = sh["sequence"].unique()
    K = ttruth.read(scene / "truth.parquet").K
    dth = sh[list(tshard.INCREMENTS[:3])].to_numpy().reshape(len(ids), K, 3)
    dv = sh[list(tshard.INCREMENTS[3:])].to_numpy().reshape(len(ids), K, 3)
    cth, cdv = tcorr.arrays(scene / "c.parquet", ids, K)
    vals = list(test_.VALUES[:24])
    for i, sid in enumerate(ids):
        r = e[e["sequence"] == sid]
        k = np.arange(K)
        j = np.searchsorted(r["sample"].to_numpy(), k, "left") - 1  # last epoch before k
        on = j >= 0
        est = r[vals].to_numpy(float)[j[on]]
        th, u = test_.corrected_increments(dth[i, on], dv[i, on], est, 0.01)
        np.testing.assert_allclose(dth[i, on] - th, cth[i, on], rtol=1e-5, atol=1e-10)
        np.testing.assert_allclose(dv[i, on] - u, cdv[i, on], rtol=1e-5, atol=1e-9)
        assert np.all(cth[i, ~on] == 0.0)


def _perfect(scene, sd, every=10):
    """A learned table of the truth's body velocity at 1 Hz with noise of sigmas ``sd``."""
    truth = ttruth.read(scene / "truth.parquet")
    g = tgnss.read(scene / "g.parquet")
    ids = g["sequence"].unique()
    t = g.loc[g["sequence"] == ids[0], "time_s"].to_numpy()
    k = np.searchsorted(truth.time_s, t - 1e-9)
    vb = np.einsum("jki,jk->ji", quat_to_dcm(truth.q_nb[k]), truth.v_n[k])
    rng = np.random.default_rng(3)
    z = vb[None] + sd * rng.standard_normal((len(ids), len(t), 3))
    z[:, np.arange(len(t)) % every != 0] = np.nan
    cov = np.broadcast_to(np.asarray(sd) ** 2, z.shape)
    return ids, t, z, cov


def test_perfect_learned_velocity_from_a_file_shrinks_the_outage_drift(scene, tmp_path):
    ids, t, z, cov = _perfect(scene, np.array([0.05, 0.02, 0.02]))
    tlearned.write(tlearned.frame(ids, t, z, cov), {"what": "truth"}, tmp_path / "l.parquet")
    params = AID.AidOptions(intervals=(OUTAGE,))
    AID.run(scene / "truth.parquet", _shard(scene), tmp_path / "g.parquet",
            tmp_path / "a.parquet", params, learned_in=tmp_path / "l.parquet",
            out_estimates=tmp_path / "e.parquet")  # fmt: skip

    def drift(path):
        a = taided.read(path)
        end = a[np.isclose(a["since_fix_s"], a["since_fix_s"].max(), atol=0.2)]
        return np.hypot(end["err_e_m"], end["err_n_m"]).to_numpy()

    raw, lrn = drift(scene / "a.parquet"), drift(tmp_path / "a.parquet")
    assert np.median(lrn) < 0.5 * np.median(raw), (raw, lrn)
    flags = test_.read(tmp_path / "e.parquet")["flags"].to_numpy()
    assert np.any(flags & 256)  # F_LEARNED
    assert test_.read_meta(tmp_path / "e.parquet")["learned"] == "l.parquet"


def test_bad_learned_files_are_refused_in_one_line(scene, tmp_path, cli):
    ids, t, z, cov = _perfect(scene, np.array([0.05, 0.02, 0.02]))
    rows = pd.DataFrame(tlearned.frame(ids, t, z, cov))

    def refused(df, match, via_cli=False):
        p = tmp_path / "bad.parquet"
        tlearned.write(df, {}, p)
        g, a = tmp_path / "g.parquet", tmp_path / "a.parquet"
        if not via_cli:
            with pytest.raises(InputError, match=match):
                AID.run(scene / "truth.parquet", _shard(scene), g, a,
                        AID.AidOptions(intervals=(OUTAGE,)), learned_in=p)  # fmt: skip
        else:
            r = cli("aid", str(scene / "truth.parquet"), str(_shard(scene)),
                    f"--gnss-out={g}", f"--output={a}", f"--learned-in={p}",
                    "--scenario=outage:30@80")  # fmt: skip
            assert r.returncode != 0 and match in r.stderr, r.stderr
            assert len(r.stderr.strip().splitlines()) == 1, r.stderr
        assert not a.exists() and not g.exists()

    refused(rows.assign(sequence=rows["sequence"] + 1000), "is not in the shard", via_cli=True)
    refused(rows.assign(time_s=rows["time_s"] + 0.05), "is not a filter")
    refused(rows.drop(columns=["vb_cov_xy_m2ps2"]), "missing column")
    refused(rows.assign(vb_cov_xy_m2ps2=1.0), "is not positive definite")
    refused(pd.concat([rows, rows.iloc[:1]]), "given twice")
    with pytest.raises(InputError, match="neither"):
        tlearned.write(rows[["sequence", "time_s"]], {}, tmp_path / "n.parquet")
        tlearned.arrays(tmp_path / "n.parquet", ids, t)


def test_workflow_writes_the_estimates_only_when_asked(tmp_path):
    """Dry runs: ``aided.estimates: true`` gives every aid job ``--estimates-out`` and the
    estimates table as an output (a target of the default run); off by default."""
    import helpers as W

    cfg = {**W.TINY, "gnss": {"enabled": True}, "scenarios": {"outages_s": [60]}}
    W.write_config(tmp_path, cfg)
    proc = W.snakemake(tmp_path, "-n", "-p", "-j1")
    assert proc.returncode == 0 and "--estimates-out" not in proc.stdout
    W.write_config(tmp_path, {**cfg, "aided": {"estimates": True}})
    proc = W.snakemake(tmp_path, "-n", "-p", "-j1")
    out = proc.stdout
    assert proc.returncode == 0, proc.stderr
    n_aid = out.count("imugen aid ")
    assert n_aid > 0 and out.count("--estimates-out=") == n_aid
    assert "/estimates/" in out
    # a learner's files per shard (aided.learned_in): an input of the aid jobs, passed on
    tmpl = "learned/{route}/{grade}/shard-{shard}.parquet"
    W.write_config(tmp_path, {**cfg, "aided": {"learned_in": tmpl}})
    proc = W.snakemake(tmp_path, "-n", "-p", "-j1")
    assert proc.returncode != 0 and "learned/" in proc.stdout + proc.stderr  # missing input
    for route in cfg["routes"]:
        for grade in cfg["grades"]:
            for s in range(cfg["simulate"]["sequences"] // cfg["simulate"]["sequences_per_shard"]):
                f = tmp_path / tmpl.format(route=route, grade=grade, shard=f"{s:03d}")
                f.parent.mkdir(parents=True, exist_ok=True)
                f.write_bytes(b"")
    proc = W.snakemake(tmp_path, "-n", "-p", "-j1")
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.count("--learned-in=learned/") == proc.stdout.count("imugen aid ") > 0


def test_loader_serves_the_filter_aware_target_and_the_estimates(scene):
    """``target="filter_aware_error"`` = the effective error minus what the filter removed from
    each increment (its ``--correction-out``), NaN before its first epoch; the ``filter`` and
    ``filter_sd`` extras hold the table's rows (absent states read 0)."""
    shard = scene / "car" / "imu" / "consumer" / "shard-001.parquet"
    route = RouteFiles("car", scene / "truth.parquet", (shard,), "consumer")
    W = 500
    ds = WindowDataset([route], window=W, target="filter_aware_error", dtype=np.float64,
                       extras=["filter", "filter_sd"], cache_dir=scene / "cache")  # fmt: skip
    eff = WindowDataset([route], window=W, target="effective_error", dtype=np.float64,
                        cache_dir=scene / "cache")  # fmt: skip
    sh = tshard.read(shard).to_pandas()
    ids = sh["sequence"].unique()
    K = ttruth.read(scene / "truth.parquet").K
    cth, cdv = tcorr.arrays(scene / "c.parquet", ids, K)
    corr = np.concatenate([cth, cdv], -1)
    idx = np.arange(len(ds))
    _x, y, ex = ds.get_batch(idx)
    _, y_eff = eff.get_batch(idx)
    e = test_.read(scene / "e.parquet")
    for b in idx:
        info = ds.window_info(int(b))
        s = int(np.flatnonzero(ids == info["sequence"])[0])
        rows = np.arange(info["start"], info["stop"])
        k0 = int(e.loc[e["sequence"] == info["sequence"], "sample"].min())
        on = rows > k0
        assert np.isnan(y[b, ~on]).all()
        want = y_eff[b, on] - corr[s, rows[on]]
        np.testing.assert_allclose(y[b, on], want, rtol=0, atol=2e-6 * np.abs(corr).max())
    # the filter removes most of the effective error (velocity part) once it runs
    late = np.isfinite(y[..., 3])
    assert np.sqrt(np.mean(y[..., 3:][late] ** 2)) < 0.5 * np.sqrt(
        np.mean(y_eff[..., 3:][late] ** 2)
    )
    cols = ds.extra_columns["filter"]
    f = ex["filter"]
    valid = f[..., cols.index("filter_valid")] == 1
    assert valid.mean() > 0.8
    assert np.all(f[..., cols.index("gyro_sf_x")][valid] == 0.0)  # no scale-factor state
    assert np.abs(f[..., cols.index("gyro_bias_z_radps")][valid]).max() > 0
    sd = ex["filter_sd"][..., ds.extra_columns["filter_sd"].index("sd_att_u_rad")]
    assert np.all(sd[valid] > 0)


def test_the_how_to_example_runs(tmp_path, monkeypatch):
    """The runnable example of docs/how-to/plug-a-learner.md, executed as written: the learned
    velocity shrinks every sequence's drift at the end of the outage."""
    import contextlib
    import io
    import re

    from helpers import REPO

    page = (REPO / "docs" / "how-to" / "plug-a-learner.md").read_text()
    block = page.split("A runnable example", 1)[1]
    code = re.search(r"```python\n(.*?)```", block, re.S).group(1)
    monkeypatch.setattr("tempfile.mkdtemp", lambda: str(tmp_path))
    out = io.StringIO()
    ns = {}
    with contextlib.redirect_stdout(out):
        exec(compile(code, "plug-a-learner.md", "exec"), ns)
    assert np.all(ns["drift"](tmp_path / "a2.parquet") < ns["drift"](tmp_path / "a.parquet"))
    assert "(B, 200, 6)" not in out.getvalue()  # real shapes printed
    assert ns["ex"]["filter"].shape[-1] == len(test_.NAV) + len(test_.VALUES) + 3
