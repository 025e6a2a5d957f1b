"""Parquet plumbing shared by the table modules: opening, reading, clear errors.

Every reader maps a missing or unreadable file, or a missing column, to one-line
:class:`~imugen.core.errors.InputError` naming the file and the kind of table expected.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Iterator, Sequence
from contextlib import contextmanager
from types import SimpleNamespace

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from imugen.core.errors import InputError
from imugen.core.io import atomic_output


def to_numpy(col) -> np.ndarray:
    """A numeric Arrow column (Array or ChunkedArray) as a NumPy array (read-only view of its
    buffers when it has no nulls). pyarrow's own conversion imports pandas: ~0.5 s of CPU at
    the start of every job that would not otherwise need it."""
    chunks = col.chunks if isinstance(col, pa.ChunkedArray) else [col]
    parts = []
    for x in chunks:
        if x.null_count or not (pa.types.is_integer(x.type) or pa.types.is_floating(x.type)):
            return col.to_numpy()
        dt = np.dtype(x.type.to_pandas_dtype())
        parts.append(np.frombuffer(x.buffers()[1], dt, len(x), x.offset * dt.itemsize))
    if len(parts) == 1:
        return parts[0]
    return np.concatenate(parts) if parts else col.to_numpy()


def from_numpy(a: np.ndarray, type_: pa.DataType | None = None) -> pa.Array:
    """A 1-D numeric NumPy array as an Arrow array over its buffer (no nulls; zero-copy when
    contiguous). ``pyarrow.array`` would import pandas to inspect it."""
    a = np.ascontiguousarray(a, None if type_ is None else type_.to_pandas_dtype())
    if a.ndim != 1 or a.dtype.kind not in "iuf":
        return pa.array(a, type_)
    return pa.Array.from_buffers(pa.from_numpy_dtype(a.dtype), len(a), [None, pa.py_buffer(a)])


def open_file(path, what: str = "table", **options) -> pq.ParquetFile:
    """``pyarrow.parquet.ParquetFile`` of ``path`` (InputError if absent or not Parquet)."""
    try:
        return pq.ParquetFile(path, **options)
    except FileNotFoundError:
        raise InputError(path, "no such file") from None
    except (OSError, pa.ArrowInvalid) as exc:
        raise InputError(path, f"cannot read as a Parquet {what} ({_short(exc)})") from None


def _short(exc: Exception) -> str:
    return " ".join(str(exc).split())[:200]


def names(path, what: str = "table") -> list[str]:
    """Column names of a Parquet file (footer only)."""
    return list(open_file(path, what).schema_arrow.names)


def num_rows(path, what: str = "table") -> int:
    """Row count of a Parquet file (footer only)."""
    return int(open_file(path, what).metadata.num_rows)


def require(path, have: Iterable[str], need: Sequence[str], what: str) -> None:
    """InputError naming the columns of ``need`` absent from ``have``."""
    have = set(have)
    miss = [c for c in need if c not in have]
    if miss:
        raise InputError(path, f"not a {what}: missing column(s) {', '.join(miss)}")


def read_table(path, columns=None, filters=None, what: str = "table") -> pa.Table:
    """Read ``columns`` (default all) of ``path``, rows kept by ``filters`` (pyarrow syntax)."""
    if columns is not None:
        require(path, names(path, what), list(columns), what)
    cols = None if columns is None else list(columns)
    try:
        if filters is None:  # no dataset machinery: ~0.4 s less CPU at a stage's start-up
            return pq.ParquetFile(path).read(columns=cols)
        return pq.read_table(path, columns=cols, filters=filters)
    except FileNotFoundError:
        raise InputError(path, "no such file") from None
    except (OSError, pa.ArrowInvalid) as exc:
        raise InputError(path, f"cannot read as a Parquet {what} ({_short(exc)})") from None


@contextmanager
def block_writer(out, meta: dict | None, schema_of: Callable[[dict], pa.Schema]) -> Iterator:
    """Stream a table to ``out`` atomically, one row group per block: yields ``w`` with
    ``w.put(cols)`` (a mapping of every column of the schema to a 1-D array) and ``w.meta``,
    settable until the first ``put`` (the schema, with its metadata, is ``schema_of(w.meta)``).
    A table with no block put is written empty."""
    w = SimpleNamespace(meta=dict(meta or {}), rows=0)
    with atomic_output(out) as tmp:
        pw = schema = None

        def put(cols) -> None:
            nonlocal pw, schema
            if pw is None:
                schema = schema_of(w.meta)
                pw = pq.ParquetWriter(tmp, schema)
            arrays = [from_numpy(np.asarray(cols[f.name]), f.type) for f in schema]
            pw.write_table(pa.Table.from_arrays(arrays, schema=schema))
            w.rows += len(arrays[0])

        w.put = put
        try:
            yield w
            if pw is None:
                pq.write_table(schema_of(w.meta).empty_table(), tmp)
        finally:
            if pw is not None:
                pw.close()
