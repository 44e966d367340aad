"""The learned wingbeat controller in flight, with the bundled database."""

import mujoco
import numpy as np
import pytest

from flapsim.bird.body.model import Dove
from flapsim.bird.control.controller import (
    BaseController,
    bundled_database_path,
    cruise_metrics,
    fly_controlled,
    load_controller,
    start_cruise,
)
from flapsim.bird.control.database import load_database
from flapsim.bird.control.targets import CruiseTarget, target_state, trim_of_base_flight
from flapsim.bird.flight import cycle
from flapsim.bird.flight.dove_flight import DoveFlight
from flapsim.bird.flight.wingbeat import RANGE_TOLERANCE, control_table
from flapsim.core.errors import DataFileError

#: this module's flight keeps its feather forces registered from test to test (conftest)
SHARED_FLIGHT = True


@pytest.fixture(scope="module")
def flight():
    fl = DoveFlight(Dove.load())
    yield fl
    fl.close()


@pytest.fixture(scope="module")
def controller(flight):
    return load_controller(flight, method="lwlr")


@pytest.fixture(scope="module")
def trim(flight, controller):
    return trim_of_base_flight(flight, controller.P0)


def test_the_trim_is_the_still_air_one_whatever_the_flights_wind(trim, controller):
    """The trim is what P0 does in still air: the target adds the wind itself. Measured on a
    flight in a 2 m/s crosswind and a breeze it must be the still-air trim (the flow is
    zeroed in place for it), and the flight's wind is back afterwards. Measured in the wind,
    its angle of attack was 0.142 rad against 0.049 in still air, and the crosswind scenario
    was lost by slowing to ~4.5 m/s. Not to the bit: a flow of two zeroed primitives is summed
    by other compiled code than one still one, and on some processors the fused multiply-adds
    differ in the last bits (7e-14 seen); 1e-9 is far below the wind's 0.09 rad."""
    from flapsim.fluid.flow import Breeze

    fl = DoveFlight(Dove.load(), wind=(0.0, 2.0, 0.0), flow=(Breeze((1, 0, 0), 1.5, 0.3),))
    try:
        windy = trim_of_base_flight(fl, controller.P0)
        np.testing.assert_allclose(windy.S, trim.S, rtol=0, atol=1e-9)
        assert abs(trim.aoa) < 0.1  # 0.049 rad; 0.142 when measured in the crosswind
        np.testing.assert_allclose(fl.flow.velocity(np.zeros((1, 3)), 0.0), [[0.0, 2.0, 0.0]],
                                   atol=1e-12)  # the breeze is sin(0) = 0 at t = 0
    finally:
        fl.close()


def test_bundled_modal_database_is_for_the_modal_dove_and_finished():
    """The modal-feather dove's own bundled database: the rigid one's command with --feathers
    modal (the same sampling and seed), bound to the modal dove's hash, chosen by default."""
    modal = Dove.load(feathers="modal")
    db = load_database(bundled_database_path("modal"), model_hash=modal.hash(), require_finalized=True)
    rigid = load_database(bundled_database_path(), require_finalized=True)
    assert db.header["config"]["feathers"] == "modal" and db.n == rigid.n == 10000
    assert db.header["seed"] == rigid.header["seed"]
    assert {k: v for k, v in db.header["config"].items() if k != "feathers"} == rigid.header["config"]
    fl = DoveFlight(modal)
    try:
        assert load_controller(fl).regressor.n == 2 * db.n  # the default for a modal flight
    finally:
        fl.close()


def test_bundled_database_is_for_this_model_and_finished():
    db = load_database(bundled_database_path(), model_hash=Dove.load().hash(),
                       require_finalized=True)
    assert db.header["kind"] in ("dove-phase1", "dove-phase2")
    assert db.n >= 1000 and db.arrays["dP"].shape == (db.n, 29)
    # the regression searches every sample and its mirror image; k is 2 % of both for LWLR
    # (the default method) and the paper's 0.5 % for k-NN
    fl = DoveFlight(Dove.load())
    try:
        assert load_controller(fl).regressor.n == 2 * db.n
        assert load_controller(fl).regressor.k == round(0.02 * 2 * db.n)
        assert load_controller(fl, method="knn").regressor.k == round(0.005 * 2 * db.n)
        assert load_controller(fl, mirror=False).regressor.n == db.n
    finally:
        fl.close()


def test_level_cruise_holds_altitude_speed_heading_from_a_roll_error(flight, controller, trim):
    # a learned controller's cruise: 100 wingbeats from a 2 deg roll error within 0.5 m of
    # the start altitude, 0.5 m/s of 7 m/s and 5 deg of the start heading
    start_cruise(flight, controller.P0, roll_deg=2.0)
    target = CruiseTarget(trim, altitude=10.0, speed=7.0)
    f = fly_controlled(controller, target, 100)
    m = cruise_metrics(f, target)
    assert m["max_altitude_deviation"] < 0.5, m
    assert m["max_speed_deviation"] < 0.5, m
    assert m["max_heading_deviation_deg"] < 5.0, m
    # the commanded wingbeats stay inside the joint ranges, and the simulated joints too
    # (MuJoCo's soft limits: within the sampler's tolerance, here none needed at all)
    assert m["max_range_excess_deg"] <= np.degrees(RANGE_TOLERANCE)


def test_the_base_controller_loses_the_same_start(flight, controller, trim):
    # without the learned controller the roll error grows (spiral divergence) and the bird
    # leaves the acceptance band: the cruise test above is the controller's doing
    start_cruise(flight, controller.P0, roll_deg=2.0)
    target = CruiseTarget(trim, altitude=10.0, speed=7.0)
    m = cruise_metrics(fly_controlled(BaseController(flight, controller.P0), target, 100), target)
    assert (m["max_altitude_deviation"] > 0.5 or m["max_heading_deviation_deg"] > 5.0
            or m["max_speed_deviation"] > 0.5), m


def test_controlled_torques_never_exceed_the_limits(flight, controller, trim):
    # replay three controlled wingbeats step by step and read the actuator forces MuJoCo
    # applied: forcerange clamps them, so none may exceed its limit
    m = flight.model
    assert np.all(m.actuator_forcelimited)
    start_cruise(flight, controller.P0, roll_deg=2.0)
    target = CruiseTarget(trim, altitude=10.0)
    peak = np.zeros(m.nu)
    for _ in range(3):
        snap = cycle.snapshot(flight)
        step = controller.choose(target, snap)
        cycle.restore(flight, snap)
        ctrl, _, _ = control_table(flight.ref, step.P, m.opt.timestep, flight.kp, flight.kv)
        for c in ctrl:
            flight.data.ctrl[:] = c
            mujoco.mj_step(m, flight.data)
            peak = np.maximum(peak, np.abs(flight.data.actuator_force))
        # the replay is the controller's wingbeat: same end state (bit for bit)
        np.testing.assert_array_equal(cycle.snapshot(flight).physics[1:], step.end.snapshot.physics[1:])
    lim = np.max(np.abs(m.actuator_forcerange), axis=1)
    assert np.all(peak <= lim + 1e-12)


def test_target_state_banks_into_a_coordinated_turn(trim):
    # a left turn at omega with speed v banks the left wing down by atan(v omega / g)
    # (the paper's eq. 5): pitch_roll's roll (+ right wing down) is -atan(v omega / g)
    v, w = 7.0, 0.5
    S = target_state(trim, v, heading=0.3, climb=0.0, turn_rate=w)
    assert S[1] == pytest.approx(-np.arctan(v * w / 9.81), abs=1e-9)
    # speed is kept and the body-frame velocity has no sideslip
    assert np.linalg.norm(S[2:5]) == pytest.approx(v, rel=1e-12)
    assert S[3] == pytest.approx(0.0, abs=1e-12)
    # level flight: the trim's pitch and angular velocity
    S0 = target_state(trim, v, heading=1.0, climb=0.0, turn_rate=0.0)
    assert S0[0] == pytest.approx(np.arctan2(-trim.S[4], trim.S[2]), abs=1e-9)
    np.testing.assert_allclose(S0[5:8], trim.S[5:8], atol=1e-12)


def test_target_state_asks_more_angle_of_attack_per_g_of_the_turn(trim):
    # a 60 deg bank is a 2 g turn (n = 1 / cos 60 deg): aoa_per_g asks the nose that much
    # higher above the flight path, read back from the body-frame velocity's direction;
    # level flight is unchanged
    v = 7.0
    w = 9.81 * np.tan(np.radians(60.0)) / v
    per_g = np.radians(20.0)
    base = target_state(trim, v, heading=0.0, climb=0.0, turn_rate=w)
    more = target_state(trim, v, heading=0.0, climb=0.0, turn_rate=w, aoa_per_g=per_g)

    def aoa(S):
        return -np.arctan2(S[4], S[2])

    assert aoa(base) == pytest.approx(trim.aoa, abs=1e-9)
    assert aoa(more) == pytest.approx(trim.aoa + per_g * (2.0 - 1.0), abs=1e-9)
    assert more[1] == pytest.approx(base[1], abs=1e-12)  # the same bank
    assert np.linalg.norm(more[2:5]) == pytest.approx(v, rel=1e-12) and abs(more[3]) < 1e-12
    np.testing.assert_allclose(target_state(trim, v, 0.0, 0.0, 0.0, aoa_per_g=per_g),
                               target_state(trim, v, 0.0, 0.0, 0.0), atol=1e-12)


def test_a_mirrored_sample_is_the_mirror_birds_flight(flight):
    # the database's mirror images (MIRROR_STATE, mirror_params) are samples only if the dove
    # flies them: from a rolled, side-slipping, yawing state with a lopsided wingbeat, and
    # from the mirror state with the mirror wingbeat, the two ends are mirror images (the
    # model is symmetric to round-off; one wingbeat amplifies it to < 1e-9)
    from flapsim.bird.control.regression import MIRROR_STATE
    from flapsim.bird.flight.wingbeat import mirror_params, p0

    P = p0()
    P[0], P[3], P[27] = 1.05, 0.04, 0.02  # left shoulder bigger and shifted; tail spread
    ends = []
    for sign, p in ((1.0, P), (-1.0, mirror_params(P))):
        flight.reset(p=p)
        d = flight.data
        r = sign * 0.15
        d.qpos[3:7] = (np.cos(r / 2), np.sin(r / 2), 0.0, 0.0)
        d.qvel[1] = sign * 0.4
        d.qvel[3], d.qvel[5] = sign * 0.5, sign * -0.3
        mujoco.mj_forward(flight.model, d)
        ends.append(cycle.fly_cycle(flight, None, p).S)
    assert abs(ends[0][1]) > 0.05  # the start's roll is not gone
    np.testing.assert_allclose(ends[1], ends[0] * MIRROR_STATE, atol=1e-9)


def test_foreign_and_other_model_databases_are_refused(flight, tmp_path):
    bad = tmp_path / "x.db"
    bad.write_text("not a database\n")
    with pytest.raises(DataFileError):
        load_controller(flight, bad)
    from flapsim.bird.control.database import save_database

    other = tmp_path / "other.db"
    save_database(other, {"kind": "dove-phase1", "model_hash": "0123456789ab"},
                  np.arange(3), {"dS": np.zeros((3, 8)), "dP": np.zeros((3, 29))}, {})
    with pytest.raises(DataFileError, match="model"):
        load_controller(flight, other)
