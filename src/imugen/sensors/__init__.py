"""The sensor library every stage may use (it imports no stage).

- :mod:`~imugen.sensors.grades`: sensor grades (presets and custom), their error terms;
- :mod:`~imugen.sensors.grade_io`: grade import (Kalibr, VINS, i2Nav, datasheets) and export;
- :mod:`~imugen.sensors.ideal`: the ideal IMU a sensor measures, served in chunks;
- :mod:`~imugen.sensors.model`: the sensor error model (drawn parameters, noise theory), with
  its compiled kernels in :mod:`imugen.sensors._kernel`;
- :mod:`~imugen.sensors.vibration`: vibration of the IMU case;
- :mod:`~imugen.sensors.mounting`: IMU misalignment and lever arm.
"""
