"""Where a shard's sequences go as they are generated, chunk by chunk.

A sink offers ``reserve(j, k0, L)`` (buffers the sensor kernels write into, in place) and
takes ``put(j, k0, L, t, outs)``: :class:`MemorySink` keeps every sequence in memory
(:func:`imugen.simulate.stage.simulate`), :class:`WriterSink` commits the chunks to a shard
writer (:mod:`imugen.tables.shard`), :class:`NavSink` navigates the sequences as they are
produced (``imugen simulate --navigate``), passing every chunk on.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from imugen.core.errors import InputError
from imugen.sensors.ideal import CHUNK
from imugen.simulate.plan import Plan
from imugen.tables import nav as tnav
from imugen.tables import truth as ttruth


class MemorySink:
    """Sequences kept in memory, float64 ``(M, K, 3)`` per group; the kernels write in place."""

    def __init__(self, M, K, names):
        self.data = {n: np.empty((M, K, 3)) for n in names}

    def reserve(self, j, k0, L):
        return {n: a[j, k0 : k0 + L] for n, a in self.data.items()}

    def put(self, j, k0, L, t, outs):
        pass


class WriterSink:
    """Lets the kernels write each chunk in place into a :class:`imugen.tables.shard.Writer`'s
    column buffers (strided ``(L, 3)`` views), committed under the sequence's global id.

    Measured (``benchmarks/README.md``, issue 14): 219 against 230 CPU-ns per sample-sequence
    of generation + Parquet write for the former contiguous chunk buffers copied into the
    column buffers (the copy wrote every row group's 24 MiB a second time, out of cache)."""

    def __init__(self, writer, ids):
        self.w = writer
        self.ids = ids

    def reserve(self, j, k0, L):
        return self.w.reserve(L)

    def put(self, j, k0, L, t, outs):
        self.w.commit(int(self.ids[j]), t)


class NavSink:
    """Navigates the sequences as they are produced, passing every chunk on to ``inner``.

    Keeps one batch of measurements (float64 buffers holding the values as stored, i.e.
    rounded to the shard's ``dtype``), mechanizes the batch when its last sequence is
    complete and streams its errors to ``nav_writer``: the same numbers as ``imugen navigate``
    on the written shard (same batches, same arithmetic), without re-reading it.
    """

    def __init__(self, inner, navigator, plan: Plan, dtype, nav_writer, batch):
        self.inner = inner
        self.nav = navigator
        self.kind = "increments" if plan.outputs in ("increments", "both") else "rates"
        self.groups = ("dtheta", "dv") if self.kind == "increments" else ("gyro", "accel")
        self.raw = plan.raw and self.kind == "increments"
        self.skip = 1 if self.kind == "increments" else 0
        self.K = plan.truth.K
        self.dtype = np.dtype(dtype)
        self.ids = plan.ids
        self.mount = plan.mount
        self.w = nav_writer
        self.batch = int(batch)
        width = self.K - self.skip
        self.bufs = tuple(np.empty((self.batch, width, 3)) for _ in self.groups)
        self.first = 0  # sequence index of the batch's first row
        self.n = 0  # complete sequences in the buffers
        self.own = {n: np.empty((CHUNK, 3), self.dtype) for n in plan.names}

    def reserve(self, j, k0, L):
        if hasattr(self.inner, "reserve"):
            return self.inner.reserve(j, k0, L)
        return {n: a[:L] for n, a in self.own.items()}

    def put(self, j, k0, L, t, outs):
        lo = max(k0, self.skip)
        if lo < k0 + L:
            for buf, g in zip(self.bufs, self.groups, strict=True):
                # the stored rounding (float32 by default), widened exactly to float64; axis
                # by axis: each is a contiguous row of the writer's column buffers
                dst = buf[self.n, lo - self.skip : k0 + L - self.skip]
                for i in range(3):
                    dst[:, i] = outs[g][lo - k0 :, i]
        if self.inner is not None:
            self.inner.put(j, k0, L, t, outs)
        if k0 + L == self.K:
            self.n += 1
            if self.n == self.batch:
                self.flush()

    def flush(self):
        if self.n:
            a, b = (buf[: self.n] for buf in self.bufs)
            ids = self.ids[self.first : self.first + self.n]
            mount = None
            if self.mount is not None:
                sel = self.mount[self.first : self.first + self.n]
                mount = tuple(np.array(x) for x in zip(*sel, strict=True))
            self.w.put(self.nav.columns(ids, *self.nav.measured(self.kind, self.raw, a, b), mount))
            self.first += self.n
            self.n = 0


def navigation_sink(
    stack, inner, plan, truth, out, nav_out, eval_rate_hz, dtype, vertical=None
) -> NavSink:
    """A :class:`NavSink` writing to ``nav_out`` (entered on ``stack``), with the metadata
    ``imugen navigate`` would record for the written shard (``vertical``: the
    :class:`imugen.navigate.vertical.VerticalSpec`, default ``auto``)."""
    from imugen.navigate import navigator as nv

    truth_table = ttruth.read(truth, columns=nv.NAV_TRUTH_COLUMNS, arrow=True)
    nav = nv.Navigator(truth_table, eval_rate_hz, vertical)
    if nav.K != plan.truth.K:
        raise InputError(truth, "changed while being read")
    meta = nv.table_meta(
        plan.truth.meta["file"],
        plan.truth.meta["sha256"],
        None if out is None else Path(out).name,
        json.loads(json.dumps(plan.meta)),
        eval_rate_hz,
        nav.vertical.meta(),
    )
    nw = stack.enter_context(tnav.writer(nav_out, meta))
    return NavSink(inner, nav, plan, dtype, nw, nv.batch_size(nav.K))
