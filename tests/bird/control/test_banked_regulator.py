"""The banked lateral regulator (``lateral = "banked"``): integral action on the roll error,
gains scheduled on the bank, the turn trims it is designed around, the banked start state,
and the left-right symmetric answer beside it."""

import json

import mujoco
import numpy as np
import pytest

from flapsim.bird.body.model import Dove
from flapsim.bird.control import lateral
from flapsim.bird.control.config import ControllerConfig
from flapsim.bird.control.controller import bundled_database_path, load_controller
from flapsim.bird.flight import cycle
from flapsim.bird.flight.dove_flight import CRUISE, DoveFlight, FlightConfig
from flapsim.bird.flight.wingbeat import mirror_params, p0, with_tail_bias
from flapsim.core.errors import DataFileError, InputError

SHARED_FLIGHT = True
N = lateral.N_STATE


def _toy_map():
    """A lateral map with the cruise dove's kind of trouble: roll grows 1.3x a wingbeat, one
    input rolls the trunk (and nothing else couples), the other states decay."""
    A = np.diag(np.r_[1.3, np.full(N - 1, 0.5)])
    B = np.zeros((N, 12))
    B[0, 0] = np.radians(3.0)  # one step: 3 deg of roll, as the shoulders' twist does
    return A, B


def _regulator(A, B, z_scale):
    K = lateral.integral_lqr(A, B, 0.01, z_scale)
    return lateral.BankedRegulator(np.radians([0.0, 30.0]), np.stack([K, K]),
                                   np.eye(12, 29), A, B, z_scale)


def test_the_integral_works_off_a_steady_roll_error_that_the_proportional_gain_leaves():
    """A steady roll disturbance d (what holding a bank asks of a steady input) leaves the
    proportional LQR the closed-form steady error (I - A + B K)^-1 d; with the roll summed
    (z' = z + roll error) the only steady state has no roll error. Tolerance 1e-6 deg: the
    closed loop's slowest mode decays within the 400 wingbeats flown to far below it."""
    A, B = _toy_map()
    d = np.zeros(N)
    d[0] = np.radians(2.0)
    target = np.zeros(N)
    target[0] = np.radians(20.0)
    K = lateral.lqr(A, B, 0.01)
    steady = np.linalg.solve(np.eye(N) - A + B @ K, d + (A - np.eye(N) - B @ K) @ -target)
    assert abs(np.degrees(steady[0] - target[0])) > 0.5  # the error the integral must remove
    reg = _regulator(A, B, np.radians(40.0))
    x = np.zeros(N)
    for _ in range(400):
        u = reg.offset(x, target)[:12]
        x = A @ x + B @ u + d
    assert abs(np.degrees(x[0] - target[0])) < 1e-6
    # the augmented closed loop is stable (spectral radius < 1)
    Ka = lateral.integral_lqr(A, B, 0.01, np.radians(40.0))
    Aa = np.block([[A, np.zeros((N, 1))], [np.eye(1, N), np.ones((1, 1))]])
    Ba = np.vstack([B, np.zeros((1, 12))])
    assert np.abs(np.linalg.eigvals(Aa - Ba @ Ka)).max() < 1.0
    # a new flight sums nothing
    reg.reset()
    assert reg.z == 0.0


def test_the_gain_is_scheduled_on_the_bank_either_way():
    """Linear between the trims (the midpoint's gain the mean of its neighbours', to round-off),
    the same for a left bank as for the right one (the map of a mirrored bird is the mirrored
    map: negating every lateral state and input leaves A and B as they are), held past the
    last trim."""
    K0, K1 = np.zeros((12, N + 1)), np.ones((12, N + 1))
    reg = lateral.BankedRegulator(np.radians([0.0, 30.0]), np.stack([K0, K1]), np.eye(12, 29),
                                  np.eye(N), np.zeros((N, 12)), 1.0)
    np.testing.assert_allclose(reg.gain(np.radians(15.0)), 0.5 * K1, atol=1e-12)
    np.testing.assert_allclose(reg.gain(np.radians(-15.0)), reg.gain(np.radians(15.0)))
    np.testing.assert_allclose(reg.gain(np.radians(80.0)), K1)


@pytest.fixture(scope="module")
def cruise_flight():
    fl = DoveFlight(Dove.load(induced=True), table=CRUISE.table)
    yield fl
    fl.close()


def test_the_banked_start_is_rolled_and_turns_at_the_coordinated_rate(cruise_flight):
    """Rolled 30 deg about the trunk's forward axis, right wing down (roll +30 in the reduced
    state), turning at g tan(30 deg) / V about the vertical, to the right (clockwise from
    above: a negative world yaw rate); speed and joints as before."""
    fl = cruise_flight
    P = with_tail_bias(p0(), CRUISE.tail_bias_deg)
    fl.reset(CRUISE, P)
    level = cycle.snapshot(fl)
    S0, q0 = fl.reduced_state(), fl.data.qpos[7:].copy()
    speed = float(np.linalg.norm(fl.data.qvel[0:3]))
    lateral.bank_state(fl, level, 30.0)
    S = fl.reduced_state()
    assert np.degrees(S[1]) == pytest.approx(np.degrees(S0[1]) + 30.0, abs=1e-9)
    R = np.zeros(9)
    mujoco.mju_quat2Mat(R, fl.data.qpos[3:7])
    world_rate = R.reshape(3, 3) @ fl.data.qvel[3:6]
    assert world_rate[2] == pytest.approx(-9.81 * np.tan(np.radians(30.0)) / speed, rel=1e-3)
    assert np.linalg.norm(world_rate[:2]) < 1e-9
    assert float(np.linalg.norm(fl.data.qvel[0:3])) == pytest.approx(speed, rel=1e-12)
    np.testing.assert_array_equal(fl.data.qpos[7:], q0)


def test_turn_trims_are_bundled_for_the_cruise_dove_only_and_bad_files_are_one_line(tmp_path):
    cruise = with_tail_bias(p0(), CRUISE.tail_bias_deg)
    trims = lateral.turn_trims_for(cruise)
    assert trims is not None and trims.banks_deg[0] > 0 and np.all(np.diff(trims.banks_deg) > 0)
    assert lateral.turn_trims_for(with_tail_bias(p0(), FlightConfig.tail_bias_deg)) is None
    for content in ("not json", json.dumps({"results": []}),
                    json.dumps({"P0": [0.0] * 29, "results": [{"bank_deg": -5,
                                                               "wingbeat": [0.0] * 29}]}),
                    json.dumps({"P0": [0.0] * 29, "results": [{"bank_deg": 15,
                                                               "wingbeat": [0.0] * 3}]})):
        f = tmp_path / "t.json"
        f.write_text(content)
        with pytest.raises(DataFileError) as e:
            lateral.TurnTrims.load(f)
        assert "\n" not in str(e.value) and "t.json" in str(e.value)


def test_banked_needs_trims_for_the_database_and_makes_the_answer_symmetric(cruise_flight):
    """The robofly dove's database has no turn trims: a one-line refusal naming the way out.
    Under the cruise database the regression's answer is mirror-symmetric about P0 (the
    regulator flies the bank): the same answer mirrored is itself."""
    cfg = ControllerConfig(lateral="banked", lookahead="off")
    robofly = DoveFlight(Dove.load())
    try:
        with pytest.raises(InputError) as e:
            load_controller(robofly, config=cfg)
        assert "turn trims" in str(e.value) and "\n" not in str(e.value)
    finally:
        robofly.close()
    ctl = load_controller(cruise_flight, bundled_database_path("cruise"), config=cfg)
    assert isinstance(ctl.lateral, lateral.BankedRegulator)
    assert len(ctl.lateral.banks) == len(lateral.turn_trims_for(ctl.P0).banks_deg) + 1
    dS = np.zeros(8)
    dS[1], dS[7] = np.radians(5.0), 0.3  # asks a roll and a yaw: an asymmetric answer
    raw = ctl.regressor.predict(dS, None)
    assert np.abs(raw - (mirror_params(ctl.P0 + raw) - ctl.P0)).max() > 1e-3
    Pp, _ = ctl._answer(dS, None, ctl.P0)
    np.testing.assert_allclose(mirror_params(Pp), Pp, atol=1e-12)
