"""The lane a part travels: the fence configurations, the fences as built from the ``scene``
settings, and the settings themselves. Pure descriptions, shared by the simulator (``sim``) and
the analytic mechanics (``mechanics``)."""
