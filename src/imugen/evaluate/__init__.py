"""Evaluate stage: navigation errors -> per-sequence metrics and the RMSE tables
(:mod:`~imugen.evaluate.stage`: ``imugen evaluate``, ``imugen tables``)."""
