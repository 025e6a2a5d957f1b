"""The stream as a PyTorch ``IterableDataset`` (the optional ``torch`` extra: ``pip install imugen[torch]``).

torch is imported when :func:`StreamDataset` is first called, never by ``import imugen.stream``.
Each DataLoader worker serves the batches ``w, w + W, ...`` of the stream
(:func:`imugen.stream.keys.worker_batches`), so the batches, and their order within a worker,
do not depend on the number of workers; use ``batch_size=None`` in the DataLoader (the
stream makes whole batches).
"""

from __future__ import annotations

import itertools

_CLASS = None


def _dataset_class():
    global _CLASS
    if _CLASS is None:
        import torch

        class _StreamDataset(torch.utils.data.IterableDataset):
            """Batches of :class:`imugen.stream.Stream` as tensors (see :func:`StreamDataset`)."""

            def __init__(self, stream, batches=None, device=None):
                super().__init__()
                self.stream = stream
                self.n = batches
                self.device = device

            def __iter__(self):
                info = torch.utils.data.get_worker_info()
                w, nw = (0, 1) if info is None else (info.id, info.num_workers)
                it = self.stream.batches(w, nw)
                if self.n is not None:
                    # batch numbers first .. first + n - 1, shared among the workers
                    it = itertools.islice(it, len(range(w, self.n, nw)))
                for b in it:
                    out = {}
                    for k, v in b.items():
                        t = torch.from_numpy(v) if k != "keys" else torch.from_numpy(_keys_array(v))
                        out[k] = t.to(self.device) if self.device is not None else t
                    yield out

        _CLASS = _StreamDataset
    return _CLASS


def _keys_array(keys):
    """Window keys as an ``(B, 5)`` int64 array: route, grade, shard, j, k0."""
    import numpy as np

    return np.column_stack([keys[n].astype(np.int64) for n in keys.dtype.names])


def StreamDataset(stream, batches: int | None = None, device=None):
    """A ``torch.utils.data.IterableDataset`` yielding the stream's batches as dicts of tensors.

    Parameters
    ----------
    stream : imugen.stream.Stream
    batches : int, optional
        Stop after this many batches (numbers ``first .. first + batches - 1``, shared among
        workers); default endless.
    device : torch device, optional
        Move each tensor there (in the worker; prefer moving in the training loop with
        ``num_workers > 0``).

    Returns
    -------
    IterableDataset
        Items ``{"x": (B, W, 6), <target>: ..., "keys": (B, 5) int64}``.
    """
    return _dataset_class()(stream, batches, device)
