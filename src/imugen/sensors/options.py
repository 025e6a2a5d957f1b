"""Options of ``imugen grade import``, ``grade export``, ``grade fit`` and
``imugen vibration fit``; imports nothing else."""

from __future__ import annotations

from dataclasses import dataclass

from imugen.core.options import Command, argument, option


@dataclass(frozen=True, kw_only=True)
class GradeImportOptions:
    """Name and id of an imported grade (:func:`imugen.sensors.grade_io.import_grade`)."""

    name: str | None = option(
        None, shown="the grade's own, the datasheet part, the file name", help="grade name"
    )
    grade_id: int | None = option(
        None, flag="--id", shown="the grade's own, else 1000", help="stable grade id >= 100"
    )


@dataclass(frozen=True, kw_only=True)
class GradeExportOptions:
    """What the Kalibr file holds (:func:`imugen.sensors.grade_io.to_kalibr`)."""

    grades_file: str | None = option(None, help="YAML file with custom grades")
    rate_hz: float = option(100.0, unit="Hz", help="update_rate")
    topic: str = option("/imu0", help="rostopic")


@dataclass(frozen=True, kw_only=True)
class GradeFitOptions:
    """How a still log is read and fitted (:func:`imugen.sensors.fit.run`)."""

    rate_hz: float | None = option(
        None, unit="Hz", shown="from the log's time stamps", help="sample rate of the log"
    )
    name: str = option("fitted", help="grade name")
    grade_id: int = option(1000, flag="--id", help="stable grade id >= 100")
    internal_rate_hz: float | None = option(
        None,
        unit="Hz",
        shown="16 x the rate",
        help="the part's internal sample rate, if known (ADIS16405: 819.2)",
    )
    bias_model: str = option(
        "auto",
        choices=("auto", "flicker", "gauss_markov"),
        help="in-run bias: auto chooses by the width of the Allan floor (and says why)",
    )
    slow_bias: str = option(
        "auto",
        choices=("auto", "off"),
        help="a second, slower Gauss-Markov bias beyond the floor (slow_bias): auto keeps it "
        "where it lowers the weighted chi-square by more than 5 % (and says so)",
    )
    plot: str | None = option(
        None, shown="beside the grade, .png", help="figure of the measured and fitted Allan curves"
    )


def _positive(text: str) -> float:
    value = float(text)
    if not value > 0 or value == float("inf"):
        raise ValueError(f"{text!r} is not a positive number")
    return value


@dataclass(frozen=True, kw_only=True)
class VibrationFitOptions:
    """What the recording's residual is taken against (:mod:`imugen.sensors.vibration_fit`)."""

    truth: str | None = option(
        None, metavar="TRUTH", shown="none: a still record (minus its mean)",
        help="imugen truth table on the recording's clock (the residual is recording - truth)",
    )  # fmt: skip
    rotation_hz: float | None = option(
        None, unit="Hz", parse=_positive, shown="estimated from the lines",
        help="rotation (rotor, shaft) the harmonics are locked to",
    )  # fmt: skip
    rpm_column: str | None = option(
        None, metavar="COL[,COL...]", help="recording columns of rotor speeds [rpm] (their mean "
        "is the rotation; a varying rotation is order-tracked)",
    )  # fmt: skip
    reference: str | None = option(
        None, metavar="STILL", help="recording of the same IMU without vibration (motors off): "
        "its spectrum is the sensor's own noise floor",
    )  # fmt: skip
    f_min_hz: float = option(2.0, unit="Hz", help="lowest frequency taken as vibration")


_OUT = "-o", "--output"
COMMANDS = {
    "grade import": Command(
        GradeImportOptions,
        "imugen.sensors.grade_io:main_import",
        (
            argument(
                "file",
                help="Kalibr/EuRoC imu.yaml, VINS config, i2Nav/KF-GINS config, datasheet "
                "figures (a 'datasheet:' YAML) or an imugen grades file",
            ),
            argument(*_OUT, help="grades YAML to write (default: print)"),
        ),
    ),
    "grade export": Command(
        GradeExportOptions,
        "imugen.sensors.grade_io:main_export",
        (
            argument("grade", help="preset name, or FILE.yaml:NAME"),
            argument(*_OUT, help="imu.yaml to write (default: print)"),
        ),
    ),
    "grade fit": Command(
        GradeFitOptions,
        "imugen.sensors.fit:main",
        (
            argument(
                "log",
                help="still IMU log: CSV with named columns, Parquet, EuRoC imu0/data.csv, "
                "ROS 2 bag (sensor_msgs/Imu)",
            ),
            argument(*_OUT, required=True, help="grade YAML to write"),
        ),
    ),
    "vibration fit": Command(
        VibrationFitOptions,
        "imugen.sensors.vibration_fit:main",
        (
            argument("record", help="IMU recording: CSV or Parquet (imugen or EuRoC columns)"),
            argument(*_OUT, required=True, help="YAML of the fitted vibration model"),
        ),
    ),
}
