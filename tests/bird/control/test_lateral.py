"""The lateral wingbeat map and the once-a-beat regulator on it (the default robofly dove:
no induced flow, so a wingbeat is cheap)."""

import dataclasses

import mujoco
import numpy as np
import pytest

from flapsim.bird.body.model import Dove
from flapsim.bird.control import lateral
from flapsim.bird.control.config import ControllerConfig
from flapsim.bird.flight import cycle
from flapsim.bird.flight.dove_flight import DoveFlight, FlightConfig
from flapsim.bird.flight.wingbeat import p0, with_tail_bias
from flapsim.core.errors import InputError

#: this module's flight keeps its feather forces registered from test to test (conftest)
SHARED_FLIGHT = True
CFG = FlightConfig()
P0 = with_tail_bias(p0(), CFG.tail_bias_deg)


@pytest.fixture(scope="module")
def flight():
    fl = DoveFlight(Dove.load())
    yield fl
    fl.close()


@pytest.fixture(scope="module")
def regulator(flight):
    return lateral.build_regulator(flight, P0, CFG, r=0.3)


def _settled(fl):
    fl.reset(CFG, P0)
    for _ in range(lateral.SETTLE):
        cycle.fly_cycle(fl, None, P0)
    return cycle.snapshot(fl)


def test_the_map_predicts_a_wingbeat_from_a_state_it_was_not_measured_at(flight, regulator):
    """A is measured one state at a time; a start that moves four of them at once (2 deg of
    roll, 0.1 m/s sideways, -0.1 rad/s of yaw rate, the shoulders' twist 0.5 deg apart) must
    end where superposition puts it. Tolerance 15 % of the change: the steps are 1-2x the
    difference steps, so second-order terms are a few per cent of the first-order ones."""
    start = _settled(flight)
    cycle.restore(flight, start)
    x0 = lateral.lateral_state(flight)
    cycle.fly_cycle(flight, None, P0)
    y0 = lateral.lateral_state(flight)
    cycle.restore(flight, start)
    twist = 4 + lateral.WING_DOFS.index("shoulder_twist")
    for j, eps in ((0, np.radians(2.0)), (1, 0.1), (3, -0.1), (twist, np.radians(0.5))):
        lateral.perturb(flight, j, eps)
    dx = lateral.lateral_state(flight) - x0
    cycle.fly_cycle(flight, None, P0)
    dy = lateral.lateral_state(flight) - y0
    predicted = regulator.A @ dx
    trunk = slice(0, len(lateral.TRUNK))
    assert np.linalg.norm(dy[trunk]) > 0.05  # the start's change is not lost in one wingbeat
    assert np.linalg.norm(dy[trunk] - predicted[trunk]) < 0.15 * np.linalg.norm(dy[trunk])


def test_lqr_gain_is_the_scalar_riccati_solution():
    """Each trunk state driven by its own input, x' = a x + b u with cost x^2/s^2 + r u^2: the
    scalar Riccati equation X = a^2 X - (a b X)^2 / (r + b^2 X) + 1/s^2 has the positive root
    below, and K = a b X / (r + b^2 X) (closed form, per channel)."""
    n = lateral.N_STATE
    a = np.array([1.3, 0.8, 0.5, 1.1])
    b, r = 0.4, 0.3
    A = np.zeros((n, n))
    A[:4, :4] = np.diag(a)
    B = np.zeros((n, 12))
    B[:4, :4] = b * np.eye(4)
    K = lateral.lqr(A, B, r)
    q = 1.0 / lateral.STATE_SCALE ** 2
    # b^2 X^2 + (r (1 - a^2) - q b^2) X - q r = 0
    c1 = r * (1 - a ** 2) - q * b ** 2
    X = (-c1 + np.sqrt(c1 ** 2 + 4 * b ** 2 * q * r)) / (2 * b ** 2)
    np.testing.assert_allclose(np.diag(K[:4, :4]), a * b * X / (r + b ** 2 * X), rtol=1e-8)
    assert np.abs(K[4:, :]).max() < 1e-9 and np.abs(K[:4, 4:]).max() < 1e-9


def test_the_regulator_levels_a_pushed_dove_that_the_reference_wingbeat_lets_roll(flight, regulator):
    """Pushed 3 N sideways for 0.1 s, the reference wingbeat flown on lets the dove roll on
    (the map's largest eigenvalue is above 1: an unstable lateral mode); the regulator's
    closed loop has every eigenvalue within 0.8, so eight wingbeats after the push what is
    left is below 0.8^8 = 0.17 of it. Asserted over the last four of ten wingbeats: open loop
    past 15 deg of roll, regulated within 8 deg throughout (about half the 15 deg that the
    push's wingbeat and the next two reach; measured 4.4 deg at most, where the regulator's
    sign flipped swings the dove through +-50 deg)."""
    assert regulator.open_loop_radius > 1.0
    assert regulator.closed_loop_radius < 0.8
    trunk = mujoco.mj_name2id(flight.model, mujoco.mjtObj.mjOBJ_BODY, "trunk")
    steps = int(round(0.1 / flight.model.opt.timestep))
    ends = {}
    for name, reg in (("open", None), ("regulated", regulator)):
        start = _settled(flight)
        cycle.restore(flight, start)
        x_ref = np.zeros(lateral.N_STATE)
        rolls = []
        for wb in range(10):
            P = P0 if reg is None else P0 + reg.offset(lateral.lateral_state(flight), x_ref)
            push = cycle.Push(trunk, np.array([0.0, 3.0, 0.0]), steps) if wb == 0 else None
            cycle.fly_cycle(flight, None, P, push=push)
            rolls.append(np.degrees(flight.reduced_state()[1]))
        ends[name] = rolls
    assert np.abs(ends["open"][-4:]).max() > 15.0
    assert np.abs(ends["regulated"][-4:]).max() < 8.0


def test_the_regulator_is_on_for_cruise_databases_only_and_refused_where_it_cannot_run():
    from flapsim.bird.control.controller import lateral_on

    cruise, paper = {"config": {"capture_preset": "cruise"}}, {"config": {"capture_preset": None}}
    auto = ControllerConfig()
    assert auto.lateral == "auto"
    assert lateral_on(auto, cruise) and not lateral_on(auto, paper) and not lateral_on(auto, {})
    assert lateral_on(dataclasses.replace(auto, lateral="on"), paper)
    assert not lateral_on(dataclasses.replace(auto, lateral="off"), cruise)
    for bad in (0.0, -0.1, float("nan")):
        with pytest.raises(InputError, match="lateral_r"):
            ControllerConfig(lateral_r=bad)
    with pytest.raises(InputError, match="lateral must be one of"):
        ControllerConfig(lateral="yes")
    with pytest.raises(InputError, match="input cost"):
        lateral.build_regulator(None, P0, CFG, r=0.0)


def test_a_controller_with_the_regulator_adds_it_to_the_reference(flight):
    """Loaded with ``lateral_r``, the controller's reference for a rolled start is P0 plus the
    regulator's offset for that start, and the offset is antisymmetric (the mirror image of
    P0 + offset is P0 - offset: the left wing's change is minus the right's)."""
    from flapsim.bird.control.controller import load_controller, start_cruise
    from flapsim.bird.control.targets import CruiseTarget, trim_of_base_flight
    from flapsim.bird.flight.wingbeat import mirror_params

    cfg = dataclasses.replace(ControllerConfig(), lateral="on", lateral_r=0.3, lookahead="off",
                              carry=0.0)
    ctl = load_controller(flight, config=cfg)
    assert ctl.lateral is not None and ctl.lookahead is None
    trim = trim_of_base_flight(flight, ctl.P0)
    start_cruise(flight, ctl.P0, CFG, roll_deg=10.0)
    offset = ctl.lateral.offset(lateral.lateral_state(flight), np.zeros(lateral.N_STATE))
    assert np.abs(offset).max() > np.radians(0.5)  # a 10 deg roll asks a real correction
    ctl.choose(CruiseTarget(trim, altitude=10.0, speed=7.0))
    np.testing.assert_array_equal(ctl.reference_params(), ctl.P0 + offset)
    np.testing.assert_allclose(mirror_params(ctl.P0 + offset), ctl.P0 - offset, atol=1e-15)
