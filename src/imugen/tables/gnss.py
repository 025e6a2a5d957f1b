"""GNSS epochs table: the first output of ``imugen aid`` (one file per route, grade and shard).

One row per sequence and GNSS epoch, sorted by ``sequence`` then time:

- ``sequence`` int64 (the IMU shard's id), ``time_s`` (arrival time, an IMU sample time, s);
- ``p_{e,n,u}_m`` measured antenna position (m, ENU of the route origin; NaN without a fix),
  ``v_{e,n,u}_mps`` measured antenna velocity (m/s; NaN without a fix);
- ``sigma_p_{e,n,u}_m``, ``sigma_v_{e,n,u}_mps``: the 1-sigma the receiver reports;
- ``fix`` int8: NMEA GGA fix quality (0: no fix); ``state`` int8: scenario state
  (:data:`imugen.aid.scenarios.KINDS`; 0 nominal, 1 outage, 2/3 jamming degraded/lost, 4-8 spoofing);
- ``offset_p_{e,n,u}_m``, ``offset_v_{e,n,u}_mps``: true total error, measured minus the true
  antenna at the time of validity (receiver error plus attack);
- ``attack_p_{e,n,u}_m``, ``attack_v_{e,n,u}_mps``: the part the scenario adds (0 outside
  attacks, NaN where the fix is lost).

On a ``geodetic`` truth the positions, velocities, offsets and attacks are in its navigation
coordinates (ECEF, m and m/s), while ``sigma_*`` stay along East, North, Up at the antenna (the
receiver's errors are drawn in that local level and rotated to ECEF).

Sidecars: ``<stem>.labels.parquet``, one row per sequence with the drawn receiver parameters
(``sequence``, ``gnss_receiver_id``, ``gnss_rate_hz``, ``gnss_<figure>``,
``gnss_lever_arm_{x,y,z}_m``), and ``<stem>.intervals.parquet``, one row per scenario interval
(``sequence``, ``kind``, ``state``, ``start_s``, ``end_s`` and every parameter column, NaN when
not the kind's). Metadata (JSON under ``b"imugen"``): ``stage``, ``receiver``, ``rate_hz``,
``seed``, ``route``, ``grade``, ``shard``, ``units``.
"""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq

from imugen.core.errors import InputError
from imugen.core.io import atomic_output, with_meta, write_parquet
from imugen.core.io import read_meta as read_meta
from imugen.tables import SEQUENCE, TIME
from imugen.tables._parquet import read_table

ENU = "enu"
P = tuple(f"p_{a}_m" for a in ENU)
V = tuple(f"v_{a}_mps" for a in ENU)
SIGMA_P = tuple(f"sigma_p_{a}_m" for a in ENU)
SIGMA_V = tuple(f"sigma_v_{a}_mps" for a in ENU)
FIX = "fix"
STATE = "state"
OFFSET_P = tuple(f"offset_p_{a}_m" for a in ENU)
OFFSET_V = tuple(f"offset_v_{a}_mps" for a in ENU)
ATTACK_P = tuple(f"attack_p_{a}_m" for a in ENU)
ATTACK_V = tuple(f"attack_v_{a}_mps" for a in ENU)
COLUMNS = (
    SEQUENCE, TIME, *P, *V, *SIGMA_P, *SIGMA_V, FIX, STATE, *OFFSET_P, *OFFSET_V, *ATTACK_P,
    *ATTACK_V,
)  # fmt: skip
UNITS = {
    SEQUENCE: "1",
    TIME: "s",
    **{c: "m" for c in (*P, *SIGMA_P, *OFFSET_P, *ATTACK_P)},
    **{c: "m/s" for c in (*V, *SIGMA_V, *OFFSET_V, *ATTACK_V)},
    FIX: "NMEA GGA quality",
    STATE: "imugen.aid.scenarios.KINDS code",
}
WHAT = "GNSS epochs table"


def labels_path(path) -> Path:
    """``<stem>.labels.parquet`` beside the GNSS table."""
    path = Path(path)
    return path.with_name(path.name.removesuffix(".parquet") + ".labels.parquet")


def intervals_path(path) -> Path:
    """``<stem>.intervals.parquet`` beside the GNSS table."""
    path = Path(path)
    return path.with_name(path.name.removesuffix(".parquet") + ".intervals.parquet")


def frame(ids, scen) -> pd.DataFrame:
    """The table's rows for a :class:`imugen.aid.scenarios.ScenarioResult` of sequences ``ids``."""
    g = scen.gnss
    M, J = g.fix.shape
    out = {SEQUENCE: np.repeat(np.asarray(ids, np.int64), J), TIME: np.tile(g.time_s, M)}
    for cols, arr in (
        (P, g.p_n),
        (V, g.v_n),
        (SIGMA_P, g.sigma_p_n),
        (SIGMA_V, g.sigma_v_n),
        (OFFSET_P, g.offset_p_n),
        (OFFSET_V, g.offset_v_n),
        (ATTACK_P, scen.attack_p_n),
        (ATTACK_V, scen.attack_v_n),
    ):
        for i, c in enumerate(cols):
            out[c] = arr[..., i].ravel()
    out[FIX] = g.fix.astype(np.int8).ravel()
    out[STATE] = scen.state.astype(np.int8).ravel()
    return pd.DataFrame(out)[list(COLUMNS)]


def write(df: pd.DataFrame, labels: pd.DataFrame, intervals: pd.DataFrame, meta: dict, out):
    """Write the table and its two sidecars atomically (each with the metadata)."""
    meta = {**meta, "units": UNITS}
    write_parquet(labels, meta, labels_path(out))
    write_parquet(intervals, meta, intervals_path(out))
    return write_parquet(df, meta, out)


@contextmanager
def writer(out, meta: dict | None = None) -> Iterator[SimpleNamespace]:
    """Stream the table batch by batch: ``w.put(df)`` appends rows (one row group each); set
    ``w.labels`` and ``w.intervals`` before the block ends. ``w.meta`` (settable until the
    first ``put``) goes to the file and its sidecars. Everything is written atomically when
    the block succeeds (sidecars first), nothing when it fails."""
    w = SimpleNamespace(meta=dict(meta or {}), labels=None, intervals=None, rows=0)
    with atomic_output(out) as tmp:
        pw = None

        def put(df: pd.DataFrame) -> None:
            nonlocal pw
            m = {**w.meta, "units": UNITS}
            t = with_meta(pa.Table.from_pandas(df[list(COLUMNS)], preserve_index=False), m)
            if pw is None:
                pw = pq.ParquetWriter(tmp, t.schema)
            pw.write_table(t)
            w.rows += len(df)

        w.put = put
        try:
            yield w
        finally:
            if pw is not None:
                pw.close()
        if pw is None or w.labels is None or w.intervals is None:
            raise InputError(out, "no GNSS rows or labels to write")
        m = {**w.meta, "units": UNITS}
        write_parquet(w.labels, m, labels_path(out))
        write_parquet(w.intervals, m, intervals_path(out))


def read(path, columns=None, filters=None) -> pd.DataFrame:
    """Columns (default all) of a GNSS epochs table, rows kept by ``filters``."""
    return read_table(path, columns, filters, WHAT).to_pandas()


def read_labels(path) -> pd.DataFrame:
    """Per-sequence receiver parameters (InputError if the sidecar is missing)."""
    lp = labels_path(path)
    if not lp.exists():
        raise InputError(lp, "GNSS labels sidecar missing (incomplete aid output?)")
    return read_table(lp, what="GNSS labels table").to_pandas()


def read_intervals(path) -> pd.DataFrame:
    """One row per scenario interval (InputError if the sidecar is missing)."""
    ip = intervals_path(path)
    if not ip.exists():
        raise InputError(ip, "scenario intervals sidecar missing (incomplete aid output?)")
    return read_table(ip, what="scenario intervals table").to_pandas()
