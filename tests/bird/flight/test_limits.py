"""The sustained-turn and climb limits (flapsim.bird.flight.limits): closed forms and the selection."""

import math

import numpy as np
import pytest

from flapsim.bird.body.params import DOF_NAMES
from flapsim.bird.flight.limits import (
    GRAVITY,
    Candidate,
    TunnelPoint,
    best_sustained,
    climb_angle_deg,
    load_factor_for_radius,
    turn_radius,
)
from flapsim.bird.flight.wingbeat import p0, with_tail_bias
from flapsim.core.errors import InputError


def test_turn_radius_closed_form():
    # n = sqrt(2): the sideways lift equals the weight, so v^2 / r = g (a 45 deg bank)
    assert turn_radius(math.sqrt(2.0), 7.0) == pytest.approx(49.0 / GRAVITY, rel=1e-12)
    # n = 1.25: sqrt(n^2 - 1) = 0.75 exactly
    assert turn_radius(1.25, 6.0) == pytest.approx(36.0 / (GRAVITY * 0.75), rel=1e-12)
    assert turn_radius(1.0, 7.0) == math.inf
    assert turn_radius(0.8, 7.0) == math.inf
    for r, v in ((3.0, 5.0), (3.6, 7.0), (10.0, 8.0)):
        assert turn_radius(load_factor_for_radius(r, v), v) == pytest.approx(r, rel=1e-12)
    # the paper's 3.6 m circle at 7 m/s: a 54 deg bank, n = 1 / cos(bank)
    bank = math.degrees(math.acos(1.0 / load_factor_for_radius(3.6, 7.0)))
    assert bank == pytest.approx(math.degrees(math.atan(49.0 / (GRAVITY * 3.6))), abs=1e-9)
    with pytest.raises(InputError):
        turn_radius(float("nan"), 7.0)
    with pytest.raises(InputError):
        load_factor_for_radius(0.0, 7.0)


def test_climb_angle():
    # 30 deg: thrust 1/2 and lift cos 30 = 0.866 of the weight
    assert climb_angle_deg(0.9, 0.5) == pytest.approx(30.0, abs=1e-9)
    assert climb_angle_deg(math.sqrt(3) / 2, 0.5) == pytest.approx(30.0, abs=1e-9)
    assert climb_angle_deg(0.8, 0.5) is None  # not enough lift for that climb
    # a thrust deficit holds only a glide: asin(-0.1) = -5.74 deg
    assert climb_angle_deg(1.0, -0.1) == pytest.approx(math.degrees(math.asin(-0.1)), abs=1e-9)


def test_candidate_params():
    P0 = with_tail_bias(p0(), 17.0)
    assert np.array_equal(Candidate(1.0, 1.0, 0.0).params(P0), P0)
    P = Candidate(1.2, 0.9, -3.0).params(P0)
    changed = {i for i in range(len(P0)) if P[i] != P0[i]}
    flap = [2 * DOF_NAMES.index(f"{s}_shoulder_flap") for s in "lr"]
    twist = [2 * DOF_NAMES.index(f"{s}_shoulder_twist") + 1 for s in "lr"]
    assert changed == set(flap) | set(twist) | {len(P0) - 1}
    assert P[flap] == pytest.approx([1.2, 1.2])
    assert P[twist] == pytest.approx(np.radians([-3.0, -3.0]))
    assert P[-1] == pytest.approx(0.9)


def _pt(v, lift, thrust, flap=1.0, excess=0.0):
    return TunnelPoint(v, 5.0, flap, 1.0, 0.0, lift, thrust, excess)


def test_best_sustained_keeps_held_in_range_wingbeats():
    pts = [
        _pt(7.0, 1.30, -0.10),         # more lift but slows: not held at constant speed
        _pt(7.0, 1.15, 0.02, 1.1),     # the best held one
        _pt(7.0, 1.05, 0.20, 1.2),     # the best climber: asin(0.2) = 11.5 deg
        _pt(7.0, float("nan"), float("nan"), 1.3, 5.0),  # out of range: never counts
        _pt(5.0, 0.90, 0.05),          # too little lift to turn at all
    ]
    b = best_sustained(pts)
    r7 = next(r for r in b["per_speed"] if r["speed"] == 7.0)
    assert r7["max_load_factor"] == pytest.approx(1.15)
    assert r7["tightest_turn_m"] == pytest.approx(49.0 / (GRAVITY * math.sqrt(1.15 ** 2 - 1)))
    assert r7["steepest_climb_deg"] == pytest.approx(math.degrees(math.asin(0.2)))
    assert r7["wingbeats_in_range"] == 3
    r5 = next(r for r in b["per_speed"] if r["speed"] == 5.0)
    assert r5["max_load_factor"] == pytest.approx(0.90) and r5["tightest_turn_m"] is None
    assert b["tightest_turn_speed"] == 7.0
    # a thrust floor below the slowing wingbeat's deficit admits it
    b2 = best_sustained(pts, thrust_floor=-0.1)
    r7 = next(r for r in b2["per_speed"] if r["speed"] == 7.0)
    assert r7["max_load_factor"] == pytest.approx(1.30)


def test_free_flight_range_excess_is_the_joints_own_overshoot():
    """The search keeps a wingbeat by the database's rule; its excess equals a brute-force
    overshoot from MuJoCo's joint ranges and the recorded joint angles of the same wingbeat,
    is nil for the reference wingbeat, and exceeds the tolerance for a wide, fast beat (the
    flap x1.25 beat 10 % faster twists the left elbow 7 deg past its -30 deg end)."""
    import mujoco

    from flapsim.bird.body.model import Dove
    from flapsim.bird.flight import cycle
    from flapsim.bird.flight.dove_flight import DoveFlight, FlightConfig
    from flapsim.bird.flight.limits import free_flight_range_excess
    from flapsim.bird.flight.wingbeat import RANGE_TOLERANCE, reference_wingbeat

    fl = DoveFlight(Dove.load(), reference_wingbeat())
    try:
        P0 = with_tail_bias(p0(), FlightConfig.tail_bias_deg)
        wide = Candidate(1.25, 0.9, 0.0).params(P0)
        assert free_flight_range_excess(fl, P0, 7.0) <= RANGE_TOLERANCE
        got = free_flight_range_excess(fl, wide, 7.0)
        assert got > RANGE_TOLERANCE
        # brute force: fly the same two wingbeats, record every step, compare every limited
        # hinge joint of the 14 DOF with its range
        fl.reset(FlightConfig(speed=7.0), P0)
        start = cycle.fly_cycle(fl, cycle.snapshot(fl), P0, fl.ref).snapshot
        e = cycle.fly_cycle(fl, start, wide, fl.ref, record=True)
        m = fl.model
        worst = 0.0
        checked = 0
        for name in DOF_NAMES:
            j = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, name)
            if j < 0 or not m.jnt_limited[j]:
                continue  # the tail spread is a tendon
            checked += 1
            lo, hi = m.jnt_range[j]
            q = e.qpos[:, m.jnt_qposadr[j]]
            worst = max(worst, float(np.max(q - hi)), float(np.max(lo - q)))
        assert checked >= 12
        assert got == pytest.approx(worst, abs=1e-12)
    finally:
        fl.close()
