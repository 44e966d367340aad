"""The longitudinal wingbeat map and the once-a-beat regulator on it (the default robofly dove:
no induced flow, so a wingbeat is cheap)."""

import dataclasses

import mujoco
import numpy as np
import pytest

from flapsim.bird.body.model import Dove
from flapsim.bird.control import longitudinal as lo
from flapsim.bird.control.config import ControllerConfig
from flapsim.bird.flight import cycle
from flapsim.bird.flight.dove_flight import DoveFlight, FlightConfig
from flapsim.bird.flight.wingbeat import mirror_params, p0, with_tail_bias
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
    return lo.build_regulator(flight, P0, CFG, r=0.1)


def _settled(fl):
    fl.reset(CFG, P0)
    for _ in range(lo.SETTLE):
        cycle.fly_cycle(fl, None, P0)
    return cycle.snapshot(fl)


def test_the_map_predicts_a_wingbeat_from_a_state_it_was_not_measured_at(flight, regulator):
    """A is measured one state at a time; a start that moves four of them at once (2 deg of
    pitch, 0.1 m/s forward, -0.1 rad/s of pitch rate, the flaps' mean 0.5 deg up) must end
    where superposition puts it. Tolerance 15 % of the change: the steps are 1-2x the
    difference steps, so second-order terms are a few per cent of the first-order ones."""
    start = _settled(flight)
    cycle.restore(flight, start)
    x0 = lo.longitudinal_state(flight)
    cycle.fly_cycle(flight, None, P0)
    y0 = lo.longitudinal_state(flight)
    cycle.restore(flight, start)
    flap = len(lo.TRUNK) + lo.WING_DOFS.index("shoulder_flap")
    for j, eps in ((0, np.radians(2.0)), (1, 0.1), (3, -0.1), (flap, np.radians(0.5))):
        lo.perturb(flight, j, eps)
    dx = lo.longitudinal_state(flight) - x0
    assert dx[0] == pytest.approx(np.radians(2.0), rel=1e-6)  # the perturbation is nose up
    cycle.fly_cycle(flight, None, P0)
    dy = lo.longitudinal_state(flight) - y0
    trunk = slice(0, len(lo.TRUNK))
    dy, predicted = dy[trunk] / lo.STATE_SCALE, (regulator.A @ dx)[trunk] / lo.STATE_SCALE
    assert np.linalg.norm(dy) > 0.1  # the start's change is not lost in one wingbeat
    assert np.linalg.norm(dy - predicted) < 0.15 * np.linalg.norm(dy)


def test_the_trim_is_the_maps_fixed_point(flight, regulator):
    """The trim is extrapolated from one wingbeat through (A - I)^-1: flown on from the settled
    start, the reference wingbeat converges to it. Its slow mode (|lambda| ~0.97, a speed-pitch
    oscillation of ~40 wingbeats' period) leaves 0.97^120 = 0.03 of the start's distance after
    120 wingbeats; asserted within a quarter of it (the rest: the map's nonlinearity between
    the settled start and the trim)."""
    start = _settled(flight)
    cycle.restore(flight, start)
    x0 = lo.longitudinal_state(flight)[:len(lo.TRUNK)]
    for _ in range(120):
        cycle.fly_cycle(flight, None, P0)
    x = lo.longitudinal_state(flight)[:len(lo.TRUNK)]
    xt = regulator.trim[:len(lo.TRUNK)]
    d0 = np.linalg.norm((x0 - xt) / lo.STATE_SCALE)
    assert d0 > 0.05  # the settled start is not yet trimmed: the check can fail
    assert np.linalg.norm((x - xt) / lo.STATE_SCALE) < 0.25 * d0, (x0, x, xt)


def test_the_regulator_damps_the_phugoid_after_a_push_from_behind(flight, regulator):
    """Pushed forward 3 N for 0.1 s (1.8 m/s more speed), the reference wingbeat flown on
    leaves the slow speed-pitch oscillation (the map's largest |eigenvalue| above 0.95) nearly
    undamped; the regulator's closed loop has every eigenvalue within 0.85, so twelve wingbeats
    after the push what is left is below 0.85^12 = 0.14 of it. Asserted on the forward speed's
    distance from the trim over wingbeats 9-12: regulated below half the open loop's."""
    assert regulator.open_loop_radius > 0.95
    assert regulator.closed_loop_radius < 0.85
    trunk = mujoco.mj_name2id(flight.model, mujoco.mjtObj.mjOBJ_BODY, "trunk")
    steps = int(round(0.1 / flight.model.opt.timestep))
    late = {}
    for name, reg in (("open", None), ("regulated", regulator)):
        cycle.restore(flight, _settled(flight))
        dv = []
        for wb in range(13):
            P = P0 if reg is None else P0 + reg.offset(lo.longitudinal_state(flight), reg.trim)
            push = cycle.Push(trunk, np.array([3.0, 0.0, 0.0]), steps) if wb == 0 else None
            cycle.fly_cycle(flight, None, P, push=push)
            dv.append(lo.longitudinal_state(flight)[1] - regulator.trim[1])
        late[name] = np.abs(dv[9:]).max()
    assert late["open"] > 0.2, late
    assert late["regulated"] < 0.5 * late["open"], late


def test_the_regulator_is_off_by_default_and_refused_where_it_cannot_run():
    from flapsim.bird.control.controller import longitudinal_on

    cruise, paper = {"config": {"capture_preset": "cruise"}}, {"config": {"capture_preset": None}}
    default = ControllerConfig()
    assert not longitudinal_on(default, cruise) and not longitudinal_on(default, paper)
    auto = dataclasses.replace(default, longitudinal="auto")
    assert longitudinal_on(auto, cruise) and not longitudinal_on(auto, paper)
    assert longitudinal_on(dataclasses.replace(default, longitudinal="on"), paper)
    for bad in (0.0, -0.1, float("nan")):
        with pytest.raises(InputError, match="longitudinal_r"):
            ControllerConfig(longitudinal_r=bad)
    with pytest.raises(InputError, match="longitudinal must be one of"):
        ControllerConfig(longitudinal="yes")
    with pytest.raises(InputError, match="input cost"):
        lo.build_regulator(None, P0, CFG, r=0.0)


def test_a_controller_with_the_regulator_adds_a_symmetric_change_to_the_reference(flight):
    """Loaded with ``longitudinal = "on"``, the controller's reference for a slowed start is P0
    plus the regulator's offset for that start, and the offset is symmetric (the mirror image
    of P0 + offset is itself: both wings change alike)."""
    from flapsim.bird.control.controller import load_controller, start_cruise
    from flapsim.bird.control.targets import CruiseTarget, trim_of_base_flight

    cfg = dataclasses.replace(ControllerConfig(), longitudinal="on", longitudinal_r=0.1,
                              lookahead="off", carry=0.0)
    ctl = load_controller(flight, config=cfg)
    assert ctl.longitudinal is not None and ctl.lateral is None and ctl.lookahead is None
    trim = trim_of_base_flight(flight, ctl.P0)
    start_cruise(flight, ctl.P0, dataclasses.replace(CFG, speed=6.0))
    offset = ctl.longitudinal.offset(lo.longitudinal_state(flight), ctl.longitudinal.trim)
    assert np.abs(offset).max() > np.radians(0.5)  # 1 m/s slow asks a real correction
    ctl.choose(CruiseTarget(trim, altitude=10.0, speed=7.0))
    np.testing.assert_array_equal(ctl.reference_params(), ctl.P0 + offset)
    np.testing.assert_allclose(mirror_params(ctl.P0 + offset), ctl.P0 + offset, atol=1e-15)
