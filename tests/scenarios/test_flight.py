"""The scenario registry, the flight tasks' disturbances and judges, and ``flapsim eval``."""

from __future__ import annotations

import json
from pathlib import Path

import mujoco
import numpy as np
import pytest

from flapsim import scenarios
from flapsim.bird.tasks.flight_tasks import Forest, PushSpec, Tree
from flapsim.cli.main import main
from flapsim.core.errors import InputError
from flapsim.scenarios.flight import min_separation, primary_name


def test_the_registry_lists_the_papers_flight_suite_once_each():
    names = scenarios.names(family="flight")
    assert len(names) == len(set(names))
    for needed in ("figure8", "sinusoid", "climb-turn-0", "climb-turn-15", "climb-turn-30",
                   "climb-turn-45", "forest", "flock", "plucked-3", "plucked-4", "wind-steady",
                   "wind-breeze", "wind-gusts", *(f"push-{d}" for d in
                                                  ("front", "back", "left", "right", "up", "down"))):
        assert needed in names
    assert "path" not in scenarios.names(all_only=True)  # needs a file: not part of 'all'
    with pytest.raises(InputError, match="figure8"):
        scenarios.get("no-such-scenario")


def test_a_broken_run_is_a_failed_result_not_an_exception(tmp_path):
    bad = tmp_path / "foreign.db"
    bad.write_bytes(b"not a database at all")
    r = scenarios.run_scenario("wind-gusts", scenarios.EvalOptions(db=str(bad), quick=True))
    assert r["status"] == "failed" and r["ok"] is False and "foreign.db" in r["reason"]


def test_the_paper_counts_plucked_primaries_from_the_outermost():
    # 10 primaries, p10 outermost: the 2nd, 5th and 8th from the tip are p9, p6 and p3
    assert [primary_name("l", i) for i in (2, 5, 8)] == ["l_p9", "l_p6", "l_p3"]


def test_plucked_feathers_lose_exactly_their_triangles_area():
    from flapsim.bird.body.model import Dove
    from flapsim.bird.body.params import left_feathers
    from flapsim.bird.flight.dove_flight import DoveFlight

    dove = Dove.load()
    names = ("l_p9", "l_p6", "l_p3")
    whole, plucked = DoveFlight(dove), DoveFlight(dove, plucked=names)
    try:
        # the feathers' own mesh areas, from the generator (not from the polygon set)
        lost = sum(f.area for f in left_feathers(dove.params) if f.name in names)
        assert lost > 0
        assert whole.polygons.area.sum() - plucked.polygons.area.sum() == pytest.approx(lost, rel=1e-5)
        assert not set(names) & set(plucked.polygons.labels)
    finally:
        whole.close()
        plucked.close()
    with pytest.raises(InputError, match="l_p11"):
        DoveFlight(dove, plucked=("l_p11",))


def test_a_push_is_xfrc_applied_for_its_steps_only():
    # a free box in zero gravity pushed by F for n of 2n steps: v = F n dt / m exactly (the
    # push's controls carry ctrl and xfrc_applied in mj_getState's own layout)
    from mujoco import rollout

    from flapsim.bird.flight.cycle import Push, _push_controls

    m = mujoco.MjModel.from_xml_string(
        '<mujoco><option gravity="0 0 0" timestep="0.001"/><worldbody><body name="b">'
        '<freejoint/><geom type="box" size=".1 .1 .1" mass="2"/></body></worldbody></mujoco>')
    d = mujoco.MjData(m)
    n = 50
    F = np.array([3.0, -1.0, 2.0])
    controls, spec = _push_controls(m, np.zeros((2 * n, m.nu)), Push(1, F, n))
    spec_full = mujoco.mjtState.mjSTATE_FULLPHYSICS
    s0 = np.empty(mujoco.mj_stateSize(m, spec_full))
    mujoco.mj_getState(m, d, s0, spec_full)
    states, _ = rollout.rollout(m, d, s0[None], controls[None], control_spec=spec)
    qvel = states[0, -1, 1 + m.nq:1 + m.nq + 3]
    np.testing.assert_allclose(qvel, F * n * 0.001 / 2.0, rtol=1e-9)


def test_push_directions_turn_with_the_heading():
    # flying +y (heading 90 deg): front is +y, left is -x, up is +z
    np.testing.assert_allclose(PushSpec(0, 8.0, "front").world_force(np.pi / 2), [0, 8, 0], atol=1e-12)
    np.testing.assert_allclose(PushSpec(0, 8.0, "left").world_force(np.pi / 2), [-8, 0, 0], atol=1e-12)
    np.testing.assert_allclose(PushSpec(0, 8.0, "down").world_force(1.0), [0, 0, -8], atol=1e-12)
    with pytest.raises(InputError):
        PushSpec(0, 8.0, "sideways")


def test_tree_clearance_is_the_distance_to_trunk_or_crown():
    t = Tree(0.0, 0.0, height=10.0, trunk_radius=0.2, crown_radius=2.0)
    f = Forest((t,), bird_radius_m=0.26)
    # beside the trunk at 5 m height, 3 m from the axis: 3 - 0.2 - 0.26
    assert f.clearance(np.array([3.0, 0, 5.0]))[0] == pytest.approx(3 - 0.2 - 0.26)
    # above the crown's centre by 5 m: 5 - 2 - 0.26
    assert f.clearance(np.array([0.0, 0, 15.0]))[0] == pytest.approx(5 - 2 - 0.26)
    # inside the crown: negative
    assert f.clearance(np.array([0.5, 0.5, 10.0]))[0] < 0


def test_flock_separation_is_the_closest_approach_at_equal_times():
    # two birds on crossing straight lines, one 0.5 s late: closest approach of
    # a(t) = (7t, 0, 0) and b(t) = (7, 7(t - 1.5), 1) is at t = 1.25 s: |(-1.75, 1.75, -1)|
    t = np.linspace(0, 3, 3001)
    a = np.stack([7 * t, 0 * t, 0 * t], 1)
    b = np.stack([7 + 0 * t, 7 * (t - 1.5), 1 + 0 * t], 1)
    assert min_separation([(t, a), (t, b)]) == pytest.approx(np.sqrt(1.75**2 * 2 + 1), abs=1e-3)


@pytest.mark.slow
def test_eval_runs_a_scenario_and_writes_table_json_and_plot(tmp_path, capsys):
    js, plots = tmp_path / "e.json", tmp_path / "plots"
    rc = main(["eval", "--scenario", "wind-breeze", "--quick", "--workers", "1", "--plots", str(plots),
               "--json", str(js)])
    s = json.loads(js.read_text())
    r = s["scenarios"][0]
    out = capsys.readouterr().out
    assert "wind-breeze" in out and "Ep m" in out
    # 20 m straight in air swinging 1.5 m/s side to side at 0.3 Hz: uncorrected, the bird
    # would drift with the air by up to 1.5 / (2 pi 0.3) = 0.8 m each way; it must stay within
    # the 3 m tube and reach the end
    assert r["status"] == "completed" and rc == 0, r
    assert r["metrics"]["max_path_distance"] < 3.0
    assert (plots / "wind-breeze.png").stat().st_size > 10_000


def test_eval_cli_errors_are_one_line(tmp_path, capsys):
    assert main(["eval", "--scenario", "nope"]) == 2
    err = capsys.readouterr().err
    assert "nope" in err and len(err.strip().splitlines()) == 1
    assert main(["eval", "--scenario", "path"]) == 2
    assert "--path" in capsys.readouterr().err
    f = tmp_path / "file"
    f.write_text("x")
    assert main(["eval", "--plots", str(f)]) == 2
    assert "folder" in capsys.readouterr().err
    assert main(["eval", "--list", "--json", str(tmp_path / "l.json")]) == 0
    listed = {r["name"] for r in json.loads((tmp_path / "l.json").read_text())["scenarios"]}
    assert set(scenarios.names()) <= listed
    # a bad path file is refused before any run starts, as fly and view refuse it: exit 2, one
    # line naming the file, and no JSON (a failed run in the table used to be written)
    for name, content in (("nan.csv", "x,y,z\n0,0,0\nnan,1,1\n"), ("noheader.csv", "1,2,3\n4,5,6\n"),
                          ("one.csv", "x,y,z\n0,0,0\n")):
        f, js = tmp_path / name, tmp_path / f"{name}.json"
        f.write_text(content)
        assert main(["eval", "--path", str(f), "--json", str(js)]) == 2
        err = capsys.readouterr().err
        assert name in err and len(err.strip().splitlines()) == 1, err
        assert not js.exists() and not Path(f"{js}.partial").exists()


@pytest.mark.slow
def test_eval_follows_a_users_path_that_is_no_scenario(tmp_path, capsys):
    # an S of two opposite 25 m turns, level (bank atan(49 / (9.81 * 25)) = 11 deg each)
    a = np.linspace(0, np.pi / 2, 20)
    first = np.stack([25 * np.sin(a), 25 * (1 - np.cos(a))], 1)
    second = np.array([50.0, 25.0]) + 25 * np.stack([-np.cos(a), np.sin(a)], 1)[1:]
    xy = np.vstack([first, second])
    f = tmp_path / "s.csv"
    np.savetxt(f, np.column_stack([xy, np.full(len(xy), 10.0)]), delimiter=",", header="x,y,z",
               comments="")
    js = tmp_path / "p.json"
    assert main(["eval", "--path", str(f), "--workers", "1", "--json", str(js)]) == 0
    r = json.loads(js.read_text())["scenarios"][0]
    assert r["status"] == "completed" and r["metrics"]["max_path_distance"] < 2.0, r
    # what the path asks, reported: level; the arcs' 25 m, tightened to ~20 m where the
    # spline (continuous curvature) joins the two opposite turns
    g = r["metrics"]["path_geometry"]
    assert g["max_climb_deg"] < 1e-6 and g["max_descent_deg"] < 1e-6
    assert 15.0 < g["min_radius_m"] < 25.5 and 30.0 < g["min_radius_at_m"] < 50.0, g
    # the turn held over 2 m and its load factor at 7 m/s, sqrt(1 + (v^2 / (g r))^2)
    assert g["min_radius_m"] <= g["sustained_radius_m"] < 25.5
    assert r["metrics"]["sustained_turn_load_factor"] == pytest.approx(
        np.hypot(1.0, 49.0 / (9.81 * g["sustained_radius_m"])), rel=1e-9)
    out = capsys.readouterr().out
    assert "radius >= " in out and "held over 2 m" in out


@pytest.mark.slow
def test_eval_follows_a_users_3_m_circle_by_slowing_into_it(tmp_path):
    """The tightest of the user paths: a level 3 m circle from its first point (no lead-in,
    entered at 7 m/s). At 7 m/s it needs sqrt(1 + (49 / (9.81 * 3))^2) = 1.94 g; at 6 m/s
    1.58 g, past the 1.39 g (a 3.8 m turn) the wing sustains there (studies/
    dove_turn_limit.py): a dove that follows it has flown it slower than 6 m/s on average.

    One verdict here is a draw near the tube's edge (seven starts under 1 mm/s apart: with
    the corrections 1.91-2.20 m off at most on six, 3.59 m and lost on one; without them
    lost on all seven, 3.6-15.6 m), so the verdicts are asserted over five starts: the median
    start with the corrections stays in the 3 m tube, and without them four of five leave it."""
    from flapsim.bird.tasks.flight_tasks import Task, fly_task
    from flapsim.bird.tasks.path_control import load_path

    t = np.linspace(0.0, 2 * np.pi, 49)
    f = tmp_path / "c3.csv"
    np.savetxt(f, np.column_stack([3 * np.sin(t), 3 * (1 - np.cos(t)), np.full(t.size, 10.0)]),
               delimiter=",", header="x,y,z", comments="")
    js = tmp_path / "r.json"
    main(["eval", "--path", str(f), "--workers", "1", "--json", str(js)])
    m = json.loads(js.read_text())["scenarios"][0]["metrics"]
    assert m["way_speed_m_s"] == m["progress_m"] / m["simulated_s"]  # what the note reports
    path = load_path(f)
    starts = (0.0, 0.0007, -0.0004, 0.0002, -0.0009)  # m/s of start speed
    refined = [fly_task(Task(path, start_speed_change=dv), refine=2) for dv in starts]
    far = np.median([r.metrics["max_path_distance"] for r in refined])
    assert far < 3.0, [r.metrics["max_path_distance"] for r in refined]
    assert np.median([r.metrics["way_speed_m_s"] for r in refined]) < 6.0
    # the regression's answers alone (no simulated corrections) spiral out of the 3 m tube:
    # on at least four of the five starts (the closest of seven left it by only 0.6 m)
    alone = [fly_task(Task(path, start_speed_change=dv), refine=0) for dv in starts]
    assert sum(r.status == "lost" for r in alone) >= 4, [r.metrics["max_path_distance"] for r in alone]


def test_what_a_path_asks_per_wingbeat_is_the_arc_over_the_radius():
    # a bird exactly on a circle of radius R, flying d per wingbeat: the path's heading turns
    # d / R rad a wingbeat (left, +); along the reversed circle, -d / R. The spline's
    # curvature is within 0.5 % of the circle's away from its ends (48 points a turn)
    from flapsim.bird.tasks import path_shapes as paths
    from flapsim.bird.tasks.flight_tasks import _path_steering
    from flapsim.bird.tasks.path_control import FlightPath

    R, d = 5.0, 0.7
    path = paths.inclined_circle(R, 0.0, turns=1.0)
    s = np.arange(5.0, path.length - 6.0, d)
    pos = path.point(s)
    progress = [0.0, *s]  # the closest point as each wingbeat began, after the initial one
    lo, hi = _path_steering(path, progress, pos)
    assert lo == pytest.approx(np.degrees(d / R), rel=5e-3)
    assert hi == pytest.approx(np.degrees(d / R), rel=5e-3)
    rev = FlightPath(path.points[::-1])
    s = np.arange(6.0, rev.length - 5.0, d)
    lo, hi = _path_steering(rev, [0.0, *s], rev.point(s))
    assert hi == pytest.approx(-np.degrees(d / R), rel=5e-3) and lo < 0


def test_eval_options_reach_every_flight(monkeypatch):
    """--speed and the path configuration replace the task's own values in the task flown
    (without a configuration: the dove's defaults); the controller configuration reaches
    fly_task."""
    import dataclasses

    import flapsim.scenarios.flight as flight_scenarios
    from flapsim.bird.control.config import ControllerConfig
    from flapsim.bird.tasks.config import PathControlConfig
    from flapsim.bird.tasks.flight_tasks import DEFAULT_BANK_LEAD_S, Task
    from flapsim.bird.tasks.path_shapes import straight
    from flapsim.scenarios import EvalOptions
    from flapsim.scenarios.flight import _fly_task

    seen = []
    monkeypatch.setattr(flight_scenarios, "fly_task",
                        lambda task, *a, **kw: seen.append((task, kw["config"])))
    task = Task(straight(10.0))
    _fly_task(task, EvalOptions(), record=False)
    path = PathControlConfig(bank_lead_s=0.1, aoa_per_g_deg=30.0, max_bank_deg=50.0)
    tuned = ControllerConfig(refine=1)
    _fly_task(task, EvalOptions(speed=5.5, path_control=path, controller=tuned), record=False)
    (first, none), (second, config) = seen
    assert none is None and config is tuned
    assert (first.speed, first.bank_lead_s, first.max_bank_deg, first.turn_speed_floor) == (
        7.0, DEFAULT_BANK_LEAD_S["rigid"], 60.0, 6.5)
    assert (second.speed, second.bank_lead_s, second.aoa_per_g_deg, second.max_bank_deg) == (
        5.5, 0.1, 30.0, 50.0)
    # the lowest speed asked for a turn is never above the speed asked
    assert second.turn_speed_floor == 5.5
    assert first.max_climb_deg == second.max_climb_deg == 15.0
    assert dataclasses.replace(second, speed=7.0, **{f: getattr(task, f) for f in (
        "bank_lead_s", "aoa_per_g_deg", "max_bank_deg", "climb_per_speed_deficit",
        "max_climb_deg", "turn_load_factor", "turn_speed_floor")}) == task


def test_wilsons_interval_is_its_closed_form():
    # Wilson's score interval, from its formula worked by hand: 7 of 10 at z = 1.96 is
    # (7 + 1.9208 -+ 1.96 sqrt(2.1 + 0.9604)) / 13.8416 = 0.3968..0.8922 (the textbook values);
    # 0 of 10 starts at 0 and 10 of 10 ends at 1, never an empty interval
    lo, hi = scenarios.completion_interval(7, 10)
    assert (lo, hi) == pytest.approx((0.3968, 0.8922), abs=1e-4)
    assert scenarios.completion_interval(0, 10) == pytest.approx((0.0, 0.2775), abs=1e-4)
    assert scenarios.completion_interval(10, 10) == pytest.approx((0.7225, 1.0), abs=1e-4)
    with pytest.raises(InputError, match="completion rate"):
        scenarios.completion_interval(3, 2)


def test_eval_starts_flies_each_scenario_from_perturbed_starts_and_counts_them(tmp_path, capsys):
    # three starts of the quick level 3.6 m circle: the first as it is, the other two with the
    # forward speed changed by the seed's uniform draws within +-1 mm/s (drawn here
    # independently); each run reaches the flight (the largest distances differ: a change of
    # 0.3 mm/s that never reached the dove would fly the same metres to the last digit), and
    # the count is the runs' own verdicts
    js = tmp_path / "s.json"
    main(["eval", "--scenario", "climb-turn-0", "--quick", "--starts", "3", "--workers", "1",
          "--json", str(js)])
    out = json.loads(js.read_text())
    runs = out["scenarios"]
    want = [0.0, *np.random.default_rng(0).uniform(-1e-3, 1e-3, 2)]
    assert [r["start_speed_change_m_s"] for r in runs] == pytest.approx(want, abs=1e-15)
    far = [r["metrics"]["max_path_distance"] for r in runs]
    assert len(set(far)) == 3, far
    spread = out["starts"]["scenarios"]["climb-turn-0"]
    k = sum(r["status"] == "completed" for r in runs)
    assert (spread["completed"], spread["starts"]) == (k, 3)
    assert spread["max_path_distance_range_m"] == [min(far), max(far)]
    assert "completed over 3 starts" in capsys.readouterr().out


def test_eval_starts_errors_are_one_line(capsys):
    for argv, words in ((["--starts", "0"], "--starts must be"),
                        (["--starts", "2", "--start-jitter", "nan"], "--start-jitter"),
                        (["--starts", "2", "--start-jitter", "0.5"], "--start-jitter"),
                        (["--starts", "2", "--scenario", "swim-cross-current"], "--scenario flight"),
                        (["--starts", "2", "--table1"], "drop --starts")):
        assert main(["eval", *argv]) == 2
        err = capsys.readouterr().err
        assert words in err and len(err.strip().splitlines()) == 1, err


def test_a_family_name_selects_its_part_of_all():
    # 'flight' and 'swim' split 'all' by family (what --starts needs: flight only), in order
    import argparse

    from flapsim.cli.commands.eval import _names

    every = scenarios.names(all_only=True)
    for family in ("flight", "swim"):
        got = _names(argparse.Namespace(path=None, scenario=family))
        assert got == [n for n in every if scenarios.get(n).family == family]
    assert sorted(_names(argparse.Namespace(path=None, scenario="flight"))
                  + _names(argparse.Namespace(path=None, scenario="swim"))) == sorted(every)


def test_the_sharp_sinusoid_is_flown_and_mirrored(monkeypatch):
    # sinusoid-sharp (and -rapid) fly the path and its mirror image: the dove and the
    # regression's samples are mirror images of themselves, so the mirror flight's first
    # wingbeats turn exactly the other way (until the chaotic flight amplifies rounding: 1e-6
    # deg over the first ten wingbeats, where they turn by degrees), and the range reported
    # both ways spans the two flights'
    from flapsim.scenarios import flight

    flown = []
    real = flight._fly

    def keep(sc, opt, task, tag=""):
        r, files = real(sc, opt, task, tag)
        flown.append((task, r))
        return r, files

    monkeypatch.setattr(flight, "_fly", keep)
    sc = scenarios.get("sinusoid-sharp")
    assert not sc.in_all
    res = sc.runner(sc, scenarios.EvalOptions(quick=True))
    (task, r), (_, rm) = flown
    n = 10
    assert np.abs(r.steering_deg[:n]).max() > 1.0
    np.testing.assert_allclose(rm.steering_deg[:n], -r.steering_deg[:n], atol=1e-6)
    m = res["metrics"]
    assert m["mirror"]["steering_range_deg"] == [float(np.min(rm.steering_deg)),
                                                 float(np.max(rm.steering_deg))]
    assert m["steering_range_both_ways_deg"] == [
        min(np.min(r.steering_deg), np.min(rm.steering_deg)),
        max(np.max(r.steering_deg), np.max(rm.steering_deg))]
    # in the tube: the wingbeats that end within it, found here from the flown positions
    off = np.array([task.path.distance(p) for p in r.positions[1:]])
    inside = len(off) if np.all(off <= task.tube_m) else int(np.argmax(off > task.tube_m))
    assert inside >= n  # the quick path's first wave is followed
    assert r.metrics["steering_range_in_tube_deg"] == [float(np.min(r.steering_deg[:inside])),
                                                       float(np.max(r.steering_deg[:inside]))]


@pytest.mark.parametrize("ranges, wider, word", [
    # (the path's flight, its mirror's), in the tube; the capture's is -12.5..+7.0
    (([-13.8, 12.2], [-10.6, 9.0]), {"right": True, "left": True}, "wider on both sides"),
    (([-11.5, 11.5], [-11.8, 10.0]), {"right": False, "left": True}, "wider on the left only"),
    (([-12.0, 6.0], [-12.4, 6.9]), {"right": False, "left": False}, "wider on neither side"),
    (([-12.0, 6.0], [-12.6, 6.9]), {"right": True, "left": False}, "wider on the right only"),
])
def test_the_slow_sinusoid_flies_the_sharp_path_at_the_captures_speed(monkeypatch, capsys, ranges,
                                                                      wider, word):
    # sinusoid-slow asks 5 m/s, about the capture's fastest (2.0-5.1 m/s, the paper's sec. 7),
    # on sinusoid-sharp's path; each side of the steering range is judged against the
    # capture's over both flights while in the tube (the flights are stubbed: the verdict's
    # arithmetic, on ranges chosen each side of -12.5 and +7.0)
    from types import SimpleNamespace

    from flapsim.cli.commands.eval import print_table
    from flapsim.scenarios import flight

    flown = []

    def fake(sc, opt, task, tag=""):
        flown.append(task)
        rng = ranges[len(flown) - 1]
        return SimpleNamespace(status="lost", ok=False, reason="", metrics={
            "steering_range_deg": rng, "steering_range_in_tube_deg": rng}), []

    monkeypatch.setattr(flight, "_fly", fake)
    slow, sharp = scenarios.get("sinusoid-slow"), scenarios.get("sinusoid-sharp")
    assert not slow.in_all
    res = slow.runner(slow, scenarios.EvalOptions())
    task, mirrored = flown
    assert task.speed == flight.CAPTURE_TOP_SPEED == 5.0 and mirrored.speed == 5.0
    assert flight.capture_steering_range() == [-12.5, 7.0]
    m = res["metrics"]
    assert m["steering_wider_than_capture"] == wider
    np.testing.assert_allclose(mirrored.path.points * [1, -1, 1], task.path.points)
    # the same path as sinusoid-sharp's, flown at 7 m/s
    flown.clear()
    sharp.runner(sharp, scenarios.EvalOptions())
    assert flown[0].speed == 7.0
    np.testing.assert_allclose(flown[0].path.points, task.path.points)
    print_table([{**res, "scenario": "sinusoid-slow", "family": "flight"}])
    assert f"(capture -12.5..+7.0: {word})" in capsys.readouterr().out


@pytest.mark.parametrize("radius, speed, feathers, slow", [
    (3.0, None, "rigid", True), (25.0, None, "rigid", False), (3.0, 5.5, "rigid", True),
    (4.0, 5.5, "rigid", False), (3.0, None, "modal", None)])
def test_a_users_path_is_told_when_its_turn_asks_more_lift_than_the_wing_holds(
        monkeypatch, capsys, tmp_path, radius, speed, feathers, slow):
    # the flight is stubbed: this is the note's arithmetic. The wing holds 1.23 g at 7 m/s and
    # 1.35 / 1.39 g at 5 / 6 m/s (studies/dove_turn_limit.py), so at 5.5 m/s 1.37 g. A level
    # circle of r held at v needs sqrt(1 + (v^2 / g r)^2): 3 m at 7 m/s 1.94 g and 25 m 1.09 g;
    # at 5.5 m/s 3 m asks 1.45 g (over 1.37) and 4 m 1.30 g (under). The tightest turn the wing
    # holds is v^2 / (g sqrt(n^2 - 1)): 7.0 m at 7 m/s (the study's 6.9 m, from n unrounded),
    # 3.3 m at 5.5 m/s. Modal feathers were not measured: nothing is said.
    from types import SimpleNamespace

    from flapsim.cli.commands.eval import print_table
    from flapsim.scenarios import flight

    monkeypatch.setattr(flight, "_fly", lambda sc, opt, task, tag="": (SimpleNamespace(
        status="completed", ok=True, reason="", metrics={}), []))
    a = np.linspace(0.0, 2 * np.pi, 49)
    f = tmp_path / "c.csv"
    np.savetxt(f, np.column_stack([radius * np.sin(a), radius * (1 - np.cos(a)), np.full(49, 10.0)]),
               delimiter=",", header="x,y,z", comments="")
    opt = scenarios.EvalOptions(path_file=str(f), speed=speed, feathers=feathers)
    res = scenarios.get("path").runner(scenarios.get("path"), opt)
    m = res["metrics"]
    v = speed or 7.0
    if slow is None:
        assert "wing_load_factor" not in m
    else:
        n = {7.0: 1.23, 5.5: 1.37}[v]
        assert m["wing_load_factor"] == pytest.approx(n, abs=1e-12)
        assert m["wing_min_turn_radius_m"] == pytest.approx({7.0: 6.97, 5.5: 3.29}[v], abs=0.01)
        # the natural spline bends tighter than the points' circle near its ends (held over
        # 2 m: 2.9 m for 3 m, 21 m for 25 m), never wider
        r = m["path_geometry"]["sustained_radius_m"]
        assert 0.8 * radius < r <= 1.01 * radius
        assert (m["sustained_turn_load_factor"] > n) == slow
    print_table([{**res, "scenario": "path", "family": "flight"}])
    out = capsys.readouterr().out
    assert ("must slow into it" in out) == bool(slow), out


def test_the_steering_in_the_tube_stops_where_the_bird_left_it():
    # a tube too narrow for the sharp sinusoid: the bird leaves it within a few wingbeats and
    # flies on; the range "in the tube" covers the wingbeats that ended within it, found here
    # from the flown positions and the path
    from flapsim.bird.tasks import path_shapes as paths
    from flapsim.bird.tasks.flight_tasks import Task, fly_task

    task = Task(paths.sinusoid(amplitude_m=3.0, wavelength_m=10.0, waves=1.0), tube_m=0.5)
    r = fly_task(task)
    assert r.status == "lost"
    off = np.array([task.path.distance(p) for p in r.positions[1:]])
    inside = int(np.argmax(off > task.tube_m))
    assert 0 < inside < len(r.steering_deg)
    assert r.metrics["steering_range_in_tube_deg"] == [float(np.min(r.steering_deg[:inside])),
                                                       float(np.max(r.steering_deg[:inside]))]


def test_every_flight_scenario_flies_at_its_databases_speed(monkeypatch):
    """A database describes the bird at the speed its pre-states were drawn around: a cruise
    database sampled at 8.5 m/s flown at 7 sinks on every path (its wingbeats cannot hold a
    slower bird up), so every scenario without a speed of its own (the pushes, the forest and
    the flock as much as the paths) asks that speed."""
    import contextlib

    import flapsim.scenarios.flight as flight_scenarios
    from flapsim.bird.control.controller import bundled_database_path
    from flapsim.bird.control.database import read_header

    db = bundled_database_path("cruise")
    sampled_at = float(read_header(db)["config"]["cruise_speed"])  # the header, as written
    assert sampled_at != 7.0  # else this test could not tell the database's speed from the default

    class Flown(Exception):
        pass

    seen: dict[str, float] = {}

    def record(task, opt, record):
        seen[name] = task.speed
        raise Flown

    monkeypatch.setattr(flight_scenarios, "_fly_task", record)
    for name in scenarios.names(family="flight"):
        sc = scenarios.get(name)
        if sc.params.get("shape") == "file":
            continue  # a user's path: needs --path
        with contextlib.suppress(Flown):
            scenarios.run_scenario(name, scenarios.EvalOptions(db=str(db), quick=True))
        assert seen.get(name) == sc.params.get("speed", sampled_at), name
