"""Datasets in the layouts the field's training and evaluation code reads.

``imugen export --format euroc,tum,tlio,ronin,kfgins,ros2 TRUTH SHARD... -o DIR`` writes, for
every sequence of the shards (streamed one at a time: memory is one sequence whatever their
number), one folder per format under ``DIR/<format>/`` named ``<route>_<grade>_<sequence>``:

========  ==========================================  =========================================
format    files                                       read by
========  ==========================================  =========================================
euroc     ``mav0/imu0/data.csv``, ``sensor.yaml``,    evo (``evo_traj euroc``), AirIMU
          ``mav0/state_groundtruth_estimate0/...``
tum       ``truth.tum``, ``<seq>.tum`` (free-inertial) evo (``evo_ape tum``), navlie
          ``<seq>.aided.tum`` (with ``--aided``),
          ``<seq>.truth.tum`` (a mounted IMU's truth)
tlio      ``<seq>/imu0_resampled.npy`` + description,  TLIO's ``SequencesDataset`` and forks
          ``train/val/test_list.txt``
ronin     ``<seq>/data.hdf5`` + ``info.json``,         RoNIN, RNIN, CTIN loaders (h5py)
          ``list_train/val/test.txt``
kfgins    ``imu.txt``, ``truth.nav``, ``kf-gins.yaml``  KF-GINS, OB_GINS (i2Nav), NED/FRD
ros2      rosbag2 folder (sqlite3 or MCAP)            ros2 bag, robot_localization, rosbags,
                                                      evo (``evo_traj bag2``)
========  ==========================================  =========================================

Conversions (ENU/FLU to NED/FRD, scalar-last quaternions, integer clocks) are in
:mod:`imugen.export.convert`; each writer's module docstring states its columns and frames.
The whole tree is written under a temporary name beside ``DIR`` and renamed when complete.
"""

from __future__ import annotations

import os
import shutil
import sys
import tempfile
from pathlib import Path

import numpy as np

from imugen.core.errors import InputError
from imugen.export import euroc, kfgins, ronin, ros2, tlio, tum
from imugen.export.common import split_parts, write_split_lists
from imugen.export.options import ExportOptions
from imugen.export.source import (
    INCREMENT_COLUMNS,
    RATE_COLUMNS,
    Sequence,
    imu_truth,
    iter_sequences,
    mounting_of,
    read_truth,
)
from imugen.tables import shard as tshard
from imugen.tables import truth as ttruth

WRITERS = {
    "euroc": euroc.write,
    "tum": tum.write,
    "tlio": tlio.write,
    "ronin": ronin.write,
    "kfgins": kfgins.write,
    "ros2": ros2.write,
}
FORMATS = tuple(WRITERS)
SPLIT_LISTS = {"tlio": "{part}_list.txt", "ronin": "list_{part}.txt"}
"""Formats given the train/val/test lists of imugen's split, and their file names."""


def parse_formats(text) -> list[str]:
    """``"euroc,tum"`` or a list -> validated format names (order kept, duplicates dropped)."""
    items = text.split(",") if isinstance(text, str) else list(text)
    out = []
    for f in (i.strip().lower() for i in items):
        if not f:
            continue
        if f not in WRITERS:
            raise InputError("--format", f"unknown format {f!r}; one of {', '.join(FORMATS)}")
        if f not in out:
            out.append(f)
    if not out:
        raise InputError("--format", f"name at least one of {', '.join(FORMATS)}")
    return out


def _navigator(truth, nav_rate_hz: float):
    """A function ``seq -> (index (M,), p_n (M, 3), q_nb (M, 4))``: free-inertial navigation."""
    from imugen.core.earth import earth_rate_n
    from imugen.navigate.mechanize import increments_from_rates, mechanize
    from imugen.sensors.mounting import imu_states

    frame = ttruth.origin_frame(truth.meta)
    Om = earth_rate_n(frame)
    every = max(1, round(1.0 / (truth.dt * nav_rate_hz)))

    def nav(seq: Sequence):
        if seq.has(INCREMENT_COLUMNS):
            inc = seq.stack(INCREMENT_COLUMNS)[1:]
            dth, dv = inc[:, :3], inc[:, 3:]
        elif seq.has(RATE_COLUMNS):
            r = seq.stack(RATE_COLUMNS)
            dth, dv = increments_from_rates(r[:, :3], r[:, 3:], truth.dt)
        else:
            raise InputError(f"sequence {seq.id}", "holds no IMU columns")
        x0 = truth.p_n[0], truth.v_n[0], truth.q_nb[0]
        mount = mounting_of(seq.labels)
        if mount is not None:  # a mounted IMU starts from its own truth
            w0 = truth.gyro[:1]
            p, v, q = imu_states(truth.p_n[:1], truth.v_n[:1], truth.q_nb[:1], w0, Om, *mount)
            x0 = p[0, 0], v[0, 0], q[0, 0]
        n = mechanize(
            dth,
            dv,
            truth.dt,
            *x0,
            frame,
            every=every,
            outputs=("p", "q"),
        )
        return n.index, n.p_n, n.q_nb

    return nav, every


def export(
    formats, truth_path, shard_paths, out_dir, *, gnss_paths=None, aided_paths=None,
    companion_paths=None, log=None, **options,
) -> dict:  # fmt: skip
    """:func:`run` with the options as keywords: ``formats`` (names, or ``"euroc,tum"``) and
    the other fields of :class:`~imugen.export.options.ExportOptions`."""
    return run(
        truth_path, shard_paths, out_dir, ExportOptions(formats=formats, **options),
        gnss_paths=gnss_paths, aided_paths=aided_paths, companion_paths=companion_paths, log=log,
    )  # fmt: skip


def run(
    truth_path, shard_paths, out_dir, options: ExportOptions, *, gnss_paths=None,
    aided_paths=None, companion_paths=None, log=None,
) -> dict:  # fmt: skip
    """Write the sequences of ``shard_paths`` in each of ``options.formats`` under ``out_dir``.

    ``gnss_paths``: the GNSS epoch tables of ``imugen aid`` for these shards (optional): KF-GINS
    then gets ``gnss.pos`` and ROS 2 bags a ``/gnss/fix`` topic. ``aided_paths``: the aided
    navigation tables of ``imugen aid`` (optional): TUM then gets ``<seq>.aided.tum``.
    ``companion_paths``: the companion-sensor tables of ``imugen aid`` (optional): ROS 2 bags
    then get ``/wheel/odometry`` and ``/baro/pressure`` for the sensors they hold. The
    train/val/test lists of ``split_*``, ``holdout_routes``, ``val_fraction``,
    ``test_fraction`` (:func:`imugen.export.common.split_parts`) are consistent across the
    exports of the routes of a dataset. Returns ``{format: number of files written}`` and
    prints one line per format to ``log``.
    """
    o = options
    route, grade, nav_rate_hz, storage = o.route, o.grade, o.nav_rate_hz, o.storage
    split_seed, split_by, holdout_routes = o.split_seed, o.split_by, list(o.holdout_routes)
    val_fraction, test_fraction, sequences = o.val_fraction, o.test_fraction, o.sequences
    log = log or (lambda msg: print(msg, file=sys.stderr))
    formats = parse_formats(o.formats)
    out_dir = Path(out_dir)
    if not shard_paths:
        raise InputError(out_dir, "no IMU shards to export")
    if out_dir.exists() and not o.overwrite:
        raise InputError(out_dir, "exists; remove it, choose another folder or pass --overwrite")
    if not (nav_rate_hz > 0 and np.isfinite(nav_rate_hz)):
        raise InputError("--nav-rate-hz", f"must be a positive number, got {nav_rate_hz!r}")
    split_parts([], by=split_by, val_fraction=val_fraction, test_fraction=test_fraction)  # checks
    truth = read_truth(truth_path)
    if "kfgins" in formats:  # refusals and once-per-export warnings before anything is written
        kfgins.check(truth, shard_paths, gnss_paths, warn=lambda m: log(f"imugen: warning: {m}"))
    route = route or Path(truth_path).resolve().parent.name
    grade = grade or (tshard.read_meta(shard_paths[0]).get("grade") or {}).get("name", "imu")
    nav, every = _navigator(truth, nav_rate_hz)
    only = None if sequences is None else {int(s) for s in sequences}
    start_ns = 0
    out_dir.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{out_dir.name}.", suffix=".tmp", dir=out_dir.parent))
    counts = dict.fromkeys(formats, 0)
    keys = []
    warned = set()

    def warn(msg):  # once per export, not once per sequence
        if msg not in warned:
            warned.add(msg)
            log(f"imugen: warning: {msg}")

    try:
        if "tum" in formats:
            (tmp / "tum").mkdir()
            tum.write_truth(truth, tmp / "tum" / "truth.tum", every)
            counts["tum"] += 1
        aided = aided_paths if "tum" in formats else None
        comp = companion_paths if "ros2" in formats else None
        for seq in iter_sequences(shard_paths, truth.K, only, gnss_paths, aided, comp):
            name = f"{route}_{grade}_{seq.id:06d}"
            keys.append((route, seq.id, name))
            seq_truth = imu_truth(truth, seq.labels)  # the IMU's, for a mounted sequence
            for fmt in formats:
                files = WRITERS[fmt](
                    seq,
                    seq_truth,
                    tmp / fmt / name,
                    nav=nav,
                    start_ns=start_ns,
                    every=every,
                    storage=storage,
                    warn=warn,
                )
                counts[fmt] += len(files)
        if not keys:
            raise InputError(shard_paths[0], "no sequences to export")
        lists = {f: n for f, n in SPLIT_LISTS.items() if f in formats}
        if lists:
            parts = split_parts(
                [(r, s) for r, s, _ in keys],
                seed=split_seed,
                by=split_by,
                holdout_routes=holdout_routes,
                val_fraction=val_fraction,
                test_fraction=test_fraction,
                warn=warn,
            )
            names = {(r, s): n for r, s, n in keys}
            for fmt, pattern in lists.items():
                counts[fmt] += len(write_split_lists(tmp / fmt, parts, names, pattern))
        if out_dir.exists():
            shutil.rmtree(out_dir)
        os.replace(tmp, out_dir)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    for fmt in formats:
        size = sum(p.stat().st_size for p in (out_dir / fmt).rglob("*") if p.is_file())
        log(
            f"{out_dir / fmt}: {fmt}, {len(keys)} sequences, {counts[fmt]} files, {size / 1e6:.1f} MB"
        )
    return counts


def main(options: ExportOptions, truth, shards, output, gnss, aided, companions) -> None:
    """``imugen export``."""
    run(
        truth, shards, output, options, gnss_paths=gnss, aided_paths=aided,
        companion_paths=companions,
    )  # fmt: skip
