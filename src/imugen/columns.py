"""Column names of the ENU and truth tables: a thin re-export of :mod:`imugen.tables`.

Kept only so that modules still importing ``imugen.columns`` keep working; new code imports
:mod:`imugen.tables.enu` and :mod:`imugen.tables.truth`.
"""

from imugen.io import METADATA_KEY
from imugen.tables.enu import ALT, ENU, LAT, LON, E, N, U
from imugen.tables.truth import (
    ACCEL,
    DTHETA,
    DV,
    EULER,
    GYRO,
    POS,
    QUAT,
    TIME,
    UNITS,
    VEL,
)
from imugen.tables.truth import COLUMNS as TRUTH_COLUMNS

__all__ = [
    "ACCEL",
    "ALT",
    "DTHETA",
    "DV",
    "ENU",
    "EULER",
    "GYRO",
    "LAT",
    "LON",
    "METADATA_KEY",
    "POS",
    "QUAT",
    "TIME",
    "TRUTH_COLUMNS",
    "UNITS",
    "VEL",
    "E",
    "N",
    "U",
]
