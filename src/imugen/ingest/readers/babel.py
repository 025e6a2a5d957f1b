"""Formats imugen does not read itself, converted to GPX by GPSBabel when it is installed.

The file name's suffix names the GPSBabel input format (:data:`imugen.ingest.formats.GPSBABEL`). ``gpsbabel -t -r
-i FORMAT -f FILE -o gpx -F TMP.gpx`` runs in a temporary directory with a timeout
(:data:`TIMEOUT_S`), and the GPX reader reads the result; every path gets a note naming the
conversion. Without ``gpsbabel`` on the ``PATH`` the file is refused with the command to run.
"""

from __future__ import annotations

import shutil
import subprocess
import tempfile
from pathlib import Path

from imugen.core.errors import InputError
from imugen.ingest.formats import GPSBABEL
from imugen.ingest.route import RoutePath

#: Longest a conversion may run (s).
TIMEOUT_S = 120.0


def read_with_gpsbabel(path: str | Path) -> list[RoutePath]:
    """Convert ``path`` to GPX with GPSBabel and read every candidate path of the result."""
    from imugen.ingest.readers.gpx import read_gpx

    path = Path(path)
    fmt = GPSBABEL[path.suffix.lower()]
    exe = shutil.which("gpsbabel")
    if exe is None:
        raise InputError(
            path,
            f"imugen does not read this format ({fmt}) itself; install GPSBabel "
            "(https://www.gpsbabel.org) and imugen converts it, or convert it to GPX: "
            f"gpsbabel -t -r -i {fmt} -f {path.name} -o gpx -F {path.stem}.gpx",
        )
    with tempfile.TemporaryDirectory(prefix="imugen-gpsbabel-") as tmp:
        out = Path(tmp) / "converted.gpx"
        cmd = [exe, "-t", "-r", "-i", fmt, "-f", str(path.resolve()), "-o", "gpx", "-F", str(out)]
        try:
            proc = subprocess.run(
                cmd, capture_output=True, text=True, timeout=TIMEOUT_S, cwd=tmp, check=False
            )
        except subprocess.TimeoutExpired:
            raise InputError(
                path, f"GPSBabel did not convert the file within {TIMEOUT_S:g} s"
            ) from None
        except OSError as exc:
            raise InputError(path, f"GPSBabel could not be run ({exc})") from None
        if proc.returncode != 0 or not out.exists():
            why = (proc.stderr or proc.stdout).strip().splitlines()
            raise InputError(
                path,
                f"GPSBabel ({fmt}) could not convert the file"
                + (f": {why[-1][:200]}" if why else f" (exit status {proc.returncode})"),
            )
        try:
            paths = read_gpx(out)
        except InputError as exc:
            raise InputError(path, f"after conversion by GPSBabel: {exc.message}") from None
    for p in paths:
        p.notes.append(f"converted from {fmt} to GPX by GPSBabel")
    return paths
