"""Simulate stage: a truth table (or a still IMU) -> shards of M erroneous IMU sequences.

:mod:`~imugen.simulate.stage` is the face (``imugen simulate``, :func:`simulate` in memory);
:mod:`~imugen.simulate.options` its options, :mod:`~imugen.simulate.plan` validates a shard's
options and draws its parameters, :mod:`~imugen.simulate.sources` serves the truth,
:mod:`~imugen.simulate.sinks` takes the sequences (memory, shard writer, navigation).
``simulate``, ``Shard`` and ``SimulateOptions`` load on first use (the command line's parser
reads the options alone).
"""

import importlib

_LAZY = {"Shard": "stage", "simulate": "stage", "SimulateOptions": "options"}
__all__ = sorted(_LAZY)


def __getattr__(name):
    if name in _LAZY:
        value = getattr(importlib.import_module(f"{__name__}.{_LAZY[name]}"), name)
        globals()[name] = value
        return value
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def __dir__():
    return sorted({*globals(), *_LAZY})
