"""Files written by imugen: atomic outputs, and Parquet tables with JSON metadata.

Every stage writes its outputs under a temporary name in the target directory
(``.NAME.XXXXXXXX.tmp``) and renames it into place only when complete, so an interrupted job
never leaves a truncated file that looks done; the temporaries a killed job leaves behind are
removed by the next successful write of the same output. Metadata (source, units, parameters, code version) travels as JSON under the
Parquet schema metadata key :data:`METADATA_KEY`.
"""

from __future__ import annotations

import glob
import json
import os
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import TYPE_CHECKING

import pyarrow as pa
import pyarrow.parquet as pq

from imugen.core.errors import InputError

if TYPE_CHECKING:
    import pandas as pd

METADATA_KEY = b"imugen"
"""Key of the JSON metadata in the Parquet schema metadata."""


def _one_line(exc: OSError) -> str:
    """The reason of an OS error on one line (Arrow's messages may span several)."""
    return " ".join(str(exc.strerror or exc).split())


@contextmanager
def atomic_output(out: str | Path) -> Iterator[Path]:
    """Yield a temporary path beside ``out``; rename it to ``out`` when the block succeeds.

    On any failure the temporary file is removed; an OS error (no space, no permission)
    becomes a one-line :class:`InputError` naming ``out``. After a success, temporaries of
    ``out`` left by killed earlier attempts are deleted (one writer per output is assumed, as
    under Snakemake).
    """
    out = Path(out)
    try:
        out.parent.mkdir(parents=True, exist_ok=True)
        fd, name = tempfile.mkstemp(prefix=f".{out.name}.", suffix=".tmp", dir=out.parent)
    except OSError as exc:
        raise InputError(out, f"cannot write here ({_one_line(exc)})") from None
    os.close(fd)
    tmp = Path(name)
    try:
        yield tmp
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(tmp, 0o666 & ~umask)  # mkstemp creates 0600; give the usual permissions
        os.replace(tmp, out)
    except OSError as exc:
        tmp.unlink(missing_ok=True)
        raise InputError(out, f"cannot write ({_one_line(exc)})") from None
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise
    for stale in out.parent.glob(glob.escape(f".{out.name}.") + "*.tmp"):
        try:
            stale.unlink()
        except OSError:
            pass


def with_meta(table: pa.Table, meta: dict) -> pa.Table:
    """``table`` with ``meta`` stored as JSON in its schema metadata."""
    md = dict(table.schema.metadata or {})
    md[METADATA_KEY] = json.dumps(meta).encode()
    return table.replace_schema_metadata(md)


def write_parquet(df: pd.DataFrame, meta: dict, out: str | Path, **options) -> Path:
    """Write ``df`` with ``meta`` atomically; ``options`` go to :func:`pyarrow.parquet.write_table`."""
    table = with_meta(pa.Table.from_pandas(df, preserve_index=False), meta)
    with atomic_output(out) as tmp:
        pq.write_table(table, tmp, **options)
    return Path(out)


def read_meta(path: str | Path) -> dict:
    """The imugen metadata of a Parquet file (InputError if unreadable or absent)."""
    try:
        md = pq.read_schema(path).metadata or {}
    except FileNotFoundError:
        raise InputError(path, "no such file") from None
    except (OSError, pa.ArrowInvalid) as exc:
        raise InputError(path, f"cannot read as Parquet ({exc})") from None
    if METADATA_KEY not in md:
        raise InputError(path, "is not a file written by imugen (no imugen metadata)")
    return json.loads(md[METADATA_KEY])
