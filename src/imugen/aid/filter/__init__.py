"""The loosely-coupled error-state Kalman filter of the aid stage (GNSS/INS, NHC, ZUPT,
odometer, barometer); today in one module, :mod:`imugen.aid.filter.ekf`."""
