"""Evaluation plots people can read: floors on auto-scaled axes, linear axes, a legend for
every line, and outputs named after the path file."""

import dataclasses

import numpy as np
import pytest

from flapsim.bird.tasks.flight_tasks import TaskResult
from flapsim.bird.tasks.path_shapes import straight
from flapsim.scenarios import flight as scen_flight
from flapsim.scenarios.plots import STEERING_FLOOR_DEG, flight_plot, floored_limits, plot_stem
from flapsim.scenarios.registry import EvalOptions, Scenario


def _straight_glide(n: int = 12) -> tuple:
    """A straight level flight along +x at 7 m/s, one 0.1075 s wingbeat apart: the steering
    per wingbeat is round-off (1e-13 deg), as a straight glide's is."""
    path = straight(20.0)
    x = 7.0 * 0.1075 * np.arange(n + 1)
    pos = np.stack([x, np.zeros_like(x), np.full_like(x, path.points[0, 2])], 1)
    q = np.tile([1.0, 0.0, 0.0, 0.0], (n, 1))
    desired = [(p, qq) for p, qq in zip(pos[1:], q, strict=True)]
    steer = 1e-13 * np.sin(np.arange(n))  # round-off: signed, far below anything visible
    r = TaskResult("completed", "", {}, pos, q, desired, steer, np.zeros(n), None,
                   0.1075 * np.arange(n + 1), 1.0)
    return path, r


def test_straight_glide_steering_axis_spans_the_floor(tmp_path):
    path, r = _straight_glide()
    drawn = flight_plot(path, r, tmp_path / "g.png", title="glide")
    lo, hi = drawn["steering_deg"]
    # the floor: a 1e-13 deg round-off must be drawn inside +-1 deg, not fill the axis
    assert lo <= -STEERING_FLOOR_DEG and hi >= STEERING_FLOOR_DEG
    # and not a 100x wider axis either (the floor plus its 8 % margin)
    assert hi < 1.2 * STEERING_FLOOR_DEG
    assert drawn["yscale"] == ["linear"] * 3  # no symmetric-log axes
    # a legend entry for every line, with the units in it
    assert {"path asked", "start", "steering: heading change per wingbeat [deg]"} <= set(drawn["legend"])
    assert any("[m]" in t for t in drawn["legend"]) and any("[deg]" in t for t in drawn["legend"])
    assert (tmp_path / "g.png").stat().st_size > 20_000


def test_floored_limits_keep_real_signals():
    # a 10 deg turn is drawn at its size, with the margin (8 % of the 10 + 1 deg span)
    lo, hi = floored_limits([0.0, 10.0], 1.0, symmetric=True)
    assert hi == pytest.approx(10.0 + 0.08 * 11.0) and lo == -hi
    assert floored_limits([], 0.05) == pytest.approx((0.0, 0.054))
    assert floored_limits([np.nan, 0.2], 0.05)[1] == pytest.approx(0.2 * 1.08)


def test_two_path_files_into_one_folder_leave_two_sets(tmp_path, monkeypatch):
    """The user's path scenario names its files after the path file, so a second file into
    the same folder does not overwrite the first."""
    path, r = _straight_glide(4)
    videos = []
    monkeypatch.setattr(scen_flight, "dove_video", lambda dove, q, out, *a, **k: videos.append(out))
    monkeypatch.setattr(scen_flight, "database_dove", lambda *a, **k: None)
    r = dataclasses.replace(r, qpos=np.zeros((3, 7)))
    sc = Scenario("path", "flight", "the user's path", scen_flight.run_path, {"shape": "file"})
    task = type("T", (), {"path": path, "forest": None})()
    files = []
    for name in ("loop_a.csv", "loop_b.json"):
        opt = EvalOptions(plots_dir=str(tmp_path), video_dir=str(tmp_path),
                          path_file=str(tmp_path / name))
        files += scen_flight._outputs(sc, opt, task, r)
    assert sorted((tmp_path).glob("*.png")) == [tmp_path / "loop_a.png", tmp_path / "loop_b.png"]
    assert [p.name for p in videos] == ["loop_a.mp4", "loop_b.mp4"]
    assert len(set(files)) == 4
    assert plot_stem("figure8", None, "mirror") == "figure8-mirror"
