"""Options of ``imugen truth`` (:class:`TruthOptions`); imports nothing of the stage."""

from __future__ import annotations

from dataclasses import dataclass

from imugen.core.options import VEHICLES, Command, argument, floats, option

EARTH_MODELS = ("flat", "wgs84", "geodetic", "auto")
"""Earth models of the truth (:mod:`imugen.core.earth`; ``auto`` chooses one)."""


def _name_values(items: tuple[str, ...]) -> dict:
    """``("NAME=VALUE", "NAME=A,B")`` -> ``{"NAME": "VALUE", "NAME": ["A", "B"]}``."""
    out = {}
    for item in items:
        name, sep, value = item.partition("=")
        if not sep or not name or not value:
            raise ValueError(f"{item!r} is not NAME=VALUE")
        out[name] = value.split(",") if "," in value else value
    return out


def _xyz(text: str) -> tuple[float, float, float]:
    return floats(text, 3, "X,Y,Z")


@dataclass(frozen=True, kw_only=True)
class TruthOptions:
    """Rate, Earth model and vehicle of a truth (:func:`imugen.truth.build.build_truth`)."""

    rate_hz: float = option(100.0, unit="Hz", help="IMU rate", config="truth.rate_hz")
    earth: str = option(
        "auto", choices=EARTH_MODELS, config="truth.earth",
        help="Earth model; auto picks flat when every term it drops stays below 10 % of the "
        "grades' error effect, geodetic (ECEF, any distance) when the route reaches beyond "
        "64 km from its origin (as the workflow does)",
    )  # fmt: skip
    vehicle: str = option(
        "car", choices=VEHICLES, config="routes.*.vehicle", help="vehicle model of the truth motion"
    )
    grade: tuple[str, ...] = option(
        (), many="append", shown="consumer",
        help="sensor grade, preset name or FILE.yaml:NAME, whose error budget `--earth auto` "
        "compares the dropped terms with (repeat for several: the most demanding decides)",
    )  # fmt: skip
    vehicle_params: dict | None = option(
        None, flag="--vehicle-param", many="append", metavar="NAME=VALUE", parse=_name_values,
        help="override a vehicle model parameter or limit (SI units, e.g. max_curvature_1pm=0.1)",
    )  # fmt: skip
    allow_implausible: bool = option(
        False,
        help="write a truth that exceeds its vehicle's limits (the pre-write gate then only "
        "warns; for studying implausible inputs)",
    )
    suspension: str = option(
        "auto", choices=("auto", "rigid", "damped"), config="routes.*.suspension",
        help="body roll and pitch on the suspension of a ground vehicle: damped (a second-order "
        "response to the lateral and longitudinal acceleration, passenger-car gradients; "
        "--vehicle-param roll_gradient_radpmps2=... etc.), rigid (the path's attitude), or auto "
        "(the vehicle class's: damped for a car, rigid for every other class)",
    )  # fmt: skip
    pose_body: str = option(
        "flu", choices=("flu", "frd", "rdf"), config="routes.*.pose_body",
        help="axes of a pose trajectory's body (rdf: a camera, x right, y down, z forward)",
    )  # fmt: skip
    imu_rotation_deg: tuple = option(
        (0.0, 0.0, 0.0), metavar="ROLL,PITCH,YAW", unit="deg", parse=_xyz,
        config="routes.*.imu_rotation_deg",
        help="rotation of the IMU's FLU axes in the pose body's (FLU-ordered) axes",
    )  # fmt: skip
    lever_arm_m: tuple = option(
        (0.0, 0.0, 0.0), metavar="X,Y,Z", unit="m", parse=_xyz, config="routes.*.lever_arm_m",
        help="IMU position in the pose body's axes, from the body's origin",
    )  # fmt: skip
    marker_offset_m: tuple = option(
        (0.0, 0.0, 0.0), metavar="X,Y,Z", unit="m", parse=_xyz,
        config="routes.*.marker_offset_m",
        help="tracked point (the poses' position) in the pose body's axes, from its origin",
    )  # fmt: skip
    time_offset_s: float = option(
        0.0, unit="s", config="routes.*.time_offset_s",
        help="added to a pose trajectory's clock to give the IMU's",
    )  # fmt: skip
    pose_sigma_m: float | None = option(
        None, unit="m", shown="estimated", help="position noise of a pose trajectory, per axis"
    )
    pose_sigma_deg: float | None = option(
        None, unit="deg", shown="estimated", help="attitude noise of a pose trajectory, per axis"
    )
    pose_cutoff_hz: float | None = option(
        None, unit="Hz", shown="from the noise",
        help="smoothing cutoff of a pose trajectory (instead of the discrepancy principle)",
    )  # fmt: skip


COMMANDS = {
    "truth": Command(
        TruthOptions,
        "imugen.truth.stage:main",
        (
            argument("enu", help="ENU Parquet written by `imugen ingest`"),
            argument("-o", "--output", required=True, help="truth Parquet"),
        ),
    )
}
