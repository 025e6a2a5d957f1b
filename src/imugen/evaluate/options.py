"""Options of ``imugen evaluate`` and ``imugen tables``; imports nothing of the stage."""

from __future__ import annotations

from dataclasses import dataclass

from imugen.core.options import Command, argument, option


def _seconds(text: str) -> tuple[float, ...]:
    """``"30,60,120"`` -> ``(30.0, 60.0, 120.0)``: durations > 0 s."""
    try:
        out = tuple(float(x) for x in text.split(",") if x.strip())
    except ValueError:
        raise ValueError(f"not a comma-separated list of seconds: {text!r}") from None
    if not out or any(not x > 0 for x in out):
        raise ValueError(f"need durations > 0 s, got {text!r}")
    return out


@dataclass(frozen=True, kw_only=True)
class EvaluateOptions:
    """What the metrics of one grade hold (:func:`imugen.evaluate.stage.run`)."""

    grade: str = option(help="grade name (recorded in the output)")
    segments_s: tuple[float, ...] = option(
        (), flag="--segments", metavar="T,T,...", unit="s", parse=_seconds,
        config="evaluate.segments_s", help="relative drift after T seconds from true starts "
        "(needs --imu), e.g. 30,60,120",
    )  # fmt: skip


@dataclass(frozen=True, kw_only=True)
class TablesOptions:
    """``imugen tables`` has inputs and an output only."""


COMMANDS = {
    "evaluate": Command(
        EvaluateOptions,
        "imugen.evaluate.stage:main",
        (
            argument("truth", help="truth Parquet"),
            argument("nav", nargs="+", help="navigation-error Parquet files of the grade"),
            argument("-o", "--output", required=True, help="per-sequence metrics Parquet"),
            argument(
                "--imu", nargs="+", default=[], help="IMU shards of the grade (for --segments)"
            ),
            argument(
                "--aided",
                nargs="+",
                default=[],
                help="aided error tables of the grade (imugen aid)",
            ),
        ),
    ),
    "tables": Command(
        TablesOptions,
        "imugen.evaluate.stage:main_tables",
        (
            argument("metrics", nargs="+", help="metrics Parquet files, one per grade"),
            argument("-o", "--output", required=True, help="CSV path; .md/.tex/.html beside it"),
        ),
    ),
}
