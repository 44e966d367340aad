"""Open-loop flight: the wingbeat, the capture it comes from, one wingbeat from any state,
the simulated flight and its analyses (power, limits, calibration, video)."""
