"""Figures stage: the route figures (:mod:`~imugen.figures.stage`: ``imugen figures``), the
outage figure (:mod:`~imugen.figures.outage`: ``imugen outage-figure``), the drift at the end
of each outage (:mod:`~imugen.figures.outage_drift`: ``imugen outage-drift``) and the map beneath
them (:mod:`~imugen.figures.mapview`)."""
