"""The spawn-key tree: every random draw of imugen, named by what it belongs to.

Each draw comes from ``Generator(PCG64(SeedSequence(seed, spawn_key=key)))``, with the root
``seed`` of the run (the IMU's) or a per-sequence entropy (the aid stage's) and a ``key``
naming route, grade or receiver, shard, sequence and stream. So a draw never depends on how
many routes, shards or jobs exist, nor on their order, and never repeats elsewhere. The keys:

IMU sensors (simulate stage; :func:`sensor_rng`)
    ``(route_id, grade_id, shard, j, stream)``, ``j`` the sequence's index in its shard and
    ``stream`` from :data:`SENSOR_STREAMS` (parameter draw, white noise, rate random walk and
    bias instability per sensor, the second slow bias process (a grade's ``slow_bias``) per
    sensor, vibration, mounting, the internal-rate white noise of a
    sensor with an output bandwidth, and the window-mode draws of :mod:`imugen.stream`: the
    kernel's, and those of an output bandwidth and rounding quantization). ``route_id`` is
    :func:`imugen.tables.shard.route_id` of the route name.
GNSS receiver (aid stage; :func:`gnss_rng`)
    ``(GNSS_KEY, receiver_id, shard, j, stream)``, streams :data:`GNSS_STREAMS`.
GNSS scenarios (aid stage; :func:`scenario_rng`)
    ``(SCENARIO_KEY, shard, j, stream)``, streams :data:`SCENARIO_STREAMS`.
Reference learned model (:mod:`imugen.learn`; :func:`learn_seed`)
    ``(LEARN_KEY, grade_id, stream)``, streams :data:`LEARN_STREAMS` (the network's initial
    weights and batch order given to PyTorch as one integer seed).
Companion sensors (aid stage; :func:`companion_rng`)
    ``(COMPANION_KEY, kind, sensor_id, shard, j, stream)``, streams :data:`COMPANION_STREAMS`
    (``kind`` is :data:`imugen.aid.companions.KINDS` of the sensor).

The aid stage draws a sequence's receiver, scenarios and companions with the entropy
:func:`sequence_entropy` ``[seed, route_id, index]`` (the sequence's index in its route) and
``shard = j = 0`` inside the keys: the identity is in the entropy, so those draws depend on
neither the IMU grade (grades compare on the same GNSS: common random numbers) nor the shard
size. The first key elements ``GNSS_KEY``, ``SCENARIO_KEY``, ``COMPANION_KEY`` (ASCII "GNSS",
"SCEN", "COMP") keep those trees apart from the IMU's, whose first element is a route id.

Bit-identity across machines holds for the same NumPy bit-generator algorithms (PCG64,
``standard_normal``); the NumPy version is recorded in the shard metadata.
"""

from __future__ import annotations

import numpy as np

BIT_GENERATOR = "PCG64"
"""The bit generator of every draw (recorded in the shard metadata)."""

SENSOR_STREAMS = {
    "params": 0,
    "gyro_white": 1,
    "accel_white": 2,
    "gyro_rrw": 3,
    "accel_rrw": 4,
    "gyro_bi": 5,
    "accel_bi": 6,
    "vibration": 7,
    "mounting": 8,
    "gyro_band": 9,
    "accel_band": 10,
    "window": 11,
    "window_band": 12,
    "gyro_slow": 13,
    "accel_slow": 14,
}
"""Per-sequence streams of the IMU (last element of its spawn key)."""

GNSS_KEY = 0x474E5353
"""First element of every GNSS spawn key ("GNSS"), apart from the IMU's ``route_id``."""
GNSS_STREAMS = {"params": 0, "position_white": 1, "position_bias": 2, "velocity_white": 3}
"""Per-sequence streams of the GNSS receiver (last element of its spawn key)."""

SCENARIO_KEY = 0x5343454E
"""First element of every scenario spawn key ("SCEN")."""
SCENARIO_STREAMS = {"draw": 0, "noise": 1}
"""Per-sequence streams of the scenarios: the drawn intervals, the jamming noise."""

COMPANION_KEY = 0x434F4D50
"""First element of every companion spawn key ("COMP")."""
COMPANION_STREAMS = {"params": 0, "white": 1, "bias": 2}
"""Per-sequence streams of a companion sensor (last element of its spawn key)."""

LEARN_KEY = 0x4C45524E
"""First element of the reference learned model's spawn keys ("LERN")."""
LEARN_STREAMS = {"init": 0}
"""Streams of the reference learned model (last element of its spawn key)."""


def generator(seed, key: tuple[int, ...]) -> np.random.Generator:
    """``Generator(PCG64(SeedSequence(seed, spawn_key=key)))``: the one way a draw is made."""
    return np.random.Generator(np.random.PCG64(np.random.SeedSequence(seed, spawn_key=key)))


def sensor_key(route_id: int, grade_id: int, shard: int, j: int, stream: str) -> tuple:
    """Spawn key of stream ``stream`` (:data:`SENSOR_STREAMS`) of sequence ``j`` of a shard."""
    return (route_id, grade_id, shard, j, SENSOR_STREAMS[stream])


def sensor_rng(seed, route_id, grade_id, shard, j, stream) -> np.random.Generator:
    """IMU draws of sequence ``j`` of shard ``shard`` of a route and grade (simulate stage)."""
    return generator(seed, sensor_key(route_id, grade_id, shard, j, stream))


def gnss_rng(seed, receiver_id, shard, j, stream) -> np.random.Generator:
    """GNSS receiver draws (stream of :data:`GNSS_STREAMS`) of sequence ``j``."""
    return generator(seed, (GNSS_KEY, receiver_id, shard, j, GNSS_STREAMS[stream]))


def scenario_rng(seed, shard, j, stream) -> np.random.Generator:
    """Scenario draws (stream of :data:`SCENARIO_STREAMS`) of sequence ``j``."""
    return generator(seed, (SCENARIO_KEY, shard, j, SCENARIO_STREAMS[stream]))


def companion_rng(seed, kind: int, sensor_id: int, shard, j, stream) -> np.random.Generator:
    """Draws of a companion sensor (kind code, preset id; stream of :data:`COMPANION_STREAMS`)
    for sequence ``j``."""
    return generator(seed, (COMPANION_KEY, kind, sensor_id, shard, j, COMPANION_STREAMS[stream]))


def sequence_entropy(seed: int, route_id: int, index: int) -> list[int]:
    """``[seed, route_id, index]``: the entropy of a sequence's aid-stage draws (receiver,
    scenarios, companions), ``index`` its position in the route (``shard * shard_size + j``)."""
    return [int(seed), int(route_id), int(index)]


def learn_seed(seed, grade_id: int, stream: str = "init") -> int:
    """A 63-bit integer seed for PyTorch (``torch.manual_seed``) of the reference learned model
    of grade ``grade_id`` (stream of :data:`LEARN_STREAMS`)."""
    ss = np.random.SeedSequence(seed, spawn_key=(LEARN_KEY, int(grade_id), LEARN_STREAMS[stream]))
    return int(ss.generate_state(1, np.uint64)[0] >> np.uint64(1))
