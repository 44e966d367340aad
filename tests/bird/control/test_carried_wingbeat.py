"""The wingbeat carry (WingbeatController.carry): each wingbeat starts from P0 plus a share
of the last one's change, is simulated from there for S0, and the regression's answer is
added to it."""

import numpy as np
import pytest

from flapsim.bird.body.model import Dove
from flapsim.bird.body.params import DOF_NAMES
from flapsim.bird.control.config import DEFAULT_CARRY, ControllerConfig
from flapsim.bird.control.controller import WingbeatController, load_controller
from flapsim.bird.control.regression import Regressor
from flapsim.bird.flight import cycle
from flapsim.bird.flight.dove_flight import DoveFlight, FlightConfig
from flapsim.bird.flight.wingbeat import N_PARAMS, p0, with_tail_bias
from flapsim.cli.main import main
from flapsim.core.errors import InputError

#: this module's flight keeps its feather forces registered from test to test (conftest)
SHARED_FLIGHT = True

#: the constant answer: the tail bent 0.01 rad more (well inside every range)
D = np.zeros(N_PARAMS)
D[2 * DOF_NAMES.index("tail_bend") + 1] = 0.01


@pytest.fixture(scope="module")
def flight():
    fl = DoveFlight(Dove.load())
    yield fl
    fl.close()


def _controller(flight, carry):
    rng = np.random.default_rng(0)
    # a regression whose database spans +-1 in every dP (so nothing carried is clipped),
    # answering every request with D
    reg = Regressor(rng.normal(size=(200, 8)), rng.uniform(-1, 1, (200, N_PARAMS)), k=50,
                    method="lwlr")
    reg.predict = lambda x, s=None: D.copy()
    P0 = with_tail_bias(p0(), FlightConfig.tail_bias_deg)
    return WingbeatController(flight, reg, P0, carry=carry)


@pytest.mark.parametrize("carry", [0.0, 0.5, 1.0])
def test_the_carried_change_is_a_geometric_sum(flight, carry):
    # wingbeat n flies P0 + D (1 + c + ... + c^(n-1)); its S0 is the simulation of the
    # reference P0 + c (P_last - P0) from the same state (to round-off)
    ctl = _controller(flight, carry)
    flight.reset(FlightConfig(), ctl.P0)
    ctl.reset()
    last = None
    for n in range(1, 4):
        snap = cycle.snapshot(flight)
        step = ctl.choose(lambda e0: e0.S, snap)
        expect = sum(carry ** i for i in range(n))
        np.testing.assert_allclose(step.P - ctl.P0, expect * D, atol=1e-15)
        base = ctl.P0 if last is None else ctl.P0 + carry * (last - ctl.P0)
        ref = cycle.fly_cycle(flight, snap, base, ctl.ref)
        np.testing.assert_allclose(step.reference.S, ref.S, atol=1e-12)
        cycle.restore(flight, step.end.snapshot)
        last = step.P
    ctl.reset()  # a new flight starts from P0 again
    flight.reset(FlightConfig(), ctl.P0)
    np.testing.assert_allclose(ctl.choose(lambda e0: e0.S).P - ctl.P0, D, atol=1e-15)


def test_carry_options_are_checked(flight, capsys, tmp_path):
    assert all(0.0 <= c <= 1.0 for c in DEFAULT_CARRY.values())
    for bad in (-0.1, 1.5, float("nan")):
        with pytest.raises(InputError, match="carry"):
            _controller(flight, bad)
        with pytest.raises(InputError, match="carry must be a share 0..1"):
            load_controller(flight, carry=bad)
    with pytest.raises(InputError, match="carry needs S0 simulated"):
        load_controller(flight, carry=0.5, predict="regression")
    # the default carries nothing where S0 is predicted for P0 alone
    assert load_controller(flight, predict="regression").carry == 0.0
    assert ControllerConfig.for_dove("rigid", predict="regression").carry == 0.0
    assert load_controller(flight, carry=0.3).carry == 0.3
    assert load_controller(flight, config=ControllerConfig(carry=0.3)).carry == 0.3
    assert load_controller(flight).carry == DEFAULT_CARRY["rigid"] == ControllerConfig().carry == 0.4
    config = tmp_path / "carry.toml"
    config.write_text("[controller]\ncarry = 2\n")
    for command in (["eval", "--scenario", "figure8-level"], ["fly", "--controller", "learned"]):
        assert main([*command, "--config", str(config)]) == 2
        err = capsys.readouterr().err.strip()
        assert "carry must be a share 0..1" in err and "carry.toml" in err and "\n" not in err


def test_the_coarse_prediction_flies_the_carried_reference(flight):
    # with S0 simulated on the coarse copy, the copy flies P0 + c (P_last - P0) too
    from flapsim.bird.control.prediction import CoarsePredictor

    ctl = _controller(flight, 0.5)
    ctl.predictor = CoarsePredictor()
    flight.reset(FlightConfig(), ctl.P0)
    ctl.reset()
    step = ctl.choose(lambda e0: e0.S)
    cycle.restore(flight, step.end.snapshot)
    snap = cycle.snapshot(flight)
    step2 = ctl.choose(lambda e0: e0.S, snap)
    twin = ctl.predictor._twin
    ref = cycle.fly_cycle(twin, snap, ctl.P0 + 0.5 * (step.P - ctl.P0), ctl.ref)
    np.testing.assert_allclose(step2.reference.S, ref.S, atol=1e-12)
    np.testing.assert_allclose(step2.P - ctl.P0, 1.5 * D, atol=1e-15)
