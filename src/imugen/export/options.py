"""Options of ``imugen export`` and ``imugen export-mat``; imports nothing of the stage."""

from __future__ import annotations

from dataclasses import dataclass

from imugen.core.options import Command, argument, option


def _names(text: str) -> tuple[str, ...]:
    """``"a, b"`` -> ``("a", "b")``."""
    return tuple(s.strip() for s in text.split(",") if s.strip())


@dataclass(frozen=True, kw_only=True)
class ExportOptions:
    """Which datasets are written and how their sequences are split (:func:`imugen.export.stage.run`)."""

    formats: tuple[str, ...] = option(
        flag="--format", metavar="FORMATS", parse=_names, config="exports.formats",
        help="comma-separated formats: euroc, tum, tlio, ronin, kfgins, ros2",
    )  # fmt: skip
    route: str | None = option(None, shown="the truth's folder", help="route name in folder names")
    grade: str | None = option(None, shown="from the shards", help="grade name in folder names")
    nav_rate_hz: float = option(
        10.0, unit="Hz", config="exports.nav_rate_hz", help="rate of TUM trajectories"
    )
    split_seed: int = option(
        0, config="exports.split.seed", help="seed of the TLIO and RoNIN split lists"
    )
    split_by: str = option(
        "sequence", choices=("sequence", "route"), config="exports.split.by",
        help="split unit of the lists: each sequence, or each route whole",
    )  # fmt: skip
    holdout_routes: tuple[str, ...] = option(
        (), metavar="A,B", parse=_names, config="exports.split.holdout_routes",
        help="routes whose sequences form the test list, whole, in every export",
    )  # fmt: skip
    val_fraction: float = option(
        0.1, config="exports.split.val_fraction", help="share of the val list"
    )
    test_fraction: float = option(
        0.1, config="exports.split.test_fraction",
        help="share of the test list without --holdout-routes",
    )  # fmt: skip
    sequences: tuple[int, ...] | None = option(
        None, many="+", metavar="ID", shown="all", help="export only these sequence ids"
    )
    storage: str = option("sqlite3", choices=("sqlite3", "mcap"), help="ROS 2 bag storage")
    overwrite: bool = option(False, help="replace an existing output folder")


@dataclass(frozen=True, kw_only=True)
class ExportMatOptions:
    """What the ``.mat`` file records (:func:`imugen.export.mat.export_mat`)."""

    grade: str = option(help="grade name (checked against the shards)")
    route: str | None = option(
        None, shown="the truth's folder", help="route name recorded in the file"
    )
    mat_version: str = option(
        "auto", choices=("auto", "5", "7.3"),
        help="MAT format: v5 while every variable is under 2 GiB (auto), else v7.3 (h5py)",
    )  # fmt: skip


COMMANDS = {
    "export": Command(
        ExportOptions,
        "imugen.export.stage:main",
        (
            argument("truth", help="truth Parquet of the route"),
            argument("shards", nargs="+", help="IMU shard Parquet files (with their labels)"),
            argument(
                "-o", "--output", required=True, help="output folder (one subfolder per format)"
            ),
            argument(
                "--gnss",
                nargs="+",
                metavar="GNSS.parquet",
                help="GNSS epoch tables of `imugen aid` for these shards (KF-GINS gnss.pos, ROS "
                "/gnss/fix)",
            ),
            argument(
                "--aided",
                nargs="+",
                metavar="AIDED.parquet",
                help="aided navigation tables of `imugen aid` for these shards (TUM "
                "<seq>.aided.tum)",
            ),
            argument(
                "--companions",
                nargs="+",
                metavar="COMPANIONS.parquet",
                help="companion-sensor tables of `imugen aid` for these shards "
                "(ROS /wheel/odometry, /baro/pressure)",
            ),
        ),
    ),
    "export-mat": Command(
        ExportMatOptions,
        "imugen.export.mat:main",
        (
            argument("--truth", required=True, help="truth Parquet"),
            argument("--shards", nargs="+", required=True, help="the grade's shard Parquet files"),
            argument("--nav", nargs="+", help="the grade's navigation-error files (optional)"),
            argument("-o", "--output", required=True, help=".mat path"),
        ),
    ),
}
