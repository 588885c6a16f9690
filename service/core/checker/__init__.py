"""The pass-fail checker: the traffic rules of a control type (``rules``, over asp/), the
judge of an ego trajectory (``check``), people on foot as it sees them (``pedestrians``) and
its verdict as data (``verdict``)."""
