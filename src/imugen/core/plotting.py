"""Plotting shared by the figure-making stages: one style, reproducible and atomic files.

Drawing starts from Matplotlib's default style (a user's matplotlibrc does not leak in) with a
few project settings; figures use the object API and the Agg renderer (no display, no global
pyplot state); files are written atomically, SVG ids salted with a fixed string, glyphs
embedded as paths, date stamps left out, so output is byte-reproducible for a given Matplotlib.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from contextlib import contextmanager
from pathlib import Path

import numpy as np

from imugen.core.errors import InputError
from imugen.core.io import atomic_output

# rcParams set on top of Matplotlib's defaults for every figure
_RC = {
    "svg.hashsalt": "imugen",
    "svg.fonttype": "path",
    "font.size": 9,
    "axes.titlesize": 10,
    "legend.fontsize": 8,
    "axes.grid": True,
    "grid.alpha": 0.3,
    "path.simplify": True,
}
# savefig metadata per format: no date stamps
_METADATA = {
    "svg": {"Date": None},
    "pdf": {"CreationDate": None, "ModDate": None},
}


@contextmanager
def style():
    import matplotlib as mpl

    with mpl.rc_context():
        mpl.rcdefaults()
        mpl.rcParams.update(_RC)
        yield


def figure(**kw):
    from matplotlib.figure import Figure

    return Figure(**kw)


def check_formats(formats: Sequence[str]) -> tuple[str, ...]:
    from matplotlib.backend_bases import FigureCanvasBase

    if isinstance(formats, str):
        formats = (formats,)
    supported = FigureCanvasBase.get_supported_filetypes()
    fmts = tuple(str(f).lower().lstrip(".") for f in formats)
    for f in fmts:
        if f not in supported:
            raise InputError("formats", f"unknown figure format {f!r} (one of {sorted(supported)})")
    if not fmts:
        raise InputError("formats", "no figure format requested")
    return fmts


def save(fig, out_stem, formats: Sequence[str], dpi: float) -> list[Path]:
    """Write ``fig`` as ``<out_stem>.<ext>`` for each format, atomically."""
    fmts = check_formats(formats)
    # lay out once (at the style's 100 dpi), then freeze: every format and dpi gets the same
    # positions whatever the order of the formats
    fig.draw_without_rendering()
    fig.set_layout_engine("none")
    paths = []
    for ext in fmts:
        out = Path(f"{out_stem}.{ext}")
        with atomic_output(out) as tmp:
            fig.savefig(tmp, format=ext, dpi=dpi, metadata=_METADATA.get(ext))
        paths.append(out)
    return paths


def format_length(x: float) -> str:
    """A length for people: three significant digits, metres below 1 km, else kilometres with
    thousands separators (``0.44 m``, ``7.40 m``, ``172 m``, ``1.73 km``, ``13,400 km``)."""
    if not np.isfinite(x):
        return str(x)
    a = abs(x)
    unit, v = ("km", x / 1000.0) if a >= 1000.0 else ("m", x)
    if v == 0:
        return f"0 {unit}"
    digits = 3 - 1 - math.floor(math.log10(abs(v)))
    r = round(v, digits)
    text = f"{r:,.{max(digits, 0)}f}"
    return f"{text} {unit}"
