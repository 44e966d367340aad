"""The rigid dove's turn defaults: how far ahead the path target asks the bank, and how much
more angle of attack it asks per g of a turn's load factor."""

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

STARTS = (0.0, 3e-4, -3e-4, 6e-4, -6e-4)  # m/s of start speed: five starts under 1 mm/s apart


def _flights(path: FlightPath, tasks_asked: list[dict]) -> list[list]:
    """Per task options, the flights (task results) from each of :data:`STARTS`. A flight this
    tight is chaotic: one start's verdict says little, and the same start differs between
    processors (the 20 deg per g flight below ended 5.10 m off at most on one and 3.44 on
    another), so the claims are counts over the starts with wide margins."""
    fl, ctl = build_flight(Task(path))
    out = []
    try:
        for options in tasks_asked:
            out.append([fly_task(Task(path, start_speed_change=dv, **options), controller=ctl)
                         for dv in STARTS])
    finally:
        fl.close()
    return out


@pytest.mark.slow
def test_the_default_lead_keeps_the_dove_closer_to_an_s_of_3_5_m_half_circles():
    """The rigid dove's default bank lead (0.2 s) against the 0.3 s it replaced, both at the 30
    deg per g of angle of attack and the 45 deg bank cap the lead was chosen with. Measured over
    seven starts under 1 mm/s apart: largest distances 2.3-2.7 m on six and 5.4 m on one with
    0.2 s (six completed), 3.8-6.2 m with 0.3 s (none completed), 0.2 s the closer on every
    start; another processor gave medians 2.62 against 6.02 m. Asserted: 0.2 s is the closer
    on at least three of the five starts (a lead that did nothing would tie on all five), and
    completes at least two of them (six of seven here, eight of ten there: fewer than two of
    five happens by chance under 1 % of the time at either rate)."""
    assert DEFAULT_BANK_LEAD_S == {"rigid": 0.2, "modal": 0.3}
    default, old = [[r.metrics["max_path_distance"] for r in flights] for flights in _flights(
        s_curve(), [{"aoa_per_g_deg": 30.0, "max_bank_deg": 45.0},
                    {"aoa_per_g_deg": 30.0, "bank_lead_s": 0.3, "max_bank_deg": 45.0}])]
    assert sum(d < o for d, o in zip(default, old, strict=True)) >= 3, (default, old)
    assert sum(d <= Task(s_curve()).tube_m for d in default) >= 2, default


def _seconds_in_tube(r, path: FlightPath, tube_m: float) -> float:
    """Simulated seconds from the start until a wingbeat first ends outside the tube (the whole
    flight if none does)."""
    off = [path.distance(p) > tube_m for p in r.positions]
    end = off.index(True) if True in off else len(off) - 1
    return float(r.times[end] - r.times[0])


@pytest.mark.slow
def test_the_default_angle_of_attack_per_g_holds_the_dove_through_the_s():
    """A banked wing at the level trim's angle of attack carries cos(bank) of the weight: the
    S's half circles (1.74 g at 7 m/s) need the nose raised in the turn. Without it (0 deg per
    g) the dove sinks out of the first half circle: it leaves the 3 m tube 2.3-2.4 s after the
    start on five of five starts (and is stopped 15 m off); with the nose lowered instead of
    raised (the sign flipped) it leaves at 1.8 s. With the default 40 deg per g it stays in
    the tube past 4.8 s on all five (three to the S's end at ~5 s, two leave it at 4.8 and 5.4
    s, in the last turn). Asserted as counts with 3.5 s between them, over a second from
    either: at least four of five default starts stay in the tube 3.5 s, at most one of five
    without the nose raised does. (That 40 holds the S in the tube where 20 loses it, as
    measured once, is not asserted: the 20 deg per g flight is on the edge, 3.0-15.7 m off at
    most over seven starts here, two completed, and a median 3.44 m here against 5.10 m on
    another processor.)"""
    assert DEFAULT_AOA_PER_G_DEG == {"rigid": 40.0, "modal": 0.0}
    path = s_curve()
    tube = Task(path).tube_m
    default, none = _flights(path, [{}, {"aoa_per_g_deg": 0.0}])
    held = [_seconds_in_tube(r, path, tube) for r in default]
    dropped = [_seconds_in_tube(r, path, tube) for r in none]
    assert sum(t >= 3.5 for t in held) >= 4, held
    assert sum(t >= 3.5 for t in dropped) <= 1, dropped


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
    # 60 deg for the rigid dove: the sharp sinusoid steered wider than the capture on both
    # sides in 15 of 20 starts with it, 1 of 10 at 45; modal feathers keep the 45 deg they
    # were measured with. A given bank reaches the target as given.
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


def test_a_result_records_the_path_targets_settings_as_flown():
    """Every flown task (and so every eval run's JSON, under ``path_target``) says what the
    target asked under, with the dove's defaults resolved: None in a Task means 60 deg, 0.2 s,
    40 deg per g and a 15 deg climb for the rigid dove (the tables above); a given value is
    recorded as given."""
    from flapsim.scenarios.flight import _summary

    fl, ctl = build_flight(Task(s_curve()))
    try:
        default = fly_task(Task(s_curve(), max_wingbeats=1), controller=ctl)
        given = fly_task(Task(s_curve(), max_wingbeats=1, max_bank_deg=50.0, bank_lead_s=0.1,
                              max_climb_deg=35.0), controller=ctl)
    finally:
        fl.close()
    assert len(default.quats) == 1
    t = default.path_target
    assert (t["max_bank_deg"], t["bank_lead_s"], t["aoa_per_g_deg"], t["speed"]) == (60.0, 0.2, 40.0, 7.0)
    assert t["max_climb_deg"] == 15.0
    g = given.path_target
    assert (g["max_bank_deg"], g["bank_lead_s"], g["max_climb_deg"]) == (50.0, 0.1, 35.0)
    assert _summary(given)["path_target"] == given.path_target
