"""GNSS fixes and scenario states of streamed sequences: the aid stage's draws, in memory.

A sequence's receiver, its errors and its scenarios are drawn as the aid stage draws them
(:func:`imugen.aid.gnss.simulate_gnss`, :func:`imugen.aid.scenarios.draw` and
:func:`imugen.aid.scenarios.apply`, entropy :func:`imugen.core.seeding.sequence_entropy`
``[seed, route_id, index]``): a written sequence (``index = shard * shard_size + j``, the
written shards' size) gets the fixes of the aid stage's GNSS table bit for bit. A streamed
sequence (``shard >= 2^31``) has ``index >= 2^31``, never a written one's.

Per window the epochs are laid on its rows (an epoch arrives at IMU sample ``index``):
``gnss_p_n``, ``gnss_v_n`` ``(B, W, 3)`` the measured antenna position and velocity (NaN on rows
without an epoch or without a fix), ``gnss_sigma_p_n``, ``gnss_sigma_v_n`` the reported
1-sigma (NaN on rows without an epoch), ``gnss_state`` ``(B, W)`` int8 the scenario state
(:data:`imugen.aid.scenarios.KINDS`; -1 on rows without an epoch), and ``gnss_labels``
``(B, L)`` the receiver's drawn parameters (columns of the GNSS table's labels sidecar).
"""

from __future__ import annotations

import numpy as np

from imugen.aid import gnss as G
from imugen.aid import scenarios as SC
from imugen.core.earth import earth_rate_n
from imugen.core.seeding import sequence_entropy

KEYS = ("gnss_p_n", "gnss_v_n", "gnss_sigma_p_n", "gnss_sigma_v_n", "gnss_state", "gnss_labels")
"""Batch entries of the ``gnss`` target."""


def sequence_gnss(truth, params, seed, route_id: int, index: int, mount=None):
    """The scenario result (:class:`imugen.aid.scenarios.ScenarioResult`) of one sequence.

    Parameters
    ----------
    truth : imugen.tables.truth.Truth
        The route's truth table (positions, velocities, attitude, rates).
    params : imugen.aid.options.AidOptions
        Receiver and scenarios (the aid stage's options).
    seed : int
        The aid stage's seed (that of the shard's simulation).
    route_id, index : int
        The sequence's route id and index in its route.
    mount : ((3,), (3,)), optional
        The sequence's mounting ``(angles [rad], lever arm [m])`` (stream ``mounting``): the
        antenna's lever arm is then from the IMU, in its axes, on the mounted IMU's truth
        (:func:`imugen.sensors.mounting.imu_states`), as the aid stage does for a shard
        written with mounting.
    """
    t = truth.time_s
    frame = truth.origin_frame()
    ent = sequence_entropy(seed, route_id, index)
    sid = (int(route_id) << 31) | int(index) if index < (1 << 31) else -1
    states = (truth.p_n, truth.v_n, truth.q_nb, truth.omega_ib_b)
    if mount is not None:
        states = _imu_truth(truth, frame, *mount)
    g = G.simulate_gnss(
        t, *states, G.get_receiver(params.receiver),
        1, ent, 0, rate_hz=params.rate_hz, draw=params.draw, lever_arm_b_m=params.lever_arm_b_m,
        lever_sd_m=params.lever_arm_sd_m, omega_ie_n=earth_rate_n(frame), first=sid, frame=frame,
    )  # fmt: skip
    ivs = list(params.intervals_parsed)
    if params.draw_kinds:
        ivs += SC.draw(
            params.draw_kinds, float(t[-1] - t[0]), ent, 0, 1, settle_s=params.settle_s,
            durations_s=params.outage_durations_s,
        )[0]  # fmt: skip
    return SC.apply(g, [ivs], ent, 0, first=sid, frame=frame)


def _imu_truth(truth, frame, angles, lever):
    """``(p_n, v_n, q_nb, omega_ib_b)`` (K, 3|4) of one mounted IMU (the aid stage's)."""
    from imugen.sensors.mounting import C_vb, imu_states

    w = truth.omega_ib_b
    p, v, q = imu_states(truth.p_n, truth.v_n, truth.q_nb, w, earth_rate_n(frame), angles, lever)
    return p[0], v[0], q[0], w @ C_vb(angles)


def label_names(scen) -> list[str]:
    """Columns of ``gnss_labels`` (the labels sidecar's, without ``sequence``)."""
    return [c for c in scen.gnss.labels.columns if c != "sequence"]


def lay(scen, k0, W: int, out: dict, b: int) -> None:
    """Write one window's epochs (rows ``k0 .. k0 + W - 1``) into row ``b`` of ``out``."""
    g = scen.gnss
    idx = np.asarray(g.index)
    sel = np.flatnonzero((idx >= k0) & (idx < k0 + W))
    r = idx[sel] - k0
    for name, arr in (("gnss_p_n", g.p_n), ("gnss_v_n", g.v_n), ("gnss_sigma_p_n", g.sigma_p_n),
                      ("gnss_sigma_v_n", g.sigma_v_n)):  # fmt: skip
        out[name][b] = np.nan
        out[name][b, r] = arr[0, sel]
    out["gnss_state"][b] = -1
    out["gnss_state"][b, r] = scen.state[0, sel]
    lab = g.labels
    out["gnss_labels"][b] = lab[label_names(scen)].to_numpy()[0]
