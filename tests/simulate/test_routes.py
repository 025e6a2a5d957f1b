"""Independent randomness per route: spawn keys, sequence ids, path-independent shard bytes."""

import hashlib
import os

import numpy as np
import pandas as pd
import pytest

from imugen.core.errors import InputError
from imugen.core.seeding import SENSOR_STREAMS
from imugen.simulate import stage as S
from imugen.simulate.plan import enabled_terms
from imugen.tables import shard as tshard

from helpers import simulate_shard

KW = {"static_s": 1.0, "rate_hz": 50.0}
ROUTES = ("paper", "example", "city-loop", "")


def test_route_id_is_the_documented_hash():
    for name in ("paper", "Zürich", ""):
        digest = hashlib.sha256(name.encode("utf-8")).digest()
        assert tshard.route_id(name) == int.from_bytes(digest[:4], "big")
    assert tshard.route_id("paper") != tshard.route_id("paper2")
    rid, idx = tshard.split_ids(tshard.sequence_ids(2**32 - 1, [0, 2**31 - 1]))
    assert rid.tolist() == [2**32 - 1] * 2 and idx.tolist() == [0, 2**31 - 1]
    assert tshard.sequence_ids(2**32 - 1, 2**31 - 1) == 2**63 - 1  # fits int64


def test_no_two_route_grade_sequence_share_a_draw():
    """Every (route, grade, sequence) has its own parameters and noise; ids unique per grade."""
    draws = {}
    ids = {}
    for grade in ("consumer", "tactical"):
        for route in ROUTES:
            for shard in (0, 1):
                sh = S.simulate(None, grade, sequences=3, seed=9, shard=shard, route=route, **KW)
                for j in range(3):
                    key = (route, grade, int(sh.labels["sequence"][j]))
                    # turn-on bias draw and the first noisy increments identify the draw
                    draws[key] = np.concatenate(
                        [sh.gyro.b_on[j], sh.accel.b_on[j], sh.data["dtheta"][j, 1:4].ravel()]
                    )
                    ids.setdefault(grade, []).append(key[2])
    assert len(draws) == 2 * len(ROUTES) * 2 * 3
    rows = np.array(list(draws.values()))
    assert len({r.tobytes() for r in rows}) == len(rows)  # no draw repeated anywhere
    # no shared component either: the first noisy increments (white noise, present in every
    # grade; some presets have no turn-on bias) differ between every pair of draws
    b = {r[6:].tobytes() for r in rows}
    assert len(b) == len(rows)
    for grade, got in ids.items():
        assert len(set(got)) == len(got), grade  # unique across routes within a grade
    # the same (route, index) has the same id in another grade
    assert sorted(ids["consumer"]) == sorted(ids["tactical"])


def test_a_route_never_depends_on_other_routes_or_shards():
    alone = S.simulate(None, "industrial", sequences=2, seed=4, shard=2, route="paper", **KW)
    for route in ("b", "paper", "c"):  # other routes generated before and after
        other = S.simulate(None, "industrial", sequences=2, seed=4, shard=2, route=route, **KW)
        same = route == "paper"
        for name in alone.data:
            assert np.array_equal(alone.data[name], other.data[name]) == same
    for k in range(4, -1, -1):  # more shards, another order
        S.simulate(None, "industrial", sequences=2, seed=4, shard=k, route="paper", **KW)
    again = S.simulate(None, "industrial", sequences=2, seed=4, shard=2, route="paper", **KW)
    for name in alone.data:
        np.testing.assert_array_equal(alone.data[name], again.data[name])
    pd.testing.assert_frame_equal(alone.labels, again.labels)


def test_spawn_key_names_route_grade_shard_sequence_stream():
    sh = S.simulate(None, "consumer", sequences=1, seed=3, shard=5, route="r", **KW)
    rid = tshard.route_id("r")
    assert sh.meta["spawn_key"] == [rid, sh.meta["grade"]["id"], 5]
    # the parameter draw is exactly the documented child seed sequence
    ss = np.random.SeedSequence(
        3, spawn_key=(rid, sh.meta["grade"]["id"], 5, 0, SENSOR_STREAMS["params"])
    )
    rng = np.random.Generator(np.random.PCG64(ss))
    from imugen.sensors.grades import get_grade
    from imugen.sensors.model import draw_sensor

    grade = get_grade("consumer")
    enabled = enabled_terms(grade)
    p = draw_sensor(grade.gyro, rng, enabled["gyro"])
    np.testing.assert_array_equal(p.b_on[0], sh.gyro.b_on[0])


def _truth_file(path):
    K = 101
    t = np.arange(K) * 0.01
    cols = {"time_s": t}
    for name, v in (("gyro", (0, 0, 0.1)), ("accel", (0, 0, 9.8))):
        unit = "radps" if name == "gyro" else "mps2"
        for a, x in zip("xyz", v, strict=True):
            cols[f"{name}_{a}_{unit}"] = np.full(K, x)
    for name, v in (("dtheta", (0, 0, 0.001)), ("dv", (0, 0, 0.098))):
        unit = "rad" if name == "dtheta" else "mps"
        for a, x in zip("xyz", v, strict=True):
            cols[f"{name}_{a}_{unit}"] = np.r_[0.0, np.full(K - 1, x)]
    path.parent.mkdir(parents=True)
    pd.DataFrame(cols).to_parquet(path)


def test_shard_bytes_do_not_depend_on_how_the_truth_path_is_spelled(tmp_path, monkeypatch):
    truth = tmp_path / "myroute" / "truth.parquet"
    _truth_file(truth)
    monkeypatch.chdir(tmp_path)
    a = simulate_shard(truth.resolve(), tmp_path / "a.parquet", "consumer", sequences=2, seed=1)
    b = simulate_shard(
        os.path.join("myroute", "..", "myroute", "truth.parquet"),
        tmp_path / "b.parquet",
        "consumer",
        sequences=2,
        seed=1,
    )
    assert a["route"] == b["route"] == "myroute"  # default: the truth's folder name
    assert a["truth"]["file"] == "truth.parquet" and "path" not in a["truth"]
    # the shard and labels bytes are identical once each is written under the same name
    simulate_shard(
        "myroute/truth.parquet", tmp_path / "x" / "s.parquet", "consumer", sequences=2, seed=1
    )
    simulate_shard(truth.resolve(), tmp_path / "y" / "s.parquet", "consumer", sequences=2, seed=1)
    for name in ("s.parquet", "s.labels.parquet"):
        assert (tmp_path / "x" / name).read_bytes() == (tmp_path / "y" / name).read_bytes()


def test_route_option_and_errors(tmp_path):
    truth = tmp_path / "r1" / "truth.parquet"
    _truth_file(truth)
    m = simulate_shard(
        truth, tmp_path / "s.parquet", "consumer", sequences=1, seed=1, route="other"
    )
    assert m["route"] == "other" and m["route_id"] == tshard.route_id("other")
    with pytest.raises(InputError, match="--route"):
        S.simulate(None, "consumer", route=3, **KW)
