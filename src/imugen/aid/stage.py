"""Aid stage: a shard of measured IMU sequences + GNSS (with scenarios) -> aided navigation errors.

For every sequence of the shard (streamed in batches, memory bounded as in
:mod:`imugen.navigate.stage`):

1. GNSS fixes are drawn (:func:`imugen.aid.gnss.simulate_gnss`) from the truth, then the
   configured scenario intervals (declared, and/or drawn per sequence) are applied
   (:func:`imugen.aid.scenarios.apply`);
2. the loosely-coupled error-state filter (:func:`imugen.aid.filter.run`) runs on the shard's
   increments (raw ones get navigation's coning/sculling correction; rates are integrated as
   navigation does) with its tuning from the grade's and the receiver's figures
   (``tuning_level``: by default the law they are drawn from), aligned by :func:`imugen.aid.filter.align` (moving starts at
   ``align_speed_mps``);
3. the GNSS epochs (:mod:`imugen.tables.gnss`, with the receiver and scenario labels) and the
   aided errors and filter state at the evaluation epochs (:mod:`imugen.tables.aided`) are
   written, each streamed one row group per batch;
4. with an odometer and/or a barometer configured (``companions``), their epochs are drawn
   from the truth (:mod:`imugen.aid.companions`), used by the filter (at the GNSS epochs that are
   also companion epochs) and written to the companion table (:mod:`imugen.tables.companions`).

Randomness: sequence ``i`` (its index in the route, ``shard * shard_size + j``) of route id
``r`` draws its receiver, its scenario and the jamming noise from ``SeedSequence([seed, r, i],
spawn_key=(KEY, ...))`` with the receiver's and the scenarios' own keys and streams
(``shard = j = 0`` inside those keys: the identity is in the entropy). The draw therefore
depends on neither the IMU grade (grades are compared on the same GNSS, common random
numbers), nor the shard size, nor the other sequences. The companions draw likewise from the
same entropy with their own key, sensor kind and id (the tree: :mod:`imugen.core.seeding`).
"""

from __future__ import annotations

import math
import warnings
from contextlib import nullcontext
from dataclasses import asdict, fields, replace
from pathlib import Path

import numpy as np
import pandas as pd

from imugen import __version__
from imugen.aid import companions as CP
from imugen.aid import filter as A
from imugen.aid import gnss as G
from imugen.aid import scenarios as SC
from imugen.aid.options import AidOptions
from imugen.core.earth import earth_rate_n
from imugen.core.errors import InputError
from imugen.core.rotations import quat_to_dcm
from imugen.core.seeding import sequence_entropy
from imugen.navigate import local_errors as lerr
from imugen.navigate.mechanize import compensate_raw, increments_from_rates
from imugen.navigate.navigator import batch_size
from imugen.tables import SEQUENCE, TIME
from imugen.tables import aided as taided
from imugen.tables import companions as tcomp
from imugen.tables import filter_estimates as test
from imugen.tables import gnss as tgnss
from imugen.tables import imu_correction as tcorr
from imugen.tables import learned as tlearned
from imugen.tables import shard as tshard
from imugen.tables import truth as ttruth
from imugen.tables.nav import ERR_ATT, ERR_POS, ERR_TRACK

AID_TRUTH_COLUMNS = [TIME, *ttruth.POS, *ttruth.VEL, *ttruth.QUAT, *ttruth.GYRO]


def filter_options(
    params: AidOptions,
    vehicle: str | None,
    mounting: dict | None = None,
    plausibility: dict | None = None,
    vehicle_params: dict | None = None,
) -> A.Options:
    """The filter's options from the stage's; ``vehicle`` (the truth's) decides NHC when
    ``params.nhc`` is None; ``mounting`` (the shard metadata's, :mod:`imugen.sensors.mounting`)
    gives NHC its nominal lever arm and the misalignment sigmas its noise must cover;
    ``plausibility`` (the truth's report) the vehicle's residual slip, unless
    ``params.nhc_slip_sd_mps`` is set; ``vehicle_params`` (the truth metadata's) whether the
    vehicle rides on its suspension (:func:`suspension_pitch_sd`)."""
    p = params
    nhc = (vehicle == "car") if p.nhc is None else bool(p.nhc)
    slip = p.nhc_slip_sd_mps
    mount = {
        "nhc_sd_mps": truth_slip_sd(plausibility) if slip is None else slip,
        "nhc_pitch_sd_rad": suspension_pitch_sd(
            vehicle, {"damped": True, "rigid": False}.get((vehicle_params or {}).get("suspension"))
        ),
    }
    if mounting:
        sd = np.radians(mounting["misalignment_sd_deg"])
        mount |= {
            "nhc_lever_arm_m": tuple(mounting["lever_arm_m"]),
            "nhc_misalignment_sd_rad": (float(sd[1]), float(sd[2])),
            "nhc_lever_arm_sd_m": tuple(mounting["lever_arm_sd_m"]),
        }
    return A.Options(
        scale_factors=p.scale_factors,
        gyro_cross_coupling=p.gyro_cross_coupling,
        accel_cross_coupling=p.gyro_cross_coupling,
        gnss_bias=p.gnss_bias_states,
        nhc=nhc,
        zupt=p.zupt,
        gate_sigma=p.gate_sigma,
        odometer=p.odometer is not None,
        odo_scale_state=p.odometer_scale_state,
        baro=p.barometer is not None,
        **mount,
    )


def suspension_pitch_sd(vehicle: str | None, damped: bool | None = None) -> float:
    """1-sigma of the body's pitch on its suspension relative to its velocity [rad] that NHC's
    vertical row must cover (``Options.nhc_pitch_sd_rad``): the vehicle class's pitch
    gradient x its tyre-limited acceleration ``max_accel_mps2`` (a car: 2 deg/g x 0.8 g =
    1.6 deg, 0.40 m/s of vertical body speed at 14 m/s); 0 for a class without a suspension
    (``damped``: whether the truth's vehicle is on its suspension; None: the class's default,
    damped for a car).

    The dive and squat last seconds (a braking, the body's 1.2 Hz rocking) while NHC takes
    its noise as white at every epoch, so the sigma covers the largest dive, not the typical
    one. Measured on the car rectangle of tests/aid/test_companions.py (30 runs, NEES/dof of
    position, velocity and attitude at 25 epochs, band 7.1-11.1): the class's 0.2 g as sigma
    gave a mean of 11.4 with 10 epochs above the band, 0.4 g 9.9 and 4, 0.8 g 9.6 and 2 (the
    rigid car before: 9.5 and 2). The class's figures (:data:`imugen.truth.VEHICLES`), not the
    truth's motion; whether the vehicle rides on its suspension is the truth's configuration
    (its metadata's ``vehicle_params.suspension``, which :func:`filter_options` reads)."""
    from dataclasses import replace

    from imugen.truth import VEHICLES
    from imugen.truth.vehicles import has_suspension

    vp = VEHICLES.get(vehicle or "")
    if vp is None:
        return 0.0
    if damped is not None:
        vp = replace(vp, suspension="damped" if damped else "rigid")
    if not has_suspension(vp):
        return 0.0
    return vp.pitch_gradient_radpmps2 * vp.max_accel_mps2


def truth_slip_sd(plausibility: dict | None) -> tuple[float, float]:
    """The vehicle's residual slip (lateral, vertical) [m/s] NHC must cover: the RMS lateral
    body speed and the RMS vertical speed of the vehicle under the body's pitch on its
    suspension (the path's own; the body's on a truth without a suspension or of an older
    report) of the truth's plausibility report (:mod:`imugen.truth.report`), at least
    :data:`SLIP_FLOOR_MPS`, or :data:`SLIP_FALLBACK_MPS` for a truth without them.

    Each from its own source: the dive and squat of a car on its suspension are NHC's
    ``nhc_pitch_sd_rad`` (:func:`suspension_pitch_sd`, the class's figure); the body's
    vertical speed includes them, so taken as the slip too they were counted twice.

    The RMS, with NHC's own innovation gate (``Options.nhc_gate_sigma``) rejecting the bursts
    where the truth's path is implausible (the paper scene: RMS 0.010 m/s, largest 0.33 m/s
    in its last 7 s): the largest as white noise at every epoch left heading NEES/dof
    0.13-0.17 and tilt 2.3 (consumer), and a 60 s outage drift of 4.6 m against 2.6 m."""
    rep = plausibility or {}
    out = []
    vertical = "rms_vehicle_vertical_speed_mps"
    if vertical not in rep:
        vertical = "rms_body_vertical_speed_mps"
    for key in ("rms_body_lateral_speed_mps", vertical):
        v = rep.get(key)
        ok = v is not None and math.isfinite(v)
        out.append(max(float(v), SLIP_FLOOR_MPS) if ok else SLIP_FALLBACK_MPS)
    return out[0], out[1]


SLIP_FLOOR_MPS = 0.01
"""Smallest NHC slip sigma [m/s]: NHC at every GNSS epoch takes its noise as white, but the
constraint's linearization error is correlated over seconds; an exact constraint (the
simulator's car, 5e-8 m/s) left velocity NEES/dof 1.9 in a consumer's 30 s outage, 1.07 with
0.01 m/s (r26 study)."""

SLIP_FALLBACK_MPS = 0.1
"""NHC slip sigma [m/s] of a truth whose report gives no body speeds (the former constant)."""


def entropy_of(seed: int, sequence_id: int) -> list[int]:
    """:func:`imugen.core.seeding.sequence_entropy` of a global sequence id."""
    rid, idx = tshard.split_ids([sequence_id])
    return sequence_entropy(seed, rid[0], idx[0])


_PER_SEQUENCE = (
    "p_n", "v_n", "p_ant_n", "v_ant_n", "bias_n", "offset_p_n", "offset_v_n", "sigma_p_n",
    "sigma_v_n", "fix",
)  # fmt: skip
"""Fields of :class:`imugen.aid.gnss.GnssData` with a leading sequence axis."""


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


def gnss_for(truth: ttruth.Truth, ids, params: AidOptions, seed: int, mount=None):
    """GNSS fixes after the scenarios of the sequences ``ids`` (global ids) of a truth (a
    :class:`imugen.aid.scenarios.ScenarioResult`). ``mount``: the sequences' ``(angles, lever)``
    (:func:`imugen.tables.shard.mounting`) when the IMU is mounted: the antenna lever arm is
    then from the IMU, in its axes, on the IMU's truth."""
    t = truth.time_s
    frame = truth.origin_frame()
    rec = G.get_receiver(params.receiver)
    duration = float(t[-1] - t[0])
    parts = []
    states = (truth.p_n, truth.v_n, truth.q_nb, truth.omega_ib_b)
    for i, sid in enumerate(np.asarray(ids, np.int64)):
        ent = entropy_of(seed, int(sid))
        if mount is not None:
            states = _imu_truth(truth, frame, mount[0][i], mount[1][i])
        g = G.simulate_gnss(
            t, *states, rec, 1, ent, 0,
            rate_hz=params.rate_hz, draw=params.draw, lever_arm_b_m=params.lever_arm_b_m,
            lever_sd_m=params.lever_arm_sd_m, omega_ie_n=earth_rate_n(frame), first=int(sid),
            frame=frame,
        )  # fmt: skip
        ivs = list(params.intervals_parsed)
        if params.draw_kinds:
            ivs += SC.draw(
                params.draw_kinds, duration, ent, 0, 1, settle_s=params.settle_s,
                durations_s=params.outage_durations_s,
            )[0]  # fmt: skip
        parts.append(SC.apply(g, [ivs], ent, 0, first=int(sid), frame=frame))
    return _stack(parts)


def _stack_companion(parts: list[CP.CompanionData]) -> CP.CompanionData:
    """Concatenate one-sequence companion data along the sequence axis."""
    p0 = parts[0]
    cat = {k: np.concatenate([getattr(p, k) for p in parts]) for k in (
        "value", "true", "ticks", "count", "bias")}  # fmt: skip
    params = {k: np.concatenate([p.params[k] for p in parts]) for k in p0.params}
    labels = pd.concat([p.labels for p in parts], ignore_index=True)
    return replace(p0, **cat, params=params, labels=labels)


def companions_for(truth: ttruth.Truth, ids, params: AidOptions, seed: int):
    """``(odometer, barometer)`` :class:`imugen.aid.companions.CompanionData` of the sequences
    ``ids`` (global ids), each None when not configured."""
    t = truth.time_s
    frame = truth.origin_frame()
    out = []
    w_eb = None
    if params.odometer is not None:
        C = quat_to_dcm(truth.q_nb)
        w_eb = truth.omega_ib_b - np.einsum("kji,j->ki", C, earth_rate_n(frame))
    for kind, preset in (("odometer", params.odometer), ("barometer", params.barometer)):
        if preset is None:
            out.append(None)
            continue
        parts = []
        for sid in np.asarray(ids, np.int64):
            ent = entropy_of(seed, int(sid))
            if kind == "odometer":
                d = CP.simulate_odometer(
                    t, truth.v_n, truth.q_nb, w_eb, preset, 1, ent, 0,
                    rate_hz=params.odometer_rate_hz, draw=params.companion_draw,
                    lever_arm_b_m=params.odometer_lever_b_m, first=int(sid),
                )  # fmt: skip
            else:
                d = CP.simulate_barometer(
                    t, truth.p_n, frame, preset, 1, ent, 0, rate_hz=params.barometer_rate_hz,
                    draw=params.companion_draw, first=int(sid),
                )  # fmt: skip
            parts.append(d)
        out.append(_stack_companion(parts))
    return tuple(out)


def _imu_truth(truth, frame, angles, lever):
    """``(p_n, v_n, q_nb, omega_ib_b)`` (K, 3|4) of one mounted IMU (:mod:`imugen.sensors.mounting`)."""
    from imugen.sensors.mounting import C_vb, imu_states

    w = truth.omega_ib_b
    p, v, q = imu_states(truth.p_n, truth.v_n, truth.q_nb, w, earth_rate_n(frame), angles, lever)
    return p[0], v[0], q[0], w @ C_vb(angles)


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


def aided_errors(truth: ttruth.Truth, ids, res: A.AidedResult, scen, every: int, mount=None):
    """The aided table's rows (:data:`imugen.tables.aided.COLUMNS`) for a filter result of
    sequences ``ids``: errors against the truth, scenario context and the filter's state
    (``mount``: as :func:`gnss_for`; errors of a mounted IMU are against its own truth)."""
    idx = res.index
    t = res.time_s
    p_true, q_true = truth.p_n[idx][None], truth.q_nb[idx][None]
    if mount is not None:
        from imugen.sensors.mounting import imu_states

        Om = earth_rate_n(truth.origin_frame())
        p_true, _, q_true = imu_states(p_true[0], None, q_true[0], None, Om, *mount)
    C = lerr.rotation_ln(truth.origin_frame(), truth.p_n[idx])
    track = lerr.track_direction(np.einsum("jik,jk->ji", C, truth.v_n[idx]))
    err = lerr.apply(C, track, res.p_n - p_true)
    q = np.where(np.isnan(res.q_nb), [1.0, 0.0, 0.0, 0.0], res.q_nb)
    att = np.linalg.norm(A.attitude_error(q, q_true), axis=-1)
    valid = scen.gnss.valid
    aligned = (res.flags & A.F_ALIGNED) != 0
    keep = eval_mask(idx, every, valid) & aligned & np.isfinite(err[..., :3]).all(-1)
    S, J = keep.shape
    since = _since_fix(t, valid)
    geo = truth.origin_frame().model == "geodetic"  # the filter's sigmas are local there
    sd = res.sd_of("p") if geo else lerr.local_sd(C, res.sd_of("p"))
    rows = {SEQUENCE: np.repeat(np.asarray(ids, np.int64), J)[keep.ravel()]}
    rows[TIME] = np.tile(t, S)[keep.ravel()]
    rows[ERR_ATT] = att[keep]
    rows[taided.GNSS_USED] = ((res.flags & A.F_GNSS_P) != 0)[keep].astype(np.int8)
    rows[taided.STATE] = scen.state[keep].astype(np.int8)
    rows[taided.SINCE_FIX] = since[keep]
    for cols, arr in (
        ((*ERR_POS, *ERR_TRACK), err),
        (taided.SD_POS, sd),
        (ttruth.POS, res.p_n),
        (ttruth.VEL, res.v_n),
        (ttruth.QUAT, res.q_nb),
        (taided.GYRO_BIAS, res.gyro_bias),
        (taided.ACCEL_BIAS, res.accel_bias),
        (taided.SD_VEL, res.sd_of("v")),
        (taided.SD_ATT, res.sd_of("att")),
        (taided.SD_GYRO_BIAS, res.sd_of("bg")),
        (taided.SD_ACCEL_BIAS, res.sd_of("ba")),
    ):
        for i, c in enumerate(cols):
            rows[c] = arr[..., i][keep]
    return pd.DataFrame(rows)[list(taided.COLUMNS)]


def filter_estimates(ids, res: A.AidedResult) -> dict:
    """The filter-estimates table's rows (:mod:`imugen.tables.filter_estimates`) of a filter
    result of sequences ``ids``: every epoch from the filter's start on; NaN for the states
    the filter does not have."""
    keep = (res.flags & A.F_ALIGNED) != 0
    S, J = keep.shape
    k = keep.ravel()
    rows = {
        SEQUENCE: np.repeat(np.asarray(ids, np.int64), J)[k],
        TIME: np.tile(np.asarray(res.time_s, float), S)[k],
        test.SAMPLE: np.tile(np.asarray(res.index, np.int64), S)[k],
        test.FLAGS: res.flags[keep].astype(np.int16),
    }
    for cols, arr in ((ttruth.POS, res.p_n), (ttruth.VEL, res.v_n), (ttruth.QUAT, res.q_nb)):
        for i, c in enumerate(cols):
            rows[c] = arr[..., i][keep]
    lay = res.layout
    values = {"bg": res.gyro_bias, "ba": res.accel_bias, "sg": res.gyro_sf, "sa": res.accel_sf,
              "cc": res.gyro_cc, "ca": res.accel_cc, "gnss_bias": res.gnss_bias}  # fmt: skip
    nan = np.full(int(k.sum()), np.nan)
    for key, cols in test.ESTIMATES.items():
        for i, c in enumerate(cols):
            rows[c] = values[key][..., i][keep] if lay.has(key) else nan
    for key, cols in test.SD.items():
        sd = res.sd_of(key) if lay.has(key) else None
        for i, c in enumerate(cols):
            rows[c] = sd[..., i][keep] if sd is not None else nan
    return rows


def filter_block(
    truth: ttruth.Truth, ids, dth, dvb, params: AidOptions, seed: int, tun, opts, mount=None,
    *, learned=None, store_correction: bool = False, scen=None,
):  # fmt: skip
    """The aided filter over a block of sequences, as the stage runs it: their GNSS
    (:func:`gnss_for`) and companions (:func:`companions_for`), the tuning, the alignment
    (:func:`imugen.aid.filter.align`) and :func:`imugen.aid.filter.run`.

    Parameters
    ----------
    truth : imugen.tables.truth.Truth
    ids : (S,) int64  global sequence ids (:func:`imugen.tables.shard.sequence_ids`)
    dth, dvb : (S, K, 3)  the increments the filter is given [rad, m/s] (row 0 unused)
    params : AidOptions;  seed : int  the simulation's seed
    tun, opts : the filter's tuning (:meth:`imugen.aid.filter.Tuning.from_grade`) and options
        (:func:`filter_options`)
    mount : the sequences' ``(angles, lever)`` of a mounted IMU, or None
    learned : callable ``scen -> imugen.aid.filter.LearnedInputs``, optional
    scen : imugen.aid.scenarios.ScenarioResult, optional
        The sequences' GNSS when already drawn (default :func:`gnss_for`)

    Returns
    -------
    ``(scen, odometer, barometer, init, res)``: the scenario result, the companions' data,
    the alignment and the filter's :class:`imugen.aid.filter.AidedResult`.
    """
    frame = truth.origin_frame()
    if scen is None:
        scen = gnss_for(truth, ids, params, seed, mount)
    odo, baro = companions_for(truth, ids, params, seed)
    ce = CP.filter_input(
        scen.gnss.index, len(ids), odo, baro, h0_m=frame.h0_m, level=params.tuning_level,
        lever_arm_b_m=params.odometer_lever_b_m,
    )  # fmt: skip
    T = A.companion_tuning(
        A.tuning_matrix(
            tun, len(ids), gnss_receiver=scen.gnss.receiver,
            gnss_level="law" if params.tuning_level == "law" else "nominal",
        ),
        ce,
    )  # fmt: skip
    init = A.align(dth, dvb, truth.dt, scen.gnss, tun, opts, frame,
                   speed_mps=params.align_speed_mps, tuning_T=T)  # fmt: skip
    res = A.run(
        dth, dvb, truth.dt, frame, scen.gnss, tun, opts, init, tuning_T=T, companions=ce,
        learned=None if learned is None else learned(scen), store_correction=store_correction,
    )  # fmt: skip
    return scen, odo, baro, init, res


def aid(
    truth_path, shard_path, params: AidOptions, *, batch: int | None = None, sink=None,
    aided_sink=None, companion_sink=None, correction_in=None, correction_sink=None,
    estimates_sink=None, learned_in=None,
):  # fmt: skip
    """Run the stage on one shard: ``(gnss rows, labels, intervals, aided rows, meta)``.

    ``correction_in``: an IMU correction table (:mod:`imugen.tables.imu_correction`, a
    learner's) subtracted from the increments before the filter; ``correction_sink(cols)``
    receives, batch by batch, what the filter removed from each increment (the same layout).
    ``estimates_sink(meta, cols)`` receives, batch by batch, the filter's state and sigmas at every
    epoch (:mod:`imugen.tables.filter_estimates`). ``learned_in``: a learned-measurements table
    (:mod:`imugen.tables.learned`) fed to the filter.

    ``sink(meta, df)`` and ``aided_sink(meta, df)``, when given, receive the GNSS rows and the
    aided rows batch by batch (and ``gnss rows``, ``aided rows`` are then None), so neither
    table of a shard sits whole in memory. ``companion_sink(rows, labels)`` receives the
    companion-table rows and labels of each batch.
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
    opts = filter_options(
        params, truth.meta.get("vehicle"), smeta.get("mounting"), truth.meta.get("plausibility"),
        truth.meta.get("vehicle_params"),
    )  # fmt: skip
    mlabels = tshard.read_labels(shard_path, smeta) if smeta.get("mounting") else None
    shard_ids = None
    if learned_in is not None:
        shard_ids = tshard.read_labels(shard_path, smeta)[SEQUENCE].to_numpy(np.int64)
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
        "odometer": params.odometer,
        "barometer": params.barometer,
        "error": "filter minus truth, ENU at the true position; along/cross the true track",
        "dt_s": float(truth.dt),
        "learned": None if learned_in is None else Path(learned_in).name,
    }
    gnss_rows, labels, intervals, aided_rows = [], [], [], []
    never = batches = 0
    for ids, a, c in tshard.iter_blocks(shard_path, columns, K, int(batch), 0):
        ids = ids.copy()
        dth, dvb = _increments(a, c, kind, raw, truth.dt)
        mount = tshard.mounting(mlabels, ids)
        learned = None
        if correction_in is not None or learned_in is not None:

            def learned(scen, ids=ids):
                corr = (
                    (None, None) if correction_in is None else tcorr.arrays(correction_in, ids, K)
                )
                meas = {}
                if learned_in is not None:
                    meas = tlearned.arrays(learned_in, ids, scen.gnss.time_s, shard_ids)
                return A.LearnedInputs(*corr, **meas)

        scen, odo, baro, init, res = filter_block(
            truth, ids, dth, dvb, params, seed, tun, opts, mount, learned=learned,
            store_correction=correction_sink is not None,
        )  # fmt: skip
        never += int(np.sum(init.k0 >= K))
        if correction_sink is not None:
            correction_sink(tcorr.frame(ids, res.correction))
        if estimates_sink is not None:
            estimates_sink(meta, filter_estimates(ids, res))
        if companion_sink is not None:
            clab = pd.DataFrame({SEQUENCE: ids})
            for d in (odo, baro):
                if d is not None:
                    clab = clab.join(d.labels.drop(columns="sequence"))
            companion_sink(tcomp.frame(ids, odo, baro), clab)
        if sink is None:
            gnss_rows.append(tgnss.frame(ids, scen))
        else:
            sink(meta, tgnss.frame(ids, scen))
        lab = scen.gnss.labels.copy()
        lab[SEQUENCE] = ids  # global int64 ids (the receiver's labels count from ``first``)
        labels.append(lab)
        intervals.append(scen.intervals)
        rows = aided_errors(truth, ids, res, scen, every, mount)
        if aided_sink is None:
            aided_rows.append(rows)
        else:
            aided_sink(meta, rows)
        batches += 1
    if not batches:
        raise InputError(shard_path, "holds no sequences")
    if never:
        warnings.warn(
            f"{shard_path}: {never} sequence(s) never aligned (not still at the start, and no "
            f"fix at >= {params.align_speed_mps:g} m/s): no aided rows for them; lower "
            "aided.align_speed_mps (--align-speed)",
            stacklevel=2,
        )
    return (
        pd.concat(gnss_rows, ignore_index=True) if sink is None else None,
        pd.concat(labels, ignore_index=True),
        pd.concat(intervals, ignore_index=True),
        pd.concat(aided_rows, ignore_index=True) if aided_sink is None else None,
        meta,
    )


def run(
    truth, shard, out_gnss, out_nav, params: AidOptions | None = None, *, batch=None,
    out_companions=None, correction_in=None, out_correction=None, out_estimates=None,
    learned_in=None,
):  # fmt: skip
    """Run the stage on one shard and write the GNSS table (with sidecars), the aided table
    (both streamed batch by batch) and, when ``out_companions`` is given, the companion table
    (with its labels; no rows when no companion is configured) atomically; ``correction_in``
    a learner's IMU correction table to apply, ``out_correction`` where to stream what the
    filter removed (:mod:`imugen.tables.imu_correction`), ``out_estimates`` where to stream the
    filter's state and sigmas at every epoch (:mod:`imugen.tables.filter_estimates`),
    ``learned_in`` a learned-measurements table (:mod:`imugen.tables.learned`). Returns
    ``(out_gnss, out_nav)`` paths."""
    params = params or AidOptions()
    if out_companions is None and (params.odometer or params.barometer):
        raise InputError("--companions-out", "needed with an odometer or a barometer")
    crow, clab = [], []

    def csink(rows, labels):
        crow.append(rows)
        clab.append(labels)

    with (
        tgnss.writer(out_gnss) as w,
        taided.writer(out_nav) as wa,
        tcorr.writer(out_correction) if out_correction else nullcontext() as wc,
        test.writer(out_estimates) if out_estimates else nullcontext() as we,
    ):
        correction_sink = None
        if wc is not None:
            wc.meta = {"stage": "aid-correction", "shard": Path(shard).name, "what": "filter"}
            correction_sink = wc.put

        def sink(meta, df):
            w.meta = {**meta, "stage": "aid-gnss"}
            w.put(df)

        def aided_sink(meta, df):
            wa.meta = {**meta, "stage": "aid", "gnss": Path(out_gnss).name}
            wa.put(df)

        def estimates_sink(meta, cols):
            keys = ("imugen_version", "truth", "shard", "grade", "route", "options",
                    "tuning_level", "learned")  # fmt: skip
            we.meta = {k: meta.get(k) for k in keys} | {"stage": "aid-estimates",
                                                        "dt_s": meta["dt_s"]}  # fmt: skip
            we.put(cols)

        _, w.labels, w.intervals, _, meta = aid(
            truth, shard, params, batch=batch, sink=sink, aided_sink=aided_sink,
            companion_sink=csink, correction_in=correction_in, correction_sink=correction_sink,
            estimates_sink=estimates_sink if we is not None else None, learned_in=learned_in,
        )  # fmt: skip
        if out_companions is not None:
            cmeta = {
                k: meta[k] for k in ("imugen_version", "truth", "shard", "grade", "route", "seed")
            }
            cmeta.update(
                stage="aid-companions", odometer=params.odometer, barometer=params.barometer,
                odometer_rate_hz=_rate("odometer", params.odometer, params.odometer_rate_hz),
                barometer_rate_hz=_rate("barometer", params.barometer, params.barometer_rate_hz),
            )  # fmt: skip
            tcomp.write(
                pd.concat(crow, ignore_index=True), pd.concat(clab, ignore_index=True), cmeta,
                out_companions,
            )  # fmt: skip
    return Path(out_gnss), Path(out_nav)


def _rate(kind, preset, rate):
    if preset is None:
        return None
    return float(rate or CP.get_sensor(kind, preset).rate_hz)


def main(
    options: AidOptions, truth, shard, gnss_out, output, companions_out, correction_in=None,
    correction_out=None, estimates_out=None, learned_in=None,
) -> None:  # fmt: skip
    """``imugen aid``."""
    run(
        truth, shard, gnss_out, output, options, out_companions=companions_out,
        correction_in=correction_in, out_correction=correction_out, out_estimates=estimates_out,
        learned_in=learned_in,
    )  # fmt: skip


__all__ = [
    "AidOptions", "aid", "aided_errors", "companions_for", "eval_mask", "filter_block",
    "filter_estimates",
    "filter_options",
    "gnss_for", "run",
]  # fmt: skip
