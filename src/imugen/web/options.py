"""Options of ``imugen serve`` (:class:`ServeOptions`); imports nothing else."""

from __future__ import annotations

from dataclasses import dataclass

from imugen.core.options import Command, option


@dataclass(frozen=True, kw_only=True)
class ServeOptions:
    """Where the local page listens and keeps its runs (:func:`imugen.web.app.serve`)."""

    port: int = option(8765, help="TCP port")
    host: str = option("127.0.0.1", help="address to listen on (127.0.0.1: this machine only)")
    workdir: str = option("imugen-runs", help="folder of the runs")
    repo: str | None = option(None, shown="found", help="project folder with the Snakefile")


COMMANDS = {"serve": Command(ServeOptions, "imugen.web:main")}
