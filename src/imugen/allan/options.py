"""Options of ``imugen allan`` (:class:`AllanOptions`); imports nothing of the stage."""

from __future__ import annotations

from dataclasses import dataclass

from imugen.core.options import Command, argument, option


@dataclass(frozen=True, kw_only=True)
class AllanOptions:
    """How much of a static shard the Allan check reads (:func:`imugen.allan.stage.run`)."""

    max_sequences: int = option(16, help="sequences to analyse")


COMMANDS = {
    "allan": Command(
        AllanOptions,
        "imugen.allan.stage:main",
        (
            argument("shard", help="shard Parquet written by `imugen simulate --static`"),
            argument("--plot", help="also draw the Allan plot to this PNG/SVG"),
            argument("-o", "--output", help="write the report (JSON) here instead of printing it"),
        ),
    )
}
