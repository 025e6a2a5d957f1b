"""Navigation stage: a shard of measured IMU sequences -> strapdown -> errors against truth.

Each sequence starts from the true initial state (position, velocity, attitude at ``t_0``:
no initial-alignment error) and is mechanized with :mod:`imugen.navigate.mechanize` on the shard's
angle/velocity increments (or, when the shard holds rates only, on increments formed from
them by :func:`imugen.navigate.mechanize.increments_from_rates`), in the Earth model of the truth.
Raw increments (shard metadata ``increments: raw``: plain integrals of rate and specific
force) first get the two-sample coning/sculling correction
(:func:`imugen.navigate.mechanize.compensate_raw`). Sequences are streamed from the shard in batches,
so memory is bounded by the batch size.

The truth is that of the IMU: a shard simulated with a mounting (metadata ``mounting``,
:mod:`imugen.sensors.mounting`) starts from, and is compared with, the IMU's point and axes
(``p + C_nv l``, ``C_nv C_vb``, from the drawn values in its labels); otherwise the vehicle's.

Output: the navigation error table of :mod:`imugen.tables.nav` (``sequence``, ``time_s``,
``err_e_m``, ``err_n_m``, ``err_u_m``, ``err_along_m``, ``err_cross_m``, ``err_att_rad``), one
row per sequence and evaluation epoch (every ``round(rate / eval_rate_hz)`` samples from
``t_0``); position errors in the local level at the true position
(:mod:`imugen.navigate.local_errors`), whatever the Earth model.

:func:`navigate_arrays` does the same for increments held in memory (no files): the loop of
a user who corrects increments and wants to see the navigation errors.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from imugen import __version__
from imugen.core.errors import InputError
from imugen.core.rotations import log_quat, quat_conj, quat_mul
from imugen.navigate import local_errors as lerr
from imugen.navigate.mechanize import compensate_raw, increments_from_rates, mechanize
from imugen.tables import nav as tnav
from imugen.tables import shard as tshard
from imugen.tables import truth as ttruth
from imugen.tables._parquet import SEQUENCE, TIME

BATCH_BYTES = 64 << 20
"""Budget of the float64 increment buffers of one batch (both sensors): with the reused
buffers it bounds a navigate job's memory whatever the shard's size and the IMU rate."""

NAV_TRUTH_COLUMNS = [TIME, *ttruth.POS, *ttruth.VEL, *ttruth.QUAT, *ttruth.GYRO]


def batch_size(samples: int, budget: int = BATCH_BYTES) -> int:
    """Sequences per batch so that two ``(batch, samples, 3)`` float64 buffers fit ``budget``."""
    return int(max(1, min(256, budget // (2 * 3 * 8 * max(int(samples), 1)))))


class Navigator:
    """Mechanizes batches of increments against one truth and tabulates their errors (used by
    :func:`navigate` on a shard file and by ``imugen simulate --navigate`` on the sequences as
    they are generated: the same arithmetic, hence the same table).

    Parameters
    ----------
    truth : imugen.tables.truth.Truth
        Needs ``time_s``, ``p_n``, ``v_n``, ``q_nb``, ``omega_ib_b`` (for a mounted IMU) and the
        metadata's origin and Earth model.
    eval_rate_hz : float
        Error epochs per second.
    """

    def __init__(self, truth: ttruth.Truth, eval_rate_hz: float):
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
                        outputs=("p", "q"))  # fmt: skip
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


def navigate(truth_path, shard_path, *, eval_rate_hz: float = 1.0, batch: int | None = None):
    """Mechanize every sequence of a shard and return its errors at the evaluation epochs.

    ``batch`` sequences are mechanized together (default :func:`batch_size`, from a fixed
    memory budget); the result does not depend on it. Returns a DataFrame (the table of
    :mod:`imugen.tables.nav`).
    """
    import pandas as pd

    frames = [pd.DataFrame(c) for c in _iter_errors(truth_path, shard_path, eval_rate_hz, batch)]
    if not frames:
        raise InputError(shard_path, "holds no sequences")
    return pd.concat(frames, ignore_index=True)


def _iter_errors(truth_path, shard_path, eval_rate_hz, batch):
    """Error-table columns of each batch of sequences of a shard (a generator)."""
    truth_path, shard_path = Path(truth_path), Path(shard_path)
    smeta = tshard.read_meta(shard_path)
    nav = Navigator(ttruth.read(truth_path, columns=NAV_TRUTH_COLUMNS, arrow=True), eval_rate_hz)
    K = nav.K
    columns, kind = tshard.measurement(shard_path)
    raw = kind == "increments" and tshard.increment_kind(smeta) == "raw"
    n = smeta.get("samples_per_sequence")
    if n is not None and n != K:
        raise InputError(shard_path, f"has {n} samples per sequence where the truth has {K}")

    if batch is None:
        batch = batch_size(K)
    skip = 1 if kind == "increments" else 0
    labels = tshard.read_labels(shard_path, smeta) if smeta.get("mounting") else None
    for seq_ids, a, b in tshard.iter_blocks(shard_path, columns, K, int(batch), skip):
        mount = tshard.mounting(labels, seq_ids)
        yield nav.columns(seq_ids, *nav.measured(kind, raw, a, b), mount)


def _as_increments(increments, K: int):
    """``(dtheta, dv, ids, semantics or None)`` float64 (S, K-1, 3) from the accepted forms."""
    semantics = None
    ids = None
    mount = None
    meta = getattr(increments, "meta", None)
    if meta is not None and hasattr(increments, "data"):  # imugen.simulate.stage.Shard
        semantics = tshard.increment_kind(meta)
        ids = increments.labels[SEQUENCE].to_numpy()
        mount = tshard.mounting(increments.labels)
        increments = increments.data
    if isinstance(increments, dict):
        if "dtheta" not in increments or "dv" not in increments:
            raise InputError("increments", "a dict needs 'dtheta' and 'dv' arrays")
        dth, dv = increments["dtheta"], increments["dv"]
    elif isinstance(increments, tuple | list) and len(increments) == 2:
        dth, dv = increments
    else:
        a = np.asarray(increments, dtype=np.float64)
        if a.shape[-1] != 6:
            raise InputError("increments", f"expected (..., 6) or (dtheta, dv), got {a.shape}")
        dth, dv = a[..., :3], a[..., 3:]
    out = []
    for name, x in (("dtheta", dth), ("dv", dv)):
        x = np.asarray(x, dtype=np.float64)
        if x.ndim == 2:
            x = x[None]
        if x.ndim != 3 or x.shape[-1] != 3 or x.shape[1] not in (K, K - 1):
            raise InputError(
                "increments", f"{name} must be (S, K, 3) or (S, K-1, 3) with K = {K}, got {x.shape}"
            )
        if x.shape[1] == K:  # rows aligned with the truth: row 0 is the empty interval
            x = x[:, 1:]
        if not np.all(np.isfinite(x)):
            raise InputError("increments", f"{name} holds non-finite values")
        out.append(np.array(x, dtype=np.float64, order="C"))  # a copy: never alter the caller's
    if out[0].shape != out[1].shape:
        raise InputError("increments", f"dtheta {out[0].shape} and dv {out[1].shape} differ")
    return out[0], out[1], ids, semantics, mount


def navigate_arrays(
    truth,
    increments,
    *,
    semantics: str | None = None,
    eval_rate_hz: float = 1.0,
    sequence_ids=None,
):
    """Navigate increments held in memory against a truth; no files written.

    Parameters
    ----------
    truth : path or imugen.tables.truth.Truth
        Truth file (or one already read with :func:`imugen.tables.truth.read`).
    increments : (dtheta, dv), dict, ndarray or imugen.simulate.stage.Shard
        Angle [rad] and velocity [m/s] increments, each ``(S, K, 3)`` with rows aligned with
        the truth (row 0, the empty interval, is ignored) or ``(S, K-1, 3)``; ``(K, 3)`` for one
        sequence. A dict with ``"dtheta"``, ``"dv"`` (``Shard.data``), an ``(S, K, 6)`` array
        (dtheta then dv), or an in-memory shard from :func:`imugen.simulate.stage.simulate` (whose
        mounting, when it has one, is taken into account: errors against the IMU's point and
        axes, :meth:`Navigator.imu_truth`).
    semantics : {"compensated", "raw"}, optional
        Increment semantics; raw increments get the two-sample coning/sculling correction.
        Default: the shard's, else compensated.
    eval_rate_hz : float
        Error epochs per second (every ``round(rate / eval_rate_hz)`` samples from ``t_0``).
    sequence_ids : array of int, optional
        Ids of the ``S`` sequences in the result (default the shard's, else ``0 .. S-1``).

    Returns
    -------
    pandas.DataFrame
        The navigation error table (:mod:`imugen.tables.nav`): ``sequence``, ``time_s``,
        ``err_e_m``, ``err_n_m``, ``err_u_m``, ``err_along_m``, ``err_cross_m``,
        ``err_att_rad``.
    """
    if not isinstance(truth, ttruth.Truth):
        truth = ttruth.read(truth, columns=NAV_TRUTH_COLUMNS, arrow=True)
    nav = Navigator(truth, eval_rate_hz)
    dth, dv, ids, kind, mount = _as_increments(increments, nav.K)
    kind = semantics or kind or "compensated"
    if kind not in tshard.INCREMENT_KINDS:
        raise InputError("semantics", f"must be compensated or raw, got {kind!r}")
    if sequence_ids is not None:
        ids = np.asarray(sequence_ids, np.int64)
    if ids is None:
        ids = np.arange(len(dth), dtype=np.int64)
    if len(ids) != len(dth):
        raise InputError("sequence_ids", f"{len(ids)} ids for {len(dth)} sequences")
    if kind == "raw":
        compensate_raw(dth, dv)  # in place, on the copies
    return nav.errors(ids, dth, dv, mount)


def table_meta(truth_name, truth_sha256, shard_name, smeta: dict, eval_rate_hz) -> dict:
    """Metadata of the error table of a shard (``smeta``: the shard's metadata; ``shard_name``
    None when the shard was navigated in memory and not written)."""
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
    }


def run(truth, shard, out, *, eval_rate_hz: float = 1.0, batch: int | None = None) -> Path:
    """Navigate a shard and stream its error table to ``out`` atomically (one row group per
    batch: memory stays flat in the shard's size)."""
    out = Path(out)
    smeta = tshard.read_meta(shard)
    meta = table_meta(
        Path(truth).name, ttruth.checksum(truth), Path(shard).name, smeta, eval_rate_hz
    )
    with tnav.writer(out, meta) as w:
        for cols in _iter_errors(truth, shard, eval_rate_hz, batch):
            w.put(cols)
        if w.rows == 0:
            raise InputError(shard, "holds no sequences")
    return out
