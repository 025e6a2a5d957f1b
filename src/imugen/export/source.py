"""What the export formats read: the truth of a route and its shards, one sequence at a time.

Every format writer sees the same two objects: :class:`TruthArrays` (the route's truth, in
memory once: ``K`` rows of float64) and, per sequence, :class:`Sequence` (its measured IMU
columns, ``K`` rows, its labels row and the shard's metadata). Files are read only through the
contract layer (:mod:`imugen.tables`); shards are streamed sequence by sequence, so an export
holds one sequence in memory whatever the number of sequences.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from imugen.core.errors import InputError
from imugen.tables import SEQUENCE
from imugen.tables import shard as tshard
from imugen.tables import truth as ttruth

RATE_COLUMNS = tshard.RATES
INCREMENT_COLUMNS = tshard.INCREMENTS
BIAS_COLUMNS = tshard.BIAS


@dataclass
class TruthArrays:
    """A route's truth (``K`` samples): time (K,), p_n, v_n (K, 3), q_nb (K, 4), rates,
    increments (K, 3); ``meta`` is the truth file's metadata."""

    time_s: np.ndarray
    p_n: np.ndarray
    v_n: np.ndarray
    q_nb: np.ndarray
    gyro: np.ndarray
    accel: np.ndarray
    dtheta: np.ndarray
    dv: np.ndarray
    meta: dict

    @property
    def K(self) -> int:
        return len(self.time_s)

    @property
    def dt(self) -> float:
        return float((self.time_s[-1] - self.time_s[0]) / (self.K - 1))


def read_truth(path) -> TruthArrays:
    """Read a truth table whole (it is one route: a few tens of MB)."""
    t = ttruth.read(path)
    return TruthArrays(t.time_s, t.p_n, t.v_n, t.q_nb, t.omega_ib_b, t.f_b, t.dtheta, t.dv, t.meta)


def mounting_of(labels: dict):
    """``(angles (3,) rad, lever (3,) m)`` of a sequence's labels row, or None (no mounting)."""
    if any(c not in labels for c in tshard.MOUNTING):
        return None
    angles = np.array([labels[c] for c in tshard.MOUNT_ANGLES], dtype=float)
    return angles, np.array([labels[c] for c in tshard.LEVER_ARM], dtype=float)


def imu_truth(truth: TruthArrays, labels: dict) -> TruthArrays:
    """The truth of a sequence's IMU: ``truth`` itself, or, for a sequence simulated with a
    mounting (labels :data:`imugen.tables.shard.MOUNTING`), the IMU's point, axes and ideal
    (compensated) signals (:mod:`imugen.sensors.mounting`; the gravitation-gradient term, below
    ``3e-6 |l|`` m/s^2, is left out)."""
    mount = mounting_of(labels)
    if mount is None:
        return truth
    from imugen.core.earth import earth_rate_n
    from imugen.sensors.ideal import ArrayTruth
    from imugen.sensors.mounting import Mounting, imu_states

    angles, lever = mount
    Om = earth_rate_n(ttruth.origin_frame(truth.meta))
    p, v, q = imu_states(truth.p_n, truth.v_n, truth.q_nb, truth.gyro, Om, angles, lever)
    tr = ArrayTruth(truth.time_s, truth.gyro, truth.accel, truth.dtheta, truth.dv)
    m = Mounting(tr)
    w, f, dth, dv = m.apply(0, m.shared(0, tr.K, False), angles, lever, truth.dtheta, truth.dv)
    return TruthArrays(truth.time_s, p[0], v[0], q[0], w, f, dth, dv, truth.meta)


@dataclass
class Sequence:
    """One measured sequence: ``id``, columns by name (K,) float64, labels, shard metadata."""

    id: int
    data: dict[str, np.ndarray]
    labels: dict
    meta: dict = field(repr=False)
    gnss: object = None  # the sequence's GNSS epochs (DataFrame, imugen.tables.gnss), if given
    aided: object = None  # its aided navigation (DataFrame, imugen.tables.aided), if given
    companions: object = None  # its companion epochs (DataFrame, imugen.tables.companions)

    def has(self, names) -> bool:
        return all(n in self.data for n in names)

    def stack(self, names) -> np.ndarray:
        return np.column_stack([self.data[n] for n in names])


def gnss_of(gnss_paths, sid: int):
    """The GNSS epochs of sequence ``sid`` (DataFrame with its receiver labels in ``attrs``)
    from whichever file holds it, or None; reads only that sequence's rows."""
    from imugen.tables import gnss as tgnss

    for g in gnss_paths or ():
        df = tgnss.read(g, filters=[(SEQUENCE, "==", int(sid))])
        if len(df):
            lab = tgnss.read_labels(g)
            row = lab[lab[SEQUENCE] == sid]
            df.attrs["labels"] = row.iloc[0].to_dict() if len(row) else {}
            return df.sort_values(ttruth.TIME, kind="stable").reset_index(drop=True)
    return None


def aided_of(aided_paths, sid: int):
    """The aided navigation of sequence ``sid`` (DataFrame: ``time_s``, position, velocity,
    ``q_nb`` of :mod:`imugen.tables.aided`, time-sorted) from whichever table holds it, or
    None; reads only that sequence's rows. InputError for a table without the state columns
    (written by an older ``imugen aid``)."""
    from imugen.tables import aided as taided

    cols = [ttruth.TIME, *ttruth.POS, *ttruth.VEL, *ttruth.QUAT]
    for a in aided_paths or ():
        if not taided.has_state(a):
            raise InputError(
                a, "holds no navigation state (written by an older imugen aid): rerun it"
            )
        df = taided.read(a, columns=cols, filters=[(SEQUENCE, "==", int(sid))])
        if len(df):
            return df.sort_values(ttruth.TIME, kind="stable").reset_index(drop=True)
    return None


def companions_of(companion_paths, sid: int):
    """The companion-sensor epochs of sequence ``sid`` (DataFrame of
    :mod:`imugen.tables.companions`, sorted by sensor then time, its drawn parameters in
    ``attrs["labels"]``) from whichever table holds it, or None; reads only that sequence's rows."""
    from imugen.tables import companions as tcomp

    for c in companion_paths or ():
        df = tcomp.read(c, filters=[(SEQUENCE, "==", int(sid))])
        if len(df):
            lab = tcomp.read_labels(c)
            row = lab[lab[SEQUENCE] == sid]
            df.attrs["labels"] = row.iloc[0].to_dict() if len(row) else {}
            return df.sort_values([tcomp.SENSOR, ttruth.TIME], kind="stable", ignore_index=True)
    return None


def iter_sequences(
    shard_paths, K: int, only=None, gnss_paths=None, aided_paths=None, companion_paths=None
) -> Iterator[Sequence]:
    """Yield every sequence of the shards (file order), one at a time.

    ``only``: optional set of sequence ids to keep; ``gnss_paths``: GNSS epoch tables
    (``imugen aid``) whose epochs of each sequence ride along as ``Sequence.gnss``;
    ``aided_paths``: aided navigation tables (``imugen aid``), as ``Sequence.aided``;
    ``companion_paths``: companion-sensor tables (``imugen aid``), as ``Sequence.companions``.
    """
    for p in map(Path, shard_paths):
        meta = tshard.read_meta(p)
        have = set(tshard.column_names(p))
        names = [c for c in (*RATE_COLUMNS, *INCREMENT_COLUMNS, *BIAS_COLUMNS) if c in have]
        labels = tshard.read_labels(p, meta).set_index(SEQUENCE)
        for sid, block in tshard.iter_sequences(p, names, K, np.float64):
            if only is not None and sid not in only:
                continue
            row = labels.loc[sid].to_dict() if sid in labels.index else {}
            yield Sequence(
                sid,
                dict(zip(names, block, strict=True)),
                row,
                meta,
                gnss_of(gnss_paths, sid),
                aided_of(aided_paths, sid),
                companions_of(companion_paths, sid),
            )
