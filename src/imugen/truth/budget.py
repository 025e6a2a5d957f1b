"""The ``--earth auto`` budget of a truth: which Earth model the simulated grades need."""

from __future__ import annotations

import numpy as np

from imugen.core import earth as ea


def grade_figures(grade) -> ea.GradeFigures:
    """Budget figures of a grade given as figures, a :class:`imugen.sensors.grades.Grade`, a preset
    name or ``FILE.yaml:NAME`` (a custom grade)."""
    if isinstance(grade, ea.GradeFigures):
        return grade
    from imugen.sensors.grades import budget_figures

    return budget_figures(grade)


def earth_budget(motion, samples, lat0_rad, grades=None, fraction=0.1):
    """Budget of the dropped Earth terms of ``motion`` against the grades' own errors.

    Parameters
    ----------
    motion : TimedMotion or PathMotion
    samples : int
        IMU samples of the truth (the scene is sampled at most 20,001 times).
    lat0_rad : float
        Origin latitude [rad].
    grades : str, Grade, GradeFigures or a list of them, optional
        Default ``consumer``. With several, the most demanding model decides (``geodetic``,
        then ``wgs84``, then ``flat``).
    fraction : float
        ``flat`` when every dropped term is below ``fraction`` x the grade effect.

    Returns
    -------
    imugen.core.earth.EarthBudget
        The deciding grade's budget.
    """
    if grades is None:
        grades = ["consumer"]
    elif isinstance(grades, (str, ea.GradeFigures)) or not isinstance(grades, (list, tuple)):
        grades = [grades]
    pts = motion.position(np.linspace(motion.t0, motion.t1, min(samples, 20001)))
    bt = np.linspace(motion.t0, motion.t1, len(pts))
    budgets = [
        ea.choose_earth_model(bt, pts, lat0_rad, grade_figures(g), fraction=fraction)
        for g in grades
    ]
    # the most demanding model decides: any grade that needs wgs84 gets it for all
    rank = {"flat": 0, "wgs84": 1, "geodetic": 2}
    top = max(rank[b.model] for b in budgets)
    if top == 0:
        return min(budgets, key=lambda b: b.grade_effect_m)
    return next(b for b in budgets if rank[b.model] == top)


def budget_meta(budget: ea.EarthBudget, grades) -> dict:
    """The budget as truth metadata (JSON types)."""
    if grades is None:
        names = None
    else:
        names = [_name(g) for g in (grades if isinstance(grades, (list, tuple)) else [grades])]
    return {
        "grade": budget.grade,
        "grades_considered": names,
        "fraction": budget.fraction,
        "grade_effect_m": budget.grade_effect_m,
        "terms_m": budget.terms_m,
        "lines": budget.lines,
    }


def _name(g) -> str:
    return g if isinstance(g, str) else str(getattr(g, "name", g))
