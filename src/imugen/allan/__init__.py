"""Allan stage: Allan deviation of a static shard against its grade
(:mod:`~imugen.allan.stage`: ``imugen allan``)."""
