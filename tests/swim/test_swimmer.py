"""The swimmer: floating with and without lungs, density sweep, strokes, stroke files.

Numbers asserted here are what the model does on its defaults; the issue's human speed
ranges are NOT all met (see the README), so the stroke tests guard the measured
behaviour (forward motion at the measured speeds) rather than claim those ranges.
"""

import mujoco
import numpy as np
import pytest

from flapsim.swim.model import Swimmer, SwimmerParams
from flapsim.swim.simulate import swim


def com_heights(params: SwimmerParams, seconds: float) -> np.ndarray:
    """Centre-of-mass height every 0.1 s while the swimmer lies passive (no motor torque)."""
    sw = Swimmer(params)
    sw.reset("prone")
    m, d = sw.model, sw.data
    every = int(round(0.1 / m.opt.timestep))
    zs = []
    with sw:
        for i in range(int(round(seconds / m.opt.timestep))):
            mujoco.mj_step(m, d)
            if i % every == every - 1:
                zs.append(sw.com()[2])
    return np.asarray(zs)


def test_lungs_decide_floating():
    # the paper: the 1.044 g/mL body sinks; ~3 L of air in the lungs makes it float
    z0 = com_heights(SwimmerParams(lung_volume_l=0.0), 12.0)
    z3 = com_heights(SwimmerParams(lung_volume_l=3.0), 12.0)
    # without lungs it sinks steadily towards the pool floor (3 m down): -2.36 m at 12 s
    assert z0[-1] < -2.0 and z0[-1] < z0[-40] - 0.5
    # with 3 L it settles legs-down with the trunk at the surface: -0.55 m, moving < 0.1 m
    # over the last 4 s (measured -0.58..-0.52: a slow bob)
    assert z3[-1] > -0.7
    assert abs(z3[-1] - z3[-40]) < 0.1


def test_density_sweep_is_monotone():
    # denser water floats the swimmer higher: monotone over five densities
    heights = [com_heights(SwimmerParams(water_density=rho), 4.0)[-1]
               for rho in (1000.0, 1010.0, 1025.0, 1040.0, 1060.0)]
    assert np.all(np.diff(heights) > 0), heights


@pytest.fixture(scope="module")
def crawl():
    return swim("crawl", 12.0).summary()


@pytest.fixture(scope="module")
def breaststroke():
    return swim("breaststroke", 12.0).summary()


def test_crawl_moves_forward_at_the_measured_speed(crawl):
    # measured 0.54 m/s (20 s) on the defaults: below the 0.7-2.0 m/s human range (README);
    # 0.45 guards the windmill recovery (an underwater recovery went backwards, -0.1 m/s)
    assert crawl["speed_m_s"] > 0.45
    assert 0.6 <= crawl["stroke_rate_hz"] <= 1.0  # human crawl cycle rates
    assert crawl["head_height_mean_m"] > -0.1  # the head stays at the surface
    # breathing to one side only curves the path a little: measured 2.1 m sideways over
    # ~6 m forward in 12 s; the heading must stay within ~27 deg of the start on average
    assert abs(crawl["lateral_drift_m"]) < 0.5 * crawl["distance_m"]


def test_breaststroke_moves_forward_at_the_measured_speed(breaststroke):
    # measured 0.27 m/s: below the 0.5-1.5 m/s human range (README, bluff box drag)
    assert breaststroke["speed_m_s"] > 0.2
    assert 0.4 <= breaststroke["stroke_rate_hz"] <= 1.1
    assert abs(breaststroke["lateral_drift_m"]) < 0.05  # a symmetric stroke goes straight
    assert breaststroke["head_height_mean_m"] > -0.2


def test_treading_stays_in_place():
    r = swim("treading", 10.0).summary()
    # the head centre stays ~5 cm below the surface (the top of the head is out); the
    # issue asks for the head above water, which the model does not reach (README)
    assert r["head_horizontal_drift_max_m"] < 0.3
    assert r["head_height_mean_m"] > -0.1
