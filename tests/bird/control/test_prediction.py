"""The learned controller's cheaper S0 (``predict="regression"``) and the P0 rollout's caches."""

import numpy as np
import pytest

from flapsim.bird.body.model import Dove
from flapsim.bird.control.controller import (
    attach_predictor,
    bundled_database_path,
    fly_controlled,
    load_controller,
    start_cruise,
)
from flapsim.bird.control.database import load_database
from flapsim.bird.control.prediction import S0Predictor
from flapsim.bird.control.targets import CruiseTarget, trim_of_base_flight
from flapsim.bird.flight import cycle
from flapsim.bird.flight.dove_flight import DoveFlight
from flapsim.core.errors import InputError

SHARED_FLIGHT = True
EVERY = 4


@pytest.fixture(scope="module")
def flight():
    fl = DoveFlight(Dove.load())
    yield fl
    fl.close()


@pytest.fixture(scope="module")
def controller(flight):
    return load_controller(flight, predict="regression", predict_every=EVERY)


@pytest.fixture(scope="module")
def trim(flight, controller):
    return trim_of_base_flight(flight, controller.P0)


@pytest.fixture(scope="module")
def cruise(flight, controller, trim):
    """16 wingbeats from a 3 deg roll, with each wingbeat's start state."""
    start_cruise(flight, controller.P0, roll_deg=3.0)
    starts = []
    orig = controller.choose

    def choose(target, snap=None, record=False, push=None):
        starts.append((cycle.snapshot(flight), flight.reduced_state()))
        return orig(target, snap, record, push)

    controller.choose = choose
    try:
        f = fly_controlled(controller, CruiseTarget(trim, altitude=10.0), 16)
    finally:
        del controller.choose
    return f, starts


def test_p0_is_simulated_on_the_warmup_then_every_nth_or_after_a_miss(controller, cruise):
    # the schedule recomputed from the recorded wingbeats: the first 8 simulated; after a
    # simulated wingbeat i >= 7 the next simulated is i + 1 when the prediction would have
    # missed S0 by more than the tolerance there (its innovation: miss - bias before), else
    # i + 4
    f, starts = cruise
    pr = controller.predictor
    b, nxt, expected = None, 0, []
    for i, (step, (_, S)) in enumerate(zip(f.steps, starts, strict=True)):
        sim = i >= nxt
        expected.append(not sim)
        if sim:
            miss = step.reference.S - pr.regressor.predict(S)
            calm = b is not None and bool(np.all(np.abs((miss - b)[:5]) <= pr.tolerance))
            b = miss if b is None else 0.5 * b + 0.5 * miss
            nxt = i + (EVERY if calm and i + 1 >= 8 else 1)
    assert [s.reference.predicted for s in f.steps] == expected
    assert expected[:8] == [False] * 8 and sum(expected) >= 3  # some predicted
def test_simulated_references_are_p0_flown_from_the_start(flight, controller, cruise):
    f, starts = cruise
    for step, (snap, _) in zip(f.steps, starts, strict=True):
        if not step.reference.predicted:
            e0 = cycle.fly_cycle(flight, snap, controller.P0, controller.ref)
            np.testing.assert_array_equal(step.reference.S, e0.S)


def test_predicted_s0_is_the_regression_plus_the_low_passed_bias(controller, cruise):
    # the bias recomputed here from the simulated wingbeats alone: b = miss at wingbeat 0,
    # then b <- (1 - g) b + g miss at every simulated one; a predicted S0 is g(S) + b
    f, starts = cruise
    reg, g = controller.predictor.regressor, controller.predictor.gain
    b = None
    for step, (_, S) in zip(f.steps, starts, strict=True):
        guess = reg.predict(S)
        if not step.reference.predicted:
            miss = step.reference.S - guess
            b = miss if b is None else (1 - g) * b + g * miss
        else:
            np.testing.assert_allclose(step.reference.S, guess + b, rtol=0, atol=1e-12)


def test_predicted_s0_is_close_to_the_simulated_one(flight, controller, cruise):
    # measured over 60 cruise wingbeats from 0 and 3 deg of roll, the largest misses were
    # 0.012 / 0.018 rad (pitch, roll) and 0.017 / 0.087 / 0.057 m/s (body velocity); the
    # bounds leave ~1.5-2x room, while the regression without its bias (vy 0.05 m/s off,
    # up to 0.25 m/s) or without the warm-up (pitch 0.046 rad, vz 0.22 m/s) fails them
    f, starts = cruise
    miss = []
    for step, (snap, _) in zip(f.steps, starts, strict=True):
        if step.reference.predicted:
            e0 = cycle.fly_cycle(flight, snap, controller.P0, controller.ref)
            miss.append(np.r_[step.reference.S[:5] - e0.S[:5],
                              step.reference.com_vel - e0.com_vel,
                              step.reference.trunk_pos - e0.trunk_pos])
    miss = np.abs(np.array(miss))
    assert len(miss) >= 3
    assert np.all(miss[:, 0:2] < 0.03), miss[:, 0:2]
    assert np.all(miss[:, 2:5] < 0.12), miss[:, 2:5]
    assert np.all(miss[:, 5:8] < 0.12), miss[:, 5:8]  # world centre-of-mass velocity, m/s
    assert np.all(miss[:, 8:11] < 0.02), miss[:, 8:11]  # trunk position over 0.1 s, m


def test_a_state_set_from_outside_restarts_with_a_simulation(flight, controller, trim):
    pr = controller.predictor
    pr.warmup, pr.tolerance = 1, (np.inf,) * 5
    try:
        start_cruise(flight, controller.P0)
        f = fly_controlled(controller, CruiseTarget(trim, altitude=10.0), 3)
        assert [s.reference.predicted for s in f.steps] == [False, False, True]
        start_cruise(flight, controller.P0, roll_deg=1.0)  # not where the last wingbeat ended
        f = fly_controlled(controller, CruiseTarget(trim, altitude=10.0), 3)
        assert [s.reference.predicted for s in f.steps] == [False, False, True]
    finally:
        pr.warmup, pr.tolerance = 8, S0Predictor.tolerance


def test_default_is_simulate_and_bad_settings_are_one_line_errors(flight):
    assert load_controller(flight).predict == "simulate"
    with pytest.raises(InputError, match="simulate, coarse, regression"):
        load_controller(flight, predict="guess")
    db = load_database(bundled_database_path())
    with pytest.raises(InputError, match="N >= 1"):
        S0Predictor.from_arrays(db.arrays["S"][:50], db.arrays["S0"][:50], k=20, every=0)
    with pytest.raises(InputError, match=">= 1 wingbeat"):
        S0Predictor.from_arrays(db.arrays["S"][:50], db.arrays["S0"][:50], k=20, warmup=0)
    with pytest.raises(InputError, match="gain"):
        S0Predictor.from_arrays(db.arrays["S"][:50], db.arrays["S0"][:50], k=20, gain=0.0)


def test_a_database_without_s0_is_refused_for_regression(flight, tmp_path):
    from flapsim.bird.control.database import save_database

    src = load_database(bundled_database_path())
    arrays = {k: v[:200] for k, v in src.arrays.items() if k not in ("S", "S0")}
    head = {k: v for k, v in src.header.items() if k != "fields"}
    path = tmp_path / "no_s0.db"
    save_database(path, head, np.arange(200), arrays, {})
    ctl = load_controller(flight, path)  # the simulating controller needs only dS, dP
    with pytest.raises(InputError, match="'S'"):
        attach_predictor(ctl, path)
    with pytest.raises(InputError, match="'S'"):
        load_controller(flight, path, predict="regression")


def test_dof_ranges_follow_an_edit_of_the_model(flight):
    m = flight.model
    lo, hi = cycle.model_dof_ranges(flight)
    j = int(np.flatnonzero(m.jnt_limited)[0])
    i = int(np.flatnonzero(flight.dove.qadr == m.jnt_qposadr[j])[0])
    old = m.jnt_range[j].copy()
    try:
        m.jnt_range[j] = old + 0.1
        lo2, hi2 = cycle.model_dof_ranges(flight)
        assert lo2[i] == pytest.approx(old[0] + 0.1) and hi2[i] == pytest.approx(old[1] + 0.1)
    finally:
        m.jnt_range[j] = old
    lo3, _ = cycle.model_dof_ranges(flight)
    assert lo3[i] == lo[i]


def test_a_zero_tolerance_simulates_every_wingbeat(flight, controller, trim):
    # every innovation exceeds 0: the prediction is never trusted
    pr = controller.predictor
    pr.warmup, pr.tolerance = 1, (0.0,) * 5
    try:
        start_cruise(flight, controller.P0)
        f = fly_controlled(controller, CruiseTarget(trim, altitude=10.0), 4)
        assert [s.reference.predicted for s in f.steps] == [False] * 4
    finally:
        pr.warmup, pr.tolerance = 8, S0Predictor.tolerance
