"""The stream's filter targets (issue 26): the aided filter's held estimates and the
filter-aware target of exact-mode sequences equal the written path's (the aid stage with
``--estimates-out`` on the same shard keys, read through the loader)."""

import numpy as np
import pandas as pd
import pytest

from imugen import truth as T
from imugen.aid import stage as AID
from imugen.core.errors import InputError
from imugen.dataset import RouteFiles, WindowDataset
from imugen.stream import Stream
from imugen.tables import layout
from imugen.tables import truth as ttruth

from helpers import simulate_shard

OUTAGE = {"kind": "outage", "start_s": 30.0, "duration_s": 15.0}
SEED, SHARD, SIZE, W = 5, 1, 2, 400


MOUNT = {"misalignment_sd_deg": 2.0, "lever_arm_m": [0.4, -0.2, 0.6]}


@pytest.fixture(scope="module", params=[None, MOUNT], ids=["rigid", "mounted"])
def scene(tmp_path_factory, request):
    """A short car truth (flat, 100 Hz), a consumer shard of 2 sequences in the results layout
    (the IMU on the vehicle, or mounted with a drawn misalignment and lever arm), the aid
    stage run on it with the estimates written beside it."""
    d = tmp_path_factory.mktemp("sfilt")
    pts = np.array([[0, 0, 0], [300, 0, 0], [300, 150, 0], [0, 150, 0]], float)
    enu = pd.DataFrame(pts, columns=["e_m", "n_m", "u_m"])
    meta = {"origin": {"lat_deg": 45.0, "lon_deg": 7.0, "alt_m": 200.0}, "timed": False}
    df, tm = T.build_truth(enu, meta, rate_hz=100.0, earth="flat", vehicle="car", verbose=False)
    ttruth.write(df, tm, d / "truth.parquet")
    shard = d / "car" / "imu" / "consumer" / "shard-001.parquet"
    shard.parent.mkdir(parents=True)
    simulate_shard(d / "truth.parquet", shard, "consumer", sequences=SIZE, seed=SEED,
                   shard=SHARD, shard_size=SIZE, route="car", series=True,
                   mounting=request.param)  # fmt: skip
    est = layout.beside(shard, "estimates")
    est.parent.mkdir(parents=True)
    AID.run(d / "truth.parquet", shard, d / "g.parquet", d / "a.parquet",
            AID.AidOptions(intervals=(OUTAGE,)), out_estimates=est)  # fmt: skip
    return d, shard, request.param


def test_stream_filter_targets_are_the_written_path(scene, monkeypatch):
    """Bit for bit with the written path; with the gnss target too, each sequence's GNSS is
    drawn once (shared by both targets)."""
    from imugen.stream import gnss as SG

    d, shard, mount = scene
    calls = []
    draw = SG.sequence_gnss
    monkeypatch.setattr(SG, "sequence_gnss", lambda *a, **k: calls.append(a) or draw(*a, **k))
    ds = WindowDataset([RouteFiles("car", d / "truth.parquet", (shard,), "consumer")], window=W,
                       target="filter_aware_error", extras=["filter", "filter_sd"],
                       cache_dir=d / "cache")  # fmt: skip
    idx = np.arange(len(ds))
    _, y, ex = ds.get_batch(idx)
    info = [ds.window_info(int(i)) for i in idx]
    st = Stream({"car": d / "truth.parquet"}, "consumer", window=W, batch_size=SIZE,
                windows_per_sequence=1, seed=SEED, exact=True, shard_size=SIZE,
                targets=["filter", "filter_sd", "filter_aware_error", "gnss"],
                gnss={"intervals": (OUTAGE,)}, mounting=mount)  # fmt: skip
    j = np.array([i["sequence"] & ((1 << 31) - 1) for i in info]) - SHARD * SIZE
    keys = st.keys("car", "consumer", SHARD, j, [i["start"] for i in info])
    out = st.generate(keys)
    assert len(calls) == len(set(j))  # one GNSS draw per sequence
    assert st.filter_columns == ds.extra_columns
    for n in ("filter", "filter_sd"):
        assert out[n].shape == ex[n].shape and out[n].dtype == np.float32
        np.testing.assert_array_equal(out[n], ex[n])
    fa = out["filter_aware_error"]
    assert np.isnan(fa).any() and np.isfinite(fa).mean() > 0.5  # NaN before the first epoch
    np.testing.assert_array_equal(fa, y)
    valid = ex["filter"][..., ds.extra_columns["filter"].index("filter_valid")] == 1
    assert valid.mean() > 0.5


def test_filter_targets_outside_exact_mode_are_refused_in_one_line(scene):
    d = scene[0]
    for kw in ({}, {"exact": True, "inputs": "rates"}):
        with pytest.raises(InputError) as e:
            Stream({"car": d / "truth.parquet"}, "consumer", window=W, batch_size=2,
                   windows_per_sequence=1, targets=["filter_aware_error"], **kw)  # fmt: skip
        assert "\n" not in str(e.value)
    st = Stream({"car": d / "truth.parquet"}, "consumer", window=W, batch_size=2,
                windows_per_sequence=1, targets=["filter"], exact=True)  # fmt: skip
    with pytest.raises(InputError, match="exact=True") as e:
        st.generate(st.keys("car", "consumer", 0, 0, 1), exact=False)
    assert "\n" not in str(e.value)
