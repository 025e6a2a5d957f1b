"""ENU route table: the output of ``imugen ingest``, the input of ``imugen truth``.

One row per kept input point: ``time_s`` (s, timed routes only), geodetic ``lat_deg``,
``lon_deg`` (WGS-84, degrees), ``alt_m`` (ellipsoidal height, m), and the exact local ENU
coordinates ``e_m``, ``n_m``, ``u_m`` (m) in the topocentric frame of the origin (a rigid
transform of ECEF: exact Cartesian coordinates at any distance and across the antimeridian, but
their axes are the origin's: far from it ``u_m`` is no height and the geodetic columns are the
position at the vehicle; the truth's ``geodetic`` model uses them so); optionally
``utm_e_m``, ``utm_n_m`` (``--utm``); for a pose trajectory the attitude ``q_w``, ``q_x``,
``q_y``, ``q_z`` of the pose body relative to the local ENU at the point (scalar first;
:mod:`imugen.ingest.pose`, metadata ``pose``). Metadata (JSON under ``b"imugen"``): ``origin``
{lat_deg, lon_deg, alt_m}, ``timed``, ``source`` and the ingestion report.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

from imugen.core.io import read_meta as read_meta
from imugen.core.io import write_parquet
from imugen.tables import TIME
from imugen.tables._parquet import read_table

LAT = "lat_deg"
LON = "lon_deg"
ALT = "alt_m"
E = "e_m"
N = "n_m"
U = "u_m"
ENU = (E, N, U)
UTM = ("utm_e_m", "utm_n_m")
ATTITUDE = ("q_w", "q_x", "q_y", "q_z")
COLUMNS = (TIME, LAT, LON, ALT, E, N, U)
UNITS = {
    TIME: "s",
    LAT: "deg",
    LON: "deg",
    ALT: "m",
    **dict.fromkeys((*ENU, *UTM), "m"),
    **dict.fromkeys(ATTITUDE, "1"),
}
WHAT = "ENU route table"

if TYPE_CHECKING:  # pandas is imported by the readers' to_pandas only when used
    import pandas as pd


def write(df: pd.DataFrame, meta: dict, out) -> Path:
    """Write the table with its metadata atomically."""
    return write_parquet(df, meta, out)


def read(path, columns=None) -> tuple[pd.DataFrame, dict]:
    """The table (``columns``, default all) and its metadata (InputError if unreadable, not
    written by imugen or without a requested column)."""
    meta = read_meta(path)
    return read_table(path, columns, what=WHAT).to_pandas(), meta
