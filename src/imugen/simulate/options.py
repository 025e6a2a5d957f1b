"""Options of ``imugen simulate`` (:class:`SimulateOptions`); imports nothing of the stage."""

from __future__ import annotations

import json
from dataclasses import dataclass

from imugen.core.options import DRAWS, Command, argument, option, same_as
from imugen.navigate.options import NavigateOptions

OUTPUTS = ("increments", "rates", "both")
"""IMU columns a shard holds (:data:`imugen.tables.shard.OUTPUTS`)."""
INCREMENTS = ("compensated", "raw")
"""Increment semantics (:data:`imugen.tables.shard.INCREMENT_KINDS`)."""
VIBRATIONS = ("off", "car", "aircraft", "quadrotor", "vehicle")
"""Vibration of the IMU case (:mod:`imugen.sensors.vibration`), besides a model's YAML."""


def _vibration(text: str) -> str:
    if text in VIBRATIONS or text.endswith((".yaml", ".yml")):
        return text
    raise ValueError(f"expected one of {', '.join(VIBRATIONS)} or a model's .yaml, got {text!r}")


def _terms(text: str) -> tuple[str, ...]:
    return tuple(t.strip() for t in text.split(",") if t.strip())


def _json(text: str):
    try:
        return json.loads(text)
    except json.JSONDecodeError as exc:
        raise ValueError(f"is not JSON ({exc.msg})") from None


@dataclass(frozen=True, kw_only=True)
class SimulateOptions:
    """How one shard of M erroneous IMU sequences is drawn and written
    (:func:`imugen.simulate.stage.run`, :func:`imugen.simulate.stage.simulate`)."""

    grade: str | object = option(help="preset name, or FILE.yaml:NAME")
    sequences: int = option(help="sequences in this shard (M)")
    seed: int = option(help="base seed of the experiment", config="simulate.seed")
    shard: int = option(help="shard index K (0-based)")
    shard_size: int | None = option(
        None, metavar="M", shown="--sequences; give it for a shorter last shard",
        config="simulate.sequences_per_shard",
        help="sequences per shard of the experiment: global ids are K*M+j",
    )  # fmt: skip
    static_s: float | None = option(
        None, flag="--static", metavar="SECONDS", unit="s", config="allan.static_s",
        help="simulate a still, level IMU",
    )  # fmt: skip
    rate_hz: float = option(100.0, unit="Hz", help="IMU rate for --static", config="allan.rate_hz")
    static_earth: str = option(
        "flat", flag="--earth", choices=("flat", "wgs84"), help="Earth model for --static"
    )
    outputs: str = option(
        "increments", choices=OUTPUTS, config="simulate.outputs",
        help="IMU columns written: angle/velocity increments, rate samples, or both",
    )  # fmt: skip
    draw: str = option(
        "ranges", choices=DRAWS, config="simulate.draw",
        help="error levels drawn in the grade's ranges per sequence, or nominal for all",
    )  # fmt: skip
    terms: tuple[str, ...] | None = option(
        None, parse=_terms, shown="all", help="comma-separated error terms to keep"
    )
    vibration: str | None = option(
        "off", parse=_vibration, metavar="KIND|FILE.yaml", config="simulate.vibration",
        help=f"vibration of the IMU case: {', '.join(VIBRATIONS)} (vehicle: the truth's vehicle "
        "class) or the YAML of `imugen vibration fit`",
    )  # fmt: skip
    temperature: dict | str | None = option(
        None, metavar="JSON", parse=_json, help="temperature profile (see docs)"
    )
    mounting: dict | None = option(
        None, metavar="JSON", parse=_json, config="mounting", shown="none: the IMU is the "
        "vehicle frame at the vehicle reference point",
        help="IMU misalignment and lever arm drawn per sequence, e.g. '{\"misalignment_sd_deg\": "
        '[1, 1, 2], "lever_arm_m": [0.5, 0, 0.3], "lever_arm_sd_m": [0.05, 0.05, 0.05]}\'',
    )  # fmt: skip
    series: bool = option(
        False, config="simulate.series",
        help="also write the true bias, scale-factor and effective-error series",
    )  # fmt: skip
    increments: str = option(
        "compensated", choices=INCREMENTS, config="simulate.increments",
        help="increment semantics: compensated (rotation vector; body frame frozen at the "
        "interval start, sculling included) or raw (plain integrals of rate and specific force)",
    )  # fmt: skip
    dtype: str = option(
        "float32", choices=("float32", "float64"), config="simulate.dtype",
        help="storage type of the measurement columns",
    )  # fmt: skip
    explicit_time: bool = option(
        False, flag="--time-column",
        help="write time_s in every row, not only the truth's uniform clock once in the shard "
        "metadata (from which readers of imugen.tables.shard rebuild the column)",
    )  # fmt: skip
    grades_file: str | None = option(None, help="YAML file with custom grades")
    route: str | None = option(
        None, shown="the route recorded in the truth metadata, else the truth file's folder "
        "name; 'static' with --static",
        help="route name: its id enters every spawn key and the sequence ids",
    )  # fmt: skip
    eval_rate_hz: float = option(
        1.0, unit="Hz", config="navigate.eval_rate_hz",
        help="with --navigate: error epochs per second",
    )  # fmt: skip
    vertical: str = same_as(NavigateOptions, "vertical")
    vertical_order: int = same_as(NavigateOptions, "vertical_order")
    vertical_time_constant_s: float = same_as(NavigateOptions, "vertical_time_constant_s")
    vertical_reference: str = same_as(NavigateOptions, "vertical_reference")


COMMANDS = {
    "simulate": Command(
        SimulateOptions,
        "imugen.simulate.stage:main",
        (
            argument("truth", nargs="?", help="truth Parquet written by `imugen truth`"),
            argument(
                "-o",
                "--output",
                help="shard Parquet (labels go beside it); optional with --navigate",
            ),
            argument(
                "--navigate",
                metavar="NAV.parquet",
                help="also navigate the shard in the same pass and write its error table here "
                "(as `imugen navigate` would, without re-reading the shard); without -o no shard "
                "is written",
            ),
        ),
    )
}
