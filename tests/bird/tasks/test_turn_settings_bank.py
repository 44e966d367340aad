"""The rigid dove's default bank cap flown on the sharp sinusoid: its steering range per
wingbeat against the capture set's."""

import numpy as np
import pytest


@pytest.mark.slow
def test_the_default_bank_steers_the_sharp_sinusoid_about_as_far_as_the_capture_both_ways():
    """The steering range flown against the capture set's. The capture turned -12.5..+7.0 deg
    per wingbeat (its fitted cycles, computed here from the capture itself). sinusoid-sharp
    asks ~33 deg per wingbeat, flown and mirrored (both ways turn alike within ~1 deg). Its
    largest right turn in the tube with the rigid dove's 60 deg bank cap: 12.4-14.9 deg over
    20 starts under 1 mm/s apart on one processor (mean 13.1, SD 0.7), 12.7-14.1 over four on
    another. Asserted: at least 11 deg each way in the mean of two starts, over 2 SDs of one
    start below the lowest seen, so past the capture's left turn by 4 deg and within 1.5 of
    its right (a cap of 24 deg turns 4.1-4.5). That the right turn passes the capture's 12.5,
    as measured, is not asserted: the means lie 0.4-0.7 deg past it, within one start's SD."""
    from flapsim import scenarios
    from flapsim.scenarios.flight import capture_steering_range

    capture = capture_steering_range()
    assert capture == pytest.approx([-12.5, 7.0], abs=0.05)  # the paper's capture, as fitted
    sc = scenarios.get("sinusoid-sharp")
    right, left = [], []
    for dv in (0.0, 3e-4):
        res = sc.runner(sc, scenarios.EvalOptions(start_speed_change=dv))
        lo, hi = res["metrics"]["steering_range_in_tube_both_ways_deg"]
        right.append(lo)
        left.append(hi)
    assert np.mean(right) < -11.0 and np.mean(left) > 11.0, (right, left)
