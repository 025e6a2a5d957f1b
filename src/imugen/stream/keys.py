"""Keys of streamed windows: which (route, grade, sequence, window) a batch draws.

A streamed sequence is named exactly as a written one: ``(route_id, grade_id, shard, j)``,
the spawn key of its draws (:func:`imugen.core.seeding.sensor_rng`). The shard path numbers
sequences ``index = shard * shard_size + j < 2^31`` (:func:`imugen.simulate.plan.first_index`),
so every written shard has ``shard < 2^31``. Streamed training draws use the reserved
namespace ``shard >= STREAM_SHARD0 = 2^31`` (the high bit of the shard element of the spawn
key): batch ``n`` of a stream draws its sequences ``j = 0 .. n_seq - 1`` of shard
``STREAM_SHARD0 + n``. A streamed draw therefore never meets a written training, validation or
test sequence, whatever their seed, shard size or count, and no two batches share a sequence.

The choice of routes, grades and window starts of batch ``n`` comes from
``generator(seed, (STREAM_KEY, n))`` (:data:`STREAM_KEY`, ASCII "STRM", apart from the
route ids that start the IMU keys): a batch depends on ``(seed, n)`` only, never on how many
workers or processes serve the stream. Worker ``w`` of ``W`` serves the batches
``n = first + w, first + w + W, ...`` (:func:`worker_batches`).
"""

from __future__ import annotations

import numpy as np

from imugen.core.seeding import SENSOR_STREAMS, generator
from imugen.tables.shard import ROUTE_SHIFT

STREAM_SHARD0 = 1 << ROUTE_SHIFT
"""First shard number of the streamed namespace (``2^31``): written shards are all below it."""
STREAM_KEY = 0x5354524D
"""First element of the spawn key of a batch's key draw ("STRM")."""
WINDOW_STREAM = SENSOR_STREAMS["window"]
"""Stream (last spawn-key element, :data:`imugen.core.seeding.SENSOR_STREAMS`) of a
sequence's window-mode draws: the slow states at each window's start and the window's noise."""

KEY_DTYPE = np.dtype(
    [("route", np.int32), ("grade", np.int32), ("shard", np.int64), ("j", np.int64),
     ("k0", np.int64)]
)  # fmt: skip
"""A window key: route and grade (indices into the stream's lists), shard, sequence ``j`` of the
shard, first row ``k0`` of the window (rows ``k0 .. k0 + window - 1``, ``k0 >= 1``)."""


def is_streamed(shard) -> np.ndarray:
    """True where ``shard`` lies in the streamed namespace (never written)."""
    return np.asarray(shard, np.int64) >= STREAM_SHARD0


def worker_batches(first: int, worker: int, workers: int):
    """Batch numbers of worker ``worker`` of ``workers``: ``first + worker + i * workers``."""
    if not (0 <= worker < workers):
        raise ValueError(f"worker {worker} out of range for {workers} workers")
    n = int(first) + int(worker)
    while True:
        yield n
        n += int(workers)


def batch_keys(seed, n: int, n_seq: int, per_seq: int, windows, weights, grades: int):
    """The window keys of batch ``n``: ``n_seq`` fresh sequences, ``per_seq`` windows each.

    Parameters
    ----------
    seed : int
        The stream's root seed (that of the simulate stage for the same law).
    n : int
        Batch number (``>= 0``).
    n_seq, per_seq : int
    windows : (R,) int
        Windows per sequence of each route (the grid ``k0 = 1 + i * stride``).
    weights : (R,) float
        Probability of each route (sums to 1).
    grades : int
        Number of grades (drawn uniformly).

    Returns
    -------
    keys : (n_seq * per_seq,) KEY_DTYPE, grouped by sequence, window starts increasing.
    grid : (n_seq * per_seq,) int, the window's index on its route's grid.
    """
    rng = generator(seed, (STREAM_KEY, int(n)))
    route = rng.choice(len(windows), size=n_seq, p=weights)
    grade = rng.integers(0, grades, size=n_seq)
    u = rng.random((n_seq, per_seq))
    grid = np.sort(np.floor(u * np.asarray(windows)[route][:, None]).astype(np.int64), axis=1)
    keys = np.empty(n_seq * per_seq, KEY_DTYPE)
    keys["route"] = np.repeat(route, per_seq)
    keys["grade"] = np.repeat(grade, per_seq)
    keys["shard"] = STREAM_SHARD0 + int(n)
    keys["j"] = np.repeat(np.arange(n_seq), per_seq)
    return keys, grid.ravel()
