"""GNSS-denied scenarios: labelled intervals that cut, degrade or falsify a receiver's fixes.

Kinds (state code per epoch in brackets; 0 = nominal)
------------------------------------------------------
``outage`` [1]
    No fix (GGA quality 0) over ``[start, start + duration)``. Preset durations 30, 60, 120,
    180 s (:data:`OUTAGE_PRESETS_S`, the WhONet / IO-VNBD protocol).
``jamming`` [2 degraded, 3 lost]
    First ``degrade_s`` seconds: the reported sigmas grow linearly from 1x to ``sigma_factor``x
    and the fix really gets that noisy (extra white noise with variance ``(k^2 - 1)`` times the
    reported variance, k the inflation), the quality falls to 1 (autonomous); then no fix until
    the end of the interval.
``spoof_ramp`` [4]
    The fix is dragged off at ``rate_mps`` along the horizontal azimuth ``azimuth_rad`` (from
    East toward North): position offset ``rate (t - start) u``, velocity offset ``rate u``
    (a consistent spoofer); reported sigmas unchanged.
``spoof_step`` [5]
    Position jumps by ``offset_m`` along ``u``.
``spoof_oscillation`` [6]
    ``amplitude_m sin(2 pi (t - start) / period_s) u``, velocity offset its derivative.
``meaconing`` [7]
    Replay of the true signal ``delay_s`` late: the fix is the antenna's position and velocity
    ``delay_s`` earlier (plus the receiver's own noise).
``freeze`` [8]
    The last fix before the start repeats (position and velocity), with a fresh time stamp.

Directions and the jamming noise are along the local East, North, Up at the antenna: n itself
in ``flat`` and ``wgs84``, rotated to ECEF on a ``geodetic`` truth (``apply(..., frame=)``).

Intervals are declared (:class:`Interval`, or dicts with ``kind``, ``start_s``,
``duration_s`` and the kind's parameters) or drawn per sequence (:func:`draw`). Labels: the
state of every epoch, the attack offset of every epoch (measured minus what the receiver alone
would have given; the receiver's own error stays in ``GnssData.offset_p_n`` to which the attack
is added), and one row per interval with its parameters.

Draw distributions (:func:`draw`, every figure independent; ``T`` the scene length)
    * ``outage``: duration uniform over ``durations_s`` (default the presets);
    * ``jamming``: duration U(30, 120) s, ``degrade_s`` = U(0.2, 0.5) x duration,
      ``sigma_factor`` log-U(3, 30);
    * ``spoof_ramp``: duration U(30, 120) s, ``rate_mps`` log-U(0.1, 2), azimuth U(0, 2 pi);
    * ``spoof_step``: duration U(30, 120) s, ``offset_m`` log-U(5, 100), azimuth U(0, 2 pi);
    * ``spoof_oscillation``: duration U(30, 120) s, ``amplitude_m`` log-U(2, 50),
      ``period_s`` U(10, 60), azimuth U(0, 2 pi);
    * ``meaconing``: duration U(30, 120) s, ``delay_s`` log-U(0.5, 10);
    * ``freeze``: duration U(10, 60) s;
    * the intervals of one sequence never overlap: in a random order, one after another, with
      the free time ``T - settle_s - sum(durations)`` split at sorted uniform points (one kind
      alone: start uniform in ``[settle_s, T - duration]``; the filter converges first,
      default 60 s). Durations that do not fit together are shortened in proportion.
      Independent starts (before issue 26) overlapped in 34 % (2 kinds, 600 s) to 100 %
      (7 kinds, 600 s) of sequences and mislabelled epochs ("spoofed" with no fix).
Randomness: ``SeedSequence(seed, spawn_key=(SCENARIO_KEY, shard, j, stream))`` for sequence
``j`` (streams ``draw`` and ``noise``): independent of the IMU grade and of the receiver.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np
import pandas as pd

from imugen.aid.gnss import FIX_NONE, GnssData
from imugen.core.errors import InputError
from imugen.core.seeding import scenario_rng

KINDS = {
    "outage": 1,
    "jamming": 2,
    "spoof_ramp": 4,
    "spoof_step": 5,
    "spoof_oscillation": 6,
    "meaconing": 7,
    "freeze": 8,
}
"""Kind -> epoch state code (jamming also uses 3 for its loss phase)."""
STATE_JAMMING_LOST = 3
OUTAGE_PRESETS_S = (30.0, 60.0, 120.0, 180.0)
PARAMS = {
    "outage": (),
    "jamming": ("degrade_s", "sigma_factor"),
    "spoof_ramp": ("rate_mps", "azimuth_rad"),
    "spoof_step": ("offset_m", "azimuth_rad"),
    "spoof_oscillation": ("amplitude_m", "period_s", "azimuth_rad"),
    "meaconing": ("delay_s",),
    "freeze": (),
}
"""Parameters of each kind (SI units in the names)."""


@dataclass(frozen=True)
class Interval:
    """One scenario interval ``[start_s, start_s + duration_s)`` of a kind, with its parameters."""

    kind: str
    start_s: float
    duration_s: float
    params: dict = field(default_factory=dict)

    @property
    def end_s(self) -> float:
        return self.start_s + self.duration_s

    @classmethod
    def from_config(cls, d: dict, where: str = "scenario") -> Interval:
        """Validate a dict ``{kind, start_s, duration_s, <params>}``."""
        if not isinstance(d, dict) or d.get("kind") not in KINDS:
            raise InputError(where, f"kind must be one of {', '.join(KINDS)}")
        kind = d["kind"]
        extra = set(d) - {"kind", "start_s", "duration_s", *PARAMS[kind]}
        if extra:
            raise InputError(where, f"{kind}: unknown key(s) {', '.join(sorted(extra))}")
        try:
            start = float(d["start_s"])
            dur = float(d["duration_s"])
            prm = {k: float(d[k]) for k in PARAMS[kind] if k in d}
        except (KeyError, TypeError, ValueError) as exc:
            raise InputError(where, f"{kind}: start_s, duration_s and parameters: {exc}") from None
        if not (math.isfinite(start) and start >= 0 and math.isfinite(dur) and dur > 0):
            raise InputError(where, f"{kind}: need start_s >= 0 and duration_s > 0")
        defaults = {"degrade_s": 0.3 * dur, "sigma_factor": 10.0, "azimuth_rad": 0.0}
        for k in PARAMS[kind]:
            if k not in prm:
                if k not in defaults:
                    raise InputError(where, f"{kind}: missing {k}")
                prm[k] = defaults[k]
        if kind == "jamming" and not (0 <= prm["degrade_s"] <= dur and prm["sigma_factor"] >= 1):
            raise InputError(where, "jamming: need 0 <= degrade_s <= duration_s, sigma_factor >= 1")
        if kind == "spoof_oscillation" and prm["period_s"] <= 0:
            raise InputError(where, "spoof_oscillation: period_s must be > 0")
        if kind == "meaconing" and prm["delay_s"] < 0:
            raise InputError(where, "meaconing: delay_s must be >= 0")
        return cls(kind, start, dur, prm)


def _logu(u, lo, hi):
    return lo * (hi / lo) ** u


def draw(kinds, duration_s, seed=0, shard=0, sequences=1, *, settle_s=60.0, durations_s=None):
    """Draw one interval of each kind in ``kinds`` per sequence (distributions: module doc).

    Every kind consumes a fixed block of 6 uniforms of the sequence's ``draw`` stream, in the
    order of :data:`KINDS`, so a kind's duration and parameters do not depend on which others
    are requested (its start does: it makes room for them, the intervals never overlap).

    Returns
    -------
    list (per sequence) of list of Interval
    """
    kinds = [kinds] if isinstance(kinds, str) else list(kinds)
    for k in kinds:
        if k not in KINDS:
            raise InputError("scenario.kinds", f"unknown kind {k!r}; one of {', '.join(KINDS)}")
    durs = tuple(durations_s or OUTAGE_PRESETS_S)
    T = float(duration_s)
    avail = T - settle_s
    if kinds and avail <= 0:
        raise InputError("scenario", f"scene of {T:g} s leaves no time after settle_s")
    out = []
    for j in range(int(sequences)):
        u = scenario_rng(seed, shard, j, "draw").random((len(KINDS), 6))
        rows = [u[list(KINDS).index(k)] for k in kinds]
        dur_of = []
        for k, r in zip(kinds, rows, strict=True):
            if k == "outage":
                dur_of.append(durs[min(int(r[1] * len(durs)), len(durs) - 1)])
            elif k == "freeze":
                dur_of.append(10.0 + 50.0 * r[1])
            else:
                dur_of.append(30.0 + 90.0 * r[1])
        total = sum(dur_of)
        if len(dur_of) == 1:
            dur_of = [min(dur_of[0], avail)]
        elif total > avail:  # shortened in proportion, so that they fit one after another
            dur_of = [d * avail / total for d in dur_of]
        # order by each kind's 6th uniform; the free time split at its 1st uniforms, sorted
        order = sorted(range(len(kinds)), key=lambda i: rows[i][5])
        free = avail - sum(dur_of)
        cuts = sorted(rows[i][0] * free for i in order)
        start_of, t0 = {}, settle_s
        for n, i in enumerate(order):
            start_of[i] = t0 + cuts[n]
            t0 += dur_of[i]
        ivs = []
        for i, (k, r) in enumerate(zip(kinds, rows, strict=True)):
            dur, start = dur_of[i], start_of[i]
            az = 2.0 * math.pi * r[3]
            prm = {
                "outage": {},
                "jamming": {
                    "degrade_s": (0.2 + 0.3 * r[2]) * dur,
                    "sigma_factor": _logu(r[3], 3, 30),
                },
                "spoof_ramp": {"rate_mps": _logu(r[2], 0.1, 2.0), "azimuth_rad": az},
                "spoof_step": {"offset_m": _logu(r[2], 5.0, 100.0), "azimuth_rad": az},
                "spoof_oscillation": {
                    "amplitude_m": _logu(r[2], 2.0, 50.0),
                    "period_s": 10.0 + 50.0 * r[4],
                    "azimuth_rad": az,
                },
                "meaconing": {"delay_s": _logu(r[2], 0.5, 10.0)},
                "freeze": {},
            }[k]
            ivs.append(Interval(k, start, dur, prm))
        out.append(ivs)
    return out


_LOCAL_KINDS = ("jamming", "spoof_ramp", "spoof_step", "spoof_oscillation")
"""Kinds whose offsets are drawn along local-level axes (rotated to n in ``geodetic``)."""


@dataclass
class ScenarioResult:
    """Fixes after the scenarios, and the labels.

    Attributes
    ----------
    gnss : GnssData
        Altered copy (``p_n``, ``v_n``, ``sigma_*``, ``fix``, ``offset_*`` include the attack).
    state : (M, J) int8
        Scenario state of every epoch (0 nominal; codes in :data:`KINDS`, 3 jamming loss).
    attack_p_n, attack_v_n : (M, J, 3)
        Offset the scenario adds to the receiver's fix (0 outside attacks, NaN when lost).
    intervals : DataFrame
        One row per sequence and interval: ``sequence``, ``kind``, ``state``, ``start_s``,
        ``end_s`` and every parameter column (NaN when not the kind's).
    """

    gnss: GnssData
    state: np.ndarray
    attack_p_n: np.ndarray
    attack_v_n: np.ndarray
    intervals: pd.DataFrame


def apply(gnss: GnssData, intervals, seed=0, shard=0, first=None, frame=None) -> ScenarioResult:
    """Apply scenario intervals to the fixes of ``M`` sequences.

    Parameters
    ----------
    gnss : GnssData
        Receiver output (:func:`imugen.aid.gnss.simulate_gnss`).
    intervals : list of Interval/dict (same for every sequence) or list (per sequence) of lists
        Later intervals override earlier ones where they overlap; an epoch without a fix is
        labelled by what removed it (outage, or jamming's loss), never as an attack on a fix
        that does not exist.
    seed, shard : int
        Streams of the jamming noise.
    first : int, optional
        Global id of the first sequence (labels).
    frame : OriginFrame, optional
        The truth's frame: in ``geodetic`` (n = ECEF) the spoofing direction ``u`` and the
        jamming noise are in the local level at the antenna, rotated to n (elsewhere n is
        the local level).
    """
    M, J = gnss.fix.shape
    if len(intervals) and not isinstance(intervals[0], list | tuple):
        intervals = [list(intervals)] * M
    if len(intervals) != M:
        raise InputError("scenario", f"{len(intervals)} interval lists for {M} sequences")
    t = np.asarray(gnss.time_s, float)
    geo = frame is not None and frame.model == "geodetic"
    p = gnss.p_n.copy()
    v = gnss.v_n.copy()
    sp = gnss.sigma_p_n.copy()
    sv = gnss.sigma_v_n.copy()
    fix = gnss.fix.copy()
    state = np.zeros((M, J), np.int8)
    ap = np.zeros((M, J, 3))
    av = np.zeros((M, J, 3))
    rows = []
    first = shard * M if first is None else int(first)
    for j in range(M):
        noise = None
        for n, iv in enumerate(intervals[j]):
            iv = iv if isinstance(iv, Interval) else Interval.from_config(iv, f"scenario[{n}]")
            m = (t >= iv.start_s - 1e-9) & (t < iv.end_s - 1e-9)
            tau = t[m] - iv.start_s
            c = iv.params
            u = np.array(
                [math.cos(c.get("azimuth_rad", 0.0)), math.sin(c.get("azimuth_rad", 0.0)), 0.0]
            )
            dp = np.zeros((m.sum(), 3))
            dv = np.zeros((m.sum(), 3))
            code = KINDS[iv.kind]
            st = np.full(m.sum(), code, np.int8)
            if iv.kind == "outage":
                fix[j, m] = FIX_NONE
            elif iv.kind == "jamming":
                if noise is None:
                    noise = scenario_rng(seed, shard, j, "noise").standard_normal((J, 6))
                deg = tau < c["degrade_s"]
                kf = 1.0 + (c["sigma_factor"] - 1.0) * np.clip(
                    tau / max(c["degrade_s"], 1e-9), 0, 1
                )
                extra = np.sqrt(np.maximum(kf**2 - 1.0, 0.0))[:, None]
                dp = extra * sp[j, m] * noise[m, :3]
                dv = extra * sv[j, m] * noise[m, 3:]
                sp[j, m] *= kf[:, None]
                sv[j, m] *= kf[:, None]
                fix[j, m] = np.where(deg, np.minimum(fix[j, m], 1), FIX_NONE)
                st = np.where(deg, st, STATE_JAMMING_LOST).astype(np.int8)
            elif iv.kind == "spoof_ramp":
                dp = c["rate_mps"] * tau[:, None] * u
                dv = np.broadcast_to(c["rate_mps"] * u, dp.shape).copy()
            elif iv.kind == "spoof_step":
                dp = np.broadcast_to(c["offset_m"] * u, (m.sum(), 3)).copy()
            elif iv.kind == "spoof_oscillation":
                wv = 2.0 * math.pi / c["period_s"]
                dp = c["amplitude_m"] * np.sin(wv * tau)[:, None] * u
                dv = c["amplitude_m"] * wv * np.cos(wv * tau)[:, None] * u
            elif iv.kind == "meaconing":
                tt = t[m] - c["delay_s"]
                for a in range(3):
                    dp[:, a] = np.interp(tt, t, gnss.p_ant_n[j, :, a]) - gnss.p_ant_n[j, m, a]
                    dv[:, a] = np.interp(tt, t, gnss.v_ant_n[j, :, a]) - gnss.v_ant_n[j, m, a]
            elif iv.kind == "freeze":
                k0 = np.searchsorted(t, iv.start_s - 1e-9) - 1
                if k0 >= 0:
                    dp = p[j, k0] - p[j, m]
                    dv = v[j, k0] - v[j, m]
                    fix[j, m] = fix[j, k0]
            if geo and iv.kind in _LOCAL_KINDS and m.any():  # local level -> n
                C_ln = frame.C_ln(gnss.p_ant_n[j, m])
                dp = np.einsum("jki,jk->ji", C_ln, dp)
                dv = np.einsum("jki,jk->ji", C_ln, dv)
            p[j, m] += dp
            v[j, m] += dv
            if iv.kind == "freeze" and k0 >= 0:
                p[j, m] = p[j, k0]  # exactly the frozen fix (no rounding through dp)
                v[j, m] = v[j, k0]
            ap[j, m] += dp
            av[j, m] += dv
            state[j, m] = st
            rows.append(
                {
                    "sequence": first + j,
                    "kind": iv.kind,
                    "state": code,
                    "start_s": iv.start_s,
                    "end_s": iv.end_s,
                    **{k: c.get(k, np.nan) for ks in PARAMS.values() for k in ks},
                }
            )
    lost = fix == FIX_NONE
    # exact labels where declared intervals overlap: no fix is a loss (jamming's keeps its code)
    relabel = lost & (state != STATE_JAMMING_LOST) & (state != 0)
    state = np.where(relabel, KINDS["outage"], state).astype(state.dtype)
    p[lost] = np.nan
    v[lost] = np.nan
    ap[lost] = np.nan
    av[lost] = np.nan
    out = replace(
        gnss,
        p_n=p,
        v_n=v,
        sigma_p_n=sp,
        sigma_v_n=sv,
        fix=fix,
        offset_p_n=gnss.offset_p_n + np.nan_to_num(ap),
        offset_v_n=gnss.offset_v_n + np.nan_to_num(av),
    )
    cols = [
        "sequence",
        "kind",
        "state",
        "start_s",
        "end_s",
        *sorted({k for ks in PARAMS.values() for k in ks}),
    ]
    return ScenarioResult(out, state, ap, av, pd.DataFrame(rows, columns=cols))


def parse_scenarios(specs) -> dict:
    """``--scenario`` specs -> ``{"intervals": [...], "draw_kinds": [...], "outage_durations_s": [...]}``.

    ``KIND:DURATION@START[,param=value...]`` declares an interval (same for every sequence,
    seconds from the first sample); ``outage:DURATION`` without ``@START`` draws, per sequence,
    an outage whose duration is chosen uniformly among those given (start uniform after
    ``settle_s``); a bare ``KIND`` draws one interval of that kind with the documented
    distributions (this module).
    """
    intervals, kinds, durs = [], [], []
    for spec in specs or ():
        head, *extra = str(spec).split(",")
        kind, _, rest = head.partition(":")
        kind = kind.strip()
        if kind not in KINDS:
            raise InputError("--scenario", f"{spec!r}: kind must be one of {', '.join(KINDS)}")
        try:
            prm = {k.strip(): float(v) for k, v in (e.split("=", 1) for e in extra)}
            if not rest:
                if prm:
                    raise ValueError("parameters need KIND:DURATION@START")
                kinds.append(kind)
            elif "@" in rest:
                dur, start = rest.split("@", 1)
                iv = {"kind": kind, "start_s": float(start), "duration_s": float(dur), **prm}
                intervals.append(iv)
            elif kind == "outage" and not prm:
                durs.append(float(rest))
                kinds.append(kind)
            else:
                raise ValueError("only outage:DURATION may omit @START")
        except ValueError as exc:
            raise InputError("--scenario", f"{spec!r}: {exc}") from None
    out = {"intervals": intervals, "draw_kinds": list(dict.fromkeys(kinds))}
    if durs:
        if any(not d > 0 for d in durs):
            raise InputError("--scenario", "outage durations must be > 0 s")
        out["outage_durations_s"] = sorted(set(durs))
    return out
