"""Targets (heading, point, path files, figure of eight, waypoints, trajectories) and
steering with the per-cycle layer: the paper's tasks, on the defaults."""

from __future__ import annotations

import math

import numpy as np
import pytest

from flapsim.core.errors import DataFileError, InputError
from flapsim.swim.goals import Path, Point, Waypoints, figure_eight, load_path
from flapsim.swim.simulate import swim


def test_path_geometry():
    p = Path(np.array([[0.0, 0.0], [3.0, 0.0], [3.0, 4.0], [3.0, 4.0]]), lookahead=1.0)
    assert p.length == pytest.approx(7.0)  # the repeated last point is dropped
    assert np.allclose(p.at(5.0), (3.0, 2.0))
    s, d = p.project(np.array([1.0, 0.5]))
    assert s == pytest.approx(1.0) and d == pytest.approx(0.5)
    s, d = p.project(np.array([4.0, 3.5]))  # beside the last segment
    assert s == pytest.approx(6.5) and d == pytest.approx(1.0)
    # a window keeps the answer inside it: the closest point with s in [0, 2]
    s, d = p.project(np.array([4.0, 3.5]), 0.0, 2.0)
    assert s == pytest.approx(2.0) and d == pytest.approx(math.hypot(2.0, 3.5))
    # aim one look-ahead past the closest point: from (1, 0.5) at (2, 0)
    assert p.heading(np.array([1.0, 0.5]), np.zeros(2)) == pytest.approx(math.atan2(-0.5, 1.0))


def test_figure_eight_shape():
    f = figure_eight(5.0, n=400)
    # two circles of radius 5: length 2 * 2 pi r (polygon: within 0.1 %)
    assert f.length == pytest.approx(4 * math.pi * 5.0, rel=1e-3)
    assert f.points[:, 1].max() == pytest.approx(10.0, abs=1e-3)
    assert f.points[:, 1].min() == pytest.approx(-10.0, abs=1e-3)
    # it starts at the origin heading +x and ends there
    assert np.allclose(f.points[0], 0.0) and np.allclose(f.points[-1], 0.0)
    assert f.points[1, 0] > 0 and abs(f.points[1, 1]) < 0.1


def test_path_files(tmp_path):
    good = tmp_path / "p.csv"
    good.write_text("# a path\nx, y\n0, 0\n5 0\n5,5  # corner\n")
    p = load_path(str(good))
    assert p.length == pytest.approx(10.0)
    for text, match in (("0,0\n1,nope\n", "line 2"), ("0,0\n1,2,3\n", "2 numbers"),
                        ("0,0\n", "at least two"), ("0,0\n0,0\n", "two distinct"),
                        ("0,0\n1,nan\n", "non-finite"),
                        # finite, but their difference overflows a float
                        ("-1e308,0\n1e308,0\n", "within 1e\\+06 m")):
        bad = tmp_path / "bad.csv"
        bad.write_text(text)
        with pytest.raises(DataFileError, match=match):
            load_path(str(bad))
    with pytest.raises(DataFileError, match="does not exist"):
        load_path(str(tmp_path / "missing.csv"))
    with pytest.raises(InputError):
        Point(float("nan"), 0.0)


def test_steering_needs_yaw_sequences():
    import tomllib

    from flapsim.swim.strokes import load_stroke, parse_stroke, stroke_path

    raw = tomllib.loads(stroke_path("crawl").read_text())
    raw.pop("cycle")
    plain = parse_stroke(raw, "plain.toml")
    with pytest.raises(InputError, match="cannot steer"):
        swim(plain, 1.0, target=Point(1.0, 0.0))
    # the basic layer alone ignores the target (and needs no sequences)
    swim(plain, 0.5, target=Point(1.0, 0.0), layers="basic")
    with pytest.raises(InputError, match="layers"):
        swim(load_stroke("crawl"), 0.5, layers="sideways")


def test_crawl_holds_its_heading():
    # one-sided breathing curves the open-loop crawl 0.60 m sideways in 20 s; the
    # per-cycle layer holds the start heading (measured 0.26 m) without slowing it
    # much (0.96 m/s against 0.98)
    basic = swim("crawl", 20.0, layers="basic").summary()
    held = swim("crawl", 20.0, layers="cycle").summary()
    assert basic["lateral_drift_m"] > 0.45
    assert abs(held["lateral_drift_m"]) < 0.6 * basic["lateral_drift_m"]
    assert held["speed_m_s"] > 0.9


@pytest.mark.parametrize("stroke, layers, reached_by", [("crawl", "cycle", 20.0),
                                                      ("breaststroke", "all", 25.0)])
def test_swims_to_a_point_on_its_left(stroke, layers, reached_by):
    # a point 10 m to the left of the start: measured reached (within 0.5 m) at 15.5 s
    # (crawl, per-cycle layer) and 20.5 s (breaststroke, all layers). (The crawl with
    # all layers swims faster and turns wider, ~5.9 m: it circles this point.)
    s = swim(stroke, 30.0, target=Point(0.0, 10.0), layers=layers).summary()
    assert s["target_reached_s"] is not None and s["target_reached_s"] < reached_by
    assert s["time_to_reach_s"] == s["target_reached_s"]


def test_crawl_follows_a_figure_of_eight():
    # the paper's Fig. 14 task, loops of 5 m radius, per-cycle layer: measured 0.18 m
    # mean and 0.66 m max from the path, done in 66 s at 0.95 m/s
    s = swim("crawl", 70.0, target=figure_eight(5.0), layers="cycle").summary()
    assert s["path_completed_s"] is not None
    assert s["path_error_mean_m"] < 0.4 and s["path_error_max_m"] < 1.2
    assert s["track_speed_m_s"] > 0.8


def test_steering_across_a_current():
    # the paper's Fig. 15 task: a 0.2 m/s cross current. The basic layer alone is
    # carried off (measured 4.8 m sideways in 30 s); steering for a point 15 m ahead
    # heads into the current and reaches it (measured at 16.6 s)
    basic = swim("crawl", 30.0, current=(0.0, 0.2, 0.0), feedback=False).summary()
    assert basic["lateral_drift_m"] > 3.0
    steered = swim("crawl", 30.0, current=(0.0, 0.2, 0.0), target=Point(15.0, 0.0)).summary()
    assert steered["target_reached_s"] is not None and steered["target_reached_s"] < 25.0


def test_a_waypoint_reached_by_a_dive_s_own_rule_moves_the_target_on():
    wp = Waypoints(np.array([[8.0, 0.0, -2.0], [16.0, 0.0, 0.0]]), 0.75)
    # the centre of mass 0.8 m off the point below: not reached by the waypoints' rule
    wp.update(np.array([8.0, 0.0, -1.2]), 14.0)
    assert wp.current == 0 and wp.reached == [None, None]
    wp.reached_by(1, 14.2)  # not the current point: nothing happens
    assert wp.current == 0
    wp.reached_by(0, 14.5)  # the dive's head came within the radius
    assert wp.current == 1 and wp.reached == [14.5, None]
    assert np.array_equal(wp.position(15.0), [16.0, 0.0, 0.0])
