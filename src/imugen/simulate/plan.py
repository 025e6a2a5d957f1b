"""A shard's plan: its options validated once, its sequence ids and every parameter drawn.

:func:`plan_shard` resolves the truth (:mod:`imugen.simulate.sources`) and the grade, checks
the options, numbers the sequences (``route_id << 31 | shard * shard_size + j``), draws each
sequence's sensor parameters, vibration and mounting from their streams
(:func:`imugen.core.seeding.sensor_rng`) and assembles the shard's metadata; the
:class:`Plan` it returns is all :func:`imugen.simulate.stage.simulate` and
:func:`imugen.simulate.stage.run` need to generate the sequences.
"""

from __future__ import annotations

import hashlib
import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from imugen import __version__
from imugen.core.errors import InputError
from imugen.core.options import DRAWS
from imugen.core.seeding import BIT_GENERATOR, SENSOR_STREAMS, sensor_rng
from imugen.sensors.grades import TERMS, Grade, get_grade, preset_text
from imugen.sensors.ideal import CHUNK, TruthSource
from imugen.sensors.model import SensorParams, draw_sensor
from imugen.sensors.mounting import MountingSpec
from imugen.sensors.mounting import setup as setup_mounting
from imugen.sensors.vibration import setup_vibration
from imugen.simulate.options import SimulateOptions
from imugen.simulate.sources import resolve_truth, route_name
from imugen.tables import shard as tshard
from imugen.tables.shard import SEQUENCE

OUTPUTS = tshard.OUTPUTS


def temperature_profile(spec):
    """A callable ``t [s] -> temperature offset [K]`` from a profile specification.

    ``None`` (off); ``{"kind": "warmup", "delta_K": d, "tau_s": T}`` for
    ``d (1 - exp(-t / T))`` (self-heating after turn-on; the turn-on bias holds the value at
    turn-on); ``{"kind": "linear", "rate_K_per_s": r}``; ``{"kind": "table", "time_s": [...],
    "delta_K": [...]}`` (linear interpolation, held constant outside). A JSON string is accepted.
    """
    if spec is None:
        return None
    if isinstance(spec, str):
        try:
            spec = json.loads(spec)
        except ValueError:
            raise InputError("--temperature", "expected a JSON object") from None
    if not isinstance(spec, dict) or "kind" not in spec:
        raise InputError("--temperature", 'expected {"kind": warmup|linear|table, ...}')
    k = spec["kind"]
    try:
        if k == "warmup":
            d, T = float(spec["delta_K"]), float(spec["tau_s"])
            if not T > 0:
                raise ValueError("tau_s must be > 0")
            return lambda t: -d * np.expm1(-np.asarray(t) / T)
        if k == "linear":
            r = float(spec["rate_K_per_s"])
            return lambda t: r * np.asarray(t)
        if k == "table":
            tt = np.asarray(spec["time_s"], float)
            dd = np.asarray(spec["delta_K"], float)
            if tt.ndim != 1 or tt.shape != dd.shape or len(tt) < 1 or np.any(np.diff(tt) <= 0):
                raise ValueError("time_s and delta_K must be equal-length, time increasing")
            return lambda t: np.interp(t, tt, dd)
    except (KeyError, TypeError, ValueError) as exc:
        raise InputError("--temperature", f"bad {k} profile: {exc}") from None
    raise InputError("--temperature", f"unknown profile kind {k!r}")


def enabled_terms(grade: Grade, terms=None) -> dict[str, frozenset]:
    """Which terms to apply per sensor.

    ``terms=None``: everything the grade configures. Otherwise an iterable of ``"gyro"``,
    ``"accel"``, a term name (both sensors; ``"temperature"`` = both temperature terms) or
    ``"gyro.<term>"`` / ``"accel.<term>"``.
    """
    out = {"gyro": set(), "accel": set()}
    if terms is None:
        for s in out:
            out[s] = set(grade.sensor(s).configured())
        return {k: frozenset(v) for k, v in out.items()}
    if isinstance(terms, str):
        terms = [t for t in terms.replace(",", " ").split() if t]
    alias = {
        "temperature": ("temperature_bias", "temperature_scale_factor"),
        "saturation": ("range",),
        "misalignment": ("cross_coupling",),
    }
    for item in terms:
        sensors, _, name = item.rpartition(".")
        sens = [sensors] if sensors else ["gyro", "accel"]
        if not sensors and name in out:
            sens, name = [name], ""
        if any(s not in out for s in sens):
            raise InputError("--terms", f"unknown sensor in {item!r} (gyro or accel)")
        names = TERMS if not name else alias.get(name, (name,))
        for n in names:
            if n not in TERMS:
                raise InputError("--terms", f"unknown term {item!r}; terms: {', '.join(TERMS)}")
            for s in sens:
                if n in grade.sensor(s).configured():
                    out[s].add(n)
    return {k: frozenset(v) for k, v in out.items()}


def check_int(name, v, lo=0):
    if isinstance(v, bool) or not isinstance(v, int | np.integer) or v < lo:
        raise InputError(name, f"must be an integer >= {lo}, got {v!r}")
    return int(v)


def first_index(shard: int, M: int, shard_size) -> int:
    """Index of the shard's first sequence: ``shard * shard_size`` (default ``M``).

    A shard holds at most ``shard_size`` sequences; only the last shard of an experiment whose
    N is not a multiple of the shard size is shorter, and it must be given the experiment's
    shard size, or its ids would repeat those of an earlier shard.
    """
    size = M if shard_size is None else check_int("--shard-size", shard_size, 1)
    if M > size:
        raise InputError("--shard-size", f"is {size}, fewer than the {M} sequences of this shard")
    if shard * size + M - 1 >= 2**tshard.ROUTE_SHIFT:
        raise InputError("--shard", "sequence index shard * shard_size + j must be < 2^31")
    return shard * size


@dataclass
class Plan:
    """Everything one shard's generation needs, validated once (shared by simulate and run)."""

    truth: TruthSource
    grade: Grade
    M: int
    seed: int
    shard: int
    rid: int
    ids: np.ndarray
    enabled: dict
    temp: object
    gp: list
    ap: list
    outputs: str
    series: bool
    raw: bool
    names: list
    meta: dict
    vib: list | None = None  # one imugen.sensors.vibration.SequenceVibration per sequence
    mounting: object = None  # imugen.sensors.mounting.Mounting (None: the IMU is the vehicle)
    mount: list | None = None  # per sequence (angles (3,) rad, lever arm (3,) m)

    def labels(self):
        """One row per sequence: ids, provenance and every drawn parameter (a DataFrame)."""
        import pandas as pd

        return pd.DataFrame(self.label_columns())

    def label_columns(self) -> dict:
        """:meth:`labels` as a dict of columns (no pandas)."""
        M = self.M
        d = {
            SEQUENCE: self.ids,
            "route_id": np.full(M, self.rid, np.int64),
            "shard": np.full(M, self.shard, np.int32),
            "index": (self.ids & ((1 << tshard.ROUTE_SHIFT) - 1)).astype(np.int32),
            "seed": np.full(M, self.seed, np.int64),
            "grade_id": np.full(M, self.grade.id, np.int32),
        }
        gp, ap = SensorParams.stack(self.gp), SensorParams.stack(self.ap)
        d.update(gp.labels("gyro", "radps"))
        d.update(ap.labels("accel", "mps2"))
        eye = np.eye(3)[None]
        d.update(tshard.static_labels("gyro", gp.b_on, gp.cc + gp.sf[:, :, None] * eye, gp.gs))
        d.update(tshard.static_labels("accel", ap.b_on, ap.cc + ap.sf[:, :, None] * eye))
        if self.mount is not None:
            d.update(tshard.mounting_labels(*(np.array(x) for x in zip(*self.mount, strict=True))))
        if self.vib is not None:
            for name in self.vib[0].labels():
                d[name] = np.array([v.labels()[name] for v in self.vib])
        return d


def plan_shard(truth, options: SimulateOptions, dtype=None) -> Plan:
    """Resolve the truth and the grade, check ``options``, draw every sequence's parameters.

    ``truth`` is what :func:`imugen.simulate.stage.simulate` takes; ``dtype`` overrides
    ``options.dtype`` (the in-memory shard is float64)."""
    o = options
    dtype = o.dtype if dtype is None else dtype
    tr = resolve_truth(truth, o.static_s, o.rate_hz, o.static_earth)
    route = route_name(truth, tr, o.route)
    rid = tshard.route_id(route)
    grade = get_grade(o.grade, o.grades_file)
    M = check_int("--sequences", o.sequences, 1)
    seed = check_int("--seed", o.seed, 0)
    shard = check_int("--shard", o.shard, 0)
    outputs, draw, increments, series = o.outputs, o.draw, o.increments, o.series
    if outputs not in OUTPUTS:
        raise InputError("--outputs", f"must be one of {', '.join(OUTPUTS)}, got {outputs!r}")
    if draw not in DRAWS:
        raise InputError("--draw", f"must be one of {', '.join(DRAWS)}, got {draw!r}")
    if increments not in tshard.INCREMENT_KINDS:
        kinds = ", ".join(tshard.INCREMENT_KINDS)
        raise InputError("--increments", f"must be one of {kinds}, got {increments!r}")
    first = first_index(shard, M, o.shard_size)
    enabled = enabled_terms(grade, o.terms)
    temp = temperature_profile(o.temperature)
    nominal = draw == "nominal"
    gp, ap = [], []
    for j in range(M):
        rng = sensor_rng(seed, rid, grade.id, shard, j, "params")
        gp.append(draw_sensor(grade.gyro, rng, enabled["gyro"], nominal))
        ap.append(draw_sensor(grade.accel, rng, enabled["accel"], nominal))
    ids = tshard.sequence_ids(rid, first + np.arange(M))
    meta = {
        "format": tshard.FORMAT,
        "format_version": tshard.FORMAT_VERSION,
        "code_version": __version__,
        "numpy_version": np.__version__,
        "grade": {
            "name": grade.name,
            "id": grade.id,
            "origin": grade.origin,
            "description": grade.description,
            "source": grade.source,
            "reading": grade.reading,
            "config": grade.config,
        },
        "preset_source": grade.origin,
        # checksum of the shipped presets file when the grade is a preset (None: custom grade)
        "preset_sha": hashlib.sha256(preset_text().encode()).hexdigest()
        if grade.origin.startswith("imugen/data/")
        else None,
        "route": route,
        "route_id": rid,
        "seed": seed,
        "shard": shard,
        "sequences": M,
        "first_index": first,
        "sequence_ids": [int(ids[0]), int(ids[-1])],
        "sequence_id": "route_id << 31 | index, index = shard * shard_size + j",
        "spawn_key": [rid, grade.id, shard],
        "sequence_spawn_key": "(route_id, grade_id, shard, index_in_shard, stream)",
        "streams": SENSOR_STREAMS,
        "bit_generator": BIT_GENERATOR,
        "draw": draw,
        "terms": {k: sorted(v) for k, v in enabled.items()},
        "outputs": outputs,
        "increments": increments,
        "series": bool(series),
        "dtype": np.dtype(dtype).name,
        "chunk": CHUNK,
        "rate_hz": 1.0 / tr.dt,
        "dt_s": tr.dt,
        "samples_per_sequence": tr.K,
        "truth": tr.meta,
        "temperature": o.temperature,
        "vibration": None,
        "rows": "sorted by sequence then time; increments on row k are the interval ending at "
        "t_k; row 0 of each sequence is zero",
        "derived": None,
    }
    names = tshard.groups(outputs, series)
    vib, meta["vibration"] = _vibrations(tr, o.vibration, seed, rid, grade, shard, M)
    spec = MountingSpec.from_option(o.mounting, "--mounting")
    meta["mounting"] = None if spec is None else spec.as_dict()
    mount = None
    if spec is not None:
        mount = [spec.draw(sensor_rng(seed, rid, grade.id, shard, j, "mounting")) for j in range(M)]
    source = truth if isinstance(truth, str | Path) else None
    return Plan(
        tr, grade, M, seed, shard, rid, ids, enabled, temp, gp, ap, outputs, bool(series),
        increments == "raw", names, meta, vib, setup_mounting(tr, spec, source), mount,
    )  # fmt: skip


def _vibrations(truth, option, seed, rid, grade, shard, M):
    """Per-sequence vibrations (stream ``vibration``) and their metadata, or (None, meta)."""
    v = setup_vibration(truth, option)
    meta = None if option in (None, "off") else {"option": option, "profile": None}
    if v is None:
        return None, meta
    meta["profile"] = v.profile.as_dict()
    return [v.draw(sensor_rng(seed, rid, grade.id, shard, j, "vibration")) for j in range(M)], meta
