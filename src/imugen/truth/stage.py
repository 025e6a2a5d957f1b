"""The ``imugen truth`` stage: read the ENU table, build the truth, write it."""

from __future__ import annotations

import math
import sys

import pandas as pd

from imugen.core.errors import InputError
from imugen.tables import enu as tenu
from imugen.tables import truth as ttable
from imugen.truth.build import build_truth, messages
from imugen.truth.gate import refusal
from imugen.truth.options import TruthOptions
from imugen.truth.pose import PoseSettings


def pose_settings(o: TruthOptions) -> PoseSettings:
    """The pose-truth settings of the options (SI units)."""
    for name, value in (
        ("--pose-sigma-m", o.pose_sigma_m), ("--pose-sigma-deg", o.pose_sigma_deg),
        ("--pose-cutoff-hz", o.pose_cutoff_hz),
    ):  # fmt: skip
        if value is not None and not (math.isfinite(value) and value > 0):
            raise InputError(name, f"{value!r} must be a positive number")
    if not math.isfinite(o.time_offset_s):
        raise InputError("--time-offset-s", f"{o.time_offset_s!r} is not a finite number")
    return PoseSettings(
        pose_body=o.pose_body,
        imu_rotation_rad=tuple(math.radians(x) for x in o.imu_rotation_deg),
        lever_arm_m=tuple(o.lever_arm_m),
        marker_offset_m=tuple(o.marker_offset_m),
        time_offset_s=float(o.time_offset_s),
        sigma_m=o.pose_sigma_m,
        sigma_rad=None if o.pose_sigma_deg is None else math.radians(o.pose_sigma_deg),
        cutoff_hz=o.pose_cutoff_hz,
    )


def read_enu(path) -> tuple[pd.DataFrame, dict]:
    """Read an ENU Parquet written by ``imugen ingest`` (table and metadata)."""
    return tenu.read(path)


def _vehicle_params(o: TruthOptions) -> dict | None:
    """The vehicle parameter overrides of ``o`` with its suspension model (``auto``: the
    vehicle class's)."""
    if o.suspension == "auto":
        return o.vehicle_params
    return {**(o.vehicle_params or {}), "suspension": o.suspension}


def run(enu_path, out_path, options: TruthOptions | None = None, **build) -> dict:
    """Read the ENU Parquet, build the truth with ``options`` (and ``build``: further keywords
    of :func:`~imugen.truth.build.build_truth`), write it atomically, then print the Earth
    budget and the plausibility report (stderr); returns the metadata."""
    o = options or TruthOptions()
    enu, meta = read_enu(enu_path)
    try:
        df, tmeta = build_truth(
            enu, meta, rate_hz=o.rate_hz, earth=o.earth, vehicle=o.vehicle,
            grade=list(o.grade) or None, vehicle_params=_vehicle_params(o), pose=pose_settings(o),
            verbose=False,
            **build,
        )  # fmt: skip
    except InputError as exc:
        if exc.source is None:
            raise InputError(enu_path, exc.message) from None
        raise
    if tmeta.get("gate") and not o.allow_implausible:
        raise InputError(enu_path, refusal(tmeta["gate"], tmeta["vehicle"]))
    tmeta["source"] = str(enu_path)
    tmeta["route_source"] = meta.get("source")
    ttable.write(df, tmeta, out_path)
    for line in messages(tmeta):
        print(line, file=sys.stderr)
    if tmeta.get("gate"):
        print(
            f"imugen: warning: {refusal(tmeta['gate'], tmeta['vehicle'], written=True)}",
            file=sys.stderr,
        )
    return tmeta


def main(options: TruthOptions, enu, output) -> None:
    """``imugen truth``."""
    run(enu, output, options)
