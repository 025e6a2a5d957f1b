"""What the figures share: each grade's colour and line style, and error bands over sequences.

:func:`grade_styles` keeps a grade's look the same in every figure; :func:`grade_errors`
gathers a grade's navigation errors as (sequences, epochs) matrices (:func:`epoch_matrix`)
and :func:`error_bands` their 5/50/95 % bands.
"""

from __future__ import annotations

import zlib
from collections.abc import Iterable, Sequence

import numpy as np
import pandas as pd

from imugen.core.errors import InputError
from imugen.tables import SEQUENCE
from imugen.tables import nav as tnav
from imugen.tables import truth as col

ERR = tnav.ERR_POS
TRACK = tnav.ERR_TRACK

# Fixed colours: datasheet grades use the base hue, the paper's presets a darker shade of it,
# so both can share one figure (config/paper.yaml) and still read as the same class.
_COLOURS = {
    "consumer": "#d62728",
    "low_cost": "#d62728",
    "paper_low_cost": "#8b0a0a",
    "industrial": "#ff7f0e",
    "paper_industrial": "#a8520a",
    "tactical": "#1f77b4",
    "paper_tactical": "#0b3d91",
    "navigation": "#2ca02c",
    "paper_navigation": "#15601a",
}
# names containing one of these keys take its colour (e.g. "my_tactical")
_CLASS_KEYS = (
    ("low_cost", "#d62728"),
    ("consumer", "#d62728"),
    ("industrial", "#ff7f0e"),
    ("tactical", "#1f77b4"),
    ("navigation", "#2ca02c"),
)
_FALLBACK = ("#9467bd", "#8c564b", "#e377c2", "#7f7f7f", "#bcbd22", "#17becf")

_DARK = 0.55  # paper presets: the class hue darkened by this factor
_LIGHT = 0.5  # calibrated variants: the class hue mixed with white by this fraction


def _shade(hex_colour: str, dark: float = 1.0, light: float = 0.0) -> str:
    rgb = np.array([int(hex_colour[i : i + 2], 16) for i in (1, 3, 5)], float) / 255.0
    rgb = rgb * dark + (1.0 - rgb * dark) * light
    return "#" + "".join(f"{round(255 * c):02x}" for c in np.clip(rgb, 0, 1))


def grade_styles(grades: Iterable[str]) -> dict[str, dict]:
    """Colour and line style of each grade: related within a class, distinct across variants.

    A grade's class (consumer/low-cost, industrial, tactical, navigation) fixes its hue
    (:func:`grade_colours`); the paper's presets (``paper_*``) draw it darker and dashed,
    calibrated variants (``*_calibrated``) lighter and dash-dotted, datasheet presets solid.
    Returns ``{grade: {"color": hex, "ls": linestyle}}``.
    """
    grades = list(grades)
    base = grade_colours(grades)
    out = {}
    for g in grades:
        low = g.lower()
        if low.startswith("paper_"):
            out[g] = {"color": _shade(base[g], dark=_DARK), "ls": "--"}
        elif low.endswith("_calibrated"):
            out[g] = {"color": _shade(base[g], light=_LIGHT), "ls": "-."}
        else:
            out[g] = {"color": base[g], "ls": "-"}
    return out


def grade_colours(grades: Iterable[str]) -> dict[str, str]:
    """Colour of each grade: fixed for known names, a stable fallback for the others.

    Known classes (consumer/low-cost red, industrial orange, tactical blue, navigation green)
    keep their hue in every figure; other names take a colour of a fallback cycle chosen by
    a checksum of the name (the next free one if two unknown names collide).
    """
    out: dict[str, str] = {}
    used: set[str] = set()
    unknown = []
    for g in grades:
        c = _COLOURS.get(g)
        if c is None:
            low = g.lower()
            c = next((c for key, c in _CLASS_KEYS if key in low), None)
        if c is None:
            unknown.append(g)
        else:
            out[g] = c
    for g in unknown:
        i = zlib.crc32(g.encode())
        for k in range(len(_FALLBACK)):
            c = _FALLBACK[(i + k) % len(_FALLBACK)]
            if c not in used:
                break
        out[g] = c
        used.add(c)
    return out


def error_bands(values: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """5th percentile, median and 95th percentile over sequences, per epoch.

    Parameters
    ----------
    values : ndarray (S, T)
        One row per sequence, one column per epoch; NaN entries are ignored.

    Returns
    -------
    p05, p50, p95 : ndarray (T,)
        Linear interpolation between order statistics (numpy's default method).
    """
    v = np.asarray(values, dtype=np.float64)
    if v.ndim != 2 or v.shape[0] == 0:
        raise ValueError(f"expected a (sequences, epochs) array, got shape {v.shape}")
    p = np.nanpercentile(v, [5.0, 50.0, 95.0], axis=0)
    return p[0], p[1], p[2]


def epoch_matrix(nav: pd.DataFrame, source="nav") -> tuple[np.ndarray, np.ndarray, dict]:
    """Navigation errors of several sequences as (sequences, epochs) matrices.

    Parameters
    ----------
    nav : DataFrame
        Long table: ``sequence``, ``time_s``, ``err_e_m``, ``err_n_m``, ``err_u_m`` (and
        optionally ``err_along_m``, ``err_cross_m``), every sequence evaluated at the same
        epochs (any row order).

    Returns
    -------
    seq : ndarray (S,) of int
    time_s : ndarray (T,)
    err : dict of ndarray (S, T)
        ``"horizontal"`` = hypot(east, north) and ``"up"`` = |up|, metres; with the track
        columns also ``"along"`` = |along| and ``"cross"`` = |cross|.
    """
    s = nav[SEQUENCE].to_numpy()
    t = nav[col.TIME].to_numpy(dtype=np.float64)
    order = np.lexsort((t, s))
    s, t = s[order], t[order]
    ids, counts = np.unique(s, return_counts=True)
    if ids.size == 0:
        raise InputError(source, "holds no navigation epochs")
    T = int(counts[0])
    if not (counts == T).all():
        raise InputError(source, "sequences have different numbers of evaluation epochs")
    tt = t.reshape(ids.size, T)
    if not np.allclose(tt, tt[:1], rtol=0.0, atol=1e-6):
        raise InputError(source, "sequences are not evaluated at the same epochs")
    e, n, u = (nav[c].to_numpy(dtype=np.float64)[order].reshape(ids.size, T) for c in ERR)
    err = {"horizontal": np.hypot(e, n), "up": np.abs(u)}
    if set(TRACK) <= set(nav.columns):
        for key, c in zip(("along", "cross"), TRACK, strict=True):
            err[key] = np.abs(nav[c].to_numpy(dtype=np.float64)[order].reshape(ids.size, T))
    return ids, tt[0].copy(), err


def grade_errors(paths: Sequence, grade: str):
    """(time (T,), {"horizontal", "up"[, "along", "cross"]: (S, T)}) over all navigation files
    of a grade (the track errors when every file has them)."""
    time = None
    track = all(tnav.has_track(p) for p in paths)
    keys = ("horizontal", "up", "along", "cross") if track else ("horizontal", "up")
    parts: dict[str, list[np.ndarray]] = {k: [] for k in keys}
    seen: set[int] = set()
    for p in paths:
        nav = tnav.read(p, [SEQUENCE, col.TIME, *ERR, *(TRACK if track else ())])
        if nav.empty:
            continue
        ids, t, err = epoch_matrix(nav, source=p)
        del nav
        dup = seen.intersection(ids.tolist())
        if dup:
            raise InputError(p, f"sequence {min(dup)} also appears in another navigation file")
        seen.update(ids.tolist())
        if time is None:
            time = t
        elif t.shape != time.shape or not np.allclose(t, time, rtol=0.0, atol=1e-6):
            raise InputError(p, "evaluation epochs differ from the grade's other navigation files")
        for k in parts:
            parts[k].append(err[k])
    if time is None:
        raise InputError(grade, "no navigation epochs in the grade's files")
    return time, {k: np.vstack(v) for k, v in parts.items()}
