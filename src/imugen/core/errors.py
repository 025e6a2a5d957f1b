"""User-facing errors: one line naming the file and the problem."""

from __future__ import annotations

from pathlib import Path


class InputError(Exception):
    """A problem with a user's input file or option (exit status 2, no traceback).

    Parameters
    ----------
    source : str or Path or None
        File (or option) the problem is in; printed first.
    message : str
        What is wrong, in one line.
    """

    def __init__(self, source: str | Path | None, message: str):
        self.source = None if source is None else str(source)
        self.message = " ".join(str(message).split())
        super().__init__(str(self))

    def __str__(self) -> str:
        return f"{self.source}: {self.message}" if self.source else self.message


def printable(text: str) -> str:
    """``text`` with non-printable characters escaped (``\\x1b``), so that a message a file
    could smuggle terminal escapes or line breaks into stays one line."""
    if text.isprintable():
        return text
    return "".join(c if c.isprintable() else c.encode("unicode_escape").decode() for c in text)
