"""Export stage: datasets for other tools.

:mod:`~imugen.export.stage` is the face of ``imugen export`` (one module per format:
:mod:`~imugen.export.euroc`, :mod:`~imugen.export.tum`, :mod:`~imugen.export.tlio`,
:mod:`~imugen.export.ronin`, :mod:`~imugen.export.kfgins`, :mod:`~imugen.export.ros2`, over
:mod:`~imugen.export.source`, :mod:`~imugen.export.common` and :mod:`~imugen.export.convert`);
:mod:`~imugen.export.mat` writes the MATLAB file of ``imugen export-mat``.
"""
