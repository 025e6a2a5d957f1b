"""Options of ``imugen figures``, ``imugen outage-figure`` and ``imugen outage-drift``; imports nothing of the stage."""

from __future__ import annotations

from dataclasses import dataclass

from imugen.core.options import Command, argument, option, same_as

REPRESENTATIVE = ("median", "best", "worst")
"""Which sequence represents a grade in Figure 8 (by total RMSE)."""


@dataclass(frozen=True, kw_only=True)
class FiguresOptions:
    """How the route figures are drawn (:func:`imugen.figures.stage.run`)."""

    formats: tuple[str, ...] = option(
        ("png", "svg"), many="+", config="figures.formats", help="figure formats"
    )
    dpi: int = option(150, config="figures.dpi", help="raster resolution of PNG figures")
    zoom_fraction: float = option(
        0.2, config="figures.zoom_fraction", help="final fraction of the route time in the zoom "
        "of Figure 8",
    )  # fmt: skip
    representative: str = option(
        "median", choices=REPRESENTATIVE, config="figures.representative",
        help="which sequence represents a grade in Figure 8 (by total RMSE)",
    )  # fmt: skip


@dataclass(frozen=True, kw_only=True)
class OutageFigureOptions:
    """How the outage figure is drawn (:func:`imugen.figures.outage.outage_growth`)."""

    formats: tuple[str, ...] = same_as(FiguresOptions, "formats")
    dpi: int = same_as(FiguresOptions, "dpi")


@dataclass(frozen=True, kw_only=True)
class OutageDriftOptions:
    """How the outage-drift figure is drawn (:func:`imugen.figures.outage_drift.outage_drift`)."""

    formats: tuple[str, ...] = same_as(FiguresOptions, "formats")
    dpi: int = same_as(FiguresOptions, "dpi")


_NAV = argument("--nav", action="append", metavar="GRADE=PATH", help="navigation errors")
COMMANDS = {
    "figures": Command(
        FiguresOptions,
        "imugen.figures.stage:main",
        (
            argument("truth", help="truth Parquet"),
            argument("-o", "--outdir", required=True, help="folder for the figures"),
            _NAV,
            argument("--metrics", action="append", metavar="GRADE=PATH", help="per-sequence RMSE"),
            argument("--imu", action="append", metavar="GRADE=PATH", help="a shard per grade"),
        ),
    ),
    "outage-figure": Command(
        OutageFigureOptions,
        "imugen.figures.outage:main",
        (
            argument("-o", "--output", required=True, help="figure path without extension"),
            argument(
                "--aided", action="append", required=True, metavar="GRADE=PATH", help="aided tables"
            ),
            _NAV,
        ),
    ),
    "outage-drift": Command(
        OutageDriftOptions,
        "imugen.figures.outage_drift:main",
        (
            argument("-o", "--output", required=True, help="figure path without extension"),
            argument("--table", required=True, help="table CSV (a Markdown twin beside it)"),
            argument(
                "--metrics",
                action="append",
                required=True,
                metavar="GRADE=PATH",
                help="per-sequence metrics",
            ),
        ),
    ),
}
