"""The water budget splits each segment's work on the water into the part against the body's
progress and the slip, checked where the split is known in closed form: a rigid glide has
no slip, a body turning about its centre of mass makes no progress."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from flapsim.swim.budget import ARMS, GROUPS, summarize, water_work_rates
from flapsim.swim.model import Swimmer, SwimmerParams
from flapsim.swim.simulate import swim


def _prone_swimmer(body: str = "rounded") -> Swimmer:
    sw = Swimmer(SwimmerParams(body_shape=body))
    sw.reset("prone")
    mujoco.mj_forward(sw.model, sw.data)
    return sw


def test_a_rigid_glide_has_no_slip_and_pays_its_drag_times_its_speed() -> None:
    sw = _prone_swimmer()
    d = sw.data
    V = np.array([1.3, 0.2, -0.1])
    d.qvel[:] = 0.0
    d.qvel[0:3] = V  # every point moves at V: the whole body translates
    mujoco.mj_forward(sw.model, d)
    r = water_work_rates(sw)
    scale = np.abs(r).max()
    assert scale > 1.0, "a 1.3 m/s glide takes watts from the water's drag"
    # no segment moves relative to the body: the slip is round-off
    assert np.abs(r[:, 0] - r[:, 1]).max() < 1e-9 * scale
    # the whole body's: minus the water's total force (the engine's own sum) times V
    rep = sw.hydro.evaluate(d)
    assert r[:, 0].sum() == pytest.approx(-float(rep.total_force @ V), rel=1e-9)


def test_a_body_turning_about_its_centre_of_mass_only_slips() -> None:
    sw = _prone_swimmer()
    m, d = sw.model, sw.data
    w = np.array([0.0, 0.0, 1.5])  # yawing at 1.5 rad/s (free joint: body-frame rate)
    d.qvel[:] = 0.0
    d.qvel[3:6] = w
    mujoco.mj_forward(m, d)
    # the root's origin moves so that the centre of mass stands still
    root = sw.body["pelvis"]
    R = d.xmat[root].reshape(3, 3)
    d.qvel[0:3] = -np.cross(R @ w, d.subtree_com[root] - d.xpos[root])
    mujoco.mj_forward(m, d)
    mujoco.mj_subtreeVel(m, d)
    assert np.abs(d.subtree_linvel[root]).max() < 1e-12
    r = water_work_rates(sw)
    assert np.abs(r[:, 0]).sum() > 1.0, "the limbs sweep through the water"
    # the work against the progress uses the centre of mass's velocity: none here
    assert np.abs(r[:, 1]).max() < 1e-9 * np.abs(r[:, 0]).max()


def test_the_summary_adds_the_groups_and_takes_the_arms_efficiency() -> None:
    rates = np.zeros((2, len(GROUPS), 2))
    h, f, t = GROUPS.index("hand"), GROUPS.index("forearm"), GROUPS.index("thorax")
    # hands: 10 W into the water, 4 W of it thrust (against the progress -4); forearms 6 W,
    # 2 W thrust; the trunk's drag 6 W, all against the progress
    rates[:, h] = (10.0, -4.0)
    rates[:, f] = (6.0, -2.0)
    rates[:, t] = (6.0, 6.0)
    b = summarize(rates)
    assert set(ARMS) == {"hand", "forearm"}
    assert b["water_w"] == pytest.approx(22.0)
    assert b["slip_w"] == pytest.approx(14.0 + 8.0)
    assert b["arms_thrust_power_w"] == pytest.approx(6.0)
    assert b["arms_froude_efficiency"] == pytest.approx(6.0 / 16.0)
    assert b["segments"]["thorax"]["slip_w"] == pytest.approx(0.0)
    # no leg moved: no thrust, no efficiency
    assert b["legs_thrust_power_w"] == 0.0 and b["legs_froude_efficiency"] is None
    with pytest.raises(ValueError):
        summarize(np.zeros((3, 2)))


def test_sampling_the_budget_leaves_the_swim_as_it_was() -> None:
    a = swim("crawl", 1.5, SwimmerParams(body_shape="rounded"), layers="basic")
    b = swim("crawl", 1.5, SwimmerParams(body_shape="rounded"), layers="basic", budget=True)
    assert np.array_equal(a.com, b.com) and np.array_equal(a.power, b.power)
    assert a.water_rates is None and b.water_rates.shape == (len(b.times), len(GROUPS), 2)


def test_the_ideal_paddle_balances_the_drag_and_pays_it_at_the_hands_speed() -> None:
    from flapsim.swim.budget import ideal_paddle

    v, drag, rate, area, path, cd, rho = 1.2, 36.0, 0.6, 0.04, 1.0, 1.2, 1025.0
    r = ideal_paddle(v, drag, rate, area, path, cd, rho)
    u = r["slip_m_s"]
    # brute force: step each arm's pull in time, the hand backwards relative to the body at
    # v + u over the path, the water's force 1/2 rho cd A u^2; add the impulse and the work
    dt = 1e-5
    n = int(round(path / (v + u) / dt))
    force = 0.5 * rho * cd * area * u * u
    impulse = 2 * force * n * dt
    work = 2 * force * (v + u) * n * dt
    # 1e-3: the pull's duration rounded to whole 1e-5 s steps
    assert impulse == pytest.approx(drag / rate, rel=1e-3), "two pulls a cycle hold the drag"
    assert work * rate == pytest.approx(r["power_w"], rel=1e-3)
    assert r["froude_efficiency"] == pytest.approx(drag * v / r["power_w"], rel=1e-12)
    assert r["pull_fraction"] == pytest.approx(n * dt * rate, rel=1e-3)
    # an ever larger paddle need not slip: the power falls to the drag's, drag x speed
    big = ideal_paddle(v, drag, rate, 1e8, path, cd, rho)
    assert big["power_w"] == pytest.approx(drag * v, rel=1e-3)
    with pytest.raises(ValueError):
        ideal_paddle(v, drag, rate, 0.0, path)
