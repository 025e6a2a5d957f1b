"""The batch navigator: mechanize batches of measured increments from the true initial state
and tabulate their errors against one truth.

Shared by the navigate stage (:func:`imugen.navigate.stage.run` on a shard file) and by
``imugen simulate --navigate`` (on the sequences as they are generated): the same arithmetic,
hence the same table (:mod:`imugen.tables.nav`), bit for bit.
"""

from __future__ import annotations

import numpy as np

from imugen import __version__
from imugen.core.rotations import log_quat, quat_conj, quat_mul
from imugen.navigate import local_errors as lerr
from imugen.navigate.mechanize import (
    compensate_raw,
    increments_from_rates,
    mechanize,
    reference_heights,
)
from imugen.navigate.vertical import VerticalSpec
from imugen.tables import SEQUENCE, TIME
from imugen.tables import nav as tnav
from imugen.tables import truth as ttruth

BATCH_BYTES = 64 << 20
"""Budget of the float64 increment buffers of one batch (both sensors): with the reused
buffers it bounds a navigate job's memory whatever the shard's size and the IMU rate."""

NAV_TRUTH_COLUMNS = [TIME, *ttruth.POS, *ttruth.VEL, *ttruth.QUAT, *ttruth.GYRO]


def batch_size(samples: int, budget: int = BATCH_BYTES) -> int:
    """Sequences per batch so that two ``(batch, samples, 3)`` float64 buffers fit ``budget``."""
    return int(max(1, min(256, budget // (2 * 3 * 8 * max(int(samples), 1)))))


class Navigator:
    """Mechanizes batches of increments against one truth and tabulates their errors (used by
    :func:`imugen.navigate.stage.navigate` on a shard file and by ``imugen simulate
    --navigate`` on the sequences as they are generated: the same arithmetic, hence the same
    table).

    Parameters
    ----------
    truth : imugen.tables.truth.Truth
        Needs ``time_s``, ``p_n``, ``v_n``, ``q_nb``, ``omega_ib_b`` (for a mounted IMU) and the
        metadata's origin and Earth model.
    eval_rate_hz : float
        Error epochs per second.
    vertical : VerticalSpec, optional
        Vertical channel (:mod:`imugen.navigate.vertical`, default ``auto``), resolved for the
        truth's duration (:attr:`vertical`); damped, the reference is the vehicle's true height
        at every sample (for a mounted IMU too: its lever arm's vertical part then stays as a
        height offset, as for a height sensor at the vehicle's reference point).
    """

    def __init__(
        self, truth: ttruth.Truth, eval_rate_hz: float, vertical: VerticalSpec | None = None
    ):
        self.t = truth.time_s
        self.K = truth.K
        self.dt = truth.dt
        self.every = max(1, round(truth.rate_hz / eval_rate_hz))
        self.frame = truth.origin_frame()
        self.p_true = truth.p_n
        self.v_true = truth.v_n
        self.q_true = truth.q_nb
        self.x0 = (self.p_true[0], self.v_true[0], self.q_true[0])
        self._truth = truth
        self._local = None  # (epoch indices, C_ln, track) of the last batch
        duration = float(self.t[-1] - self.t[0]) if self.K else 0.0
        self.vertical = (vertical or VerticalSpec()).resolve(self.frame, duration)
        self.gains = self.vertical.kernel_gains()
        self.href = (
            reference_heights(self.p_true, self.frame)[None] if self.vertical.damped else None
        )

    def local(self, idx):
        """``(C_ln, track)`` at the epochs ``idx`` (:mod:`imugen.navigate.local_errors`), cached."""
        if self._local is None or not np.array_equal(self._local[0], idx):
            C = lerr.rotation_ln(self.frame, self.p_true[idx])
            v_l = np.einsum("jik,jk->ji", C, self.v_true[idx])
            self._local = (np.array(idx), C, lerr.track_direction(v_l))
        return self._local[1:]

    def imu_truth(self, mount, idx):
        """The mounted IMU's truth (:func:`imugen.sensors.mounting.imu_states`): initial state ``(p0,
        v0, q0)`` (S, 3|4) and ``(p, q)`` (S, len(idx), 3|4) at samples ``idx``.

        ``mount``: ``(angles, lever)`` (S, 3) from the shard's labels
        (:func:`imugen.tables.shard.mounting`)."""
        from imugen.core.earth import earth_rate_n
        from imugen.sensors.mounting import imu_states

        angles, lever = mount
        Om = earth_rate_n(self.frame)
        w0 = self._truth.omega_ib_b[:1]
        p0, v0, q0 = imu_states(
            self.p_true[:1], self.x0[1][None], self.q_true[:1], w0, Om, angles, lever
        )
        p, _, q = imu_states(self.p_true[idx], None, self.q_true[idx], None, Om, angles, lever)
        return (p0[:, 0], v0[:, 0], q0[:, 0]), p, q

    def errors(self, seq_ids, dth, dvb, mount=None):
        """:meth:`columns` as a DataFrame."""
        import pandas as pd

        return pd.DataFrame(self.columns(seq_ids, dth, dvb, mount))

    def columns(self, seq_ids, dth, dvb, mount=None) -> dict:
        """Error-table columns (:data:`imugen.tables.nav.COLUMNS` -> 1-D arrays) of increments
        ``dth``, ``dvb`` (b, K-1, 3) float64 (compensated, row 0 dropped).

        ``mount``: the sequences' ``(angles, lever)`` (b, 3) when the IMU was mounted with a
        misalignment and lever arm: navigation starts from, and is compared with, the IMU's
        truth (its point and axes, :meth:`imu_truth`); None: the vehicle's."""
        idx = np.arange(0, dth.shape[1] + 1, self.every)
        if mount is None:
            p0, v0, q0 = self.x0
            p_true, q_true = self.p_true[idx][None], self.q_true[idx][None]
        else:
            (p0, v0, q0), p_true, q_true = self.imu_truth(mount, idx)
        nav = mechanize(dth, dvb, self.dt, p0, v0, q0, self.frame, every=self.every,
                        outputs=("p", "q"), gains=self.gains,
                        href=None if self.href is None else self.href[:, : dth.shape[1] + 1])  # fmt: skip
        idx = nav.index
        err = lerr.apply(*self.local(idx), nav.p_n - p_true)
        dq = quat_mul(quat_conj(q_true), nav.q_nb)
        att = np.linalg.norm(log_quat(dq), axis=-1)
        n_seq, n_ep = err.shape[:2]
        return {
            SEQUENCE: np.repeat(np.asarray(seq_ids, np.int64), n_ep),
            TIME: np.tile(self.t[idx], n_seq),
            tnav.ERR_POS[0]: err[..., 0].ravel(),
            tnav.ERR_POS[1]: err[..., 1].ravel(),
            tnav.ERR_POS[2]: err[..., 2].ravel(),
            tnav.ERR_TRACK[0]: err[..., 3].ravel(),
            tnav.ERR_TRACK[1]: err[..., 4].ravel(),
            tnav.ERR_ATT: att.ravel(),
        }

    def measured(self, kind: str, raw: bool, a, b):
        """Compensated increments (b, K-1, 3) from a batch of a shard's measurements: ``kind``
        ``"increments"`` (row 0 dropped; ``raw``: two-sample coning/sculling correction, in
        place) or ``"rates"`` (b, K, 3)."""
        if kind == "increments":
            return compensate_raw(a, b) if raw else (a, b)
        return increments_from_rates(a, b, self.dt)


def table_meta(
    truth_name, truth_sha256, shard_name, smeta: dict, eval_rate_hz, vertical: dict | None = None
) -> dict:
    """Metadata of the error table of a shard (``smeta``: the shard's metadata; ``shard_name``
    None when the shard was navigated in memory and not written; ``vertical``: the vertical
    channel's record, :meth:`imugen.navigate.vertical.VerticalChannel.meta`)."""
    return {
        "stage": "navigate",
        "imugen_version": __version__,
        "truth": truth_name,
        "truth_sha256": truth_sha256,
        "shard": shard_name,
        "grade": smeta.get("grade"),
        "route": smeta.get("route"),
        "eval_rate_hz": eval_rate_hz,
        "increments": smeta.get("increments", "compensated"),
        "derived": smeta.get("derived"),
        "error": "navigation minus truth, ENU at the true position; along/cross the true track",
        "vertical_channel": vertical,
    }
