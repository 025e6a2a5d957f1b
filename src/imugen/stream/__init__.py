"""Training data generated in the loop: batches of IMU windows and targets, no disk.

:class:`Stream` draws ``(route, grade, sequence, window)`` keys and generates each window's
measured IMU rows and the loader's targets (:class:`imugen.dataset.WindowDataset`: effective
error, true increments, true slow bias, the sequence's drawn parameters as labels, the
filter's estimates and the filter-aware target) in memory;
:class:`imugen.stream.torch.StreamDataset` serves it as a PyTorch ``IterableDataset`` (the
optional ``torch`` extra).

Keys and seeds (:mod:`imugen.stream.keys`)
    A sequence is ``(route_id, grade_id, shard, j)``, the spawn key of the simulate stage. The
    stream's own draws live in the reserved namespace ``shard >= 2^31`` (written shards are
    all below: their sequence index ``shard * shard_size + j`` is < 2^31), one fresh shard
    number per batch, so streamed training draws never meet a written validation or test set
    and never repeat. Batch ``n`` depends on ``(seed, n)`` only: worker ``w`` of ``W`` serves
    batches ``w, w + W, ...``, and any number of workers gives the same batches.
Same keys, same numbers (:mod:`imugen.stream.windows`)
    With ``exact=True`` each sequence is generated from its turn-on with the simulate stage's
    streams and kernel: a written shard's key gives its rows bit for bit. The default window
    mode generates only the window's rows, drawing the slow states (Gauss-Markov, random walk,
    quantization residuals) from their exact law at the window's start; its parameters (and
    labels) are still the shard path's bit for bit, the windows' noise is its own stream.

Example
-------
::

    from imugen.stream import Stream, load_truths

    s = Stream(load_truths(["results/city/truth.parquet"]), "consumer", window=200,
               batch_size=256, targets=["effective_error"], seed=0)
    for b in s:                      # endless; each batch has fresh sequences
        x, y = b["x"], b["effective_error"]      # float32 (256, 200, 6) each
        break

Grades with an output bandwidth or rounding quantization (``adis16405``, ``phone``, ...) stream
in both modes (window mode warms each window's output filter up, :mod:`imugen.stream.windows`),
as do vibration and mounting (no state: window mode applies the sequence's draws to the
window's rows); the ``gnss`` target gives the aid stage's GNSS
fixes, scenario states and receiver labels on the window's rows (:mod:`imugen.stream.gnss`);
in exact mode the ``filter``, ``filter_sd`` and ``filter_aware_error`` targets run the aid
stage's filter (:func:`imugen.aid.stage.filter_block`) over each whole sequence and give the
loader's extras and target of those names (the held estimates, their sigmas, the filter-aware
target), bit for bit for a written key.
Not streamed: raw increments; the filter targets in window mode.
"""

from imugen.stream.keys import KEY_DTYPE, STREAM_SHARD0
from imugen.stream.stream import Stream, load_truths

__all__ = ["KEY_DTYPE", "STREAM_SHARD0", "Stream", "load_truths"]
