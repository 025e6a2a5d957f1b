"""imugen.stream: the shard path's numbers for the same keys, reserved keys, worker split."""

import numpy as np
import pytest

from imugen.core.errors import InputError
from imugen.simulate.plan import first_index
from imugen.stream import STREAM_SHARD0, Stream
from imugen.stream.keys import KEY_DTYPE
from imugen.tables import shard as tshard

from helpers import simulate_shard

SEED, ROUTE, W = 7, "oracle", 50


def moving_truth(K, dt=0.01):
    """A body turning and accelerating (sinusoids), as arrays of a truth table."""
    t = np.arange(K) * dt
    w = np.column_stack([0.3 * np.sin(0.7 * t), 0.2 * np.cos(0.5 * t), 0.4 + 0 * t])
    f = np.column_stack([1.5 * np.sin(0.3 * t), 0.8 * np.cos(0.9 * t), 9.8 + 0.5 * np.sin(t)])
    dth = np.vstack([np.zeros(3), 0.5 * (w[1:] + w[:-1]) * dt])
    dv = np.vstack([np.zeros(3), 0.5 * (f[1:] + f[:-1]) * dt])
    return {"time_s": t, "omega_ib_b": w, "f_b": f, "dtheta": dth, "dv": dv}


@pytest.fixture(scope="module")
def truth():
    return moving_truth(K=400)


def stream(truth, **kw):
    kw = {"window": W, "batch_size": 8, "windows_per_sequence": 4, "seed": SEED, **kw}
    return Stream({ROUTE: truth}, "consumer", **kw)


@pytest.mark.parametrize("outputs", ["increments", "rates"])
def test_exact_mode_is_the_written_shard_bit_for_bit(tmp_path, truth, outputs):
    out = tmp_path / "shard-003.parquet"
    simulate_shard(truth, str(out), "consumer", sequences=3, seed=SEED, shard=3, route=ROUTE,
                   outputs=outputs, series=True)  # fmt: skip
    cols = list(tshard.INCREMENTS if outputs == "increments" else tshard.RATES)
    err = list(tshard.EFFECTIVE_ERROR[outputs])
    t = tshard.read(out, [*cols, *err, *tshard.BIAS])
    K = len(truth["time_s"])
    s = stream(truth, inputs=outputs, targets=["effective_error", "bias", "labels"], exact=True)
    j = np.array([0, 2, 2, 1])
    k0 = np.array([1, 1, K - W, 123])
    b = s.generate(s.keys(ROUTE, "consumer", 3, j, k0))
    for name, c in (("x", cols), ("effective_error", err), ("bias", list(tshard.BIAS))):
        a = np.column_stack([t.column(n).to_numpy() for n in c])
        want = np.stack([a[jj * K + kk : jj * K + kk + W] for jj, kk in zip(j, k0, strict=True)])
        assert b[name].dtype == np.float32
        np.testing.assert_array_equal(b[name], want, err_msg=name)
    labels = tshard.read_labels(out)
    np.testing.assert_array_equal(
        b["labels"], labels[s.label_names].to_numpy()[j].astype(np.float32)
    )


def test_window_mode_labels_are_the_shard_paths(tmp_path, truth):
    out = tmp_path / "shard-000.parquet"
    simulate_shard(truth, str(out), "consumer", sequences=2, seed=SEED, route=ROUTE)
    s = stream(truth, targets=["labels"])
    b = s.generate(s.keys(ROUTE, "consumer", 0, [1, 0], [5, 9]))
    lab = tshard.read_labels(out)[s.label_names].to_numpy()
    np.testing.assert_array_equal(b["labels"], lab[[1, 0]].astype(np.float32))


def test_window_mode_draws_the_slow_state_from_its_law(truth):
    """(bias - turn-on bias) at a window's first row k0 is the Gauss-Markov state at k0: normal,
    variance ``x0^2 phi^(2 k0) + sigma^2 (1 - phi^(2 k0))`` (x0 = sigma from the stationary
    law, 0 for the consumer grade's in-run wander started at zero)."""
    s = stream(truth, batch_size=256, windows_per_sequence=2, targets=["bias", "labels"])
    names = s.label_names
    stationary = s.grades[0].gyro.bias_instability.start == "stationary"
    z = []
    for n in range(4):
        b = s.batch(n)
        tau = b["labels"][:, names.index("gyro_bias_instability_tau0_s")].astype(float)
        phi2 = np.exp(-2 * s.dt * b["keys"]["k0"] / tau)
        for ax in "xyz":
            on = b["labels"][:, names.index(f"gyro_turn_on_bias_{ax}_radps")].astype(float)
            sig = b["labels"][:, names.index(f"gyro_bias_instability_sigma0_{ax}_radps")]
            sd = sig * np.sqrt(stationary * phi2 + (1 - phi2))
            z.append((b["bias"][:, 0, "xyz".index(ax)] - on) / sd)
    z = np.concatenate(z)  # 3072 standard normals if the law is right
    assert abs(np.mean(z**2) - 1) < 4 * np.sqrt(2 / len(z))
    assert abs(np.mean(z)) < 4 / np.sqrt(len(z))


def test_streamed_keys_are_reserved_and_fresh(truth):
    s = stream(truth)
    seen = set()
    for n in range(5):
        k = s.batch(n)["keys"]
        assert k.dtype == KEY_DTYPE
        assert np.all(k["shard"] == STREAM_SHARD0 + n)
        seqs = {(int(a), int(b), int(c), int(d)) for a, b, c, d in
                zip(k["route"], k["grade"], k["shard"], k["j"], strict=True)}  # fmt: skip
        assert not seqs & seen
        seen |= seqs
        assert np.all((k["k0"] >= 1) & (k["k0"] + W <= len(truth["time_s"])))
    # the shard path cannot write into the namespace: its shards are all below 2^31
    with pytest.raises(InputError):
        first_index(STREAM_SHARD0, 1, None)
    assert first_index(STREAM_SHARD0 - 1, 1, None) == STREAM_SHARD0 - 1


def test_worker_split_gives_the_same_batches(truth):
    s = stream(truth)
    one = [next(iter(s))["x"]] + [b["x"] for _, b in zip(range(3), s.batches(1, 4), strict=False)]
    again = stream(truth)
    np.testing.assert_array_equal(one[0], again.batch(0)["x"])
    for i, x in enumerate(one[1:]):
        np.testing.assert_array_equal(x, again.batch(1 + 4 * i)["x"])
    assert not np.array_equal(s.batch(0)["x"], s.batch(1)["x"])
    # a different seed: different draws
    assert not np.array_equal(stream(truth, seed=SEED + 1).batch(0)["x"], one[0])


def test_temperature_terms_in_both_modes(truth):
    """Turn-on and temperature bias only: bias = b_on + k_b dT(t_k) exactly, in both modes."""
    from imugen.sensors.grade_io import grade_from_config

    tb = {"value": 10, "unit": "ug_per_K"}
    g = grade_from_config(
        "t",
        {
            "id": 5001,
            "gyro": {},
            "accel": {
                "turn_on_bias": {"value": 1, "unit": "mg", "kind": "one_sigma"},
                "temperature_bias": tb,
            },
        },
    )
    prof = {"kind": "warmup", "delta_K": 20.0, "tau_s": 0.5}
    kw = {"window": W, "batch_size": 8, "windows_per_sequence": 4, "seed": SEED,
          "temperature": prof, "targets": ["bias", "labels"]}  # fmt: skip
    for exact in (False, True):
        s = Stream({ROUTE: truth}, g, exact=exact, **kw)
        b = s.batch(0)
        on = b["labels"][:, s.label_names.index("accel_turn_on_bias_x_mps2")]
        kb = b["labels"][:, s.label_names.index("accel_temperature_bias_x_mps2_per_K")]
        k = b["keys"]["k0"][:, None] + np.arange(W)
        dT = 20.0 * (1 - np.exp(-k * s.dt / 0.5))
        np.testing.assert_allclose(b["bias"][..., 3], on[:, None] + kb[:, None] * dT, rtol=1e-6)
        assert np.all(kb != 0)


def test_bad_input_is_refused(truth):
    with pytest.raises(InputError):
        stream(truth, batch_size=6)
    with pytest.raises(InputError):
        stream(truth, window=10_000)
    s = stream(truth)
    with pytest.raises(InputError):
        s.generate(s.keys(ROUTE, "consumer", 0, 0, 0))


def test_window_mode_normals_are_the_keys_sfc64_stream(truth):
    """White noise only: a window's increment errors are ``white sqrt(dt) z`` with ``z`` the
    sequence's SFC64 normals (stream ``window``) after the 12 normals of its slow states
    (and, for its second window, after the first window's gyro and accelerometer draws)."""
    from imugen.core.seeding import SENSOR_STREAMS
    from imugen.sensors.grade_io import grade_from_config

    wn = {"value": 0.5, "unit": "deg_per_sqrt_h"}
    g = grade_from_config("w", {"id": 5002, "gyro": {"white_noise": wn}, "accel": {}})
    s = Stream({ROUTE: truth}, g, window=W, batch_size=4, windows_per_sequence=2, seed=SEED,
               targets=["increments", "labels"])  # fmt: skip
    b = s.generate(s.keys(ROUTE, "w", 11, [0, 0, 1], [3, 70, 9]))
    sig = b["labels"][:, s.label_names.index("gyro_white_noise_x_rad_per_sqrt_s")].astype(float)
    z = (b["x"][..., :3].astype(float) - b["increments"][..., :3]) / (sig * np.sqrt(s.dt))[
        :, None, None
    ]
    for i, (j, skip) in enumerate(((0, 12), (0, 12 + 3 * W + 12 + 12), (1, 12))):
        key = (s.route_ids[0], g.id, 11, j, SENSOR_STREAMS["window"])
        rng = np.random.Generator(np.random.SFC64(np.random.SeedSequence(SEED, spawn_key=key)))
        want = rng.standard_normal(skip + 3 * W)[skip:].reshape(W, 3)
        np.testing.assert_allclose(z[i], want, atol=2e-3)
    assert np.all(b["x"][..., 3:] == b["increments"][..., 3:].astype(np.float32))
