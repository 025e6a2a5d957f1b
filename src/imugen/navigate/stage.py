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

from imugen.core.errors import InputError
from imugen.navigate.mechanize import compensate_raw
from imugen.navigate.navigator import NAV_TRUTH_COLUMNS, Navigator, batch_size, table_meta
from imugen.navigate.options import NavigateOptions
from imugen.navigate.vertical import VerticalSpec
from imugen.tables import SEQUENCE
from imugen.tables import nav as tnav
from imugen.tables import shard as tshard
from imugen.tables import truth as ttruth


def navigate(
    truth_path,
    shard_path,
    *,
    eval_rate_hz: float = 1.0,
    batch: int | None = None,
    vertical: VerticalSpec | None = None,
):
    """Mechanize every sequence of a shard and return its errors at the evaluation epochs.

    ``batch`` sequences are mechanized together (default :func:`batch_size`, from a fixed
    memory budget); the result does not depend on it. ``vertical``: the vertical channel
    (:mod:`imugen.navigate.vertical`, default ``auto``). Returns a DataFrame (the table of
    :mod:`imugen.tables.nav`).
    """
    import pandas as pd

    frames = [
        pd.DataFrame(c)
        for c in _iter_errors(_navigator(truth_path, eval_rate_hz, vertical), shard_path, batch)
    ]
    if not frames:
        raise InputError(shard_path, "holds no sequences")
    return pd.concat(frames, ignore_index=True)


def _navigator(truth_path, eval_rate_hz, vertical) -> Navigator:
    truth = ttruth.read(Path(truth_path), columns=NAV_TRUTH_COLUMNS, arrow=True)
    return Navigator(truth, eval_rate_hz, vertical)


def _iter_errors(nav: Navigator, shard_path, batch):
    """Error-table columns of each batch of sequences of a shard (a generator)."""
    shard_path = Path(shard_path)
    smeta = tshard.read_meta(shard_path)
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
    vertical: VerticalSpec | None = None,
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
    vertical : VerticalSpec, optional
        Vertical channel (:mod:`imugen.navigate.vertical`; default ``auto``: damped by the true
        height beyond 3 growth times, 1,710 s).

    Returns
    -------
    pandas.DataFrame
        The navigation error table (:mod:`imugen.tables.nav`): ``sequence``, ``time_s``,
        ``err_e_m``, ``err_n_m``, ``err_u_m``, ``err_along_m``, ``err_cross_m``,
        ``err_att_rad``.
    """
    if not isinstance(truth, ttruth.Truth):
        truth = ttruth.read(truth, columns=NAV_TRUTH_COLUMNS, arrow=True)
    nav = Navigator(truth, eval_rate_hz, vertical)
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


def run(
    truth, shard, out, options: NavigateOptions | None = None, *, batch: int | None = None
) -> Path:
    """Navigate a shard and stream its error table to ``out`` atomically (one row group per
    batch of ``batch`` sequences, default :func:`~imugen.navigate.navigator.batch_size`: memory
    stays flat in the shard's size)."""
    options = options or NavigateOptions()
    eval_rate_hz = options.eval_rate_hz
    out = Path(out)
    smeta = tshard.read_meta(shard)
    nav = _navigator(truth, eval_rate_hz, VerticalSpec.of(options))
    meta = table_meta(
        Path(truth).name, ttruth.checksum(truth), Path(shard).name, smeta, eval_rate_hz,
        nav.vertical.meta(),
    )  # fmt: skip
    with tnav.writer(out, meta) as w:
        for cols in _iter_errors(nav, shard, batch):
            w.put(cols)
        if w.rows == 0:
            raise InputError(shard, "holds no sequences")
    return out


def main(options: NavigateOptions, truth, shard, output) -> None:
    """``imugen navigate``."""
    run(truth, shard, output, options)
