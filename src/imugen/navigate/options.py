"""Options of ``imugen navigate`` (:class:`NavigateOptions`); imports nothing of the stage."""

from __future__ import annotations

from dataclasses import dataclass

from imugen.core.options import Command, argument, option


@dataclass(frozen=True, kw_only=True)
class NavigateOptions:
    """When a shard's navigation errors are evaluated (:func:`imugen.navigate.stage.run`)."""

    eval_rate_hz: float = option(
        1.0, unit="Hz", help="evaluation epochs per second", config="navigate.eval_rate_hz"
    )


COMMANDS = {
    "navigate": Command(
        NavigateOptions,
        "imugen.navigate.stage:main",
        (
            argument("truth", help="truth Parquet"),
            argument("shard", help="shard Parquet written by `imugen simulate`"),
            argument("-o", "--output", required=True, help="navigation-error Parquet"),
        ),
    )
}
