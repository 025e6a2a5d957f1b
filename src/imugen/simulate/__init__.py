"""Simulate stage: a truth table (or a still IMU) -> shards of M erroneous IMU sequences.

:mod:`~imugen.simulate.stage` is the face (``imugen simulate``, :func:`simulate` in memory);
:mod:`~imugen.simulate.plan` validates a shard's options and draws its parameters,
:mod:`~imugen.simulate.sources` serves the truth, :mod:`~imugen.simulate.sinks` takes the
sequences (memory, shard writer, navigation).
"""

from imugen.simulate.stage import Shard, simulate

__all__ = ["Shard", "simulate"]
