"""IMU correction table: per sequence and IMU sample, a correction of the shard's increments.

Two uses, one layout (issue 26, :mod:`imugen.aid.filter.learner`):

* ``imugen aid --correction-out``: what the aided filter removed from each increment it was
  given (its bias, scale-factor and cross-coupling estimates at that sample; raw minus
  corrected). The **filter-aware target** of a learner is the shard's effective error
  (``err_dtheta_*``, ``err_dv_*``) minus it;
* ``imugen aid --correction-in``: a learner's correction, subtracted from the increments
  before the filter (the total correction of the effective error, the filter then tuned to
  what the learner leaves: :class:`imugen.aid.filter.LearnedInputs`).

Columns: ``sequence`` int64, ``sample`` int64 (the row of the sequence in its shard, ``0 ..
K - 1``; row ``k`` is the interval ending at ``t_k``, row 0 unused), ``corr_dtheta_{x,y,z}_rad``
(rad), ``corr_dv_{x,y,z}_mps`` (m/s), float32, body axes. Sorted by sequence, then sample;
every sequence holds its ``K`` rows (zeros before the filter starts).

Metadata (JSON under ``b"imugen"``): ``stage``, ``shard``, ``what`` (``"filter"`` or a
learner's name), ``units``.
"""

from __future__ import annotations

import json
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pyarrow as pa

from imugen.core.errors import InputError
from imugen.core.io import METADATA_KEY
from imugen.tables import SEQUENCE
from imugen.tables._parquet import block_writer, names, read_table, require

SAMPLE = "sample"
DTHETA = tuple(f"corr_dtheta_{a}_rad" for a in "xyz")
DV = tuple(f"corr_dv_{a}_mps" for a in "xyz")
COLUMNS = (SEQUENCE, SAMPLE, *DTHETA, *DV)
UNITS = {SEQUENCE: "1", SAMPLE: "1", **dict.fromkeys(DTHETA, "rad"), **dict.fromkeys(DV, "m/s")}
WHAT = "IMU correction table"


def _schema(meta: dict) -> pa.Schema:
    md = {METADATA_KEY: json.dumps({**meta, "units": UNITS}).encode()}
    fields = [pa.field(c, pa.int64() if c in (SEQUENCE, SAMPLE) else pa.float32()) for c in COLUMNS]
    return pa.schema(fields, metadata=md)


def frame(ids, correction) -> dict:
    """The rows of sequences ``ids`` (S,) from a (S, K, 6) correction (angle, velocity)."""
    ids = np.asarray(ids, np.int64)
    c = np.asarray(correction)
    S, K = c.shape[:2]
    cols = {SEQUENCE: np.repeat(ids, K), SAMPLE: np.tile(np.arange(K, dtype=np.int64), S)}
    for i, name in enumerate((*DTHETA, *DV)):
        cols[name] = c[..., i].reshape(-1).astype(np.float32)
    return cols


@contextmanager
def writer(out, meta: dict | None = None) -> Iterator[SimpleNamespace]:
    """Stream the table to ``out`` atomically: yields ``w`` with ``w.put(cols)`` (a mapping of
    every column, e.g. :func:`frame`), one row group per call; ``w.meta`` settable until the
    first ``put``."""
    with block_writer(out, meta, _schema) as w:
        yield w


def read(path, columns=None, filters=None):
    """Columns (default all) of an IMU correction table, rows kept by ``filters``."""
    return read_table(path, columns, filters, WHAT).to_pandas()


def arrays(path, ids, K: int) -> tuple[np.ndarray, np.ndarray]:
    """The corrections of sequences ``ids`` as ``(dtheta, dv)``, each (S, K, 3) float64, in
    the order of ``ids``; a one-line error when a sequence is missing or has not its ``K``
    samples."""
    ids = np.asarray(ids, np.int64)
    require(path, names(path, WHAT), COLUMNS, WHAT)
    df = read(path, filters=[(SEQUENCE, "in", [int(i) for i in ids])])
    df = df.sort_values([SEQUENCE, SAMPLE], kind="stable")
    counts = df.groupby(SEQUENCE).size().reindex(ids, fill_value=0)
    bad = counts[counts != K]
    if len(bad):
        raise InputError(
            path, f"sequence {int(bad.index[0])} has {int(bad.iloc[0])} samples, expected {K}"
        )
    order = {int(s): i for i, s in enumerate(ids)}
    pos = df[SEQUENCE].map(order).to_numpy()
    smp = df[SAMPLE].to_numpy()
    if np.any(smp != np.tile(np.arange(K), len(ids))):
        raise InputError(path, "samples must run 0 .. K-1 within every sequence")
    out = np.zeros((len(ids), K, 6))
    out[pos, smp] = df[[*DTHETA, *DV]].to_numpy(np.float64)
    if not np.isfinite(out).all():
        raise InputError(path, "corrections must be finite")
    return out[..., :3], out[..., 3:]


def write(cols, meta: dict, out) -> Path:
    """Write the rows ``cols`` (:func:`frame`) atomically."""
    with writer(out, meta) as w:
        w.put(cols)
    return Path(out)
