"""Figures stage: the route figures (:mod:`~imugen.figures.stage`: ``imugen figures``), the
outage figure (:mod:`~imugen.figures.outage`: ``imugen outage-figure``) and the map beneath
them (:mod:`~imugen.figures.mapview`)."""
