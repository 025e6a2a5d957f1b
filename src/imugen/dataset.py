"""Training windows: (measured IMU window, truth target) pairs with leakage-safe splits.

A map-style dataset over the Parquet files the workflow writes (``results/<route>/truth.parquet``
and ``results/<route>/imu/<grade>/shard-*.parquet``); it needs neither PyTorch nor the data in
memory. Building it reads only Parquet footers (row-group sizes and the ``sequence`` column
statistics); an item reads only the row groups its window overlaps, through a small LRU cache
of decoded row groups (``cache_mb``), so consecutive windows of one sequence cost one decode.

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

- ``"increments"``: ``(window, 6)`` true ``dtheta, dv`` of the same rows (a network learning
  to correct the IMU regresses these, or ``x - y``, the sensor error);
- ``"delta_vel_pos"``: ``(6,)`` change of true velocity ``v_n`` (m/s) then position ``p_n``
  (m) over the window, ENU: ``truth[k0 + window - 1] - truth[k0 - 1]``;
- ``"bias"``: ``(window, 6)`` true slow bias ``gyro_bias_{x,y,z}_radps``,
  ``accel_bias_{x,y,z}_mps2`` (shards simulated with ``series=True``).

Arrays are returned as ``float32`` (``dtype`` to change); differences are formed in float64
before the cast.

Splits
------
:func:`split` assigns each ``(route, sequence)`` key to a part by hashing
``(seed, route, sequence)`` (``by="sequence"``) or ``(seed, route)`` (``by="route"``) to a
number in ``[0, 1)`` and cutting ``[0, 1)`` by the fractions. The assignment of a key depends
on nothing else, so it is deterministic, never changes when sequences, shards or routes are
added, and whole sequences (or whole routes) land in one part: no window crosses a split.
The same sequence id of another grade (another noise realization of the same truth) goes to
the same part. With ``by="sequence"`` all parts share the routes' trajectories; use
``by="route"`` to test generalization to unseen trajectories.

Example
-------
::

    from imugen.dataset import WindowDataset, find_routes, sequence_keys, split

    routes = find_routes("results", grade="consumer")
    parts = split(sequence_keys(routes), {"train": 0.8, "val": 0.1, "test": 0.1},
                  seed=0, by="route")
    train = WindowDataset(routes, window=200, stride=100, keys=parts["train"],
                          inputs="increments", target="increments")
    x, y = train[0]                     # float32 (200, 6), float32 (200, 6)
    train.window_info(0)                # {"route": ..., "sequence": ..., "start": 1, ...}

    import torch                        # optional; imugen does not depend on it
    loader = torch.utils.data.DataLoader(
        train, batch_size=64, num_workers=2,
        sampler=train.local_shuffle(seed=epoch),  # shuffled, cache-friendly order
    )
    for x, y in loader:                 # torch tensors (64, 200, 6)
        ...

``shuffle=True`` also works; :meth:`WindowDataset.local_shuffle` shuffles blocks of
consecutive sequences and the windows inside each block, so that each row group is decoded
about once per epoch instead of once per window. The dataset pickles without its open files
and cache, so ``num_workers > 0`` works.
"""

from __future__ import annotations

import hashlib
from collections import OrderedDict
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pyarrow.parquet as pq

from imugen.errors import InputError
from imugen.tables import shard as tshard
from imugen.tables import truth as col
from imugen.tables.shard import BIAS, SEQUENCE

INPUTS = {"increments": tshard.INCREMENTS, "rates": tshard.RATES}
TARGETS = ("increments", "delta_vel_pos", "bias")
DEFAULT_FRACTIONS = {"train": 0.8, "val": 0.1, "test": 0.1}


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
    for truth in sorted(Path(results_dir).glob("*/truth.parquet")):
        for g in grades:
            shards = tuple(
                p
                for p in sorted((truth.parent / "imu" / g).glob("shard-*.parquet"))
                if not p.name.endswith(".labels.parquet")
            )
            if shards:
                out.append(RouteFiles(truth.parent.name, truth, shards, g))
    return out


# --- splits ------------------------------------------------------------------------------------
def _unit(seed, route, sequence) -> float:
    """A uniform number in [0, 1) from the key (SHA-256; stable across runs and platforms)."""
    h = hashlib.sha256(f"imugen-split\0{seed}\0{route}\0{sequence}".encode()).digest()
    return int.from_bytes(h[:8], "big") / 2.0**64


def _check_fractions(fractions) -> dict[str, float]:
    fr = dict(DEFAULT_FRACTIONS if fractions is None else fractions)
    vals = np.array(list(fr.values()), float)
    if not fr or np.any(~np.isfinite(vals)) or np.any(vals < 0) or abs(vals.sum() - 1) > 1e-9:
        raise InputError("split", f"fractions must be >= 0 and sum to 1, got {fr}")
    return fr


def assign(route: str, sequence: int, fractions=None, *, seed=0, by="sequence") -> str:
    """The part (e.g. ``"train"``) of one ``(route, sequence)`` key; see :func:`split`."""
    fr = _check_fractions(fractions)
    if by not in ("sequence", "route"):
        raise InputError("split", f"by must be 'sequence' or 'route', got {by!r}")
    u = _unit(seed, route, int(sequence) if by == "sequence" else "*")
    acc = 0.0
    name = None
    for name, f in fr.items():
        acc += f
        if u < acc:
            return name
    return name  # u within rounding of 1


def split(keys, fractions: Mapping[str, float] | None = None, *, seed=0, by="sequence"):
    """Assign ``(route, sequence)`` keys to parts, deterministically and leakage-free.

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

    Returns
    -------
    dict
        ``{name: [keys in input order]}`` for every part (possibly empty).
    """
    fr = _check_fractions(fractions)
    out = {name: [] for name in fr}
    for route, seq in keys:
        out[assign(route, seq, fr, seed=seed, by=by)].append((route, int(seq)))
    return out


# --- file index --------------------------------------------------------------------------------
def _row_starts(md) -> np.ndarray:
    return np.concatenate(
        [[0], np.cumsum([md.row_group(g).num_rows for g in range(md.num_row_groups)])]
    )


def _shard_sequence_ids(path: Path, K: int) -> np.ndarray:
    """Sequence ids of a shard in row order, from the footer statistics when they suffice.

    Rows are sorted by sequence then time with exactly ``K`` rows per sequence; the ids are
    contiguous when every row group's min/max statistics say so, else the ``sequence`` column
    is read once.
    """
    md = pq.ParquetFile(path).metadata
    n = md.num_rows
    if n % K:
        raise InputError(path, f"holds {n} rows: not whole sequences of {K} samples")
    nseq = n // K
    if nseq == 0:
        return np.zeros(0, np.int64)
    try:
        ci = md.schema.to_arrow_schema().get_field_index(SEQUENCE)
    except KeyError:
        ci = -1
    if ci < 0:
        raise InputError(path, "has no 'sequence' column")
    starts = _row_starts(md)
    ok = True
    first = None
    for g in range(md.num_row_groups):
        st = md.row_group(g).column(ci).statistics
        if st is None or not st.has_min_max:
            ok = False
            break
        if first is None:
            first = int(st.min)
        a, b = starts[g], starts[g + 1]
        if b > a and (st.min != first + a // K or st.max != first + (b - 1) // K):
            ok = False
            break
    if ok:
        return first + np.arange(nseq, dtype=np.int64)
    seq = pq.read_table(path, columns=[SEQUENCE]).column(SEQUENCE).to_numpy().reshape(nseq, K)
    if not (seq == seq[:, :1]).all() or np.any(np.diff(seq[:, 0]) <= 0):
        raise InputError(path, f"rows are not grouped by sequence with {K} rows each")
    return seq[:, 0].astype(np.int64)


def sequence_keys(routes: Iterable[RouteFiles]) -> list[tuple[str, int]]:
    """All distinct ``(route, sequence)`` keys of ``routes`` (footers only), sorted."""
    keys = set()
    for r in routes:
        K = pq.ParquetFile(r.truth).metadata.num_rows
        for p in r.shards:
            keys.update((r.name, int(s)) for s in _shard_sequence_ids(Path(p), K))
    return sorted(keys)


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
    target : {"increments", "delta_vel_pos", "bias"}
    cache_mb : float
        Memory for decoded row groups (least recently used evicted first).
    dtype : numpy dtype
        Of the returned arrays (float32).
    """

    def __init__(
        self,
        routes: Iterable[RouteFiles],
        *,
        window: int,
        stride: int | None = None,
        keys=None,
        inputs: str = "increments",
        target: str = "increments",
        cache_mb: float = 256,
        dtype=np.float32,
    ):
        self.routes = list(routes)
        self.window = int(window)
        self.stride = int(stride if stride is not None else window)
        if self.window < 1 or self.stride < 1:
            raise InputError("window", "window and stride must be >= 1 sample")
        if inputs not in INPUTS:
            raise InputError("inputs", f"must be one of {', '.join(INPUTS)}, got {inputs!r}")
        if target not in TARGETS:
            raise InputError("target", f"must be one of {', '.join(TARGETS)}, got {target!r}")
        self.inputs, self.target = inputs, target
        self.dtype = np.dtype(dtype)
        self.cache_bytes = int(cache_mb * 2**20)
        self.x_cols = list(INPUTS[inputs])
        self.shard_cols = self.x_cols + (list(BIAS) if target == "bias" else [])
        if target == "increments":
            self.truth_cols = [*col.DTHETA, *col.DV]
        elif target == "delta_vel_pos":
            self.truth_cols = [*col.VEL, *col.POS]
        else:
            self.truth_cols = []
        wanted = None if keys is None else {(str(r), int(s)) for r, s in keys}

        # files: 0..R-1 are the truths, then shards; entries are sequences with windows
        self.files: list[Path] = []
        self.starts: list[np.ndarray] = []  # row-group start rows per file
        self._fdtype: list = []  # decoded dtype per file (truth float64, shards as stored)
        self._truth_fi: list[int] = []  # file index of each route's truth
        ent_file, ent_row, ent_seq, ent_route, nwin = [], [], [], [], []
        for ri, r in enumerate(self.routes):
            tmd = pq.ParquetFile(r.truth).metadata
            K = tmd.num_rows
            self._truth_fi.append(self._add_file(Path(r.truth), tmd, self.truth_cols, truth=True))
            nw = (K - 1 - self.window) // self.stride + 1 if K - 1 >= self.window else 0
            for p in r.shards:
                p = Path(p)
                md = pq.ParquetFile(p).metadata
                fi = self._add_file(p, md, self.shard_cols)
                ids = _shard_sequence_ids(p, K)
                for j, sid in enumerate(ids):
                    if wanted is None or (r.name, int(sid)) in wanted:
                        ent_file.append(fi)
                        ent_row.append(j * K)
                        ent_seq.append(int(sid))
                        ent_route.append(ri)
                        nwin.append(nw)
        self._file = np.array(ent_file, np.int64)
        self._row = np.array(ent_row, np.int64)
        self._seq = np.array(ent_seq, np.int64)
        self._route = np.array(ent_route, np.int64)
        self._cum = np.concatenate([[0], np.cumsum(nwin, dtype=np.int64)])
        self._handles: OrderedDict = OrderedDict()
        self._cache: OrderedDict = OrderedDict()
        self._cached = 0

    def _add_file(self, path: Path, md, columns, truth=False) -> int:
        schema = md.schema.to_arrow_schema()
        missing = [c for c in columns if c not in schema.names]
        if missing:
            raise InputError(path, f"lacks the columns {', '.join(missing)}")
        self.files.append(path)
        self.starts.append(_row_starts(md))
        types = [schema.field(c).type.to_pandas_dtype() for c in columns]
        self._fdtype.append(np.float64 if truth or not types else np.result_type(*types))
        return len(self.files) - 1

    # --- pickling (DataLoader workers): no open files, no cache
    def __getstate__(self):
        state = dict(self.__dict__)
        state["_handles"] = OrderedDict()
        state["_cache"] = OrderedDict()
        state["_cached"] = 0
        return state

    # --- reading
    def _row_group(self, fi: int, g: int, columns) -> np.ndarray:
        key = (fi, g)
        hit = self._cache.get(key)
        if hit is not None:
            self._cache.move_to_end(key)
            return hit
        pf = self._handles.get(fi)
        if pf is None:
            pf = pq.ParquetFile(self.files[fi])
            self._handles[fi] = pf
            if len(self._handles) > 32:
                self._handles.popitem(last=False)
        else:
            self._handles.move_to_end(fi)
        t = pf.read_row_group(g, columns=list(columns))
        arr = np.empty((t.num_rows, len(columns)), self._fdtype[fi])
        for i, c in enumerate(columns):
            arr[:, i] = t.column(c).to_numpy()
        self._cache[key] = arr
        self._cached += arr.nbytes
        while self._cached > self.cache_bytes and len(self._cache) > 1:
            _, old = self._cache.popitem(last=False)
            self._cached -= old.nbytes
        return arr

    def _rows(self, fi: int, r0: int, r1: int, columns) -> np.ndarray:
        """Rows ``[r0, r1)`` of file ``fi`` as ``(r1 - r0, len(columns))``."""
        st = self.starts[fi]
        g0 = int(np.searchsorted(st, r0, "right")) - 1
        g1 = int(np.searchsorted(st, r1 - 1, "right")) - 1
        parts = [
            self._row_group(fi, g, columns)[max(r0 - st[g], 0) : min(r1, st[g + 1]) - st[g]]
            for g in range(g0, g1 + 1)
        ]
        return parts[0] if len(parts) == 1 else np.concatenate(parts)

    # --- map-style dataset
    def __len__(self) -> int:
        return int(self._cum[-1])

    def _locate(self, i: int):
        n = len(self)
        if i < 0:
            i += n
        if not 0 <= i < n:
            raise IndexError(f"window {i} out of range for {n} windows")
        e = int(np.searchsorted(self._cum, i, "right")) - 1
        k0 = 1 + (i - int(self._cum[e])) * self.stride
        return e, k0

    def window_info(self, i: int) -> dict:
        """Where window ``i`` comes from: route, grade, sequence, rows ``[start, stop)``."""
        e, k0 = self._locate(i)
        r = self.routes[int(self._route[e])]
        return {
            "route": r.name,
            "grade": r.grade,
            "sequence": int(self._seq[e]),
            "shard": str(self.files[int(self._file[e])]),
            "start": k0,
            "stop": k0 + self.window,
        }

    def __getitem__(self, i: int):
        e, k0 = self._locate(int(i))
        fi, base = int(self._file[e]), int(self._row[e])
        ti = self._truth_fi[int(self._route[e])]
        k1 = k0 + self.window
        x = self._rows(fi, base + k0, base + k1, self.shard_cols)
        nx = len(self.x_cols)
        if self.target == "bias":
            y = x[:, nx:]
        elif self.target == "increments":
            y = self._rows(ti, k0, k1, self.truth_cols)
        else:
            end = self._rows(ti, k1 - 1, k1, self.truth_cols)[0]
            y = end - self._rows(ti, k0 - 1, k0, self.truth_cols)[0]
        return x[:, :nx].astype(self.dtype), np.asarray(y).astype(self.dtype)

    def local_shuffle(self, seed: int = 0, block: int = 16) -> list[int]:
        """A permutation of all window indices with read locality, for a DataLoader sampler.

        Consecutive sequences are grouped in blocks of ``block``; the blocks are shuffled,
        then the windows inside each block. Deterministic for a ``seed`` (pass the epoch).
        """
        rng = np.random.default_rng(seed)
        nseq = len(self._cum) - 1
        out = []
        for b in rng.permutation(np.arange(0, nseq, max(int(block), 1))):
            idx = np.arange(self._cum[b], self._cum[min(b + block, nseq)])
            out.append(rng.permutation(idx))
        return np.concatenate(out).tolist() if out else []
