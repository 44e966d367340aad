"""The swimmer: floating with and without lungs, density sweep, strokes, stroke files.

Numbers asserted here are what the model does on its defaults; the issue's human speed
ranges are NOT all met (see the README), so the stroke tests guard the measured
behaviour (forward motion at the measured speeds) rather than claim those ranges.
"""

import mujoco
import numpy as np
import pytest

from flapsim.errors import DataFileError
from flapsim.swim.model import Swimmer, SwimmerParams
from flapsim.swim.simulate import swim
from flapsim.swim.strokes import Stroke, _pairs, _shifted, load_stroke


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


def test_whole_turn_keys_are_periodic_up_to_the_turn():
    key = _pairs("t", [[0, 178], [0.25, 95], [0.47, 0], [0.75, -120], [1.0, -182]])
    assert key[2] == -360.0
    st = Stroke("t", 1.0, "prone", "pchip", {"a.b": key, "c.d": _shifted(key, 0.5)})
    x = np.linspace(0, 1, 2001)
    a = st.curve("a.b", x)
    # continuous across the cycle end once the turn is taken off (no 360 deg jump):
    # just before phase 1 the angle is ~ f(0) - 360
    assert abs(a[-2] - (a[0] - 360.0)) < 1.0
    assert np.abs(np.diff(a[:-1])).max() < 1.0
    # the mirrored copy is the same curve half a cycle later, up to whole turns
    c = st.curve("c.d", x)
    d = np.mod(c - st.curve("a.b", x - 0.5) + 180.0, 360.0) - 180.0
    assert np.allclose(d, 0.0, atol=1e-9)


def test_bad_stroke_files_are_one_line_errors(tmp_path):
    bad = tmp_path / "bad.toml"
    bad.write_text("name = 'x'\n[keys.shoulder_l]\nflex = [[0.0, 0], [1.0, 100]]\n")
    with pytest.raises(DataFileError, match="whole turns"):
        load_stroke(str(bad))
    bad.write_text("name = 'x'\n[keys.shoulder_l]\nwiggle = [[0.0, 0]]\n")
    with pytest.raises(DataFileError, match="unknown dof"):
        load_stroke(str(bad))
    bad.write_text("name = [\n")
    with pytest.raises(DataFileError, match="not valid TOML"):
        load_stroke(str(bad))
