"""The spawn-key tree: every draw's key, pinned (a change would redraw every dataset)."""

import numpy as np

from imugen.core import seeding


def _rng(seed, key):
    return np.random.Generator(np.random.PCG64(np.random.SeedSequence(seed, spawn_key=key)))


def test_keys_and_streams_are_the_published_ones():
    assert seeding.GNSS_KEY == int.from_bytes(b"GNSS", "big")
    assert seeding.SCENARIO_KEY == int.from_bytes(b"SCEN", "big")
    assert seeding.COMPANION_KEY == int.from_bytes(b"COMP", "big")
    assert list(seeding.SENSOR_STREAMS.items()) == [
        ("params", 0), ("gyro_white", 1), ("accel_white", 2), ("gyro_rrw", 3), ("accel_rrw", 4),
        ("gyro_bi", 5), ("accel_bi", 6), ("vibration", 7), ("mounting", 8), ("gyro_band", 9),
        ("accel_band", 10), ("window", 11), ("window_band", 12), ("gyro_slow", 13),
        ("accel_slow", 14),
    ]  # fmt: skip
    assert seeding.GNSS_STREAMS == {
        "params": 0, "position_white": 1, "position_bias": 2, "velocity_white": 3,
    }  # fmt: skip
    assert seeding.SCENARIO_STREAMS == {"draw": 0, "noise": 1}
    assert seeding.COMPANION_STREAMS == {"params": 0, "white": 1, "bias": 2}


def test_each_generator_is_its_key():
    """Each named generator draws what ``SeedSequence(seed, spawn_key=key)`` draws, with the
    key laid out as the module docstring states; different trees never share a draw."""
    seed = [11, 3_000_000_000, 42]  # the aid stage's per-sequence entropy
    cases = [
        (seeding.sensor_rng(seed, 7, 101, 2, 5, "gyro_bi"), (7, 101, 2, 5, 5)),
        (seeding.gnss_rng(seed, 3, 0, 0, "position_bias"), (seeding.GNSS_KEY, 3, 0, 0, 2)),
        (seeding.scenario_rng(seed, 0, 0, "noise"), (seeding.SCENARIO_KEY, 0, 0, 1)),
        (seeding.companion_rng(seed, 2, 4, 0, 0, "bias"), (seeding.COMPANION_KEY, 2, 4, 0, 0, 2)),
    ]
    draws = []
    for rng, key in cases:
        x = rng.standard_normal(4)
        np.testing.assert_array_equal(x, _rng(seed, key).standard_normal(4))
        draws.append(x)
    assert len({d.tobytes() for d in draws}) == len(draws)
    assert seeding.sequence_entropy(11, 3_000_000_000, 42) == seed


def test_a_shard_records_the_tree():
    from imugen.simulate.stage import simulate

    sh = simulate(None, "consumer", sequences=1, seed=3, static_s=0.1, rate_hz=100.0)
    assert sh.meta["streams"] == seeding.SENSOR_STREAMS
    assert sh.meta["bit_generator"] == seeding.BIT_GENERATOR == "PCG64"
