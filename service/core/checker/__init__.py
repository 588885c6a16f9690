"""The pass-fail checker: the traffic rules of a control type (``rules``, over asp/), the
judge of an ego trajectory (``check``) and its verdict as data (``verdict``)."""
