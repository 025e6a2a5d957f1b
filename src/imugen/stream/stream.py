"""The stream: batches of (IMU window, targets) generated on demand, no disk (package docstring)."""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from pathlib import Path

import numpy as np

from imugen.core.errors import InputError
from imugen.core.seeding import sensor_rng
from imugen.sensors.grades import get_grade
from imugen.sensors.ideal import ArrayTruth, TruthSource
from imugen.sensors.mounting import MountingSpec
from imugen.sensors.mounting import setup as setup_mounting
from imugen.sensors.vibration import setup_vibration
from imugen.simulate.plan import enabled_terms, temperature_profile
from imugen.simulate.sources import resolve_truth, route_name
from imugen.stream.keys import KEY_DTYPE, STREAM_SHARD0, batch_keys, worker_batches
from imugen.stream.windows import (
    Scratch,
    draw_params,
    draw_params_many,
    exact_sequence,
    moved_windows,
    output_stage,
    warmup_rows,
    window_band_rng,
    window_batch,
    window_states,
    without_output_stage,
)
from imugen.tables import shard as tshard

INPUTS = ("increments", "rates")
FILTER_TARGETS = ("filter", "filter_sd", "filter_aware_error")
"""Targets of the aided filter's run over each sequence (exact mode only)."""
TARGETS = ("effective_error", "increments", "bias", "labels", "gnss", *FILTER_TARGETS)


class Stream:
    """Batches of measured IMU windows and their targets, drawn fresh and generated in memory.

    Parameters
    ----------
    routes : mapping name -> truth, or iterable of truth paths
        Truth tables (``truth.parquet`` paths, DataFrames, :class:`~imugen.sensors.ideal.TruthSource`);
        a path's route name is its folder's (as the simulate stage names it). All routes share
        one sample rate.
    grade : str, Grade, or list of them
        Grade preset(s) (or ``FILE.yaml:NAME``); each sequence draws one uniformly.
    window : int
        Rows per window (``W``).
    stride : int, optional
        Grid of window starts ``k0 = 1 + i * stride`` (the loader's; default ``window``).
    batch_size : int
        Windows per batch; a multiple of ``windows_per_sequence``.
    windows_per_sequence : int
        Windows cut from each fresh sequence (its parameter draw is shared by them).
    seed : int
        Root seed: with the same seed, a key gives the numbers of the simulate stage.
    inputs : {"increments", "rates"}
        ``x``: measured ``dtheta, dv`` or ``gyro, accel`` rows ``(B, W, 6)``.
    targets : iterable of :data:`TARGETS`
        As :class:`imugen.dataset.WindowDataset` gives them: the effective error of the
        inputs, the true increments, the true slow bias (``(B, W, 6)`` each), the sequence's
        drawn parameters ``(B, L)`` (names in :attr:`label_names`); ``gnss`` the aid stage's
        fixes (:mod:`imugen.stream.gnss`); ``filter``, ``filter_sd`` ``(B, W, C + 3)`` the
        aided filter's held estimates and sigmas and ``filter_aware_error`` ``(B, W, 6)`` the
        filter-aware target, as the loader's extras and target of the same names (columns in
        :attr:`filter_columns`; exact mode only, :mod:`imugen.stream`).
    exact : bool
        Generate each sequence from its turn-on (the shard's numbers, bit for bit) instead of
        drawing the slow states at each window's start (:mod:`imugen.stream.windows`).
    dtype : numpy dtype
        Of the arrays returned (float32; generation is float64).
    terms, draw, temperature, grades_file
        As the simulate stage's options (:class:`imugen.simulate.options.SimulateOptions`).
    weights : {"length", "uniform"}
        A route's probability: proportional to its windows, or equal.
    first_batch : int
        Number of the first batch (to resume a run).
    vibration, mounting
        As the simulate stage's options (case vibration: ``off``, ``car``, ``aircraft``,
        ``vehicle`` or a fit's YAML; the mounting's JSON or dict). Both modes: their draws
        are the shard's (streams ``vibration`` and ``mounting``), applied to the window's rows
        in window mode (:func:`~imugen.stream.windows.moved_windows`).
    gnss : AidOptions or dict, optional
        Receiver and scenarios of the ``gnss`` target and the filter of the filter targets
        (:class:`imugen.aid.options.AidOptions` or its fields; default the aid stage's
        defaults): the aid stage's draws for the same sequence (:mod:`imugen.stream.gnss`;
        with ``mounting``, on the mounted IMU's truth), drawn once per sequence and call.
        Needs routes given as truth files.
    shard_size : int, optional
        Sequences per written shard, for the ``gnss`` target of written keys (a sequence's
        index in its route is ``shard * shard_size + j``); default the batch's sequences.
    """

    def __init__(
        self,
        routes,
        grade,
        *,
        window: int = 200,
        stride: int | None = None,
        batch_size: int = 256,
        windows_per_sequence: int = 16,
        seed: int = 0,
        inputs: str = "increments",
        targets: Iterable[str] = ("effective_error",),
        exact: bool = False,
        dtype=np.float32,
        terms=None,
        draw: str = "ranges",
        temperature=None,
        grades_file=None,
        weights: str = "length",
        first_batch: int = 0,
        vibration: str | None = "off",
        mounting=None,
        gnss=None,
        shard_size: int | None = None,
    ):
        self.window = int(window)
        self.stride = int(stride if stride is not None else window)
        if self.window < 1 or self.stride < 1:
            raise InputError("window", "window and stride must be >= 1 sample")
        if inputs not in INPUTS:
            raise InputError("inputs", f"must be one of {', '.join(INPUTS)}, got {inputs!r}")
        self.inputs = inputs
        self.targets = [targets] if isinstance(targets, str) else list(targets)
        bad = [t for t in self.targets if t not in TARGETS]
        if bad:
            raise InputError("targets", f"unknown {bad}; one of {', '.join(TARGETS)}")
        self._filt = [t for t in self.targets if t in FILTER_TARGETS]
        if self._filt and not exact:
            raise InputError("exact", f"the {self._filt[0]} target needs exact=True (the filter "
                             "runs over the whole sequence)")  # fmt: skip
        if "filter_aware_error" in self.targets and inputs != "increments":
            raise InputError("targets", "filter_aware_error needs inputs='increments'")
        self.per_seq = int(windows_per_sequence)
        self.batch_size = int(batch_size)
        if self.per_seq < 1 or self.batch_size < 1 or self.batch_size % self.per_seq:
            raise InputError("batch_size", "must be a positive multiple of windows_per_sequence")
        self.seed = int(seed)
        self.exact = bool(exact)
        self.dtype = np.dtype(dtype)
        if draw not in ("ranges", "nominal"):
            raise InputError("draw", f"must be ranges or nominal, got {draw!r}")
        self.nominal = draw == "nominal"
        self.first_batch = int(first_batch)
        grades = list(grade) if isinstance(grade, list | tuple) else [grade]
        self.grades = [get_grade(g, grades_file) for g in grades]
        self.enabled = [enabled_terms(g, terms) for g in self.grades]
        self.temp = temperature_profile(temperature)
        items = routes.items() if isinstance(routes, Mapping) else ((None, r) for r in routes)
        self.truths: list[TruthSource] = []
        self.route_names: list[str] = []
        sources = []
        for name, t in items:
            tr = resolve_truth(t, None, 100.0, "flat")
            self.truths.append(tr)
            self.route_names.append(route_name(t, tr, name))
            sources.append(t if isinstance(t, str | Path) else None)
        if not self.truths:
            raise InputError("routes", "give at least one route")
        self.route_ids = [tshard.route_id(n) for n in self.route_names]
        dts = np.array([t.dt for t in self.truths])
        if np.ptp(dts) > 1e-9 * dts[0]:
            raise InputError("routes", f"routes differ in sample rate ({sorted(set(1 / dts))} Hz)")
        self.dt = float(dts[0])
        self.bands = [
            tuple(
                None if g.sensor(n).bandwidth is None
                else g.sensor(n).bandwidth.output_filter(n, 1.0 / self.dt)
                for n in ("gyro", "accel")
            )
            for g in self.grades
        ]  # fmt: skip
        self.windows = np.array(
            [max((t.K - 1 - self.window) // self.stride + 1, 0) for t in self.truths], np.int64
        )
        if not self.windows.any():
            raise InputError("routes", f"no route holds a window of {self.window} samples")
        if weights == "length":
            self.weights = self.windows / self.windows.sum()
        elif weights == "uniform":
            self.weights = (self.windows > 0) / np.count_nonzero(self.windows)
        else:
            raise InputError("weights", f"must be length or uniform, got {weights!r}")
        self._vib = [setup_vibration(t, vibration) for t in self.truths]
        self._mount_spec = MountingSpec.from_option(mounting, "mounting")
        self._mounting = [
            setup_mounting(t, self._mount_spec, src)
            for t, src in zip(self.truths, sources, strict=True)
        ]
        self._gnss_setup(gnss, shard_size, sources)
        self._concat()
        self._scratch = Scratch()

    def _concat(self):
        """The routes' truths back to back (window mode reads rows of one array)."""
        arrs = [t.chunk(0, t.K) for t in self.truths]
        self._row0 = np.concatenate([[0], np.cumsum([t.K for t in self.truths])[:-1]])
        w, f, dth, dv = (
            np.ascontiguousarray(np.concatenate([a[i] for a in arrs])) for i in (1, 2, 3, 4)
        )
        dT = np.zeros(0)
        if self.temp is not None:
            dT = np.concatenate(
                [np.asarray(self.temp(np.arange(t.K) * self.dt), float) for t in self.truths]
            )
        self._tr = (w, f, dth, dv, dT, self.dt)

    # --- what a batch holds
    @property
    def label_names(self) -> list[str]:
        """Columns of the ``labels`` target (those of the shard's labels sidecar)."""
        g = self.grades[0]
        d = draw_params(self.seed, 0, g, self.enabled[0], True, STREAM_SHARD0, 0)
        return [*d.gyro.labels("gyro", "radps"), *d.accel.labels("accel", "mps2")]

    @property
    def gnss_label_names(self) -> list[str]:
        """Columns of the ``gnss_labels`` entry (the GNSS labels sidecar's, no ``sequence``)."""
        if self.gnss is None:
            return []
        from imugen.stream import gnss as SG

        return SG.label_names(SG.sequence_gnss(self._full[0], self.gnss, self.seed,
                                               self.route_ids[0], 0))  # fmt: skip

    def batch(self, n: int) -> dict:
        """Batch number ``n``: ``{"x": (B, W, 6), <target>: ..., "keys": (B,) KEY_DTYPE}``."""
        keys, grid = batch_keys(
            self.seed, n, self.batch_size // self.per_seq, self.per_seq, self.windows,
            self.weights, len(self.grades),
        )  # fmt: skip
        keys["k0"] = 1 + grid * self.stride
        return self.generate(keys)

    def batches(self, worker: int = 0, workers: int = 1):
        """Endless batches of worker ``worker`` of ``workers`` (:func:`~imugen.stream.keys.worker_batches`)."""
        for n in worker_batches(self.first_batch, worker, workers):
            yield self.batch(n)

    def __iter__(self):
        return self.batches()

    # --- generation
    def keys(self, route, grade, shard, j, k0) -> np.ndarray:
        """Window keys from names (route, grade) or indices and integers (broadcast)."""
        route = np.atleast_1d(route)
        grade = np.atleast_1d(grade)
        if route.dtype.kind in "US":
            route = np.array([self.route_names.index(str(r)) for r in route])
        if grade.dtype.kind in "US":
            names = [g.name for g in self.grades]
            grade = np.array([names.index(str(g)) for g in grade])
        b = np.broadcast_arrays(
            route, grade, np.atleast_1d(shard), np.atleast_1d(j), np.atleast_1d(k0)
        )
        out = np.empty(b[0].shape, KEY_DTYPE).ravel()
        for name, a in zip(KEY_DTYPE.names, b, strict=True):
            out[name] = a.ravel()
        return out

    def generate(self, keys, exact: bool | None = None) -> dict:
        """The windows of ``keys`` (KEY_DTYPE; any order): ``{"x", targets..., "keys"}``.

        ``exact`` (default: the stream's) generates each sequence from its turn-on: with a
        written shard's key (``shard < 2^31``) and the stream's seed this returns the shard's
        rows ``k0 .. k0 + W - 1``, bit for bit after the cast to float32.
        """
        keys = np.asarray(keys, KEY_DTYPE)
        exact = self.exact if exact is None else exact
        W, B = self.window, len(keys)
        K = np.array([t.K for t in self.truths])[keys["route"]]
        if np.any(keys["k0"] < 1) or np.any(keys["k0"] + W > K):
            raise InputError("keys", f"window starts must lie in [1, K - {W}]")
        order = np.lexsort((keys["k0"], keys["j"], keys["shard"], keys["grade"], keys["route"]))
        sk = keys[order]
        rate = self.inputs == "rates"
        want = {
            "rate": rate,
            "inc": not rate,
            "err_rate": rate and "effective_error" in self.targets,
            "err_inc": not rate
            and ("effective_error" in self.targets or "filter_aware_error" in self.targets),
            "bias": "bias" in self.targets,
        }
        # the kernels write the returned dtype (one rounding of float64 values, as the shard's
        # float32 columns); the batch's arrays are fresh copies in the keys' order
        outs = {n: self._scratch.get(n, B, W, 6, dtype=self.dtype) for n, v in want.items() if v}
        seq_start = np.flatnonzero(
            np.concatenate(
                [
                    [True],
                    np.any(
                        [sk[f][1:] != sk[f][:-1] for f in ("route", "grade", "shard", "j")], axis=0
                    ),
                ]
            )
        )
        seq_of = np.cumsum(np.isin(np.arange(B), seq_start)) - 1
        draws = draw_params_many(
            self.seed,
            [(self.route_ids[k["route"]], int(k["grade"]), int(k["shard"]), int(k["j"]))
             for k in sk[seq_start]],
            self.grades, self.enabled, self.nominal,
        )  # fmt: skip
        if not exact and self._filt:
            raise InputError("exact", f"the {self._filt[0]} target needs exact=True (the filter "
                             "runs over the whole sequence)")  # fmt: skip
        filt = {}
        scens = {}  # each sequence's GNSS drawn once per call (gnss and filter targets)
        if exact:
            self._exact(sk, seq_start, draws, want, outs, filt, scens)
        else:
            for gi in np.unique(sk["grade"]):
                seqs = np.flatnonzero(sk["grade"][seq_start] == gi)
                sel = np.flatnonzero(sk["grade"] == gi)
                remap = np.full(len(seq_start), -1)
                remap[seqs] = np.arange(len(seqs))
                one = len(sel) == B  # a single grade: write in place
                sub = outs if one else {n: np.empty((len(sel), W, 6), self.dtype) for n in outs}
                states = window_states(self.seed, [
                    (self.route_ids[sk["route"][seq_start[s]]], self.grades[gi].id,
                     int(sk["shard"][seq_start[s]]), int(sk["j"][seq_start[s]]))
                    for s in seqs
                ])  # fmt: skip
                moves = self._window_moves(sk, seq_start, seq_of, sel)
                if self._post(gi):
                    self._window_post(gi, sk, sel, seqs, seq_start, remap[seq_of[sel]], states,
                                      [draws[s] for s in seqs], want, sub, moves)  # fmt: skip
                else:
                    rows = self._row0[sk["route"][sel]] + sk["k0"][sel]
                    tr = self._tr
                    if moves is not None:
                        tr, rows = moved_windows(tr, sk["k0"][sel], rows, W, moves)
                    window_batch(tr, [draws[s] for s in seqs], remap[seq_of[sel]], states,
                                 sk["k0"][sel], W, rows, want, sub)  # fmt: skip
                if not one:
                    for n in outs:
                        outs[n][sel] = sub[n]
        inv = np.empty(B, np.int64)
        inv[order] = np.arange(B)
        dt = self.dtype
        out = {"x": outs["rate" if rate else "inc"][inv]}
        for t in self.targets:
            if t == "effective_error":
                out[t] = outs["err_rate" if rate else "err_inc"][inv]
            elif t == "bias":
                out[t] = outs["bias"][inv]
            elif t == "increments":
                rows = self._row0[keys["route"]] + keys["k0"]
                idx = rows[:, None] + np.arange(W)
                out[t] = np.concatenate([self._tr[2][idx], self._tr[3][idx]], axis=2).astype(dt)
            elif t == "labels":
                out[t] = self._labels(draws, seq_of)[inv].astype(dt)
            elif t in ("filter", "filter_sd"):
                out[t] = filt[t][inv]
            elif t == "filter_aware_error":
                out[t] = self._filter_aware(sk, seq_of, outs, filt)[inv]
            elif t == "gnss":
                g = {}
                self._gnss(sk, seq_start, seq_of, g, scens)
                for n, a in g.items():
                    out[n] = a[inv] if a.dtype == np.int8 else a[inv].astype(dt)
        out["keys"] = keys
        return out

    def _moving(self) -> bool:
        """Mounting or vibration is on (for some route)."""
        return self._mount_spec is not None or any(v is not None for v in self._vib)

    def _moves(self, r, key) -> tuple:
        """A sequence's ``(Mounting, (angles, lever), SequenceVibration)`` (None where off):
        the shard path's draws, streams ``mounting`` and ``vibration``."""
        vib = None if self._vib[r] is None else self._vib[r].draw(sensor_rng(*key, "vibration"))
        return self._mounting[r], self._mount_draw(key), vib

    def _mount_draw(self, key):
        """A sequence's ``(angles, lever)`` (stream ``mounting``), None without mounting."""
        if self._mount_spec is None:
            return None
        return self._mount_spec.draw(sensor_rng(*key, "mounting"))

    def _scen(self, k, cache: dict):
        """The GNSS scenario result of the sequence of key ``k``
        (:func:`imugen.stream.gnss.sequence_gnss`, on the mounted IMU's truth with mounting),
        drawn once per ``cache``."""
        from imugen.stream import gnss as SG

        r, gi, shard, j = (int(k[f]) for f in ("route", "grade", "shard", "j"))
        if (r, gi, shard, j) not in cache:
            size = self.shard_size or self.batch_size // self.per_seq
            key = (self.seed, self.route_ids[r], self.grades[gi].id, shard, j)
            cache[r, gi, shard, j] = SG.sequence_gnss(
                self._full[r], self.gnss, self.seed, self.route_ids[r], shard * size + j,
                self._mount_draw(key),
            )  # fmt: skip
        return cache[r, gi, shard, j]

    def _window_moves(self, sk, seq_start, seq_of, sel):
        """:meth:`_moves` of each window of ``sel`` (None without mounting and vibration)."""
        if not self._moving():
            return None
        per_seq = {}
        out = []
        for i in sel:
            s = int(seq_of[i])
            if s not in per_seq:
                k = sk[seq_start[s]]
                r = int(k["route"])
                key = (self.seed, self.route_ids[r], self.grades[k["grade"]].id, int(k["shard"]),
                       int(k["j"]))  # fmt: skip
                per_seq[s] = self._moves(r, key)
            out.append(per_seq[s])
        return out

    def _window_post(self, gi, sk, sel, seqs, seq_start, seqs_of, states, draws, want, sub,
                     moves=None):  # fmt: skip
        """Window mode of a grade with an output bandwidth or rounding quantization: the
        kernel from :func:`~imugen.stream.windows.warmup_rows` rows before each window, then
        :func:`~imugen.stream.windows.output_stage` (``moves``: :meth:`_window_moves`)."""
        W, dt, bands = self.window, self.dt, self.bands[gi]
        Wu = warmup_rows(bands, dt)
        k0 = sk["k0"][sel]
        route = sk["route"][sel]
        K = np.array([t.K for t in self.truths])[route]
        if np.any(K < 1 + W + Wu):
            raise InputError("routes", f"a route is shorter than the window and the "
                             f"{Wu} rows of the output filter's warm-up")  # fmt: skip
        ks = np.maximum(k0 - Wu, 1)
        Wt = W + Wu
        kw = {
            "rate": want["rate"] or want["err_rate"],
            "inc": want["inc"] or want["err_inc"],
            "err_rate": want["err_rate"],
            "err_inc": want["err_inc"],
            "bias": want["bias"],
        }
        kout = {n: np.empty((len(sel), Wt, 6)) for n, v in kw.items() if v}
        kdraws = [without_output_stage(d, bands) for d in draws]
        tr, rows = self._tr, self._row0[route] + ks
        if moves is not None:
            tr, rows = moved_windows(tr, ks, rows, Wt, moves)
        window_batch(tr, kdraws, seqs_of, states, ks, Wt, rows, kw, kout)
        brng = [
            window_band_rng(self.seed, self.route_ids[sk["route"][seq_start[s]]],
                            self.grades[gi].id, int(sk["shard"][seq_start[s]]),
                            int(sk["j"][seq_start[s]]))
            for s in seqs
        ]  # fmt: skip
        rows = (rows + k0 - ks)[:, None] + np.arange(W)
        t_rate = np.concatenate([tr[0][rows], tr[1][rows]], axis=2)
        t_inc = np.concatenate([tr[2][rows], tr[3][rows]], axis=2)
        res = output_stage(draws, seqs_of, brng, bands, t_rate, t_inc, dt,
                           k0 - ks, W, kout, want)  # fmt: skip
        for n, a in sub.items():
            a[...] = res[n]

    def _gnss_setup(self, gnss, shard_size, sources):
        """Options and full truth tables of the ``gnss`` target."""
        self.gnss = None
        self.shard_size = None if shard_size is None else int(shard_size)
        n_seq = self.batch_size // self.per_seq
        if self.shard_size is not None and self.shard_size < n_seq:
            raise InputError("shard_size", f"must be >= the batch's {n_seq} sequences")
        if "gnss" not in self.targets and not self._filt:
            return
        from imugen.aid.options import AidOptions
        from imugen.tables import truth as ttruth

        if isinstance(gnss, dict):
            gnss = AidOptions(**gnss)
        self.gnss = gnss if gnss is not None else AidOptions()
        if self._filt and (self.gnss.odometer or self.gnss.barometer):
            raise InputError("gnss", "the filter targets are not streamed with companions")
        if any(src is None for src in sources):
            raise InputError("routes", "the gnss target needs routes given as truth files")
        self._full = [ttruth.read(src) for src in sources]

    def _gnss(self, sk, seq_start, seq_of, out, scens):
        """The ``gnss`` target's entries (sorted-key order) into ``out`` (``scens``: the
        sequences' GNSS drawn in this call, :meth:`_scen`)."""
        from imugen.stream import gnss as SG

        W, B = self.window, len(sk)
        scen = [self._scen(sk[a], scens) for a in seq_start]
        L = len(SG.label_names(scen[0]))
        res = {n: np.empty((B, W, 3)) for n in SG.KEYS[:4]}
        res["gnss_state"] = np.empty((B, W), np.int8)
        res["gnss_labels"] = np.empty((B, L))
        for b in range(B):
            SG.lay(scen[seq_of[b]], int(sk["k0"][b]), W, res, b)
        out.update(res)

    def _post(self, gi) -> bool:
        """Grade ``gi`` has an output bandwidth or rounding quantization."""
        g = self.grades[gi]
        return any(b is not None for b in self.bands[gi]) or any(
            g.sensor(n).quantization_mode == "round" for n in ("gyro", "accel")
        )

    def _labels(self, draws, seq_of) -> np.ndarray:
        """Per-window label rows ``(B, L)`` in :attr:`label_names` order."""
        cols = None
        rows = []
        for d in draws:
            lab = {**d.gyro.labels("gyro", "radps"), **d.accel.labels("accel", "mps2")}
            if cols is None:
                cols = list(lab)
            elif list(lab) != cols:
                raise InputError("targets", "labels need grades with the same label columns")
            rows.append([float(lab[c][0]) for c in cols])
        return np.asarray(rows)[seq_of]

    @property
    def filter_columns(self) -> dict[str, list[str]]:
        """Columns of the ``filter`` and ``filter_sd`` targets (the loader's
        ``extra_columns``): the table's, then ``<name>_new``, ``<name>_valid``,
        ``<name>_age_s``."""
        from imugen.dataset import EXTRAS

        return {
            n: [*EXTRAS[n].columns, f"{n}_new", f"{n}_valid", f"{n}_age_s"]
            for n in ("filter", "filter_sd")
        }

    def _filter(self, r, gi, k, data, scens) -> dict:
        """The aided filter over one whole sequence (``data``: its rows from turn-on), as the aid
        stage runs it on the written shard (:func:`imugen.aid.stage.filter_block`, the stage's
        tuning and options, the ``gnss`` target's fixes): the filter-estimates table's columns
        (:func:`imugen.aid.stage.filter_estimates`), its float32 columns rounded as written.
        The increments are the shard's float32 values."""
        from imugen.aid import filter as A
        from imugen.aid import stage as AID
        from imugen.tables import filter_estimates as testim

        truth, p = self._full[r], self.gnss
        size = self.shard_size or self.batch_size // self.per_seq
        index = int(k["shard"]) * size + int(k["j"])
        scen = self._scen(k, scens)
        sid = (self.route_ids[r] << 31) | index if index < (1 << 31) else -1
        tun = A.Tuning.from_grade(self.grades[gi], p.tuning_level)
        mmeta = None if self._mount_spec is None else self._mount_spec.as_dict()
        opts = AID.filter_options(p, truth.meta.get("vehicle"), mmeta,
                                  truth.meta.get("plausibility"),
                                  truth.meta.get("vehicle_params"))  # fmt: skip
        dth, dvb = (data[n].astype(np.float32).astype(np.float64)[None] for n in ("dtheta", "dv"))
        ids = np.array([sid], np.int64)
        res = AID.filter_block(truth, ids, dth, dvb, p, self.seed, tun, opts, scen=scen)[4]
        cols = AID.filter_estimates(ids, res)
        for c in (*testim.VALUES, *testim.SIGMAS):
            cols[c] = np.asarray(cols[c], np.float32).astype(np.float64)
        return cols

    def _filter_index(self, ests, seq_of, k0, filt):
        """The ``filter``, ``filter_sd`` targets (sorted-key order) into ``filt``, and the
        estimates the filter-aware target holds (``filt["held"]``)."""
        from imugen.dataset import EXTRAS, EpochIndex
        from imugen.tables import filter_estimates as testim

        W = self.window
        e = np.asarray(seq_of, np.int64)
        dt = np.array([c[1] for c in ests])[e]
        rows = np.asarray(k0, np.int64)[:, None] + np.arange(W)[None, :]

        def index(columns):
            parts = []
            for s, (cols, _) in enumerate(ests):
                v = np.column_stack([cols[c] for c in columns])
                kk = np.asarray(cols[testim.SAMPLE], np.int64)
                parts.append((np.full(len(kk), s, np.int64), kk, np.where(np.isnan(v), 0.0, v)))
            return EpochIndex.concat(parts, len(columns))

        for n in ("filter", "filter_sd"):
            if n in self.targets:
                filt[n] = index(EXTRAS[n].columns).gather(e, rows, dt, "hold", self.dtype)
        if "filter_aware_error" in self.targets:
            filt["held"] = index(testim.CORRECTION).gather(e, rows - 1, dt, "hold", np.float64)
            filt["dt"] = dt

    def _filter_aware(self, sk, seq_of, outs, filt) -> np.ndarray:
        """The filter-aware target (sorted-key order), by the loader's definition
        (:func:`imugen.tables.filter_estimates.filter_aware_error`)."""
        from imugen.tables import filter_estimates as testim

        h, C = filt["held"], len(testim.CORRECTION)
        out = testim.filter_aware_error(outs["inc"], outs["err_inc"], h[..., :C],
                                        h[..., C + 1] != 0, filt["dt"][:, None, None])  # fmt: skip
        return out.astype(self.dtype)

    def _exact(self, sk, seq_start, draws, want, outs, filt, scens):
        names = {
            "rate": ("gyro", "accel"), "inc": ("dtheta", "dv"), "bias": ("gyro_bias", "accel_bias"),
            "err_rate": ("err_gyro", "err_accel"), "err_inc": ("err_dtheta", "err_dv"),
        }  # fmt: skip
        groups = [g for n in outs for g in names[n]]
        if self._filt:
            groups = list(dict.fromkeys([*groups, "dtheta", "dv"]))
        W = self.window
        ends = [*seq_start[1:], len(sk)]
        ests = []
        for s, (a, b) in enumerate(zip(seq_start, ends, strict=True)):
            k = sk[a]
            r, gi = int(k["route"]), int(k["grade"])
            kmax = self.truths[r].K if self._filt else int(sk["k0"][a:b].max()) + W
            key = (self.seed, self.route_ids[r], self.grades[gi].id, int(k["shard"]), int(k["j"]))
            mounting, mount, vib = self._moves(r, key)
            data = exact_sequence(
                self.truths[r], draws[s], *key, kmax, self.temp, groups, bands=self.bands[gi],
                vib=vib, mounting=mounting, mount=mount,
            )  # fmt: skip
            for i in range(a, b):
                k0 = int(sk["k0"][i])
                for n in outs:
                    g0, g1 = names[n]
                    outs[n][i, :, :3] = data[g0][k0 : k0 + W]
                    outs[n][i, :, 3:] = data[g1][k0 : k0 + W]
            if self._filt:
                t = self._full[r].time_s  # the loader's interval (its clock's)
                dt = (t[-1] - t[0]) / max(len(t) - 1, 1)
                ests.append((self._filter(r, gi, k, data, scens), dt))
        if self._filt:
            seq_of = np.repeat(np.arange(len(seq_start)), np.diff([*seq_start, len(sk)]))
            self._filter_index(ests, seq_of, sk["k0"], filt)


def load_truths(paths: Iterable) -> dict[str, ArrayTruth]:
    """``{route name: truth}`` of truth files (the folder name, as the simulate stage names it)."""
    out = {}
    for p in paths:
        tr = ArrayTruth.read(p)
        out[route_name(p, tr)] = tr
    return out
