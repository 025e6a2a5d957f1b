"""Progress of long jobs: detailed lines to the job's log, a short form to the console.

A job's stderr goes to its log (the workflow redirects it); every ``every_s`` seconds, and at the
end of a job that lasted at least that long, :class:`Progress` writes ``label: done/total unit,
rate, elapsed, left`` there (a short job prints nothing, so its only stderr line is its result
or its one-line error). When the
environment names a console file descriptor (``IMUGEN_CONSOLE_FD``, set by the workflow's rules
to a copy of Snakemake's own stderr taken before the redirection), a short line goes there too,
at most every ``console_s`` seconds and at the end, so a person watching ``snakemake`` sees long
jobs advance.
"""

from __future__ import annotations

import os
import sys
import time

CONSOLE_FD = "IMUGEN_CONSOLE_FD"


def _console():
    fd = os.environ.get(CONSOLE_FD)
    if not fd or not fd.isdigit():
        return None
    try:
        return os.fdopen(os.dup(int(fd)), "w", buffering=1)
    except OSError:
        return None


def _dur(s: float) -> str:
    s = max(0.0, s)
    return f"{s:.0f} s" if s < 120 else f"{s / 60:.1f} min"


class Progress:
    """Report progress over ``total`` units of work (see the module docstring)."""

    def __init__(
        self,
        label: str,
        total: int,
        unit: str = "sequences",
        every_s: float = 10.0,
        console_s: float = 30.0,
    ):
        self.label, self.total, self.unit = label, max(int(total), 0), unit
        self.every_s, self.console_s = every_s, console_s
        self.t0 = time.monotonic()
        self.last_log = self.last_console = self.t0
        self.console = _console()
        self.done = 0

    def line(self, now: float) -> str:
        el = now - self.t0
        rate = self.done / el if el > 0 else 0.0
        left = (self.total - self.done) / rate if rate > 0 else float("nan")
        text = f"{self.label}: {self.done}/{self.total} {self.unit}, {rate:.3g}/s, {_dur(el)}"
        return text + (f", {_dur(left)} left" if self.done < self.total and rate > 0 else "")

    def update(self, done: int) -> None:
        self.done = int(done)
        now = time.monotonic()
        final = self.done >= self.total
        long_job = now - self.t0 >= self.every_s
        if (final and long_job) or now - self.last_log >= self.every_s:
            print(self.line(now), file=sys.stderr, flush=True)
            self.last_log = now
        if self.console is not None and (
            (final and long_job) or now - self.last_console >= self.console_s
        ):
            pct = 100.0 * self.done / self.total if self.total else 100.0
            self.console.write(
                f"  {self.label}: {pct:.0f} % ({self.line(now).split(', ', 1)[1]})\n"
            )
            self.last_console = now
        if final and self.console is not None:
            self.console.close()
            self.console = None
