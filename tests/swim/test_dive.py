"""The surface dive (flapsim/swim/dive.py): breathing changes buoyancy by the air's
weight of water, the exhaled lungs give REFERENCE_DATA's body density, and a
breaststroker reaches a point 2 m down by the dive."""

import numpy as np
import pytest

from flapsim.swim.dive import EXHALED_L, SurfaceDive
from flapsim.swim.goals import Waypoints
from flapsim.swim.model import SEGMENTS, Swimmer, SwimmerParams

G = 9.81


def test_exhaled_lungs_give_the_reference_density():
    # REFERENCE_DATA: ~1028 kg/m^3 after exhalation; segments at 1044 kg/m^3 plus air
    sw = Swimmer(SwimmerParams(lung_volume_l=EXHALED_L))
    m = float(sw.model.body_mass.sum())
    assert m / sw.volume == pytest.approx(1028.0, abs=1.0)  # 1.33 L rounded: +-0.5 kg/m^3


def test_breathing_out_changes_buoyancy_by_the_air_volume():
    wp = Waypoints(np.array([(5.0, 0.0, -2.0)]), 0.75)
    sw = Swimmer(SwimmerParams(lung_volume_l=3.0))
    dive = SurfaceDive(wp, lungs_l=3.0)
    k = SEGMENTS.index("thorax")
    v0 = float(sw.buoyancy.volumes[k])
    dive._breathe(sw, EXHALED_L)
    # closed form: the thorax loses exactly the air breathed out, 1.67 L
    assert sw.buoyancy.volumes[k] == pytest.approx(v0 - (3.0 - EXHALED_L) * 1e-3, rel=1e-9)
    # fully submerged, the lift lost is rho g dV = 16.8 N (the swimmer's +14 N -> ~ -2.6 N)
    assert 1025.0 * G * (v0 - sw.buoyancy.volumes[k]) == pytest.approx(16.8, abs=0.1)
    dive._breathe(sw, 3.0)
    assert sw.buoyancy.volumes[k] == pytest.approx(v0, rel=1e-9)


def test_surface_dive_reaches_two_metres_down():
    from flapsim.swim.simulate import swim

    wp = Waypoints(np.array([(8.0, 0.0, -2.0), (16.0, 0.0, 0.0)]), 0.75)
    dive = SurfaceDive(wp)
    r = swim("breaststroke", 17.0, target=wp, layers="cycle", control_hook=dive)
    # the criterion, recomputed here from the recorded head track: the head (or the
    # pelvis, which the hook also checks) within 0.75 m of the point 2 m down
    head_d = np.linalg.norm(r.head - wp.points[0], axis=1).min()
    assert dive.events["dive"] is not None and dive.events["reached"] is not None
    assert min(head_d, dive.closest_m) <= 0.75
    assert r.head[:, 2].min() < -1.25  # within 0.75 m of a point 2 m down: >= 1.25 m deep
    # breathed in once there: the head comes back up
    assert dive.events["inhale"] >= dive.events["reached"]


def test_crawl_dives_with_the_breaststroke_pull_and_crawls_on():
    from flapsim.swim.dive import UNDER_WATER_STROKE
    from flapsim.swim.simulate import swim

    wp = Waypoints(np.array([(8.0, 0.0, -1.5), (8.0, 0.0, 0.0)]), 0.75)
    dive = SurfaceDive(wp, under_stroke=UNDER_WATER_STROKE["crawl"])
    r = swim("crawl", 24.0, target=wp, control_hook=dive)
    ev = dive.events
    # the point 1.5 m down reached: head or pelvis within the 0.75 m radius (an arm's
    # length: the swimmer could touch it), recomputed for the head from its track
    head_d = np.linalg.norm(r.head - wp.points[0], axis=1).min()
    assert ev["reached"] is not None and min(head_d, dive.closest_m) <= 0.75
    assert r.head[:, 2].min() < -0.75  # within 0.75 m of a point 1.5 m down
    # then up for air, and the crawl again once the head is out of the water
    assert ev["inhale"] >= ev["reached"]
    assert ev["stroke_again"] is not None and ev["stroke_again"] > ev["inhale"]
    k = np.searchsorted(r.times, ev["stroke_again"])
    assert r.head[k:, 2].max() > 0.0
    # breaststroke from before the dive to the surface, the crawl's clock after it
    assert r.rate_hz == pytest.approx(load_crawl_rate(), rel=1e-9)


def load_crawl_rate() -> float:
    from flapsim.swim.strokes import load_stroke

    return 1.0 / load_stroke("crawl").period_s
