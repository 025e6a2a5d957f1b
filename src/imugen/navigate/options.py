"""Options of ``imugen navigate`` (:class:`NavigateOptions`); imports nothing of the stage."""

from __future__ import annotations

from dataclasses import dataclass

from imugen.core.options import Command, argument, option


def _positive(text: str) -> float:
    """A number of seconds > 0."""
    try:
        x = float(text)
    except ValueError:
        raise ValueError(f"not a number: {text!r}") from None
    if not x > 0:
        raise ValueError(f"must be > 0, got {text!r}")
    return x


@dataclass(frozen=True, kw_only=True)
class NavigateOptions:
    """When a shard's navigation errors are evaluated (:func:`imugen.navigate.stage.run`)."""

    eval_rate_hz: float = option(
        1.0, unit="Hz", help="evaluation epochs per second", config="navigate.eval_rate_hz"
    )
    vertical: str = option(
        "auto", choices=("auto", "free", "damped"), config="navigate.vertical.mode",
        help="vertical channel: free inertial, or damped by the reference height (a "
        "third-order height loop, docs/explanation/vertical-channel.md); auto: damped when "
        "the route lasts more than 3 growth times of the free channel (3 x 570 s) on a "
        "rotating Earth",
    )  # fmt: skip
    vertical_order: int = option(
        3, choices=(2, 3), config="navigate.vertical.order",
        help="order of the damped vertical loop",
    )  # fmt: skip
    vertical_time_constant_s: float = option(
        100.0, unit="s", config="navigate.vertical.time_constant_s", parse=_positive,
        help="time constant of the damped vertical loop (every pole at -1/T)",
    )  # fmt: skip
    vertical_reference: str = option(
        "truth", choices=("truth",), config="navigate.vertical.reference",
        help="reference height of the damped loop: the true height (an ideal height sensor)",
    )  # fmt: skip


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
