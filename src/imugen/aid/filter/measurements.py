"""The registry of measurement models: which run, in which order.

Every model is a module with a compiled ``update(e, md, inp, wk, x, tn, win) -> flags``
(:class:`~imugen.aid.filter.context.Epoch` ``e``, :class:`~imugen.aid.filter.context.Model`
``md``, :class:`~imugen.aid.filter.context.Inputs` ``inp``,
:class:`~imugen.aid.filter.context.Work` ``wk``, the nominal state ``x``, the sequence's tuning
``tn`` and the :class:`Windows` ``win``) that returns without doing anything when it is switched
off or has nothing to measure, fills one row at a time and calls
:func:`imugen.aid.filter.kalman.scalar_update`. The updates are sequential, in the order of
:func:`update` (it sets the numbers: the same updates in another order round differently).

A model that measures over a window of IMU samples (the odometer; a learned displacement
would too) also keeps a window in :class:`Windows` and registers its hooks in
:func:`begin_interval` (start of each interval of the strapdown), :func:`on_sample` (every IMU
sample) and :func:`after_feedback` (after the epoch's feedback).

Adding a measurement: a module with its ``update`` (and hooks), its flag bit (the bits in use:
:data:`FLAGS`), its data as a field of :class:`~imugen.aid.filter.context.Inputs`, and one line
in each function below.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from imugen.aid.filter import baro, gnss, learned, nhc, odometer, zupt
from imugen.aid.filter.kalman import F_REJECT
from imugen.core.jit import njit, njit_borrowing

F_ALIGNED = 32
"""Epoch flag: the filter runs (set at every epoch after the start)."""

FLAGS = {
    "gnss_position": gnss.F_GNSS_P,
    "gnss_velocity": gnss.F_GNSS_V,
    "zupt": zupt.F_ZUPT,
    "nhc": nhc.F_NHC,
    "rejected": F_REJECT,
    "aligned": F_ALIGNED,
    "odometer": odometer.F_ODO,
    "baro": baro.F_BARO,
    "learned": learned.F_LEARNED,
}
"""Every epoch flag bit, by name (the ``flags`` of the results)."""


class Windows(NamedTuple):
    """The windows of the windowed measurements (one sequence at a time)."""

    odometer: odometer.Window
    zupt: np.ndarray


@njit(cache=True)
def new_windows():
    """Zeroed :class:`Windows`."""
    return Windows(odometer.new_window(), zupt.new_window())


@njit_borrowing(cache=True)
def start(win):
    """A sequence's start: no window open."""
    odometer.start(win.odometer)
    zupt.start(win.zupt)


@njit_borrowing(cache=True)
def update(e, md, inp, wk, x, tn, win):
    """Every measurement update at epoch ``e``, in order; returns the flag bits."""
    flag = gnss.update(e, md, inp, wk, x, tn, win)
    flag |= zupt.update(e, md, inp, wk, x, tn, win)
    flag |= learned.update(e, md, inp, wk, x, tn, win)
    flag |= nhc.update(e, md, inp, wk, x, tn, win)
    flag |= odometer.update(e, md, inp, wk, x, tn, win)
    flag |= baro.update(e, md, inp, wk, x, tn, win)
    return flag


@njit_borrowing(cache=True, inline="always")
def begin_interval(win, md, inp, s, k, ke, x, wk):
    """Start of the strapdown from sample ``k`` to ``ke`` (nominal state ``x`` at ``k``)."""
    odometer.begin_interval(win.odometer, md, inp, s, k, ke, x, wk)


@njit_borrowing(cache=True, inline="always")
def on_sample(win, md, wk, q0, q1, q2, q3, vx, vy, vz, tx, ty, tz):
    """After each strapdown step (``wk.C`` before the step; ``q``, ``v`` after it; ``t`` the
    corrected angle increment, body)."""
    odometer.on_sample(win.odometer, md, wk, q0, q1, q2, q3, vx, vy, vz, tx, ty, tz)


@njit_borrowing(cache=True, inline="always")
def after_feedback(win, md, wk, tn):
    """After the epoch's feedback (the fed-back error still in ``wk.dx``)."""
    odometer.after_feedback(win.odometer, md, wk, tn)
