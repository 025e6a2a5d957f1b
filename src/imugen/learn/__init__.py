"""The reference learned model of the GNSS-denied benchmark (``config/benchmark.yaml``).

A small 1-D convolutional network reads a window of measured IMU increments and returns the
mean **effective error** of the window (everything the sensor adds except white noise: the
loader's ``effective_error`` target, :mod:`imugen.dataset`), trained on fresh draws of
:mod:`imugen.stream` (keys in the stream's reserved namespace, never those of a written
validation or test shard). Applied to a shard it writes an IMU correction table
(:mod:`imugen.tables.imu_correction`) that ``imugen aid --correction-in`` subtracts before the
filter: a *total* correction, the filter's own bias states then modelling what it leaves
(:mod:`imugen.aid.filter.learner`; a correction re-targeted at the filter's live estimate
would break the filter's consistency).

Commands (the face :mod:`imugen.learn.stage`, rules in ``workflow/rules/learn.smk``):
``imugen learn train`` (:mod:`imugen.learn.train`), ``imugen learn correct``
(:mod:`imugen.learn.correct`), ``imugen learn table`` (:mod:`imugen.learn.table`: the
benchmark's table and figure). PyTorch (the optional ``torch`` extra) is imported inside the
functions that need it, so this package imports without it.
"""
