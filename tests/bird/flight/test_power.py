"""The dove's energy balance in free flight (flapsim.bird.flight.power): every watt the servos put in
is accounted for by the air's drag, the dampers and the bird's mechanical energy."""

import numpy as np
import pytest

from flapsim.bird.flight.power import power_budget
from flapsim.core.errors import InputError


@pytest.fixture(scope="module")
def budget() -> dict:
    return power_budget(wingbeats=2, skip=1)


def test_work_energy_theorem(budget):
    # the work of every generalized force over each step (its force times the step's mean
    # velocity) against MuJoCo's own energy change: equal up to the trapezoid rule's error on
    # the semi-implicit step, measured 0.03 % of the muscles' power; 2 % leaves room for that
    # and still fails on a hidden force that does work (0.1 N of thrust on the trunk through
    # xfrc_applied, 0.7 W, fails it: checked). A force across the flight path does no work,
    # and no energy balance can see it
    assert budget["work_rate_all_forces_W"] == pytest.approx(
        budget["mechanical_energy_rate_W"], abs=0.02 * budget["muscle_W"])


def test_lift_does_no_work(budget):
    # lift is perpendicular to the relative flow by construction, so its work on the polygons
    # in still air is zero; what is left is the centroid velocity's finite difference over one
    # step (measured 0.3 % of the drag's dissipation)
    assert abs(budget["lift_work_W"]) < 0.02 * budget["drag_feathers_W"]


def test_the_air_and_the_dampers_take_what_the_muscles_give(budget):
    # muscles = feather drag + body drag + friction + dampers + d(mechanical energy)/dt, the
    # remainder being the twist hinges' inertial torques and stops, measured 0.5 % of the
    # muscles' power. A polygon force mapped to the wrong body, a wrench summed about the
    # wrong point, or a force applied twice breaks it by tens of per cent
    assert abs(budget["other_W"]) < 0.05 * budget["muscle_W"]
    # flapping costs work: the servos give, the air takes (both several watts for a 0.17 kg
    # dove at 7 m/s, where a dove's real mechanical power is 1.5-2.5 W)
    assert budget["muscle_W"] > 1.0 and budget["drag_feathers_W"] > 1.0


def test_the_split_adds_up(budget):
    # the stroke split and the angle-of-attack bins partition the same dissipation
    total = budget["drag_feathers_W"]
    assert (budget["drag_feathers_downstroke_W"] + budget["drag_feathers_upstroke_W"]
            == pytest.approx(total, rel=1e-9))
    assert sum(budget["drag_feathers_by_aoa_W"].values()) == pytest.approx(total, rel=1e-9)


def test_bad_input_is_one_line():
    import numpy as np

    with pytest.raises(InputError, match="skip"):
        power_budget(wingbeats=2, skip=2)
    with pytest.raises(InputError, match="speed"):
        power_budget(wingbeats=2, skip=1, speed=0.0)
    with pytest.raises(InputError, match="finite parameters"):
        power_budget(wingbeats=2, skip=1, p=np.zeros(3))


def test_fly_power_reports_the_budget(tmp_path, capsys):
    import json

    from flapsim.cli.main import main

    js = tmp_path / "f.json"
    assert main(["fly", "--wingbeats", "2", "--power", "--json", str(js)]) == 0
    pw = json.loads(js.read_text())["power"]
    # the same flight (the default start, two wingbeats, the second averaged) as the module's
    assert pw["muscle_W"] == pytest.approx(power_budget(wingbeats=2, skip=1)["muscle_W"], rel=1e-9)
    # cost of transport, closed form: P / (m g v)
    assert pw["cost_of_transport"] == pytest.approx(
        pw["muscle_W"] / (pw["mass_kg"] * 9.81 * pw["mean_speed_m_s"]), rel=1e-12)
    assert "cost of transport" in capsys.readouterr().out
    for extra in (["--controller", "learned"], ["--feathers", "modal"]):
        assert main(["fly", "--wingbeats", "2", "--power", *extra]) == 2
        err = capsys.readouterr().err.strip()
        assert "--power" in err and len(err.splitlines()) == 1


def test_the_quick_balance_matches_the_budget():
    # wingbeat_balance (searches call it thousands of times) against power_budget, which
    # records every polygon and reads MuJoCo's own energy (mjENBL_ENERGY) over the same
    # flight: the servos' power to the budget's window, which leaves out its last step (1 of
    # ~1,030: 0.1 %), so 0.5 %; the energy rate from the trunk's speed and height alone
    # against the whole bird's, the wings' kinetic energy repeating from wingbeat to wingbeat
    # so that over four wingbeats it differs by a few hundredths of a watt: 0.05 W, where
    # half the trunk's kinetic energy change (a dropped 1/2) is ~1 W
    from flapsim.bird.body.model import Dove
    from flapsim.bird.flight.dove_flight import DoveFlight
    from flapsim.bird.flight.power import wingbeat_balance
    from flapsim.bird.flight.wingbeat import p0, with_tail_bias

    fl = DoveFlight(Dove.load(), use_rollout=False)
    try:
        quick = wingbeat_balance(fl, with_tail_bias(p0(), 17.0), wingbeats=6, skip=2)
        with pytest.raises(InputError, match="skip"):
            wingbeat_balance(fl, p0(), wingbeats=2, skip=2)
    finally:
        fl.close()
    full = power_budget(wingbeats=6, skip=2)
    assert quick["power_W"] == pytest.approx(full["muscle_W"], rel=0.005)
    assert quick["energy_rate_W"] == pytest.approx(full["mechanical_energy_rate_W"], abs=0.05)


def test_the_quick_balance_turns_mirror_wingbeats_the_mirror_way():
    # the heading it reports (the centre of mass's velocity, + left): a symmetric wingbeat on
    # the symmetric dove from a level start does not turn, and a wingbeat and its mirror image
    # turn by equal and opposite angles (the model is mirror-exact: docs/flight.md's mirror starts);
    # 1e-6 deg is float noise over three wingbeats, against the several degrees turned
    from flapsim.bird.body.model import Dove
    from flapsim.bird.body.params import DOF_NAMES
    from flapsim.bird.flight.dove_flight import DoveFlight
    from flapsim.bird.flight.power import wingbeat_balance
    from flapsim.bird.flight.wingbeat import mirror_params, p0, with_tail_bias

    p = with_tail_bias(p0(), 17.0)
    lopsided = p.copy()
    lopsided[2 * DOF_NAMES.index("l_shoulder_flap")] *= 1.15  # a wider left stroke
    fl = DoveFlight(Dove.load(), use_rollout=False)
    try:
        straight, left, right = (np.diff(wingbeat_balance(fl, q, wingbeats=3, skip=1)["heading_deg"])
                                 for q in (p, lopsided, mirror_params(lopsided)))
    finally:
        fl.close()
    assert np.abs(straight).max() < 1e-6
    # the wider left stroke lifts the left wing more: the dove banks right and turns right,
    # its heading (+ left) falling, by more each wingbeat as the bank builds
    assert left[-1] < -1.0 and left[-1] < left[0]
    np.testing.assert_allclose(right, -left, atol=1e-6)


@pytest.fixture(scope="module")
def cruise_budget():
    from flapsim.bird.flight.dove_flight import CRUISE
    from flapsim.bird.flight.wingbeat import reference_wingbeat

    return power_budget(wingbeats=8, skip=2, config=CRUISE, induced=True,
                        ref=reference_wingbeat("cruise"))


def test_the_cruise_dove_flies_trimmed_on_a_doves_power(cruise_budget, budget):
    b = cruise_budget
    # in trim over wingbeats 3-8: vertical force = weight and no net force along the flight,
    # within 3 % of the weight (the trim was searched on the same start)
    assert 0.97 <= b["aero_up_per_weight"] <= 1.03
    assert abs(b["net_forward_per_weight"]) <= 0.03
    # a 0.17 kg dove at cruise needs 2.1-2.6 W (Pennycuick's momentum-jet estimate); 4 W and a
    # cost of transport of 0.3 leave room for a model without elastic storage or a flexing
    # wing, and the robofly slow-flight stroke needed 14 W: the fix must show as watts
    assert b["muscle_W"] <= 4.0 and b["cost_of_transport"] <= 0.3
    assert b["muscle_W"] < 0.4 * budget["muscle_W"]
    # a cruising wing works at low angle of attack: at most a quarter of the dissipation at
    # 30-60 deg (the slow-flight stroke: ~90 %)
    bins = b["drag_feathers_by_aoa_W"]
    assert (bins["30-45"] + bins["45-60"]) <= 0.25 * b["drag_feathers_W"]
    # the induced power is momentum theory's order: W^2 / (2 rho A V) with A the span's disk,
    # pi b^2 / 4, is 0.65 W at 8.5 m/s; a flapping wing pays more, its lift uneven over the
    # stroke (Pennycuick's induced factor 1.2, more with the downstroke carrying it all)
    assert 0.65 <= b["induced_W"] <= 3 * 0.65
    # and the energy balance still closes with the induced power as its own term
    assert abs(b["other_W"]) < 0.05 * b["muscle_W"]
    assert abs(b["lift_work_W"]) < 0.02 * b["drag_feathers_W"]
