"""Options of ``imugen learn train``, ``learn correct`` and ``learn table``; imports nothing
of the commands (no PyTorch)."""

from __future__ import annotations

from dataclasses import dataclass

from imugen.core.options import Command, argument, option, same_as
from imugen.figures.options import FiguresOptions


def _seconds(text: str) -> tuple[float, ...]:
    out = tuple(float(x) for x in text.split(",") if x.strip())
    if not out or any(not x > 0 for x in out):
        raise ValueError(f"need durations > 0 s, got {text!r}")
    return out


@dataclass(frozen=True, kw_only=True)
class TrainOptions:
    """How the reference network is trained (:func:`imugen.learn.train.train`)."""

    steps: int = option(600, config="benchmark.model.steps", help="training steps (batches)")
    batch_size: int = option(64, config="benchmark.model.batch_size", help="windows per batch")
    windows_per_sequence: int = option(
        8, config="benchmark.model.windows_per_sequence",
        help="windows cut from each fresh sequence of a batch",
    )  # fmt: skip
    window: int = option(200, config="benchmark.model.window", help="samples per window")
    width: int = option(32, config="benchmark.model.width", help="channels of the network")
    learning_rate: float = option(
        2e-3, config="benchmark.model.learning_rate", help="Adam's initial step (cosine decay)"
    )
    seed: int = option(0, help="root seed of the stream and the weights (the run's simulate.seed)")
    threads: int = option(1, help="PyTorch CPU threads")


@dataclass(frozen=True, kw_only=True)
class CorrectOptions:
    """How the network's predictions become a correction (:mod:`imugen.learn.correct`)."""

    smooth_s: float = option(
        60.0, unit="s", config="benchmark.model.smooth_s",
        help="causal running mean of the window predictions",
    )  # fmt: skip


@dataclass(frozen=True, kw_only=True)
class TableOptions:
    """What the benchmark table holds (:mod:`imugen.learn.table`)."""

    durations_s: tuple[float, ...] = option(
        (30.0, 60.0, 120.0, 180.0), flag="--durations", metavar="D,D,...", unit="s",
        parse=_seconds, config="benchmark.outages_s", help="outage lengths of the table",
    )  # fmt: skip
    formats: tuple[str, ...] = same_as(FiguresOptions, "formats")
    dpi: int = same_as(FiguresOptions, "dpi")


_PAIR = "ROUTE,GRADE=PATH"
COMMANDS = {
    "learn train": Command(
        TrainOptions,
        "imugen.learn.stage:main_train",
        (
            argument("truth", nargs="+", help="truth Parquet files of the training routes"),
            argument("-o", "--output", required=True, help="model file (.pt)"),
            argument("--grade", required=True, help="grade preset"),
        ),
    ),
    "learn correct": Command(
        CorrectOptions,
        "imugen.learn.stage:main_correct",
        (
            argument("model", help="model file of imugen learn train"),
            argument("shard", help="IMU shard Parquet"),
            argument("-o", "--output", required=True, help="IMU correction Parquet"),
        ),
    ),
    "learn table": Command(
        TableOptions,
        "imugen.learn.stage:main_table",
        (
            argument("-o", "--output", required=True, help="table path without extension"),
            argument("--figure", required=True, help="figure path without extension"),
            argument(
                "--aided",
                action="append",
                required=True,
                metavar=_PAIR,
                help="metrics of the aided filter (with free-inertial drift), per route and grade",
            ),
            argument(
                "--learned",
                action="append",
                default=[],
                metavar=_PAIR,
                help="metrics of the aided filter with the reference model",
            ),
            argument(
                "--split",
                action="append",
                default=[],
                metavar="ROUTE=SPLIT",
                help="the split of each route (train, validation, test)",
            ),
        ),
    ),
}
