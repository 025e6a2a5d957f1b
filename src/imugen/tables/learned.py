"""Learned-measurements table: a learner's measurements for the aided filter, per epoch.

Read by ``imugen aid --learned-in`` (issue 26) and given to the filter as
:class:`imugen.aid.filter.LearnedInputs` (:mod:`imugen.aid.filter.learned`): one row per
sequence and filter epoch where the learner says something; epochs without a row, and NaN
values, mean no measurement.

Columns (body axes FLU of the IMU, SI):

- ``sequence`` int64, ``time_s`` (s): a filter epoch of the sequence (a GNSS epoch time of the
  shard's receiver, ``time_s`` of :mod:`imugen.tables.gnss`, whether a fix came or not);
- ``vb_x_mps``, ``vb_y_mps``, ``vb_z_mps``: the IMU's velocity in body axes (TLIO, RINS-W
  style; ``z = C_nb^T v_n + e``), with ``vb_cov_{xx,yy,zz,xy,xz,yz}_m2ps2``, the covariance of
  ``e`` (symmetric 3x3, positive definite where the velocity is given);
- ``nhc_var_lat_m2ps2``, ``nhc_var_vert_m2ps2``: the non-holonomic constraint's variances
  (lateral, vertical) at the epoch, replacing the vehicle's slip (AI-IMU style; used only where
  the filter applies NHC).

A table holds the velocity group, the NHC group, or both (all columns of a group). Float64.
Metadata (JSON under ``b"imugen"``): free (e.g. ``what``: the learner's name), ``units``.
Refused in one line: a missing column, a sequence not in the shard, a time that is not a filter
epoch, a repeated (sequence, time), a covariance that is not positive definite, a negative
variance.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pyarrow as pa

from imugen.core.errors import InputError
from imugen.core.io import METADATA_KEY
from imugen.tables import SEQUENCE, TIME
from imugen.tables._parquet import block_writer, names, read_table, require

VB = tuple(f"vb_{a}_mps" for a in "xyz")
VB_COV = tuple(f"vb_cov_{p}_m2ps2" for p in ("xx", "yy", "zz", "xy", "xz", "yz"))
NHC_VAR = ("nhc_var_lat_m2ps2", "nhc_var_vert_m2ps2")
COLUMNS = (SEQUENCE, TIME, *VB, *VB_COV, *NHC_VAR)
UNITS = {
    SEQUENCE: "1",
    TIME: "s",
    **dict.fromkeys(VB, "m/s"),
    **dict.fromkeys((*VB_COV, *NHC_VAR), "m^2/s^2"),
}
WHAT = "learned-measurements table"
_COV_IDX = ((0, 0), (1, 1), (2, 2), (0, 1), (0, 2), (1, 2))


def _schema(cols):
    def schema_of(meta: dict) -> pa.Schema:
        md = {METADATA_KEY: json.dumps({**meta, "units": UNITS}).encode()}
        fields = [pa.field(c, pa.int64() if c == SEQUENCE else pa.float64()) for c in cols]
        return pa.schema(fields, metadata=md)

    return schema_of


def frame(ids, time_s, body_velocity=None, body_velocity_cov=None, nhc_var=None) -> dict:
    """Rows of sequences ``ids`` (S,) at epochs ``time_s`` (J,) from arrays as
    :class:`imugen.aid.filter.LearnedInputs` takes them: ``body_velocity`` (S, J, 3) with
    ``body_velocity_cov`` (S, J, 3, 3) or variances (S, J, 3), ``nhc_var`` (S, J, 2); NaN
    where absent. Only epochs with some finite value become rows."""
    ids = np.asarray(ids, np.int64)
    t = np.asarray(time_s, float)
    S, J = len(ids), len(t)
    cols, given = {}, np.zeros((S, J), bool)
    if body_velocity is not None:
        v = np.asarray(body_velocity, float).reshape(S, J, 3)
        R = np.asarray(body_velocity_cov, float)
        if R.shape == (S, J, 3):
            R = R[..., None] * np.eye(3)
        R = R.reshape(S, J, 3, 3)
        for i, c in enumerate(VB):
            cols[c] = v[..., i]
        for (a, b), c in zip(_COV_IDX, VB_COV, strict=True):
            cols[c] = R[..., a, b]
        given |= np.isfinite(v).any(-1)
    if nhc_var is not None:
        nv = np.asarray(nhc_var, float).reshape(S, J, 2)
        for i, c in enumerate(NHC_VAR):
            cols[c] = nv[..., i]
        given |= np.isfinite(nv).any(-1)
    out = {SEQUENCE: np.repeat(ids, J)[given.ravel()], TIME: np.tile(t, S)[given.ravel()]}
    out.update({c: a[given] for c, a in cols.items()})
    return out


def write(cols, meta: dict, out) -> Path:
    """Write rows ``cols`` (:func:`frame`, or a DataFrame holding one or both groups)
    atomically."""
    have = [c for c in COLUMNS if c in cols]
    with block_writer(out, meta, _schema(have)) as w:
        w.put(cols)
    return Path(out)


def read(path, columns=None, filters=None):
    """Columns (default all the file holds) of a learned-measurements table."""
    return read_table(path, columns, filters, WHAT).to_pandas()


def arrays(path, ids, time_s, shard_ids=None) -> dict:
    """The learned measurements of sequences ``ids`` (S,) at the filter epochs ``time_s`` (J,)
    as keyword arguments of :class:`imugen.aid.filter.LearnedInputs` (``body_velocity`` (S, J,
    3), ``body_velocity_cov`` (S, J, 3, 3), ``nhc_var`` (S, J, 2); NaN where absent, a group
    missing from the file left out). ``shard_ids``: every sequence of the shard when ``ids`` is
    one batch of it (rows of the others are skipped). One-line :class:`InputError` for a bad
    file (module docstring)."""
    have = set(names(path, WHAT))
    require(path, have, (SEQUENCE, TIME), WHAT)
    groups = [g for g in ((*VB, *VB_COV), NHC_VAR) if any(c in have for c in g)]
    if not groups:
        raise InputError(path, f"not a {WHAT}: holds neither {VB[0]}... nor {NHC_VAR[0]}...")
    for g in groups:
        require(path, have, g, WHAT)
    ids = np.asarray(ids, np.int64)
    t = np.asarray(time_s, float)
    S, J = len(ids), len(t)
    known = set(int(s) for s in (ids if shard_ids is None else shard_ids))
    stray = [int(s) for s in np.unique(read(path, columns=[SEQUENCE])[SEQUENCE]) if s not in known]
    if stray:
        raise InputError(path, f"sequence {stray[0]} is not in the shard")
    df = read(
        path, columns=[SEQUENCE, TIME, *(c for g in groups for c in g)],
        filters=[(SEQUENCE, "in", [int(i) for i in ids])],
    )  # fmt: skip
    seq = df[SEQUENCE].to_numpy(np.int64)
    pos = {int(s): i for i, s in enumerate(ids)}
    si = np.array([pos[int(s)] for s in seq], np.int64)
    tt = df[TIME].to_numpy(float)
    j = np.clip(np.searchsorted(t, tt), 0, max(J - 1, 0))
    jm = np.clip(j - 1, 0, max(J - 1, 0))
    j = np.where(np.abs(t[jm] - tt) < np.abs(t[j] - tt), jm, j) if J else j
    tol = 1e-6 * (float(np.min(np.diff(t))) if J > 1 else 1.0)
    off = ~(np.abs(t[j] - tt) <= tol) if J else np.ones(len(tt), bool)
    if off.any():
        raise InputError(path, f"time {tt[off][0]!r} s is not a filter (GNSS) epoch of the shard")
    flat = si * J + j
    if len(np.unique(flat)) != len(flat):
        k = np.flatnonzero(np.bincount(flat) > 1)[0]
        raise InputError(path, f"sequence {ids[k // J]} at {t[k % J]!r} s given twice")
    out = {}
    if (*VB, *VB_COV) in groups:
        v = np.full((S, J, 3), np.nan)
        v[si, j] = df[list(VB)].to_numpy(float)
        R = np.full((S, J, 3, 3), np.nan)
        c = df[list(VB_COV)].to_numpy(float)
        for i, (a, b) in enumerate(_COV_IDX):
            R[si, j, a, b] = R[si, j, b, a] = c[:, i]
        given = np.isfinite(v).all(-1)
        if np.any(np.isfinite(v).any(-1) & ~given):
            raise InputError(path, "a body velocity must give all three components or none")
        Rg = R[given]
        bad = ~np.isfinite(Rg).all((-1, -2))
        if not bad.any():
            bad = ~_pd(Rg)
        if bad.any():
            s_, j_ = np.argwhere(given)[np.flatnonzero(bad)[0]]
            raise InputError(
                path, f"covariance of sequence {ids[s_]} at {t[j_]!r} s is not positive definite"
            )
        out |= {
            "body_velocity": v,
            "body_velocity_cov": np.where(given[..., None, None], R, np.nan),
        }
    if NHC_VAR in groups:
        nv = np.full((S, J, 2), np.nan)
        nv[si, j] = df[list(NHC_VAR)].to_numpy(float)
        if np.any(nv[np.isfinite(nv)] < 0):
            raise InputError(path, "NHC variances must be >= 0")
        out["nhc_var"] = nv
    return out


def _pd(R) -> np.ndarray:
    """(N,) whether each symmetric (N, 3, 3) is positive definite (Sylvester's criterion)."""
    if not len(R):
        return np.zeros(0, bool)
    m1 = R[:, 0, 0]
    m2 = R[:, 0, 0] * R[:, 1, 1] - R[:, 0, 1] ** 2
    return (m1 > 0) & (m2 > 0) & (np.linalg.det(R) > 0)
