"""Parquet plumbing shared by the table modules: opening, reading, clear errors.

Every reader maps a missing or unreadable file, or a missing column, to one-line
:class:`~imugen.errors.InputError` naming the file and the kind of table expected.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence

import pyarrow as pa
import pyarrow.parquet as pq

from imugen.errors import InputError

SEQUENCE = "sequence"
"""Sequence id column of shards, navigation and metrics tables (int32 or int64)."""
TIME = "time_s"
"""Time column, seconds from the first sample of the route."""


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
    try:
        return pq.read_table(
            path, columns=None if columns is None else list(columns), filters=filters
        )
    except FileNotFoundError:
        raise InputError(path, "no such file") from None
    except (OSError, pa.ArrowInvalid) as exc:
        raise InputError(path, f"cannot read as a Parquet {what} ({_short(exc)})") from None
