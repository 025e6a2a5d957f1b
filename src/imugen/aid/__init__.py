"""Aid stage: GNSS with scenarios, companion sensors and the aided (GNSS/INS) navigation.

:mod:`~imugen.aid.stage` is the face (``imugen aid``); :mod:`~imugen.aid.gnss` the receiver
model, :mod:`~imugen.aid.scenarios` outages, jamming and spoofing,
:mod:`~imugen.aid.companions` the odometer and barometer, :mod:`imugen.aid.filter` the
loosely-coupled error-state filter.
"""
