"""Training windows: (measured IMU window, truth target) pairs with leakage-safe splits.

A map-style dataset over the Parquet files the workflow writes (``results/<route>/truth.parquet``
and ``results/<route>/imu/<grade>/shard-*.parquet``); it needs no PyTorch. Decoding Parquet per
window cannot feed a network (a row group is decoded whole), so each shard's needed columns are
converted once into a flat ``.npy`` cache (:func:`shard_cache`: ``.imugen-cache/`` beside the
shard, keyed by its size and modification time, written atomically) and read memory-mapped;
``in_memory=True`` copies the selected sequences into one array instead. :meth:`get_batch`
copies a batch of windows with one compiled loop (one call per shard touched), and
:meth:`batches` draws i.i.d. shuffled batches that mix windows of every sequence.

Windows
-------
Every sequence of a route has the truth's ``K`` samples. A window is ``window`` consecutive rows
``k0 .. k0 + window - 1`` of one sequence, with ``k0 = 1, 1 + stride, ...`` while the window fits
(row 0 holds no increment, so a window's increments cover exactly the time span
``[t(k0 - 1), t(k0 + window - 1)]``); each sequence gives
``(K - 1 - window) // stride + 1`` windows.

``inputs``: ``"increments"`` -> ``(window, 6)`` measured ``dtheta_{x,y,z}_rad, dv_{x,y,z}_mps``;
``"rates"`` -> ``(window, 6)`` measured ``gyro_{x,y,z}_radps, accel_{x,y,z}_mps2``.

``target``:

- ``"increments"``: ``(window, 6)`` true ``dtheta, dv`` of the same rows (whatever the
  ``inputs``), those of the IMU for a shard simulated with a mounting (:mod:`imugen.sensors.mounting`);
- ``"effective_error"``: ``(window, 6)`` everything the sensor adds except white noise and
  quantization, in the units of the input (``err_dtheta_*_rad``, ``err_dv_*_mps`` or
  ``err_gyro_*_radps``, ``err_accel_*_mps2``; shards simulated with ``series=True``): what
  a drift-correcting network should subtract;
- ``"delta_vel_pos"``: ``(6,)`` change of true velocity ``v_n`` (m/s) then position ``p_n``
  (m) over the window, ENU: ``truth[k0 + window - 1] - truth[k0 - 1]``;
- ``"bias"``: ``(window, 6)`` true slow bias ``gyro_bias_{x,y,z}_radps``,
  ``accel_bias_{x,y,z}_mps2`` (shards simulated with ``series=True``);
- ``"filter_aware_error"``: ``(window, 6)`` the **filter-aware target** (issue 26): the error
  left in each measured increment after the aided filter's own correction, i.e. the effective
  error above minus what the filter removes from that increment,
  ``err - (x - x_hat)``, where ``x_hat`` is the increment ``x`` corrected as the filter does
  (:func:`imugen.tables.filter_estimates.corrected_increments`: ``(dtheta - b_g dt) / (1 +
  s_g)`` minus the cross-coupling, likewise ``dv``) with the estimates of the last filter
  epoch **strictly before** the row (the filter corrects the increments of
  ``(t_j, t_{j+1}]`` with its state after epoch ``j``). Needs ``inputs="increments"``, a shard
  with ``series=True`` and the filter-estimates table beside it (``results/<route>/estimates/
  <grade>/``, config ``aided.estimates``); NaN at the rows before the filter's first epoch.
  For shards of raw increments the filter corrected them after its coning and sculling
  compensation: the target here uses the stored increments (a second-order difference);
- label column name(s): ``(L,)`` per-sequence scalars of the labels sidecar (the drawn
  parameters), e.g. ``["gyro_bias_x_radps", ...]``.

Arrays are returned as ``float32`` (``dtype`` to change); differences are formed in float64
before the cast.

Optional streams (``extras``)
-----------------------------
Epoch data written beside the IMU shards (``results/<route>/<folder>/<grade>/<shard name>``)
can ride along, aligned to the IMU clock (the truth's sample times: every epoch of these tables
is an IMU sample time). ``extras=["gnss", "aided"]`` makes :meth:`WindowDataset.get_batch`
return ``(x, y, extras)`` with ``extras[name]`` of shape ``(B, window, C + 3)``: the stream's
columns (:data:`EXTRAS`), then ``<name>_new`` (1 at the row where an epoch arrived),
``<name>_valid`` (1 where the values are usable) and ``<name>_age_s`` (time since that epoch);
``WindowDataset.extra_columns[name]`` names them. Streams not asked for are never opened, so the
loader works on results without GNSS or aided outputs.

- ``"gnss"`` (:mod:`imugen.tables.gnss`): measured antenna position ``p_{e,n,u}_m``, velocity
  ``v_{e,n,u}_mps``, the receiver's reported sigmas and ``fix`` (NMEA quality);
- ``"scenario"``: the scenario ``state`` of the epoch (0 nominal, 1 outage, ...; a label);
- ``"gnss_offset"``: the true total GNSS error ``offset_p_*_m``, ``offset_v_*_mps`` (a label:
  measured minus true antenna; invalid where no fix was delivered);
- ``"aided"`` (:mod:`imugen.tables.aided`): the filter's position, velocity and ``q_nb``
  (scalar first) at its evaluation epochs (invalid before the filter's alignment);
- ``"filter"`` (:mod:`imugen.tables.filter_estimates`, config ``aided.estimates``): the
  filter's position, velocity, ``q_nb``, biases, scale factors, cross-coupling and GNSS bias at
  every filter epoch; ``"filter_sd"``: the 1-sigma of every state (the filter's covariance
  diagonal). States the filter does not have read 0;
- ``"odometer"``, ``"barometer"`` (:mod:`imugen.tables.companions`): the measured ticks and
  speed, the barometric altitude; ``"odometer_error"``, ``"barometer_error"``: their true
  errors (labels: speed error; drift and total altitude error).

``extras_align="hold"`` (default) holds the latest epoch at or before each row
(sample-and-hold); ``"event"`` gives the values only at the rows where an epoch arrived. In
both, ``valid`` is 1 only where an epoch is held (``"event"``: arrived) and all its values are
finite (a GNSS epoch without a fix, during an outage, is invalid); invalid rows hold zeros (age
0), never NaN. Epochs are kept compact in memory (one row per epoch, for the selected
sequences) and expanded per batch. A new stream is one line in :data:`EXTRAS`.

Splits
------
:func:`split` assigns each ``(route, sequence)`` key to a part by hashing its unit (the
sequence id, globally unique, with ``by="sequence"``; the route with ``by="route"``) with the
seed to a number in ``[0, 1)`` and cutting ``[0, 1)`` by the fractions; a part the cut leaves
empty borrows the nearest unit (see :func:`split`), and too few units for the parts is refused.
``holdout_routes`` (test) and ``val_routes`` name whole routes; with ``holdout_routes`` and
``by="sequence"`` the test fraction of the other routes forms the part ``"test_seen"``
(:data:`SEEN_TEST`: unseen error draws on seen trajectories), so one split measures both
generalizations: to new draws (``test_seen``) and to new routes (``test``). Whole sequences (or routes) land
in one part: no window and no error draw crosses a split, and adding units never moves existing
ones (except the at most one borrowed per otherwise empty part). With ``by="sequence"`` all parts
share the routes' trajectories; hold routes out to test generalization to unseen trajectories.

Example
-------
::

    from imugen.dataset import WindowDataset, find_routes, sequence_keys, split

    routes = find_routes("results", grade="consumer")
    parts = split(sequence_keys(routes), seed=0, holdout_routes=["city"])
    # parts: train, val, test (the city route, unseen), test_seen (unseen draws, seen routes)
    train = WindowDataset(routes, window=200, stride=100, keys=parts["train"],
                          target="effective_error", in_memory=True)
    x, y = train.get_batch(train.batches(64, seed=0)[0])   # float32 (64, 200, 6) each
    train.window_info(0)                # {"route": ..., "sequence": ..., "start": 1, ...}

    import torch                        # optional; imugen does not depend on it
    loader = torch.utils.data.DataLoader(   # the dataset gathers whole batches
        train, sampler=train.batches(64, seed=epoch), batch_size=None, num_workers=0)
    for x, y in loader:                 # torch tensors (64, 200, 6)
        ...

``train[i]`` gives one window (map-style); ``train[indices]`` a batch. The dataset pickles
without its memory maps (workers reopen them), so ``num_workers > 0`` works, though one core
already outruns most networks (README, "Loading for training").
"""

from __future__ import annotations

import glob
import hashlib
import os
import tempfile
import warnings
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from imugen.core.errors import InputError
from imugen.core.jit import njit
from imugen.tables import aided as taided
from imugen.tables import companions as tcomp
from imugen.tables import filter_estimates as testim
from imugen.tables import gnss as tgnss
from imugen.tables import layout
from imugen.tables import shard as tshard
from imugen.tables import truth as ttruth
from imugen.tables.shard import BIAS, EFFECTIVE_ERROR, SEQUENCE

INPUTS = {"increments": tshard.INCREMENTS, "rates": tshard.RATES}
TARGETS = ("increments", "effective_error", "bias", "delta_vel_pos", "filter_aware_error")
CACHE_DIR = ".imugen-cache"
CACHE_FORMAT = 1  # bump when the cache layout changes
DEFAULT_FRACTIONS = {"train": 0.8, "val": 0.1, "test": 0.1}
SEEN_TEST = "test_seen"
"""Part of :func:`split` with ``holdout_routes``: unseen draws on the routes not held out."""


@dataclass(frozen=True)
class Extra:
    """An optional epoch stream of the loader (module docstring, "Optional streams").

    ``folder``: the table of IMU shard ``results/<route>/imu/<grade>/<name>`` is
    ``results/<route>/<folder>/<grade>/<name>``; ``read(path, columns, filters)``: the table
    module's reader (rows ``sequence``, ``time_s`` at IMU sample times); ``columns``: the
    values given per row; ``fill``: what a NaN value reads as.
    """

    folder: str
    read: Callable
    columns: tuple[str, ...]
    fill: float | None = None
    """What a NaN value reads as (None: the epoch is invalid); ``0`` for the filter's absent
    states."""


EXTRAS: dict[str, Extra] = {
    "gnss": Extra(
        "gnss", tgnss.read, (*tgnss.P, *tgnss.V, *tgnss.SIGMA_P, *tgnss.SIGMA_V, tgnss.FIX)
    ),
    "scenario": Extra("gnss", tgnss.read, (tgnss.STATE,)),
    "gnss_offset": Extra("gnss", tgnss.read, (*tgnss.OFFSET_P, *tgnss.OFFSET_V)),
    "aided": Extra("aided", taided.read, (*ttruth.POS, *ttruth.VEL, *ttruth.QUAT)),
    "odometer": Extra("companions", tcomp.read_odometer, (tcomp.ODO_TICKS, tcomp.ODO_SPEED)),
    "odometer_error": Extra("companions", tcomp.read_odometer, (tcomp.ODO_ERROR,)),
    "barometer": Extra("companions", tcomp.read_barometer, (tcomp.BARO_ALT,)),
    "barometer_error": Extra(
        "companions", tcomp.read_barometer, (tcomp.BARO_DRIFT, tcomp.BARO_ERROR)
    ),
    "filter": Extra("estimates", testim.read, (*testim.NAV, *testim.VALUES), fill=0.0),
    "filter_sd": Extra("estimates", testim.read, testim.SIGMAS, fill=0.0),
}
"""Streams ``extras`` may name (``*_error``: labels, the companion's true error)."""
EXTRA_ALIGN = ("hold", "event")
_HELD = Extra("estimates", testim.read, testim.CORRECTION, fill=0.0)
"""The estimates the filter corrects the increments with (the filter-aware target's)."""


def extra_path(shard, folder: str) -> Path:
    """The table of ``folder`` beside IMU shard ``<route>/imu/<grade>/<name>``
    (:func:`imugen.tables.layout.beside`)."""
    return layout.beside(Path(shard), folder)


@dataclass(frozen=True)
class RouteFiles:
    """The files of one route and grade.

    Attributes
    ----------
    name : str
        Route name (the split key's first part).
    truth : Path
        ``truth.parquet`` of the route.
    shards : tuple of Path
        IMU shards of one grade on this route.
    grade : str
        Grade name (informative).
    """

    name: str
    truth: Path
    shards: tuple[Path, ...]
    grade: str = ""


def find_routes(results_dir, grade: str | Iterable[str]) -> list[RouteFiles]:
    """Routes under ``results_dir`` (``<route>/truth.parquet``) with shards of ``grade``.

    ``grade`` may be a list: one :class:`RouteFiles` per route and grade. Routes without
    shards of a grade are skipped; the list is sorted by route then grade.
    """
    grades = [grade] if isinstance(grade, str) else list(grade)
    out = []
    for truth in layout.find_truths(results_dir):
        for g in grades:
            shards = tuple(layout.find_shards(truth.parent, g))
            if shards:
                out.append(RouteFiles(truth.parent.name, truth, shards, g))
    return out


# --- splits ------------------------------------------------------------------------------------
def _unit_hash(seed, unit) -> float:
    """A uniform number in [0, 1) from a split unit (SHA-256; stable across runs and platforms)."""
    h = hashlib.sha256(f"imugen-split\0{seed}\0{unit}".encode()).digest()
    return int.from_bytes(h[:8], "big") / 2.0**64


def _check_fractions(fractions) -> dict[str, float]:
    fr = dict(DEFAULT_FRACTIONS if fractions is None else fractions)
    vals = np.array(list(fr.values()), float)
    if not fr or np.any(~np.isfinite(vals)) or np.any(vals < 0) or abs(vals.sum() - 1) > 1e-9:
        raise InputError("split", f"fractions must be >= 0 and sum to 1, got {fr}")
    return fr


def _edges(fr: dict[str, float]) -> np.ndarray:
    """Upper ends of the parts' intervals of [0, 1) (fractions renormalized)."""
    total = sum(fr.values())
    return np.cumsum([fr[n] / total for n in fr]) if total > 0 else np.zeros(len(fr))


def _hash_part(u: float, names: list, edges: np.ndarray, fr: dict[str, float]) -> str:
    """The part whose interval holds the hash ``u``."""
    i = min(int(np.searchsorted(edges, u, "right")), len(names) - 1)
    while fr[names[i]] == 0:  # u on an edge of an empty interval (rounding)
        i -= 1
    return names[i]


def hashed_part(unit, fractions: Mapping[str, float] | None = None, *, seed=0) -> str:
    """The part the hash cut of :func:`split` gives ``unit`` (a route name with
    ``by="route"``, a sequence id with ``by="sequence"``) on its own: the part every
    :func:`split` of the same seed and fractions assigns it, unless a repair borrows it. For
    splits made piecewise (one route at a time) that must agree with each other."""
    fr = _check_fractions(fractions)
    return _hash_part(_unit_hash(seed, unit), list(fr), _edges(fr), fr)


def _cut(units: list, fr: dict[str, float], seed, what: str) -> dict:
    """Unit -> part: hash cut of [0, 1), then the repair that leaves no wanted part empty."""
    names = list(fr)
    edges = _edges(fr)
    lo = np.concatenate([[0.0], edges[:-1]])
    wanted = [n for n in names if fr[n] > 0]
    if units and len(units) < len(wanted):
        raise InputError(
            "split",
            f"{len(wanted)} non-empty parts ({', '.join(wanted)}) need at least {len(wanted)} "
            f"{what}s; the keys hold {len(units)}: name the routes of a part "
            "(holdout_routes, val_routes) or give the parts fewer non-zero fractions",
        )
    u = {x: _unit_hash(seed, x) for x in units}
    part = {x: _hash_part(ux, names, edges, fr) for x, ux in u.items()}
    if not units:
        return part
    count = {n: 0 for n in names}
    for n in part.values():
        count[n] += 1
    for i, n in enumerate(names):
        if fr[n] == 0 or count[n]:
            continue
        # borrow the unit nearest to this part's interval from a part that keeps one
        a, b = lo[i], edges[i]
        best = min(
            (x for x in units if count[part[x]] > 1),
            key=lambda x: (max(a - u[x], u[x] - b, 0.0), u[x]),
        )
        count[part[best]] -= 1
        part[best] = n
        count[n] = 1
    return part


def split(
    keys,
    fractions: Mapping[str, float] | None = None,
    *,
    seed=0,
    by: str = "sequence",
    holdout_routes: Iterable[str] | None = None,
    val_routes: Iterable[str] | None = None,
    seen_test: bool = True,
) -> dict[str, list[tuple[str, int]]]:
    """Assign ``(route, sequence)`` keys to parts, deterministically and leakage-free.

    Each unit (a sequence id with ``by="sequence"``, a route name with ``by="route"``) is
    hashed with ``seed`` to ``u`` in ``[0, 1)``, and ``[0, 1)`` is cut by the fractions. Sequence
    ids are globally unique (one id = one error draw, whatever the route), so a draw never
    lands in two parts; ids repeated across routes (shards simulated before route-keyed
    seeds, which share draws) are one unit and stay together. A unit's part depends only on
    ``(seed, unit)``, except for the repair: a part with a non-zero fraction that the cut left
    empty borrows the one unit nearest to its interval from a part holding more than one.
    Repairs happen only while a part would be empty, and stop once the hash fills it, so adding
    units moves at most one unit per repaired part.

    Parameters
    ----------
    keys : iterable of (str, int)
        Sequence keys, e.g. :func:`sequence_keys`.
    fractions : mapping name -> fraction, optional
        Parts and their expected shares (sum 1); default train 0.8, val 0.1, test 0.1.
    seed : int or str
        Changes the assignment.
    by : {"sequence", "route"}
        Hash each sequence, or each route (every sequence of a route in one part).
    holdout_routes, val_routes : iterable of str, optional
        Routes that form the ``"test"`` (``"val"``) part exactly, whole; the other routes are cut
        among the remaining parts by their renormalized fractions, except that with
        ``holdout_routes``, ``by="sequence"`` and ``seen_test`` the test fraction of those
        routes forms the part :data:`SEEN_TEST` (``"test_seen"``: unseen draws of seen routes).
    seen_test : bool
        Make the ``"test_seen"`` part (above); False gives its share to the other parts.

    Returns
    -------
    dict
        ``{name: [keys in input order]}`` for every part (and ``"test_seen"``, above).

    Raises
    ------
    InputError
        Bad fractions or routes, or fewer units than parts with a non-zero fraction.
    """
    fr = _check_fractions(fractions)
    if by not in ("sequence", "route"):
        raise InputError("split", f"by must be 'sequence' or 'route', got {by!r}")
    keys = [(str(r), int(s)) for r, s in keys]
    present = {r for r, _ in keys}
    fixed: dict[str, str] = {}
    for name, given in (("test", holdout_routes), ("val", val_routes)):
        if given is None:
            continue
        given = [given] if isinstance(given, str) else [str(r) for r in given]
        if name not in fr:
            raise InputError(
                "split", f"routes given for part {name!r}, which is not among {list(fr)}"
            )
        unknown = sorted(set(given) - present)
        if unknown:
            raise InputError("split", f"{name} route(s) {', '.join(unknown)} hold no keys")
        twice = sorted(r for r in given if fixed.get(r, name) != name)
        if twice:
            raise InputError("split", f"route(s) {', '.join(twice)} given for test and val")
        fixed.update(dict.fromkeys(given, name))
    free = {n: (0.0 if n in fixed.values() else f) for n, f in fr.items()}
    if (
        seen_test
        and by == "sequence"
        and "test" in fixed.values()
        and fr.get("test", 0) > 0
        and SEEN_TEST not in fr
    ):
        free[SEEN_TEST] = fr["test"]
    rest = [k for k in keys if k[0] not in fixed]
    if rest and sum(free.values()) == 0:
        raise InputError(
            "split", "every part with a fraction is named by routes; the other routes have none"
        )
    unit = (lambda k: k[0]) if by == "route" else (lambda k: k[1])
    units = sorted({unit(k) for k in rest})
    part = _cut(units, free, seed, by)
    out = {name: [] for name in free}
    where: dict[int, set] = {}
    for k in keys:
        name = fixed[k[0]] if k[0] in fixed else part[unit(k)]
        out[name].append(k)
        where.setdefault(k[1], set()).add(name)
    shared = sum(len(v) > 1 for v in where.values())
    if shared:
        warnings.warn(
            f"split: {shared} sequence id(s) appear in two parts under different routes; shards "
            "simulated before route-keyed seeds share those error draws across routes "
            "(re-simulate for independent draws)",
            stacklevel=2,
        )
    return out


# --- file index --------------------------------------------------------------------------------
def _shard_sequence_ids(path: Path, K: int) -> np.ndarray:
    """Sequence ids of a shard in row order (``K`` rows per sequence), from its metadata."""
    return tshard.stored_ids(path, K, tshard.read_meta(path))


def sequence_keys(routes: Iterable[RouteFiles]) -> list[tuple[str, int]]:
    """All distinct ``(route, sequence)`` keys of ``routes`` (footers only), sorted."""
    keys = set()
    for r in routes:
        K = ttruth.samples(r.truth)
        for p in r.shards:
            keys.update((r.name, int(s)) for s in _shard_sequence_ids(Path(p), K))
    return sorted(keys)


def _cache_path(path: Path, columns, dtype, cache_dir) -> Path:
    """Cache file of ``columns`` of ``path``: named by the shard (route, grade, file name and
    a hash of its absolute folder, so caches of several routes or results folders can share
    ``cache_dir``) and the columns, keyed by size and mtime."""
    st = path.stat()
    group = hashlib.sha256(f"{CACHE_FORMAT}\0{list(columns)}\0{dtype.str}".encode()).hexdigest()
    key = hashlib.sha256(f"{st.st_size}\0{st.st_mtime_ns}".encode()).hexdigest()
    folder = path.resolve().parent
    where = hashlib.sha256(str(folder).encode()).hexdigest()[:8]
    # results/<route>/imu/<grade>/shard-K.parquet: route and grade for a readable name
    name = f"{folder.parent.parent.name}-{folder.name}-{path.stem}-{where}"
    root = Path(cache_dir) if cache_dir is not None else path.parent / CACHE_DIR
    return root / f"{name}.{group[:12]}.{key[:12]}.npy"


def shard_cache(path, columns, samples: int, dtype=np.float32, cache_dir=None) -> np.ndarray:
    """``columns`` of a shard as a ``(rows, len(columns))`` memory-mapped array.

    ``samples`` rows per sequence. Converted once, streaming sequences into ``.npy`` (in ``cache_dir``, default
    ``.imugen-cache/`` beside the file), named ``STEM.COLUMNS.KEY.npy`` with ``KEY`` from the
    file's size and modification time: a rewritten shard gets a new cache and the stale one of
    the same shard and columns is deleted (``STEM`` names the shard's route, grade, file and
    folder, so one ``cache_dir`` serves many routes). Written under a temporary name and renamed, so a reader never
    sees a partial cache and concurrent builders (one per DataLoader worker or rank) only
    duplicate work.
    """
    path = Path(path)
    dtype = np.dtype(dtype)
    out = _cache_path(path, columns, dtype, cache_dir)
    if not out.exists():
        K = int(samples)
        try:
            out.parent.mkdir(parents=True, exist_ok=True)
            fd, name = tempfile.mkstemp(prefix=f".{out.name}.", suffix=".tmp", dir=out.parent)
        except OSError as exc:
            raise InputError(out.parent, f"cannot write the loader cache here ({exc})") from None
        os.close(fd)
        try:
            shape = (tshard.rows(path), len(columns))
            mm = np.lib.format.open_memmap(name, mode="w+", dtype=dtype, shape=shape)
            for j, (_, block) in enumerate(tshard.iter_sequences(path, list(columns), K, dtype)):
                mm[j * K : (j + 1) * K] = block.T
            mm.flush()
            del mm
            os.replace(name, out)
        except BaseException:
            Path(name).unlink(missing_ok=True)
            raise
        group = out.name.rsplit(".", 2)[0]
        for stale in out.parent.glob(glob.escape(group) + ".*.npy"):
            if stale != out:
                stale.unlink(missing_ok=True)
    return np.asarray(np.load(out, mmap_mode="r"))


class WindowDataset:
    """Map-style dataset of ``(IMU window, target)`` float arrays (see the module docstring).

    Parameters
    ----------
    routes : iterable of RouteFiles
        Routes (and grades) to draw windows from.
    window : int
        Window length in samples.
    stride : int, optional
        Step between window starts in samples (default ``window``: no overlap).
    keys : iterable of (str, int), optional
        Only these ``(route, sequence)`` keys (a part of :func:`split`); default all.
    inputs : {"increments", "rates"}
    target : {"increments", "effective_error", "bias", "delta_vel_pos", "filter_aware_error"}
        or label column(s)
        A name or list of names of label columns gives the per-sequence scalars of the labels
        sidecar, ``(len(names),)`` per window.
    in_memory : bool
        Copy the selected sequences into one array in memory (fastest); else gather from the
        memory-mapped shard caches (the page cache holds what fits).
    cache_dir : path, optional
        Where the shard caches go (default ``.imugen-cache/`` beside each shard).
    dtype : numpy dtype
        Of the returned arrays (float32).
    extras : iterable of str, optional
        Optional epoch streams (:data:`EXTRAS`) aligned to the IMU rows; :meth:`get_batch` then
        returns a third item, ``{name: (B, window, C + 3)}`` (module docstring).
    extras_align : {"hold", "event"}
        Sample-and-hold, or values only at the rows where an epoch arrived.
    """

    def __init__(
        self,
        routes: Iterable[RouteFiles],
        *,
        window: int,
        stride: int | None = None,
        keys=None,
        inputs: str = "increments",
        target="increments",
        in_memory: bool = False,
        cache_dir=None,
        dtype=np.float32,
        extras=(),
        extras_align: str = "hold",
    ):
        self.routes = list(routes)
        self.window = int(window)
        self.stride = int(stride if stride is not None else window)
        if self.window < 1 or self.stride < 1:
            raise InputError("window", "window and stride must be >= 1 sample")
        if inputs not in INPUTS:
            raise InputError("inputs", f"must be one of {', '.join(INPUTS)}, got {inputs!r}")
        labels = None
        if isinstance(target, str) and target in TARGETS:
            self.target = target
        else:
            labels = [target] if isinstance(target, str) else [str(c) for c in target]
            if not labels:
                raise InputError("target", f"must be one of {', '.join(TARGETS)} or label columns")
            self.target = "labels"
        self.inputs = inputs
        self.dtype = np.dtype(dtype)
        self.cache_dir = cache_dir
        self.x_cols = list(INPUTS[inputs])
        if self.target == "filter_aware_error" and inputs != "increments":
            raise InputError("target", "filter_aware_error needs inputs='increments'")
        self.y_cols = {
            "bias": list(BIAS),
            "effective_error": list(EFFECTIVE_ERROR[inputs]),
            "filter_aware_error": list(EFFECTIVE_ERROR[inputs]),
        }.get(self.target, [])
        truth_cols = {
            # the rates turn the vehicle's increments into a mounted IMU's (_mounted_increments)
            "increments": [*ttruth.DTHETA, *ttruth.DV, *ttruth.GYRO],
            "delta_vel_pos": [*ttruth.VEL, *ttruth.POS],
        }
        wanted = None if keys is None else {(str(r), int(s)) for r, s in keys}
        self.extras = [extras] if isinstance(extras, str) else list(dict.fromkeys(extras or ()))
        bad = [n for n in self.extras if n not in EXTRAS]
        if bad:
            raise InputError("extras", f"unknown stream(s) {bad}; one of {', '.join(EXTRAS)}")
        if extras_align not in EXTRA_ALIGN:
            raise InputError("extras_align", f"must be one of {', '.join(EXTRA_ALIGN)}")
        self.extras_align = extras_align
        self.extra_columns = {
            n: [*EXTRAS[n].columns, f"{n}_new", f"{n}_valid", f"{n}_age_s"] for n in self.extras
        }
        epochs = {n: [] for n in self.extras}
        held = []  # the filter-aware target's estimates
        clocks = []
        need_clock = bool(self.extras) or self.target == "filter_aware_error"

        self.files: list[Path] = []
        truths, toff, lab, file_k = [], [0], [], []
        ent_file, ent_row, ent_seq, ent_route, ent_k, nwin = [], [], [], [], [], []
        ent_mount, mounted = [], False
        for ri, r in enumerate(self.routes):
            K = ttruth.samples(r.truth)
            if self.target in truth_cols:
                t = ttruth.read_arrow(r.truth, columns=truth_cols[self.target])
                truths.append(np.column_stack([c.to_numpy() for c in t.columns]))
            toff.append(toff[-1] + K)
            if need_clock:
                clocks.append(
                    ttruth.read_arrow(r.truth, columns=[ttruth.TIME]).column(0).to_numpy()
                )
            nw = (K - 1 - self.window) // self.stride + 1 if K - 1 >= self.window else 0
            for p in map(Path, r.shards):
                ids = _shard_sequence_ids(p, K)
                sel = [
                    j for j, sid in enumerate(ids) if wanted is None or (r.name, int(sid)) in wanted
                ]
                if not sel:
                    continue
                self._check_columns(p, self.x_cols + self.y_cols)
                self.files.append(p)
                file_k.append(K)
                if labels is not None:
                    lab.append(_label_rows(p, labels, ids[sel]))
                for n in self.extras:
                    epochs[n].append(_epoch_rows(p, EXTRAS[n], ids[sel], clocks[-1], len(ent_file)))
                if self.target == "filter_aware_error":
                    held.append(_epoch_rows(p, _HELD, ids[sel], clocks[-1], len(ent_file)))
                if self.target == "increments":
                    m = None
                    if tshard.read_meta(p).get("mounting"):
                        m = tshard.mounting(tshard.read_labels(p), ids[sel])
                    mounted |= m is not None
                    ent_mount.append(np.zeros((len(sel), 6)) if m is None else np.hstack(m))
                for j in sel:
                    ent_file.append(len(self.files) - 1)
                    ent_row.append(j * K)
                    ent_seq.append(int(ids[j]))
                    ent_route.append(ri)
                    ent_k.append(K)
                    nwin.append(nw)
        self._file = np.array(ent_file, np.int64)
        self._row = np.array(ent_row, np.int64)
        self._seq = np.array(ent_seq, np.int64)
        self._route = np.array(ent_route, np.int64)
        self._cum = np.concatenate([[0], np.cumsum(nwin, dtype=np.int64)])
        self._truth_row = np.array(toff[:-1], np.int64)[self._route] if len(self._route) else None
        if self.target == "increments":
            self._truth = np.concatenate(truths).astype(self.dtype) if truths else None
        else:
            self._truth = np.concatenate(truths) if truths else None
        self._labels = np.concatenate(lab).astype(self.dtype) if lab else None
        dts = [float((c[-1] - c[0]) / (len(c) - 1)) if len(c) > 1 else 0.0 for c in clocks]
        self._dt = np.array(dts, float)[self._route] if need_clock and len(self._route) else None
        self._epochs = {n: EpochIndex.concat(v, len(EXTRAS[n].columns)) for n, v in epochs.items()}
        self._held = (
            EpochIndex.concat(held, len(_HELD.columns))
            if self.target == "filter_aware_error" else None
        )  # fmt: skip
        # per window entry (angles, lever arm) of a mounted IMU (imugen.sensors.mounting), else None
        self._mount = np.concatenate(ent_mount) if mounted else None
        self._cache_paths = [
            _cache_path(p, self.x_cols + self.y_cols, self.dtype, cache_dir) for p in self.files
        ]
        maps = [
            shard_cache(p, self.x_cols + self.y_cols, k, self.dtype, cache_dir)
            for p, k in zip(self.files, file_k, strict=True)
        ]
        self._mem = None
        if in_memory:
            # the selected sequences, back to back: one fancy index gathers a whole batch
            self._mem = (
                np.concatenate(
                    [maps[f][r : r + k] for f, r, k in zip(ent_file, ent_row, ent_k, strict=True)]
                )
                if ent_file
                else np.zeros((0, len(self.x_cols + self.y_cols)), self.dtype)
            )
            self._row = np.concatenate([[0], np.cumsum(ent_k)[:-1]]).astype(np.int64)
            maps = None
        self._maps = maps

    @staticmethod
    def _check_columns(path: Path, columns) -> None:
        names = tshard.column_names(path)
        missing = [c for c in columns if c not in names]
        if missing:
            raise InputError(path, f"lacks the columns {', '.join(missing)}")

    # --- pickling (DataLoader workers): the memory maps are reopened, not copied
    def __getstate__(self):
        state = dict(self.__dict__)
        state["_maps"] = None
        return state

    def _shard_maps(self) -> list[np.ndarray]:
        if self._maps is None:
            self._maps = [np.asarray(np.load(p, mmap_mode="r")) for p in self._cache_paths]
        return self._maps

    # --- map-style dataset
    def __len__(self) -> int:
        return int(self._cum[-1])

    def _locate(self, idx) -> tuple[np.ndarray, np.ndarray]:
        """Entries and first rows ``k0`` of window indices (negative counts from the end)."""
        n = len(self)
        idx = np.asarray(idx, np.int64)
        idx = np.where(idx < 0, idx + n, idx)
        if idx.size and (idx.min() < 0 or idx.max() >= n):
            raise IndexError(f"window index out of range for {n} windows")
        e = np.searchsorted(self._cum, idx, "right") - 1
        return e, 1 + (idx - self._cum[e]) * self.stride

    def window_info(self, i: int) -> dict:
        """Where window ``i`` comes from: route, grade, sequence, rows ``[start, stop)``."""
        e, k0 = self._locate([i])
        e, k0 = int(e[0]), int(k0[0])
        r = self.routes[int(self._route[e])]
        return {
            "route": r.name,
            "grade": r.grade,
            "sequence": int(self._seq[e]),
            "shard": str(self.files[int(self._file[e])]),
            "start": k0,
            "stop": k0 + self.window,
        }

    def get_batch(self, indices) -> tuple:
        """Windows ``indices`` gathered at once: ``x (B, window, 6)``, ``y (B, ...)`` and, with
        ``extras``, ``{name: (B, window, C + 3)}``.

        A compiled loop copies each window as one block: in memory from one array, from the
        caches one call per shard the batch touches.
        """
        e, k0 = self._locate(indices)
        nx, W = len(self.x_cols), self.window
        x = np.empty((len(e), W, nx), self.dtype)
        y = np.empty((len(e), W, len(self.y_cols)), self.dtype) if self.y_cols else x
        rows = self._row[e] + k0
        if self._mem is not None:
            _gather(self._mem, rows, np.arange(len(e)), x, y)
        else:
            maps = self._shard_maps()
            files = self._file[e]
            order = np.argsort(files, kind="stable")
            bounds = np.flatnonzero(np.diff(files[order])) + 1
            for sel in np.split(order, bounds) if len(order) else []:
                _gather(maps[files[sel[0]]], rows, sel, x, y)
        if self.target == "increments":
            t = np.empty((len(e), W, self._truth.shape[1]), self.dtype)
            _gather(self._truth, self._truth_row[e] + k0, np.arange(len(e)), t, t)
            if self._mount is None:
                y = np.ascontiguousarray(t[..., :6])
            else:
                w0 = self._truth[self._truth_row[e] + k0 - 1, 6:9]
                y = _mounted_increments(t, w0, self._mount[e]).astype(self.dtype)
        elif self.target == "delta_vel_pos":
            t0 = self._truth_row[e] + k0 - 1
            y = (self._truth[t0 + self.window] - self._truth[t0]).astype(self.dtype)
        elif self.target == "labels":
            y = self._labels[e]
        elif self.target == "filter_aware_error":
            y = self._filter_aware(e, k0, x, y)
        if self.extras:
            rows = k0[:, None] + np.arange(self.window)[None, :]
            ex = {
                n: self._epochs[n].gather(e, rows, self._dt[e], self.extras_align, self.dtype)
                for n in self.extras
            }
            return x, y, ex
        return x, y

    def _filter_aware(self, e, k0, x, y) -> np.ndarray:
        """The effective error ``y`` minus the filter's correction of the increments ``x``
        (module docstring, ``filter_aware_error``)."""
        rows = k0[:, None] + np.arange(self.window)[None, :] - 1  # held since before the row
        h = self._held.gather(e, rows, self._dt[e], "hold", np.float64)
        C = len(_HELD.columns)
        dt = self._dt[e][:, None, None]
        out = testim.filter_aware_error(x, y, h[..., :C], h[..., C + 1] != 0, dt)
        return out.astype(self.dtype)

    def __getitem__(self, i):
        """Window ``i`` as ``(x, y)``; a list or array of indices gives a batch (:meth:`get_batch`)."""
        if np.ndim(i) == 0:
            out = self.get_batch([int(i)])
            if len(out) == 3:
                return out[0][0], out[1][0], {n: a[0] for n, a in out[2].items()}
            return out[0][0], out[1][0]
        return self.get_batch(i)

    def batches(self, batch_size: int = 64, *, seed=0, drop_last: bool = False) -> list:
        """I.i.d. shuffled batches of window indices: a permutation of all windows, cut.

        Deterministic for a ``seed`` (pass the epoch). Each batch mixes windows of many
        sequences. Use as a PyTorch sampler with ``batch_size=None`` (the dataset gathers each
        batch with :meth:`get_batch`).
        """
        order = np.random.default_rng(seed).permutation(len(self))
        n = len(order) // batch_size * batch_size if drop_last else len(order)
        return [order[b : b + batch_size] for b in range(0, n, batch_size)]


def _mounted_increments(t, w0, mount):
    """True increments of mounted IMUs (:mod:`imugen.sensors.mounting`, compensated; the gravitation
    gradient term, below ``3e-6 |l|`` m/s^2, left out) from the vehicle's.

    ``t`` (B, W, 9): the vehicle's ``dtheta, dv, omega_ib`` rows; ``w0`` (B, 3): ``omega_ib``
    of the sample before each window; ``mount`` (B, 6): angles [rad] then lever arm [m].
    Returns (B, W, 6) float64."""
    from imugen.core.rotations import exp_dcm
    from imugen.sensors.mounting import C_vb

    t = t.astype(np.float64)
    dth, dv, w = t[..., :3], t[..., 3:6], t[..., 6:9]
    lever = mount[:, None, 3:]
    w_prev = np.concatenate([w0[:, None].astype(np.float64), w[:, :-1]], axis=1)
    u = np.cross(w, lever)
    dv_v = dv + np.einsum("bwij,bwj->bwi", exp_dcm(dth), u) - np.cross(w_prev, lever)
    C_bv = np.swapaxes(C_vb(mount[:, :3]), -1, -2)[:, None]
    out = np.empty((*t.shape[:2], 6))
    out[..., :3] = np.einsum("bwij,bwj->bwi", C_bv, dth)
    out[..., 3:] = np.einsum("bwij,bwj->bwi", C_bv, dv_v)
    return out


@njit(cache=True, nogil=True)
def _gather(src, rows, sel, x, y):
    """Copy windows ``src[rows[i] : rows[i] + W]`` for ``i`` in ``sel`` into ``x[i]``, ``y[i]``.

    ``src`` is ``(rows, nx [+ ny])``; its first ``nx`` columns go to ``x (B, W, nx)`` and the
    rest to ``y (B, W, ny)`` (pass ``y = x`` when ``src`` has ``nx`` columns). One contiguous
    block per window: no per-row index arrays.
    """
    W, nx = x.shape[1], x.shape[2]
    split = src.shape[1] > nx
    for i in sel:
        block = src[rows[i] : rows[i] + W]
        x[i] = block[:, :nx]
        if split:
            y[i] = block[:, nx:]


def _label_rows(shard: Path, names, ids) -> np.ndarray:
    """Label columns ``names`` of sequences ``ids`` from a shard's labels sidecar, ``(n, L)``."""
    t = tshard.read_labels(shard)
    missing = [c for c in names if c not in t.columns]
    if missing:
        raise InputError(tshard.labels_path(shard), f"has no label column(s) {', '.join(missing)}")
    path = tshard.labels_path(shard)
    seq = t[SEQUENCE].to_numpy()
    pos = {int(s): i for i, s in enumerate(seq)}
    absent = [int(s) for s in ids if int(s) not in pos]
    if absent:
        raise InputError(path, f"has no labels for sequence(s) {absent[:5]}")
    rows = np.array([pos[int(s)] for s in ids], np.int64)
    return np.column_stack([t[c].to_numpy(dtype=float)[rows] for c in names])


# --- optional epoch streams ------------------------------------------------------------------
@dataclass
class EpochIndex:
    """Epochs of one stream for every dataset entry, compact: sorted ``key = entry * KP + k``
    (``k`` the IMU row of the epoch), the entry and row of each key and its values (also the
    stream's filter targets, :mod:`imugen.stream.stream`)."""

    key: np.ndarray
    entry: np.ndarray
    k: np.ndarray
    values: np.ndarray
    finite: np.ndarray

    KP = np.int64(1) << 40  # rows per entry in the key: more than any sequence holds

    @classmethod
    def concat(cls, parts, ncols: int) -> EpochIndex:
        if not parts:
            z = np.zeros(0, np.int64)
            return cls(z, z, z, np.zeros((0, ncols)), np.zeros(0, bool))
        entry = np.concatenate([p[0] for p in parts])
        k = np.concatenate([p[1] for p in parts])
        vals = np.concatenate([p[2] for p in parts])
        key = entry * cls.KP + k
        o = np.argsort(key, kind="stable")
        finite = np.isfinite(vals[o]).all(axis=1)
        return cls(key[o], entry[o], k[o], np.nan_to_num(vals[o]), finite)

    def gather(self, e, rows, dt, align: str, dtype) -> np.ndarray:
        """``(B, W, C + 3)``: values, new, valid, age for entries ``e`` (B,) at ``rows`` (B, W)."""
        B, W = rows.shape
        C = self.values.shape[1]
        out = np.zeros((B, W, C + 3), dtype)
        if not len(self.key):
            return out
        j = np.searchsorted(self.key, e[:, None] * self.KP + rows, "right") - 1
        jc = np.maximum(j, 0)
        own = (j >= 0) & (self.entry[jc] == e[:, None])
        new = own & (self.k[jc] == rows)
        held = new if align == "event" else own
        valid = held & self.finite[jc]
        out[..., :C] = np.where(valid[..., None], self.values[jc], 0.0)
        out[..., C] = new
        out[..., C + 1] = valid
        out[..., C + 2] = np.where(valid, (rows - self.k[jc]) * dt[:, None], 0.0)
        return out


def _epoch_rows(shard: Path, extra: Extra, ids, clock: np.ndarray, first_entry: int):
    """``(entry, IMU row, values)`` of the epochs of sequences ``ids`` (entries
    ``first_entry, first_entry + 1, ...``) from the stream's table beside ``shard``."""
    path = extra_path(shard, extra.folder)
    if not path.is_file():
        raise InputError(
            path, f"no {extra.folder} table for this shard (run the aid stage: gnss.enabled)"
        )
    ids = np.asarray(ids, np.int64)
    df = extra.read(
        path, columns=[SEQUENCE, ttruth.TIME, *extra.columns],
        filters=[(SEQUENCE, "in", [int(i) for i in ids])],
    )  # fmt: skip
    pos = {int(s): first_entry + n for n, s in enumerate(ids)}
    entry = np.array([pos[int(s)] for s in df[SEQUENCE].to_numpy()], np.int64)
    t = df[ttruth.TIME].to_numpy(float)
    dt = (clock[-1] - clock[0]) / max(len(clock) - 1, 1)
    k = np.clip(np.searchsorted(clock, t - 0.5 * dt), 0, len(clock) - 1)
    off = np.abs(clock[k] - t) > 1e-6 * max(dt, 1e-12) + 1e-9
    if off.any():
        raise InputError(path, f"epoch at {t[off][0]!r} s is not an IMU sample time of the route")
    vals = df[list(extra.columns)].to_numpy(float)
    if extra.fill is not None:
        vals = np.where(np.isnan(vals), extra.fill, vals)
    return entry, k.astype(np.int64), vals
