"""Navigation error table: the output of ``imugen navigate``.

One row per sequence and evaluation epoch (every ``round(rate / eval_rate_hz)`` samples from
``t_0``): ``sequence`` (int64, the shard's id), ``time_s`` (s), position error
``err_e_m``, ``err_n_m``, ``err_u_m`` (navigation minus truth, m, East/North/Up at the TRUE
position: :mod:`imugen.navigate.local_errors`; in the ``flat`` model the ENU of the route origin),
``err_along_m``, ``err_cross_m`` (horizontal error along the true track and across it, positive
to the left, m) and attitude error ``err_att_rad`` (angle of the rotation from the true to the
computed attitude). Tables written before the track columns existed lack them; readers
asking for :data:`ERR_TRACK` should check :func:`has_track` first.
Metadata (JSON under ``b"imugen"``): ``stage``, ``truth`` and ``shard`` (file names),
``truth_sha256``, ``grade``, ``eval_rate_hz``, ``increments``, ``units``,
``vertical_channel`` (the vertical channel navigation used and why:
:meth:`imugen.navigate.vertical.VerticalChannel.meta`; absent in older tables).
"""

from __future__ import annotations

import json
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from imugen.core.io import METADATA_KEY, atomic_output
from imugen.core.io import read_meta as read_meta
from imugen.tables import SEQUENCE, TIME
from imugen.tables._parquet import from_numpy, names, read_table

ERR_POS = ("err_e_m", "err_n_m", "err_u_m")
"""Position error columns, metres, ENU at the true position."""
ERR_TRACK = ("err_along_m", "err_cross_m")
"""Along-track and cross-track (positive left) horizontal error columns, metres."""
ERR_ATT = "err_att_rad"
COLUMNS = (SEQUENCE, TIME, *ERR_POS, *ERR_TRACK, ERR_ATT)
UNITS = {
    SEQUENCE: "1",
    TIME: "s",
    **dict.fromkeys(ERR_POS, "m"),
    **dict.fromkeys(ERR_TRACK, "m"),
    ERR_ATT: "rad",
}
WHAT = "navigation error table"


def _schema(meta: dict) -> pa.Schema:
    fields = [pa.field(SEQUENCE, pa.int64()), pa.field(TIME, pa.float64())]
    fields += [pa.field(c, pa.float64()) for c in (*ERR_POS, *ERR_TRACK, ERR_ATT)]
    md = {METADATA_KEY: json.dumps({**meta, "units": UNITS}).encode()}
    return pa.schema(fields, metadata=md)


class Writer:
    """Appends blocks of rows (one row group each) to an error table being written."""

    def __init__(self, pw, schema):
        self.pw = pw
        self.schema = schema
        self.rows = 0

    def put(self, cols: dict) -> None:
        """Append a block: ``cols`` maps every column of :data:`COLUMNS` to a 1-D array."""
        arrays = [from_numpy(cols[f.name], f.type) for f in self.schema]
        self.pw.write_table(pa.Table.from_arrays(arrays, schema=self.schema))
        self.rows += len(arrays[0])


@contextmanager
def writer(out, meta: dict) -> Iterator[Writer]:
    """Stream an error table to ``out`` atomically: yields a :class:`Writer`.

    Each block put becomes a row group, so a job holds one block, never the whole table.
    """
    schema = _schema(meta)
    with atomic_output(out) as tmp:
        with pq.ParquetWriter(tmp, schema) as pw:
            w = Writer(pw, schema)
            yield w


def write(df, meta: dict, out) -> Path:
    """Write an error table held in a DataFrame (or a dict of columns) atomically."""
    with writer(out, meta) as w:
        w.put({c: np.asarray(df[c]) for c in COLUMNS})
    return Path(out)


def read(path, columns=None, filters=None):
    """Columns (default all) of a navigation error table, rows kept by ``filters``."""
    return read_table(path, columns, filters, WHAT).to_pandas()


def has_track(path) -> bool:
    """True when the table holds the along/cross-track columns (footer only)."""
    return set(ERR_TRACK) <= set(names(path, WHAT))
