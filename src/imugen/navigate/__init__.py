"""Navigate stage: measured IMU sequences -> strapdown navigation -> errors against truth.

:mod:`~imugen.navigate.stage` is the face (``imugen navigate``,
:func:`imugen.navigate_arrays`); :mod:`~imugen.navigate.mechanize` the strapdown
mechanization (its compiled kernels in :mod:`imugen.navigate._kernel`);
:mod:`~imugen.navigate.navigator` the batch navigator shared with ``imugen simulate
--navigate``; :mod:`~imugen.navigate.local_errors` position errors in the local level.
"""
