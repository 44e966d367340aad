"""The rigid dove's turn defaults: how far ahead the path target asks the bank, and how much
more angle of attack it asks per g of a turn's load factor."""

import numpy as np
import pytest

from flapsim.bird.tasks import flight_tasks as tasks
from flapsim.bird.tasks.flight_tasks import (
    DEFAULT_AOA_PER_G_DEG,
    DEFAULT_BANK_LEAD_S,
    Task,
    build_flight,
    fly_task,
)
from flapsim.bird.tasks.path_control import FlightPath
from flapsim.bird.tasks.path_shapes import s_curve


def _median_largest(path: FlightPath, tasks_asked: list[dict]) -> list[float]:
    """Per task options, the median over five starts under 1 mm/s apart of the largest
    distance from the path, m (a flight this tight is chaotic: one run's verdict says little)."""
    fl, ctl = build_flight(Task(path))
    out = []
    try:
        for options in tasks_asked:
            worst = []
            for dv in (0.0, 3e-4, -3e-4, 6e-4, -6e-4):
                r = fly_task(Task(path, start_speed_change=dv, **options), controller=ctl)
                worst.append(r.metrics["max_path_distance"])
            out.append(float(np.median(worst)))
    finally:
        fl.close()
    return out


def test_the_default_lead_follows_an_s_of_3_5_m_half_circles():
    """The S is followed with the rigid dove's default lead and lost with the 0.3 s of
    sessions 10-17, both at the 30 deg per g of angle of attack the lead was chosen with (at
    today's 40 the 0.3 s lead loses less: median 3.35 m over these starts, against 2.28, in
    session 20). Measured with scripts/dove_verdict_spread.py over 10 starts: largest distance
    1.8-3.0 m in 8, 3.3 and 6.5 m in the other two, against 3.8-6.8 m, all lost; over these
    five, medians 2.62 against 6.02 m (2.21 against 5.10 before the start's speed change was
    followed by mj_forward, session 21). The threshold is 3.5 m, half a metre past the 3 m
    tube: a start past it has come 1 in 10 with the default, and none has come under it with
    0.3 s. Both with the bank capped at 45 deg, as the lead was chosen (the rigid dove's
    default is 60 since session 26; with 60 and 30 deg per g the default lead's median here is
    3.54 m, the old lead's 5.58)."""
    assert DEFAULT_BANK_LEAD_S == {"rigid": 0.2, "modal": 0.3}
    default, old = _median_largest(s_curve(),
                                   [{"aoa_per_g_deg": 30.0, "max_bank_deg": 45.0},
                                    {"aoa_per_g_deg": 30.0, "bank_lead_s": 0.3, "max_bank_deg": 45.0}])
    assert default < 3.5 < old, (default, old)


def test_the_default_angle_of_attack_per_g_holds_the_s_where_20_loses_it():
    """A banked wing at the level trim's angle of attack carries cos(bank) of the weight: the
    S's half circles (1.74 g at 7 m/s) need the nose raised in the turn. Over these five starts
    the default 40 deg per g keeps the dove within a median 2.33 m of the path, and 20 deg per
    g loses it (5.10 m; 2.28 and 5.66 before session 21's mj_forward after the start's speed
    change; over ten starts of scripts/dove_verdict_spread.py the S completes 10 times at 40,
    6 at 30 and 2 at 20). Threshold 3.5 m as above: over a metre from either."""
    assert DEFAULT_AOA_PER_G_DEG == {"rigid": 40.0, "modal": 0.0}
    default, low = _median_largest(s_curve(),
                                   [{}, {"aoa_per_g_deg": 20.0}])
    assert default < 3.5 < low, (default, low)


@pytest.mark.parametrize("feathers, lead", [("rigid", 0.2), ("modal", 0.3)])
def test_the_task_asks_the_doves_own_lead_unless_given(feathers, lead, monkeypatch):
    seen = []

    class Spy(tasks.PathTarget):
        def __init__(self, *args, **kwargs):
            seen.append(kwargs["bank_lead_s"])
            raise RuntimeError("seen")

    monkeypatch.setattr(tasks, "PathTarget", Spy)
    path = s_curve()
    for given in (None, 0.05):
        with pytest.raises(RuntimeError, match="seen"):
            tasks.fly_task(Task(path, feathers=feathers, bank_lead_s=given))
    assert seen == [lead, 0.05]


@pytest.mark.parametrize("feathers, cap", [("rigid", 60.0), ("modal", 45.0)])
def test_the_task_asks_the_doves_largest_bank_unless_given(monkeypatch, feathers, cap):
    # session 26 measured 60 deg for the rigid dove (the sharp sinusoid steered wider than the
    # capture on both sides in 15 of 20 starts, 1 of 10 at 45); modal feathers keep the 45 deg
    # they were measured with. A given bank reaches the target as given.
    seen = []

    class Spy(tasks.PathTarget):
        def __init__(self, *args, **kwargs):
            seen.append(kwargs.get("max_bank_deg"))
            raise RuntimeError("seen")

    monkeypatch.setattr(tasks, "PathTarget", Spy)
    for given in (None, 50.0):
        with pytest.raises(RuntimeError, match="seen"):
            tasks.fly_task(Task(s_curve(), feathers=feathers, max_bank_deg=given))
    assert seen == [cap, 50.0]


def test_the_default_bank_steers_the_sharp_sinusoid_wider_than_the_capture_on_both_sides():
    """Issue #14's acceptance: the sinusoid's steering range wider than the capture set's. The
    capture turned -12.5..+7.0 deg per wingbeat (its fitted cycles, computed here from the
    capture itself). sinusoid-sharp asks ~33 deg per wingbeat, flown and mirrored. Its largest
    right turn in the tube over 20 starts under 1 mm/s apart with the 60 deg cap: 12.4-14.9
    deg, mean 13.1, SD 0.7 (past 12.5 in 15); with 45 deg over 10 starts: 11.5-12.5, mean
    11.9, SD 0.4. So the mean over three starts is past -12.5 at 60 deg (odds of a mean of
    three under it, were the starts of another processor drawn from the same spread: ~6 %),
    and not at 45 (~0.5 %). The left side (the mirror flight's) turns 12-15 deg against the
    capture's 7.0."""
    from flapsim import scenarios
    from flapsim.scenarios.flight import capture_steering_range

    capture = capture_steering_range()
    assert capture == pytest.approx([-12.5, 7.0], abs=0.05)  # the paper's capture, as fitted
    sc = scenarios.get("sinusoid-sharp")
    right, left = [], []
    for dv in (0.0, 3e-4, -3e-4):
        res = sc.runner(sc, scenarios.EvalOptions(start_speed_change=dv))
        lo, hi = res["metrics"]["steering_range_in_tube_both_ways_deg"]
        right.append(lo)
        left.append(hi)
    assert np.mean(right) < capture[0] and np.mean(left) > capture[1], (right, left)


def test_a_result_records_the_path_targets_settings_as_flown():
    """Every flown task (and so every eval run's JSON, under ``path_target``) says what the
    target asked under, with the dove's defaults resolved: None in a Task means 60 deg, 0.2 s
    and 40 deg per g for the rigid dove (the tables above); a given value is recorded as given."""
    from flapsim.scenarios.flight import _summary

    fl, ctl = build_flight(Task(s_curve()))
    try:
        default = fly_task(Task(s_curve(), max_wingbeats=1), controller=ctl)
        given = fly_task(Task(s_curve(), max_wingbeats=1, max_bank_deg=50.0, bank_lead_s=0.1),
                         controller=ctl)
    finally:
        fl.close()
    assert len(default.quats) == 1
    t = default.path_target
    assert (t["max_bank_deg"], t["bank_lead_s"], t["aoa_per_g_deg"], t["speed"]) == (60.0, 0.2, 40.0, 7.0)
    assert (given.path_target["max_bank_deg"], given.path_target["bank_lead_s"]) == (50.0, 0.1)
    assert _summary(given)["path_target"] == given.path_target
