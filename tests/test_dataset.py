"""Training windows and leakage-safe splits, on small synthetic Parquet files."""

from __future__ import annotations

import pickle

import numpy as np
import pandas as pd
import pyarrow.parquet as pq
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from imugen import dataset as ds
from imugen.core.errors import InputError
from imugen.core.io import write_parquet
from imugen.tables import truth as col

K, M = 101, 3
BIAS = list(ds.BIAS)


def make_results(
    tmp,
    routes=("alpha", "beta"),
    shards=(0, 1),
    grade="consumer",
    rows_per_group=40,
    statistics=True,
    seed=0,
):
    """results/<route>/truth.parquet and imu/<grade>/shard-*.parquet (+ a labels file)."""
    rng = np.random.default_rng(seed)
    frames = {}
    for r in routes:
        truth = pd.DataFrame({c: rng.standard_normal(K) for c in col.COLUMNS})
        truth[col.TIME] = np.arange(K) * 0.01
        write_parquet(
            truth, {"rate_hz": 100.0}, tmp / r / "truth.parquet", row_group_size=rows_per_group
        )
        parts = []
        for sh in shards:
            ids = sh * M + np.arange(M)
            df = pd.DataFrame(
                {
                    "sequence": np.repeat(ids, K).astype(np.int32),
                    col.TIME: np.tile(truth[col.TIME].to_numpy(), M),
                }
            )
            for c in [*col.DTHETA, *col.DV, *BIAS, *ds.EFFECTIVE_ERROR["increments"]]:
                df[c] = rng.standard_normal(M * K).astype(np.float32)
            p = tmp / r / "imu" / grade / f"shard-{sh:03d}.parquet"
            write_parquet(
                df,
                {"grade": {"name": grade}},
                p,
                row_group_size=rows_per_group,
                write_statistics=statistics,
            )
            lab = pd.DataFrame({"sequence": ids.astype(np.int32)})
            lab["lab_a"], lab["lab_b"] = ids * 1.5, -ids.astype(float)
            write_parquet(
                lab,
                {},
                p.with_name(f"shard-{sh:03d}.labels.parquet"),
            )
            parts.append(df)
        frames[r] = (truth, pd.concat(parts, ignore_index=True))
    return frames


def expected_windows(routes, frames, window, stride, keys=None):
    """(route, sequence, k0) of every window, in the documented order, by brute force."""
    out = []
    for r in routes:
        for p in r.shards:
            for sid in pd.read_parquet(p, columns=["sequence"])["sequence"].unique():
                if keys is not None and (r.name, int(sid)) not in keys:
                    continue
                for k0 in range(1, K, stride):
                    if k0 + window <= K:
                        out.append((r.name, int(sid), k0))
    return out


# --- splits ------------------------------------------------------------------------------------
def all_keys(nroutes=20, nseq=500):
    """Keys with globally unique sequence ids, as route-keyed seeds make them."""
    return [(f"route{r}", 10_000 * r + s) for r in range(nroutes) for s in range(nseq)]


def test_split_deterministic_disjoint_and_complete():
    keys = all_keys()
    a = ds.split(keys, seed=3)
    assert a == ds.split(keys, seed=3)
    assert sum(len(v) for v in a.values()) == len(keys)
    assert set(a["train"]).isdisjoint(a["val"]) and set(a["val"]).isdisjoint(a["test"])
    assert set().union(*map(set, a.values())) == set(keys)
    # shares close to the fractions on 10,000 keys (binomial sd ~0.004)
    assert abs(len(a["train"]) / len(keys) - 0.8) < 0.02
    assert abs(len(a["test"]) / len(keys) - 0.1) < 0.02
    assert ds.split(keys, seed=4) != a


def test_split_stable_when_sequences_and_routes_are_added():
    small = all_keys(5, 100)
    big = all_keys(8, 300)
    fr = {"train": 0.5, "val": 0.25, "test": 0.25}
    for by in ("sequence", "route"):
        a = ds.split(small, fr, seed=1, by=by)
        b = ds.split(big, fr, seed=1, by=by)
        if by == "sequence":  # 500 units: no part empty, no repair
            for name in fr:
                assert set(a[name]) == set(b[name]) & set(small)
        else:  # 5 routes: at most one route borrowed per part the hash left empty
            moved = {r for name in fr for r, _ in set(a[name]) - set(b[name])}
            assert len(moved) <= 2


def test_split_by_route_keeps_routes_whole():
    keys = [(f"route{r}", 1000 * r + s) for r in range(40) for s in range(30)]
    parts = ds.split(keys, seed=0, by="route")
    where = {}
    for name, ks in parts.items():
        for r, _ in ks:
            where.setdefault(r, set()).add(name)
    assert all(len(v) == 1 for v in where.values()) and len(where) == 40
    assert len({next(iter(v)) for v in where.values()}) == 3  # 40 routes reach all parts
    # by sequence, a route's sequences spread over the parts
    seq_parts = ds.split(keys, seed=0, by="sequence")
    assert {n for n, ks in seq_parts.items() if any(r == "route0" for r, _ in ks)} == set(parts)


def test_split_never_leaves_a_part_empty_with_enough_units():
    keys = [(f"r{r}", 100 * r + s) for r in range(4) for s in range(5)]
    for seed in range(200):
        parts = ds.split(keys, seed=seed, by="route")
        assert all(parts.values()), seed
    # a zero fraction stays empty; three sequences fill three parts
    parts = ds.split(keys, {"train": 0.9, "val": 0.1, "test": 0.0}, seed=3, by="route")
    assert parts["test"] == [] and parts["val"]
    parts = ds.split([("a", 0), ("a", 1), ("a", 2)], seed=0)
    assert sorted(len(v) for v in parts.values()) == [1, 1, 1]


def test_split_repair_moves_only_units_of_an_empty_part():
    # a unit keeps its hash part (the one it has among many units, where no part is empty)
    # unless it was borrowed to fill an otherwise empty part: at most one unit per part
    fr = {"train": 0.98, "val": 0.01, "test": 0.01}
    big_keys = [(f"r{r}", r) for r in range(2000)]
    big = ds.split(big_keys, fr, seed=0, by="route")
    hashed = {k: n for n, ks in big.items() for k in ks}
    for n in range(3, 40):
        parts = ds.split(big_keys[:n], fr, seed=0, by="route")
        assert all(parts.values())
        moved = [k for name, ks in parts.items() for k in ks if hashed[k] != name]
        empty = sum(not any(hashed[k] == name for k in big_keys[:n]) for name in fr)
        assert len(moved) == empty


def test_split_refuses_too_few_units():
    with pytest.raises(InputError, match=r"3 non-empty parts .* need at least 3 routes"):
        ds.split([("a", 0), ("b", 1)], seed=0, by="route")
    with pytest.raises(InputError, match="need at least 3 sequences"):
        ds.split([("a", 0), ("a", 1)], seed=0)


def test_split_named_routes():
    keys = [(f"r{r}", 10 * r + s) for r in range(6) for s in range(10)]
    parts = ds.split(keys, seed=0, by="route", holdout_routes=["r2"], val_routes=["r4", "r5"])
    assert {r for r, _ in parts["test"]} == {"r2"}
    assert {r for r, _ in parts["val"]} == {"r4", "r5"}
    assert {r for r, _ in parts["train"]} == {"r0", "r1", "r3"}
    # by sequence: the held-out route whole in test, the others cut into train and val
    parts = ds.split(keys, seed=0, holdout_routes="r2")
    assert {r for r, _ in parts["test"]} == {"r2"} and len(parts["test"]) == 10
    assert parts["val"] and {r for r, _ in parts["train"] + parts["val"]} == set(
        "r0 r1 r3 r4 r5".split()
    )
    with pytest.raises(InputError, match="r9 hold no keys"):
        ds.split(keys, holdout_routes=["r9"])
    with pytest.raises(InputError, match="given for test and val"):
        ds.split(keys, holdout_routes=["r1"], val_routes=["r1"])
    with pytest.raises(InputError, match="not among"):
        ds.split(keys, {"a": 0.5, "b": 0.5}, holdout_routes=["r1"])


def test_split_with_a_held_out_route_tests_unseen_draws_of_seen_routes():
    keys = [(f"r{r}", 100 * r + s) for r in range(6) for s in range(50)]
    parts = ds.split(keys, seed=0, holdout_routes=["r2"])
    assert list(parts) == ["train", "val", "test", ds.SEEN_TEST]
    assert {r for r, _ in parts["test"]} == {"r2"} and len(parts["test"]) == 50
    seen = parts[ds.SEEN_TEST]
    assert 10 <= len(seen) <= 40  # ~10 % of the 250 draws of the other routes
    assert {r for r, _ in seen} <= {r for r, _ in parts["train"]}  # trajectories trained on
    assert not {s for _, s in seen} & {s for n in ("train", "val") for _, s in parts[n]}
    # a draw's part depends on the draw only: holding out r3 too only moves r3's draws
    more = ds.split(keys, seed=0, holdout_routes=["r2", "r3"])[ds.SEEN_TEST]
    assert more == [k for k in seen if k[0] != "r3"]
    off = ds.split(keys, seed=0, holdout_routes=["r2"], seen_test=False)
    assert list(off) == ["train", "val", "test"]
    assert ds.SEEN_TEST not in ds.split(keys, seed=0, by="route", holdout_routes=["r2"])


def test_split_warns_on_draws_shared_across_routes():
    keys = [(f"r{r}", s) for r in range(6) for s in range(3)]  # legacy: same ids on every route
    with pytest.warns(UserWarning, match="share those error draws"):
        ds.split(keys, seed=0, by="route")
    parts = ds.split(keys, seed=0, by="sequence")  # ids are the units: a draw stays together
    assert all(len({s for _, s in v}) == len(v) // 6 for v in parts.values())


route_names = st.sampled_from([f"route{i}" for i in range(7)])


@settings(max_examples=150, deadline=None)
@given(
    routes=st.lists(route_names, min_size=1, max_size=7, unique=True),
    nseq=st.integers(1, 6),
    seed=st.integers(0, 10**6),
    by=st.sampled_from(["sequence", "route"]),
    hold=st.booleans(),
    fr=st.sampled_from(
        [None, {"train": 0.6, "val": 0.2, "test": 0.2}, {"train": 0.9, "test": 0.1}]
    ),
)
def test_split_properties(routes, nseq, seed, by, hold, fr):
    # globally unique ids, one per draw (route-keyed seeds)
    keys = [(r, 100 * i + s) for i, r in enumerate(routes) for s in range(nseq)]
    holdout = routes[:1] if hold and len(routes) > 1 and (fr is None or "test" in fr) else None
    names = list(fr or ds.DEFAULT_FRACTIONS)
    free = [n for n in names if not (holdout and n == "test")]
    if holdout and by == "sequence":  # the test share of the other routes: unseen draws
        names.append(ds.SEEN_TEST)
        free.append(ds.SEEN_TEST)
    rest = [k for k in keys if not holdout or k[0] not in holdout]
    units = {k[0] if by == "route" else k[1] for k in rest}
    if len(units) < len(free):
        with pytest.raises(InputError, match="need at least"):
            ds.split(keys, fr, seed=seed, by=by, holdout_routes=holdout)
        return
    parts = ds.split(keys, fr, seed=seed, by=by, holdout_routes=holdout)
    assert list(parts) == names and all(parts.values())
    assert sorted(k for v in parts.values() for k in v) == sorted(keys)
    draw_part, route_part = {}, {}
    for name, ks in parts.items():
        for r, s in ks:
            assert draw_part.setdefault(s, name) == name  # no draw in two parts
            route_part.setdefault(r, set()).add(name)
    if by == "route" or holdout:
        for r in holdout or []:
            assert route_part[r] == {"test"}
    if by == "route":
        assert all(len(v) == 1 for v in route_part.values())  # no route in two parts
    assert parts == ds.split(keys, fr, seed=seed, by=by, holdout_routes=holdout)


# --- dataset -----------------------------------------------------------------------------------
@pytest.fixture
def results(tmp_path):
    frames = make_results(tmp_path)
    return tmp_path, frames


def test_find_routes_and_keys(results):
    root, _ = results
    routes = ds.find_routes(root, "consumer")
    assert [r.name for r in routes] == ["alpha", "beta"]
    assert all(len(r.shards) == 2 and not any("labels" in p.name for p in r.shards) for r in routes)
    assert ds.find_routes(root, "tactical") == []
    keys = ds.sequence_keys(routes)
    assert keys == [(r, s) for r in ("alpha", "beta") for s in range(2 * M)]


@pytest.mark.parametrize(("window", "stride"), [(10, 10), (7, 3), (100, 1), (101, 5)])
def test_windows_are_the_right_slices(results, window, stride):
    root, frames = results
    routes = ds.find_routes(root, "consumer")
    d = ds.WindowDataset(routes, window=window, stride=stride)
    exp = expected_windows(routes, frames, window, stride)
    assert len(d) == len(exp)
    for i in range(0, len(d), max(1, len(d) // 40)):
        r, sid, k0 = exp[i]
        info = d.window_info(i)
        assert (info["route"], info["sequence"], info["start"], info["stop"]) == (
            r,
            sid,
            k0,
            k0 + window,
        )
        truth, shard = frames[r]
        rows = shard[shard["sequence"] == sid].iloc[k0 : k0 + window]
        x, y = d[i]
        assert x.dtype == np.float32 and x.shape == (window, 6) and y.shape == (window, 6)
        np.testing.assert_array_equal(x, rows[[*col.DTHETA, *col.DV]].to_numpy())
        np.testing.assert_array_equal(
            y, truth[[*col.DTHETA, *col.DV]].iloc[k0 : k0 + window].to_numpy().astype(np.float32)
        )
    with pytest.raises(IndexError):
        d[len(d)]


def test_delta_and_bias_targets(results):
    root, frames = results
    routes = ds.find_routes(root, "consumer")
    dv = ds.WindowDataset(routes, window=25, stride=20, target="delta_vel_pos", dtype=np.float64)
    db = ds.WindowDataset(routes, window=25, stride=20, target="bias")
    de = ds.WindowDataset(routes, window=25, stride=20, target="effective_error")
    assert len(dv) == len(db) == 4 * M * 4  # k0 = 1, 21, 41, 61
    for i in range(len(dv)):
        info = dv.window_info(i)
        truth, shard = frames[info["route"]]
        k0, k1 = info["start"], info["stop"]
        _, y = dv[i]
        vp = truth[[*col.VEL, *col.POS]].to_numpy()
        np.testing.assert_array_equal(y, vp[k1 - 1] - vp[k0 - 1])
        _, b = db[i]
        rows = shard[shard["sequence"] == info["sequence"]].iloc[k0:k1]
        np.testing.assert_array_equal(b, rows[BIAS].to_numpy())
        x, err = de[i]
        np.testing.assert_array_equal(err, rows[list(ds.EFFECTIVE_ERROR["increments"])])
        np.testing.assert_array_equal(x, rows[[*col.DTHETA, *col.DV]])


def test_keys_select_whole_sequences(results):
    root, frames = results
    routes = ds.find_routes(root, "consumer")
    parts = ds.split(ds.sequence_keys(routes), {"a": 0.5, "b": 0.5}, seed=2)
    full = ds.WindowDataset(routes, window=20, stride=10)
    sub = {n: ds.WindowDataset(routes, window=20, stride=10, keys=k) for n, k in parts.items()}
    assert sum(len(s) for s in sub.values()) == len(full)
    seen = {}
    for n, s in sub.items():
        exp = expected_windows(routes, frames, 20, 10, keys=set(parts[n]))
        assert len(s) == len(exp)
        for i in range(len(s)):
            info = s.window_info(i)
            seen.setdefault((info["route"], info["sequence"]), set()).add(n)
            assert (info["route"], info["sequence"], info["start"]) == exp[i]
    assert all(len(v) == 1 for v in seen.values())


def test_shard_cache_built_once_and_rebuilt_when_the_shard_changes(results, monkeypatch):
    root, _ = results
    routes = ds.find_routes(root, "consumer")
    ds.WindowDataset(routes, window=10)
    caches = sorted((root / "alpha" / "imu" / "consumer" / ds.CACHE_DIR).glob("*.npy"))
    assert len(caches) == 2  # one per shard, for the input columns
    reads = []
    orig = pq.ParquetFile.read_row_group

    def counting(self, *args, **kwargs):
        reads.append(self.metadata.num_rows)
        return orig(self, *args, **kwargs)

    monkeypatch.setattr(pq.ParquetFile, "read_row_group", counting)
    d = ds.WindowDataset(routes, window=10)
    assert reads == []  # warm: no Parquet decoded
    shard = routes[0].shards[0]
    df = pd.read_parquet(shard)
    df[col.DTHETA[0]] = 7.0
    write_parquet(df, {"grade": {"name": "consumer"}}, shard)
    d = ds.WindowDataset(routes, window=10)
    # the rewritten shard only (one row group), and its stale cache is gone
    assert reads == [M * K]
    assert len(list(caches[0].parent.glob("*.npy"))) == 2
    assert (d[0][0][:, 0] == 7.0).all()
    # another column group has its own cache beside
    ds.WindowDataset(routes, window=10, target="bias")
    assert len(list(caches[0].parent.glob("*.npy"))) == 4


@pytest.mark.parametrize(
    "target", ["increments", "effective_error", "bias", "delta_vel_pos", "lab_b"]
)
def test_batches_in_memory_and_from_disk_equal_the_items(results, target, tmp_path):
    root, _ = results
    routes = ds.find_routes(root, "consumer")
    keys = ds.sequence_keys(routes)[::2]
    kw = {"window": 20, "stride": 7, "keys": keys, "target": target, "cache_dir": tmp_path / "c"}
    disk = ds.WindowDataset(routes, **kw)
    mem = ds.WindowDataset(routes, in_memory=True, **kw)
    assert len(disk) == len(mem) > 0
    batches = disk.batches(16, seed=5)
    assert np.array_equal(np.sort(np.concatenate(batches)), np.arange(len(disk)))
    assert [len(b) for b in disk.batches(16, seed=5, drop_last=True)] == [16] * (len(disk) // 16)
    assert all(np.array_equal(a, b) for a, b in zip(batches, disk.batches(16, seed=5), strict=True))
    # batches mix sequences: the first batch draws from many of them
    info = [disk.window_info(i) for i in batches[0]]
    assert len({(w["route"], w["sequence"]) for w in info}) >= 4  # of 6
    for idx in batches[:3]:
        xd, yd = disk[idx]
        xm, ym = mem.get_batch(idx)
        assert xd.shape == (len(idx), 20, 6) and xd.dtype == np.float32
        np.testing.assert_array_equal(xd, xm)
        np.testing.assert_array_equal(yd, ym)
        for j, i in enumerate(idx):
            x1, y1 = disk[int(i)]
            np.testing.assert_array_equal(x1, xd[j])
            np.testing.assert_array_equal(y1, yd[j])


def test_label_target_is_the_sequence_scalar(tmp_path):
    frames = make_results(tmp_path, routes=("gamma",), shards=(0, 1))
    routes = ds.find_routes(tmp_path, "consumer")
    d = ds.WindowDataset(routes, window=50, stride=25, target=["lab_a", "lab_b"], dtype=np.float64)
    for i in range(len(d)):
        sid = d.window_info(i)["sequence"]
        np.testing.assert_array_equal(d[i][1], [sid * 1.5, -sid])
    assert frames
    with pytest.raises(InputError, match="no label column"):
        ds.WindowDataset(routes, window=50, target="nope")


def test_one_cache_dir_serves_every_route(results, tmp_path):
    """Every route's first shard is shard-000: their caches must not replace each other."""
    root, _ = results
    routes = ds.find_routes(root, "consumer")
    cache = tmp_path / "shared-cache"
    d = ds.WindowDataset(routes, window=10, cache_dir=cache)
    assert len(list(cache.glob("*.npy"))) == 4  # 2 routes x 2 shards
    ds.WindowDataset(routes[1:], window=10, cache_dir=cache)  # another user of the folder
    e = pickle.loads(pickle.dumps(d))  # a DataLoader worker: reopens the caches
    x, _ = e.get_batch(np.arange(len(e)))
    np.testing.assert_array_equal(x, ds.WindowDataset(routes, window=10, in_memory=True)[
        np.arange(len(e))][0])  # fmt: skip


def test_pickles_without_the_maps(results):
    root, _ = results
    d = ds.WindowDataset(ds.find_routes(root, "consumer"), window=30, stride=15)
    blob = pickle.dumps(d)
    assert len(blob) < 20_000  # the memory maps are reopened, not copied
    e = pickle.loads(blob)
    for i in (0, 5, len(d) - 1):
        np.testing.assert_array_equal(d[i][0], e[i][0])
        np.testing.assert_array_equal(d[i][1], e[i][1])


def test_without_statistics_and_missing_columns(tmp_path):
    frames = make_results(tmp_path, routes=("gamma",), shards=(2,), statistics=False)
    routes = ds.find_routes(tmp_path, "consumer")
    assert ds.sequence_keys(routes) == [("gamma", 6), ("gamma", 7), ("gamma", 8)]
    d = ds.WindowDataset(routes, window=50, stride=50)
    assert len(d) == 3 * 2
    shard = frames["gamma"][1]
    np.testing.assert_array_equal(
        d[2][0], shard[shard["sequence"] == 7][[*col.DTHETA, *col.DV]].iloc[1:51].to_numpy()
    )
    with pytest.raises(InputError, match="lacks the columns gyro_x_radps"):
        ds.WindowDataset(routes, window=10, inputs="rates")


# --- optional epoch streams (GNSS, scenario labels, aided output) ------------------------------
EVERY, OUTAGE = 10, (40, 60)  # an epoch every 10 rows from row 3; no fix on rows [40, 60)


def make_epochs(tmp, routes=("alpha", "beta"), shards=(0, 1), grade="consumer", seed=1):
    """GNSS and aided tables beside the shards of :func:`make_results` (their contracts'
    writers), with an outage; returns ``{(route, sequence): (gnss rows, aided rows)}``."""
    from imugen.tables import aided as taided
    from imugen.tables import gnss as tgnss

    rng = np.random.default_rng(seed)
    out = {}
    for r in routes:
        for sh in shards:
            g_parts, a_parts = [], []
            for sid in sh * M + np.arange(M):
                kg = np.arange(3, K, EVERY)
                g = pd.DataFrame({c: rng.standard_normal(len(kg)) for c in tgnss.COLUMNS})
                g["sequence"], g[col.TIME] = sid, kg * 0.01
                lost = (kg >= OUTAGE[0]) & (kg < OUTAGE[1])
                g["fix"] = np.where(lost, 0, 1).astype(np.int8)
                g["state"] = np.where(lost, 1, 0).astype(np.int8)
                for c in (*tgnss.P, *tgnss.V, *tgnss.OFFSET_P, *tgnss.OFFSET_V):
                    g.loc[lost, c] = np.nan
                ka = np.r_[np.arange(25, K, 20), 59]  # aligned at row 25; an outage end at 59
                a = pd.DataFrame({c: rng.standard_normal(len(ka)) for c in taided.COLUMNS})
                a["sequence"], a[col.TIME] = sid, ka * 0.01
                a = a.sort_values(col.TIME)
                g_parts.append(g)
                a_parts.append(a)
                out[(r, int(sid))] = (g.assign(k=kg), a.assign(k=np.sort(ka)))
            name = f"shard-{sh:03d}.parquet"
            tgnss.write(
                pd.concat(g_parts), pd.DataFrame({"sequence": [0]}), pd.DataFrame({"kind": []}),
                {}, tmp / r / "gnss" / grade / name,
            )  # fmt: skip
            taided.write(pd.concat(a_parts), {}, tmp / r / "aided" / grade / name)
    return out


def _held(ks, vals, k, event=False):
    """Brute force: (values, valid, age_s) of a stream (epoch rows ``ks``, values ``vals``) at
    IMU row ``k``."""
    j = [n for n, ke in enumerate(ks) if ke <= k and (ke == k or not event)]
    if not j:
        return np.zeros(vals.shape[1]), 0.0, 0.0
    v = vals[j[-1]]
    ok = bool(np.isfinite(v).all())
    return (v if ok else np.zeros(len(v))), float(ok), (k - ks[j[-1]]) * 0.01 if ok else 0.0


@pytest.mark.parametrize("align", ["hold", "event"])
def test_extras_equal_the_tables_at_their_epochs(tmp_path, align):
    make_results(tmp_path)
    tables = make_epochs(tmp_path)
    routes = ds.find_routes(tmp_path, "consumer")
    d = ds.WindowDataset(
        routes, window=30, stride=23, extras=["gnss", "scenario", "aided"], extras_align=align,
        dtype=np.float64,
    )  # fmt: skip
    x, y, ex = d.get_batch(np.arange(len(d)))
    x2, y2 = ds.WindowDataset(routes, window=30, stride=23, dtype=np.float64).get_batch(
        np.arange(len(d))
    )
    np.testing.assert_array_equal(x, x2)  # the IMU windows and targets do not change
    np.testing.assert_array_equal(y, y2)
    assert d.extra_columns["gnss"][-3:] == ["gnss_new", "gnss_valid", "gnss_age_s"]
    saw_outage = False
    for i in range(len(d)):
        info = d.window_info(i)
        g, a = tables[(info["route"], info["sequence"])]
        streams = {
            n: (t["k"].to_numpy(), t[list(ds.EXTRAS[n].columns)].to_numpy(float))
            for n, t in (("gnss", g), ("scenario", g), ("aided", a))
        }
        for w, k in enumerate(range(info["start"], info["stop"])):
            for name, (ks, vals) in streams.items():
                v, valid, age = _held(ks, vals, k, event=align == "event")
                got = ex[name][i, w]
                np.testing.assert_allclose(got[: vals.shape[1]], v, atol=1e-12)
                assert got[-3] == float(k in ks)
                assert (got[-2], got[-1]) == pytest.approx((valid, age))
            # across the outage: the held GNSS epoch has no fix -> masked; its state is labelled
            kg = streams["gnss"][0]
            lost = k >= kg[0] and OUTAGE[0] <= kg[kg <= k].max() < OUTAGE[1]
            if lost and align == "hold":
                saw_outage = True
                assert ex["gnss"][i, w, -2] == 0 and not ex["gnss"][i, w, :-3].any()
                assert ex["scenario"][i, w, 0] == 1 and ex["scenario"][i, w, -2] == 1
    assert saw_outage or align == "event"
    # in memory: the same arrays; one window: the same third item
    m = ds.WindowDataset(
        routes, window=30, stride=23, extras=["gnss", "scenario", "aided"], extras_align=align,
        dtype=np.float64, in_memory=True,
    )  # fmt: skip
    _, _, exm = m.get_batch(np.arange(len(d)))
    for n in ex:
        np.testing.assert_array_equal(exm[n], ex[n])
    x0, y0, e0 = d[5]
    np.testing.assert_array_equal(x0, x[5])
    np.testing.assert_array_equal(y0, y[5])
    np.testing.assert_array_equal(e0["aided"], ex["aided"][5])


def test_extras_absent_unless_asked_and_clear_errors(tmp_path):
    make_results(tmp_path)
    routes = ds.find_routes(tmp_path, "consumer")
    d = ds.WindowDataset(routes, window=20)  # no GNSS or aided outputs exist: works as before
    assert len(d.get_batch([0, 1])) == 2 and len(d[0]) == 2 and d.extra_columns == {}
    with pytest.raises(InputError, match="no gnss table for this shard"):
        ds.WindowDataset(routes, window=20, extras=["gnss"])
    with pytest.raises(InputError, match="unknown stream"):
        ds.WindowDataset(routes, window=20, extras=["odometer_typo"])
    with pytest.raises(InputError, match="extras_align"):
        ds.WindowDataset(routes, window=20, extras=["gnss"], extras_align="nearest")
    make_epochs(tmp_path)
    # keys select sequences: only their epochs are read
    keys = [("alpha", 1)]
    d = ds.WindowDataset(routes, window=20, keys=keys, extras="gnss_offset")
    _, _, ex = d.get_batch(np.arange(len(d)))
    assert set(ex) == {"gnss_offset"} and ex["gnss_offset"].shape == (len(d), 20, 9)
    # an epoch off the IMU clock is refused
    from imugen.tables import aided as taided

    p = tmp_path / "alpha" / "aided" / "consumer" / "shard-000.parquet"
    a = taided.read(p)
    a.loc[0, col.TIME] += 0.004
    taided.write(a, {}, p)
    with pytest.raises(InputError, match="not an IMU sample time"):
        ds.WindowDataset(routes, window=20, extras=["aided"])


def test_companion_streams_each_hold_their_own_sensor(tmp_path):
    """Odometer and barometer share one long table (:mod:`imugen.tables.companions`): each
    stream holds its own sensor's epochs only (a barometer epoch never masks the odometer),
    and the error streams give the labelled true errors."""
    from imugen.tables import companions as tcomp

    make_results(tmp_path)
    rng = np.random.default_rng(3)
    truth = {}
    for sh in (0, 1):
        parts = []
        for sid in sh * M + np.arange(M):
            for code, every, first in ((tcomp.ODOMETER, 5, 2), (tcomp.BAROMETER, 7, 4)):
                k = np.arange(first, K, every)
                d = {c: np.full(len(k), np.nan) for c in tcomp.COLUMNS}
                d[tcomp.SEQUENCE], d[tcomp.TIME] = np.full(len(k), sid), k * 0.01
                d[tcomp.SENSOR] = np.full(len(k), code, np.int8)
                d[tcomp.ODO_TICKS] = rng.integers(0, 50, len(k)) if code == 1 else np.zeros(len(k))
                cols = tcomp.ODO_COLUMNS[1:] if code == 1 else tcomp.BARO_COLUMNS
                for c in cols:
                    d[c] = rng.standard_normal(len(k))
                df = pd.DataFrame(d)
                parts.append(df)
                truth[(int(sid), code)] = df.assign(k=k)
        df = pd.concat(parts, ignore_index=True).astype(
            {tcomp.SEQUENCE: np.int64, tcomp.SENSOR: np.int8, tcomp.ODO_TICKS: np.int64}
        )
        tcomp.write(
            df, pd.DataFrame({"sequence": [0]}), {},
            tmp_path / "alpha" / "companions" / "consumer" / f"shard-{sh:03d}.parquet",
        )  # fmt: skip
    routes = [r for r in ds.find_routes(tmp_path, "consumer") if r.name == "alpha"]
    names = ["odometer", "odometer_error", "barometer", "barometer_error"]
    d = ds.WindowDataset(routes, window=30, stride=23, extras=names, dtype=np.float64)
    _, _, ex = d.get_batch(np.arange(len(d)))
    for i in range(len(d)):
        info = d.window_info(i)
        for name, code in zip(names, (1, 1, 2, 2), strict=True):
            t = truth[(info["sequence"], code)]
            ks, vals = t["k"].to_numpy(), t[list(ds.EXTRAS[name].columns)].to_numpy(float)
            for w, k in enumerate(range(info["start"], info["stop"])):
                v, valid, age = _held(ks, vals, k)
                got = ex[name][i, w]
                np.testing.assert_allclose(got[: vals.shape[1]], v, atol=1e-12)
                assert (got[-2], got[-1]) == pytest.approx((valid, age))
