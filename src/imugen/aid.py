"""Aid stage: a shard of measured IMU sequences + GNSS (with scenarios) -> aided navigation errors.

For every sequence of the shard (streamed in batches, memory bounded as in
:mod:`imugen.navigate`):

1. GNSS fixes are drawn (:func:`imugen.gnss.simulate_gnss`) from the truth, then the
   configured scenario intervals (declared, and/or drawn per sequence) are applied
   (:func:`imugen.scenarios.apply`);
2. the loosely-coupled error-state filter (:func:`imugen.aided.run`) runs on the shard's
   increments (raw ones get navigation's coning/sculling correction; rates are integrated as
   navigation does) with its tuning from the grade's figures (``tuning_level``) and the
   receiver's nominal figures, aligned by :func:`imugen.aided.align` (moving starts at
   ``align_speed_mps``);
3. the GNSS epochs (:mod:`imugen.tables.gnss`, with the receiver and scenario labels; streamed
   one row group per batch) and the aided errors at the evaluation epochs
   (:mod:`imugen.tables.aided`, small: kept until the end) are written.

Randomness: sequence ``i`` (its index in the route, ``shard * shard_size + j``) of route id
``r`` draws its receiver, its scenario and the jamming noise from ``SeedSequence([seed, r, i],
spawn_key=(KEY, ...))`` with the receiver's and the scenarios' own keys and streams
(``shard = j = 0`` inside those keys: the identity is in the entropy). The draw therefore
depends on neither the IMU grade (grades are compared on the same GNSS, common random
numbers), nor the shard size, nor the other sequences.
"""

from __future__ import annotations

import warnings
from dataclasses import asdict, dataclass, field, fields, replace
from pathlib import Path

import numpy as np
import pandas as pd

from imugen import __version__
from imugen import aided as A
from imugen import gnss as G
from imugen import local_errors as lerr
from imugen import scenarios as SC
from imugen.earth import earth_rate_n
from imugen.errors import InputError
from imugen.mechanize import compensate_raw, increments_from_rates
from imugen.navigate import batch_size
from imugen.tables import aided as taided
from imugen.tables import gnss as tgnss
from imugen.tables import shard as tshard
from imugen.tables import truth as ttruth
from imugen.tables._parquet import SEQUENCE, TIME
from imugen.tables.nav import ERR_ATT, ERR_POS, ERR_TRACK

AID_TRUTH_COLUMNS = [TIME, *ttruth.POS, *ttruth.VEL, *ttruth.QUAT, *ttruth.GYRO]


@dataclass(frozen=True)
class AidParams:
    """Receiver, scenarios and filter settings of the stage (config keys ``gnss``,
    ``scenarios``, ``aided``; see config/README.md).

    ``nhc=None`` turns the non-holonomic constraint on for a ``car`` truth; ``seed=None``
    takes the shard's simulation seed.
    """

    receiver: str = "standalone"
    rate_hz: float | None = None
    draw: str = "ranges"
    lever_arm_b_m: tuple = (0.0, 0.0, 0.0)
    lever_arm_sd_m: float = 0.0
    intervals: tuple = ()
    draw_kinds: tuple = ()
    outage_durations_s: tuple = SC.OUTAGE_PRESETS_S
    settle_s: float = 60.0
    tuning_level: str = "upper"
    gnss_bias_states: bool = True
    scale_factors: bool = False
    nhc: bool | None = None
    zupt: bool = True
    gate_sigma: float = 0.0
    align_speed_mps: float = 5.0
    eval_rate_hz: float = 1.0
    seed: int | None = None
    grade: str | None = None
    intervals_parsed: tuple = field(default=(), repr=False)

    def __post_init__(self):
        ivs = tuple(
            iv if isinstance(iv, SC.Interval) else SC.Interval.from_config(iv, f"scenario[{n}]")
            for n, iv in enumerate(self.intervals)
        )
        object.__setattr__(self, "intervals_parsed", ivs)
        object.__setattr__(self, "outage_durations_s", tuple(self.outage_durations_s))
        object.__setattr__(self, "draw_kinds", tuple(self.draw_kinds))
        object.__setattr__(self, "lever_arm_b_m", tuple(float(x) for x in self.lever_arm_b_m))
        for k in self.draw_kinds:
            if k not in SC.KINDS:
                raise InputError(
                    "scenarios.draw", f"unknown kind {k!r}; one of {', '.join(SC.KINDS)}"
                )
        if not self.align_speed_mps > 0:
            raise InputError("--align-speed", "must be > 0 m/s")
        if self.eval_rate_hz <= 0:
            raise InputError("--eval-rate-hz", "must be > 0")

    def options(self, vehicle: str | None) -> A.Options:
        nhc = (vehicle == "car") if self.nhc is None else bool(self.nhc)
        return A.Options(
            scale_factors=self.scale_factors,
            gnss_bias=self.gnss_bias_states,
            nhc=nhc,
            zupt=self.zupt,
            gate_sigma=self.gate_sigma,
        )


def parse_scenarios(specs) -> dict:
    """``--scenario`` specs -> ``{"intervals": [...], "draw_kinds": [...], "outage_durations_s": [...]}``.

    ``KIND:DURATION@START[,param=value...]`` declares an interval (same for every sequence,
    seconds from the first sample); ``outage:DURATION`` without ``@START`` draws, per sequence,
    an outage whose duration is chosen uniformly among those given (start uniform after
    ``settle_s``); a bare ``KIND`` draws one interval of that kind with the documented
    distributions (:mod:`imugen.scenarios`).
    """
    intervals, kinds, durs = [], [], []
    for spec in specs or ():
        head, *extra = str(spec).split(",")
        kind, _, rest = head.partition(":")
        kind = kind.strip()
        if kind not in SC.KINDS:
            raise InputError("--scenario", f"{spec!r}: kind must be one of {', '.join(SC.KINDS)}")
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


def sequence_entropy(seed: int, sequence_id: int) -> list[int]:
    """``[seed, route_id, index]`` of a global sequence id: the entropy of its GNSS draws."""
    rid, idx = tshard.split_ids([sequence_id])
    return [int(seed), int(rid[0]), int(idx[0])]


_PER_SEQUENCE = (
    "p_n", "v_n", "p_ant_n", "v_ant_n", "bias_n", "offset_p_n", "offset_v_n", "sigma_p_n",
    "sigma_v_n", "fix",
)  # fmt: skip
"""Fields of :class:`imugen.gnss.GnssData` with a leading sequence axis."""


def _stack(parts: list[SC.ScenarioResult]) -> SC.ScenarioResult:
    """Concatenate one-sequence scenario results along the sequence axis."""
    g0 = parts[0].gnss
    arrays = {k: np.concatenate([getattr(p.gnss, k) for p in parts]) for k in _PER_SEQUENCE}
    params = G.ReceiverParams(
        **{
            f.name: np.concatenate([getattr(p.gnss.params, f.name) for p in parts])
            for f in fields(G.ReceiverParams)
        }
    )
    labels = pd.concat([p.gnss.labels for p in parts], ignore_index=True)
    g = replace(g0, **arrays, params=params, labels=labels)
    return SC.ScenarioResult(
        g,
        np.concatenate([p.state for p in parts]),
        np.concatenate([p.attack_p_n for p in parts]),
        np.concatenate([p.attack_v_n for p in parts]),
        pd.concat([p.intervals for p in parts], ignore_index=True),
    )


def gnss_for(truth: ttruth.Truth, ids, params: AidParams, seed: int) -> SC.ScenarioResult:
    """GNSS fixes after the scenarios of the sequences ``ids`` (global ids) of a truth."""
    t = truth.time_s
    frame = truth.origin_frame()
    rec = G.get_receiver(params.receiver)
    duration = float(t[-1] - t[0])
    parts = []
    for sid in np.asarray(ids, np.int64):
        ent = sequence_entropy(seed, int(sid))
        g = G.simulate_gnss(
            t, truth.p_n, truth.v_n, truth.q_nb, truth.omega_ib_b, rec, 1, ent, 0,
            rate_hz=params.rate_hz, draw=params.draw, lever_arm_b_m=params.lever_arm_b_m,
            lever_sd_m=params.lever_arm_sd_m, omega_ie_n=earth_rate_n(frame), first=int(sid),
        )  # fmt: skip
        ivs = list(params.intervals_parsed)
        if params.draw_kinds:
            ivs += SC.draw(
                params.draw_kinds, duration, ent, 0, 1, settle_s=params.settle_s,
                durations_s=params.outage_durations_s,
            )[0]  # fmt: skip
        parts.append(SC.apply(g, [ivs], ent, 0, first=int(sid)))
    return _stack(parts)


def _increments(a, c, kind, raw, dt):
    """(b, K, 3) angle and velocity increments, row 0 unused, from a shard block (skip 0)."""
    if kind == "increments":
        if raw:
            compensate_raw(a[:, 1:], c[:, 1:])
        return a, c
    dth, dvb = increments_from_rates(a, c, dt)
    z = np.zeros((len(a), 1, 3))
    return np.concatenate([z, dth], 1), np.concatenate([z, dvb], 1)


def _since_fix(t, valid):
    """(M, J) time since the last epoch with a fix (NaN before the first)."""
    last = np.where(valid, t[None, :], -np.inf)
    last = np.maximum.accumulate(last, axis=1)
    out = t[None, :] - last
    return np.where(np.isfinite(out), out, np.nan)


def eval_mask(index, every: int, valid) -> np.ndarray:
    """(M, J) epochs kept: on the evaluation grid (sample ``index % every == 0``) or the last
    epoch of a run without a fix (the end of an outage)."""
    grid = (np.asarray(index) % every == 0)[None, :]
    nofix = ~np.asarray(valid, bool)
    nxt = np.concatenate([~nofix[:, 1:], np.ones((nofix.shape[0], 1), bool)], 1)
    return grid | (nofix & nxt)


def aided_errors(truth: ttruth.Truth, ids, res: A.AidedResult, scen, every: int):
    """The aided error table's rows for a filter result of sequences ``ids``."""
    idx = res.index
    t = res.time_s
    C = lerr.rotation_ln(truth.origin_frame(), truth.p_n[idx])
    track = lerr.track_direction(np.einsum("jik,jk->ji", C, truth.v_n[idx]))
    err = lerr.apply(C, track, res.p_n - truth.p_n[idx][None])
    q = np.where(np.isnan(res.q_nb), [1.0, 0.0, 0.0, 0.0], res.q_nb)
    att = np.linalg.norm(A.attitude_error(q, truth.q_nb[idx][None]), axis=-1)
    valid = scen.gnss.valid
    aligned = (res.flags & A.F_ALIGNED) != 0
    keep = eval_mask(idx, every, valid) & aligned & np.isfinite(err[..., :3]).all(-1)
    S, J = keep.shape
    since = _since_fix(t, valid)
    sd = lerr.local_sd(C, res.sd[..., A.I_P : A.I_P + 3])
    rows = {SEQUENCE: np.repeat(np.asarray(ids, np.int64), J)[keep.ravel()]}
    rows[TIME] = np.tile(t, S)[keep.ravel()]
    for i, c in enumerate((*ERR_POS, *ERR_TRACK)):
        rows[c] = err[..., i][keep]
    rows[ERR_ATT] = att[keep]
    for i, c in enumerate(taided.SD_POS):
        rows[c] = sd[..., i][keep]
    rows[taided.GNSS_USED] = ((res.flags & A.F_GNSS_P) != 0)[keep].astype(np.int8)
    rows[taided.STATE] = scen.state[keep].astype(np.int8)
    rows[taided.SINCE_FIX] = since[keep]
    return pd.DataFrame(rows)


def aid(truth_path, shard_path, params: AidParams, *, batch: int | None = None, sink=None):
    """Run the stage on one shard: ``(gnss rows, labels, intervals, aided rows, meta)``.

    ``sink(meta, df)``, when given, receives the GNSS rows batch by batch (and ``gnss rows`` is
    then None), so a shard's GNSS table never sits whole in memory.
    """
    truth_path, shard_path = Path(truth_path), Path(shard_path)
    truth = ttruth.read(truth_path, columns=AID_TRUTH_COLUMNS)
    smeta = tshard.read_meta(shard_path)
    K = truth.K
    n = smeta.get("samples_per_sequence")
    if n is not None and n != K:
        raise InputError(shard_path, f"has {n} samples per sequence where the truth has {K}")
    seed = params.seed
    if seed is None:
        lab = tshard.read_labels(shard_path, smeta)
        if "seed" not in lab.columns or lab["seed"].nunique() != 1:
            raise InputError(shard_path, "labels carry no single seed: pass --seed")
        seed = int(lab["seed"].iloc[0])
    sgrade = smeta.get("grade")
    sgrade = sgrade.get("name") if isinstance(sgrade, dict) else sgrade
    grade = params.grade or sgrade
    if not grade:
        raise InputError(shard_path, "records no grade: pass --grade")
    tun = A.Tuning.from_grade(grade, params.tuning_level)
    opts = params.options(truth.meta.get("vehicle"))
    frame = truth.origin_frame()
    columns, kind = tshard.measurement(shard_path)
    raw = kind == "increments" and tshard.increment_kind(smeta) == "raw"
    every = max(1, round(truth.rate_hz / params.eval_rate_hz))
    batch = batch or batch_size(K)
    rec = G.get_receiver(params.receiver)
    meta = {
        "imugen_version": __version__,
        "truth": truth_path.name,
        "truth_sha256": ttruth.checksum(truth_path),
        "shard": shard_path.name,
        "grade": sgrade,
        "route": smeta.get("route"),
        "seed": seed,
        "receiver": rec.name,
        "rate_hz": float(params.rate_hz or rec.rate_hz),
        "scenarios": [asdict(iv) for iv in params.intervals_parsed],
        "scenario_draw": list(params.draw_kinds),
        "options": asdict(opts),
        "tuning_level": params.tuning_level,
        "align_speed_mps": params.align_speed_mps,
        "eval_rate_hz": params.eval_rate_hz,
        "error": "filter minus truth, ENU at the true position; along/cross the true track",
    }
    gnss_rows, labels, intervals, aided_rows = [], [], [], []
    never = 0
    for ids, a, c in tshard.iter_blocks(shard_path, columns, K, int(batch), 0):
        ids = ids.copy()
        dth, dvb = _increments(a, c, kind, raw, truth.dt)
        scen = gnss_for(truth, ids, params, seed)
        T = A.tuning_matrix(tun, len(ids), gnss_receiver=scen.gnss.receiver)
        init = A.align(dth, dvb, truth.dt, scen.gnss, tun, opts, frame,
                       speed_mps=params.align_speed_mps, tuning_T=T)  # fmt: skip
        never += int(np.sum(init.k0 >= K))
        res = A.run(dth, dvb, truth.dt, frame, scen.gnss, tun, opts, init, tuning_T=T)
        if sink is None:
            gnss_rows.append(tgnss.frame(ids, scen))
        else:
            sink(meta, tgnss.frame(ids, scen))
        lab = scen.gnss.labels.copy()
        lab[SEQUENCE] = ids  # global int64 ids (the receiver's labels count from ``first``)
        labels.append(lab)
        intervals.append(scen.intervals)
        aided_rows.append(aided_errors(truth, ids, res, scen, every))
    if not aided_rows:
        raise InputError(shard_path, "holds no sequences")
    if never:
        warnings.warn(
            f"{shard_path}: {never} sequence(s) never aligned (not still at the start, and no "
            f"fix at >= {params.align_speed_mps:g} m/s): no aided rows for them; lower "
            "aided.align_speed_mps (--align-speed)",
            stacklevel=2,
        )
    meta["never_aligned"] = never
    return (
        pd.concat(gnss_rows, ignore_index=True) if sink is None else None,
        pd.concat(labels, ignore_index=True),
        pd.concat(intervals, ignore_index=True),
        pd.concat(aided_rows, ignore_index=True),
        meta,
    )


def run(truth, shard, out_gnss, out_nav, params: AidParams | None = None, *, batch=None):
    """Run the stage on one shard and write the GNSS table (with sidecars) and the aided
    error table atomically. Returns ``(out_gnss, out_nav)`` paths."""
    params = params or AidParams()
    with tgnss.writer(out_gnss) as w:

        def sink(meta, df):
            w.meta = {**meta, "stage": "aid-gnss"}
            w.put(df)

        _, w.labels, w.intervals, nav, meta = aid(truth, shard, params, batch=batch, sink=sink)
        taided.write(nav, {**meta, "stage": "aid", "gnss": Path(out_gnss).name}, out_nav)
    return Path(out_gnss), Path(out_nav)


__all__ = ["AidParams", "aid", "aided_errors", "eval_mask", "gnss_for", "run"]
