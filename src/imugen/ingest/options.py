"""Options of ``imugen ingest`` (:class:`IngestOptions`); imports nothing of the stage."""

from __future__ import annotations

from dataclasses import dataclass

from imugen.core.options import VEHICLES, Command, argument, option
from imugen.ingest.formats import listing


@dataclass(frozen=True, kw_only=True)
class IngestOptions:
    """How one path of a route file is chosen, cleaned and converted (:func:`imugen.ingest.stage.ingest`)."""

    path: str | int | None = option(
        None, help="candidate path name, or 1-based index, when the file has several; 'all': "
        "one route per path, written to OUT's name as a folder (OUT.parquet -> OUT/ID.parquet, "
        "stable ids '<name>-<hash of name and first point>'); 'all:ID': that one route of "
        "them; default: the only path, or the whole file when its paths are segments of one "
        "track that continue each other",
        config="routes.*.path",
    )  # fmt: skip
    origin: str | None = option(
        None, metavar="LAT,LON,H", help="ENU origin, degrees and metres", shown="first point",
        config="routes.*.origin",
    )  # fmt: skip
    dt: float | None = option(
        None, metavar="SECONDS", unit="s", help="uniform clock for an untimed path",
        config="routes.*.dt_s",
    )  # fmt: skip
    utm: bool = option(False, help="also write UTM easting/northing columns")
    max_speed_kmh: float = option(1200.0, unit="km/h", help="refuse faster implied speeds")
    max_extent_km: float | None = option(
        None, unit="km", config="routes.*.max_extent_km", shown="none: routes of any length, "
        "simulated in ECEF when long",
        help="refuse points farther than this from the origin, measured along the WGS-84 "
        "geodesic between the origin and the point (heights ignored); a sanity limit of your own",
    )  # fmt: skip
    gap_warn_s: float = option(60.0, unit="s", help="warn about longer time gaps")
    vehicle: str = option(
        "car", choices=VEHICLES, config="routes.*.vehicle",
        help="vehicle class whose limits decide what is an outlier",
    )  # fmt: skip
    max_gap_s: float | None = option(
        None, metavar="SECONDS", unit="s", shown="60", config="routes.*.max_gap_s",
        help="time gaps longer than this split the path (see --gaps)",
    )  # fmt: skip
    gaps: str = option(
        "auto", choices=("auto", "split", "bridge"), config="routes.*.gaps",
        help="judge each long gap by motion (auto: bridged by a straight leg, or a stop where "
        "the fixes nearly coincide, when the vehicle could have made it at the speed around "
        "the gap, else split; each gap reported), split the path at every long gap (parts are "
        "candidates; --path longest), or bridge them all (the truth interpolates)",
    )  # fmt: skip
    navsatfix_status: str = option(
        "lenient", choices=("lenient", "strict"),
        help="a ROS NavSatFix dump whose every row has status -1 (no fix) but finite positions "
        "and covariances: read them with a warning (a driver that never sets the status), or "
        "refuse the file",
    )  # fmt: skip
    pose_world: str = option(
        "enu", choices=("enu", "ned", "flu", "ecef"), config="routes.*.pose_world",
        help="world frame of a pose trajectory (TUM, EuRoC, pose CSV, ROS 2 bag): local ENU, "
        "NED or z-up FLU axes with their origin at --origin, or ECEF",
    )  # fmt: skip
    pose_world_yaw_deg: float = option(
        0.0, unit="deg", config="routes.*.pose_world_yaw_deg",
        help="heading of a flu pose world's x axis, from East towards North",
    )  # fmt: skip


COMMANDS = {
    "ingest": Command(
        IngestOptions,
        "imugen.ingest.stage:main",
        (
            argument("src", help=f"route file: {listing()}"),
            argument(
                "-o", "--output", required=True, help="output file ending in .parquet or .csv"
            ),
        ),
    )
}
