"""The filter's state: one list of blocks, from which every offset is derived.

Two vectors share the blocks, in the order of :data:`BLOCKS`:

* the **error state** ``dx`` (estimate minus truth; ``n`` components): only the blocks the
  :class:`~imugen.aid.filter.options.Options` switch on, each with its error size (attitude:
  the rotation vector ``psi`` [rad], ``C_hat = Exp(psi) C``);
* the **nominal state** ``x`` (the estimate; :data:`NX` components, one row per sequence):
  every block, always, each with its nominal size (attitude: the quaternion ``q_nb``, scalar
  first; the odometer's tick residuals: the start's only, the end's has mean zero).

:class:`StateLayout` is the only place that turns blocks into offsets: :func:`state_names`,
the priors (:func:`imugen.aid.filter.align.initial_covariance`), the results and the compiled
kernel (which receives :meth:`StateLayout.offsets`, a numba-friendly named tuple with ``-1``
for an absent block, and :meth:`StateLayout.feedback_table`) all read it from here.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

CC_PAIRS = ((0, 1), (0, 2), (1, 0), (1, 2), (2, 0), (2, 1))
"""Off-diagonal (row, column) of the gyro cross-coupling states, as :mod:`imugen.sensors.model`."""


@dataclass(frozen=True)
class Block:
    """One block of the state.

    Attributes
    ----------
    key : str  name of the block (a field of :class:`Offsets`)
    names : tuple of str  names of its error-state components
    nominal : int  its size in the nominal state
    additive : bool  whether the error is fed back by subtraction (``x -= dx``, over the first
        ``min(nominal, len(names))`` components); the attitude is fed back as a rotation
    doc : str  what it is, units
    """

    key: str
    names: tuple[str, ...]
    nominal: int
    additive: bool = True
    doc: str = ""

    @property
    def size(self) -> int:
        """Size in the error state."""
        return len(self.names)


def _axes(prefix: str, axes: str) -> tuple[str, ...]:
    return tuple(f"{prefix}_{a}" for a in axes)


BLOCKS: tuple[Block, ...] = (
    Block("p", _axes("dp", "enu"), 3, doc="position in n [m]"),
    Block("v", _axes("dv", "enu"), 3, doc="velocity in n [m/s]"),
    Block("att", _axes("psi", "enu"), 4, False, "attitude: q_nb (nominal), psi in n [rad] (error)"),
    Block("bg", _axes("dbg", "xyz"), 3, doc="gyro bias, body [rad/s]"),
    Block("ba", _axes("dba", "xyz"), 3, doc="accelerometer bias, body [m/s^2]"),
    Block("gnss_bias", _axes("dgnss_bias", "enu"), 3, doc="GNSS Gauss-Markov position bias [m]"),
    Block("sg", _axes("dsg", "xyz"), 3, doc="gyro scale factor, body"),
    Block("sa", _axes("dsa", "xyz"), 3, doc="accelerometer scale factor, body"),
    Block("odo_sf", ("dodo_sf",), 1, doc="odometer scale factor"),
    Block("baro_bias", ("dbaro_bias",), 1, doc="barometer Gauss-Markov drift [m]"),
    Block("mount", ("dmount_pitch", "dmount_yaw"), 2, doc="IMU pitch, yaw from the vehicle [rad]"),
    Block("lever", _axes("dlever", "xyz"), 3, doc="NHC lever arm from its nominal, body [m]"),
    Block(
        "cc",
        tuple(f"dcg_{'xyz'[i]}{'xyz'[j]}" for i, j in CC_PAIRS),
        6,
        doc="gyro cross-coupling, pairs CC_PAIRS",
    ),
    Block(
        "ca",
        tuple(f"dca_{'xyz'[i]}{'xyz'[j]}" for i, j in CC_PAIRS),
        6,
        doc="accelerometer cross-coupling, pairs CC_PAIRS",
    ),
    Block(
        "odo_tick",
        ("dodo_tick_start_m", "dodo_tick_end_m"),
        1,
        doc="odometer tick residuals at the window's start and end [m]",
    ),
)
"""Every block, in state order (the first five are always on)."""

BASE = ("p", "v", "att", "bg", "ba")
"""Blocks every filter has."""


class Offsets(NamedTuple):
    """Offset of every block in one vector (``-1``: absent) and the vector's size ``n``; the
    compiled kernel's view of a :class:`StateLayout` (a tuple of integers)."""

    p: int
    v: int
    att: int
    bg: int
    ba: int
    gnss_bias: int
    sg: int
    sa: int
    odo_sf: int
    baro_bias: int
    mount: int
    lever: int
    cc: int
    ca: int
    odo_tick: int
    n: int


assert Offsets._fields[:-1] == tuple(b.key for b in BLOCKS)


class StateLayout:
    """The blocks of one vector and their offsets.

    Parameters
    ----------
    keys : iterable of str
        Blocks present (any order; they are laid out in the order of :data:`BLOCKS`).
    nominal : bool
        Lay out the nominal state (nominal sizes) instead of the error state.
    """

    def __init__(self, keys, nominal: bool = False):
        keys = set(keys) | set(BASE)
        unknown = keys - {b.key for b in BLOCKS}
        if unknown:
            raise KeyError(f"unknown state blocks {sorted(unknown)}")
        self.nominal = nominal
        self.blocks = tuple(b for b in BLOCKS if b.key in keys)
        self._offset = {}
        i = 0
        for b in self.blocks:
            self._offset[b.key] = i
            i += b.nominal if nominal else b.size
        self.n = i

    @classmethod
    def of(
        cls, *, scale_factors=False, gnss_bias=False, odo_sf=False, baro=False, mounting=False,
        gyro_cc=False, odometer=False, lever=False, accel_cc=False,
    ) -> StateLayout:  # fmt: skip
        """The error state of a filter with these states switched on (``odo_sf``: odometer scale
        factor, ``baro``: barometer drift, ``mounting``: the IMU's pitch and yaw from the
        vehicle, ``gyro_cc``: the gyro's six cross-coupling elements, ``odometer``: the tick
        residuals at the two ends of a window, ``lever``: the NHC lever arm's departure from
        its nominal, ``accel_cc``: the accelerometer's six cross-coupling elements)."""
        on = {
            "gnss_bias": gnss_bias, "sg": scale_factors, "sa": scale_factors, "odo_sf": odo_sf,
            "baro_bias": baro, "mount": mounting, "lever": lever, "cc": gyro_cc,
            "ca": accel_cc, "odo_tick": odometer,
        }  # fmt: skip
        return cls(k for k, v in on.items() if v)

    def has(self, key: str) -> bool:
        """Whether block ``key`` is present."""
        return key in self._offset

    def offset(self, key: str) -> int:
        """Offset of block ``key`` (KeyError when absent)."""
        return self._offset[key]

    def size(self, key: str) -> int:
        """Size of block ``key`` in this vector."""
        b = next(b for b in self.blocks if b.key == key)
        return b.nominal if self.nominal else b.size

    def slice(self, key: str) -> slice:
        """The components of block ``key``."""
        i = self._offset[key]
        return slice(i, i + self.size(key))

    @property
    def names(self) -> list[str]:
        """Names of the error-state components, in order (error state only)."""
        if self.nominal:
            raise ValueError("component names are those of the error state")
        return [name for b in self.blocks for name in b.names]

    def offsets(self) -> Offsets:
        """Offsets of every block (``-1`` when absent) and ``n``, for the compiled kernel."""
        return Offsets(*(self._offset.get(b.key, -1) for b in BLOCKS), self.n)

    def feedback_table(self) -> np.ndarray:
        """``(m, 3)`` int64 rows ``(nominal offset, error offset, count)`` of the additive
        blocks present: the feedback ``x[i:i+count] -= dx[j:j+count]`` (error state only)."""
        if self.nominal:
            raise ValueError("the feedback table is built on the error state")
        rows = [
            (NOMINAL.offset(b.key), self._offset[b.key], min(b.nominal, b.size))
            for b in self.blocks
            if b.additive
        ]
        return np.array(rows, np.int64).reshape(-1, 3)

    def __eq__(self, other) -> bool:
        return isinstance(other, StateLayout) and (self.nominal, self.blocks) == (
            other.nominal,
            other.blocks,
        )

    def __hash__(self) -> int:
        return hash((self.nominal, self.blocks))

    def __repr__(self) -> str:
        kind = "nominal" if self.nominal else "error"
        return f"StateLayout({kind}, n={self.n}: {', '.join(b.key for b in self.blocks)})"


NOMINAL = StateLayout((b.key for b in BLOCKS), nominal=True)
"""The nominal state (every block)."""
NX = NOMINAL.n
"""Size of the nominal state."""


def state_names(
    scale_factors: bool, gnss_bias: bool, odo_sf: bool = False, baro: bool = False,
    mounting: bool = False, gyro_cc: bool = False, odometer: bool = False, lever: bool = False,
    accel_cc: bool = False,
) -> list[str]:  # fmt: skip
    """Names of the error-state components, in order (:meth:`StateLayout.of`)."""
    return StateLayout.of(
        scale_factors=scale_factors, gnss_bias=gnss_bias, odo_sf=odo_sf, baro=baro,
        mounting=mounting, gyro_cc=gyro_cc, odometer=odometer, lever=lever, accel_cc=accel_cc,
    ).names  # fmt: skip
