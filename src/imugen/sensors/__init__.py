"""The sensor library every stage may use (it imports no stage).

- :mod:`~imugen.sensors.grades`: sensor grades (presets and custom), their error terms;
- :mod:`~imugen.sensors.grade_io`: grade import (Kalibr, VINS, i2Nav, datasheets) and export;
- :mod:`~imugen.sensors.ideal`: the ideal IMU a sensor measures, served in chunks;
- :mod:`~imugen.sensors.model`: the sensor error model (drawn parameters, noise theory), with
  its compiled kernels in :mod:`imugen.sensors._kernel`;
- :mod:`~imugen.sensors.vibration`: vibration of the IMU case;
- :mod:`~imugen.sensors.mounting`: IMU misalignment and lever arm;
- :mod:`~imugen.sensors.bandwidth`: output bandwidth (internal rate, low-pass, decimation),
  its closed forms and the stream the simulator applies before quantization;
- :mod:`~imugen.sensors.fit`: ``imugen grade fit`` (a grade from a still log), with the noise
  terms' closed forms and simulator in :mod:`~imugen.sensors.noise_terms` and the log readers
  in :mod:`~imugen.sensors.imu_log`.
"""
