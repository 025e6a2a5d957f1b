"""The contract layer: one module per file that passes between stages.

Each module owns its table's column names, units, metadata block, reader and writer (built
on the atomic writes of :mod:`imugen.core.io`); no stage parses another's file by hand.

- :mod:`~imugen.tables.enu`: ingestion output (route points in local ENU);
- :mod:`~imugen.tables.truth`: truth motion and ideal IMU at the IMU rate;
- :mod:`~imugen.tables.shard`: measured IMU shard, its labels sidecar, optional series;
- :mod:`~imugen.tables.nav`: navigation errors per sequence and epoch;
- :mod:`~imugen.tables.metrics`: per-sequence RMSE and final errors;
- :mod:`~imugen.tables.gnss`: GNSS epochs of ``imugen aid`` with receiver and scenario labels;
- :mod:`~imugen.tables.aided`: aided (GNSS/INS filter) navigation errors and state;
- :mod:`~imugen.tables.companions`: odometer and barometer epochs of ``imugen aid``, labels;
- :mod:`~imugen.tables.imu_correction`: per-sample IMU corrections (a learner's, into
  ``imugen aid``; the filter's own, out of it);
- :mod:`~imugen.tables.filter_estimates`: the aided filter's state and sigmas at every epoch
  (``imugen aid --estimates-out``);
- :mod:`~imugen.tables.learned`: a learner's body-frame velocities and NHC variances per epoch
  (``imugen aid --learned-in``);
- :mod:`~imugen.tables.layout`: where the workflow writes each of them (``results/...``).

``SEQUENCE`` (``"sequence"``) and ``TIME`` (``"time_s"``) are shared by all of them. The
submodules load on first use (``imugen.tables.gnss`` and ``aided`` import pandas, which a
simulate or navigate job does not need: 0.4 CPU-s of its start-up).
"""

import importlib

SEQUENCE = "sequence"
"""Sequence id column of shards, navigation and metrics tables (int32 or int64)."""
TIME = "time_s"
"""Time column, seconds from the first sample of the route."""

_SUBMODULES = (
    "aided", "companions", "enu", "filter_estimates", "gnss", "imu_correction", "layout",
    "learned", "metrics", "nav", "shard", "truth",
)  # fmt: skip
__all__ = ["SEQUENCE", "TIME", *_SUBMODULES]


def __getattr__(name):
    if name in _SUBMODULES:
        return importlib.import_module(f"{__name__}.{name}")
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
