"""The flight paper's evaluation suite (its sec. 7) as scenarios of the shared registry.

Every scenario flies the learned controller (``options.db``, default the bundled
database) along a path with :func:`flapsim.bird.tasks.flight_tasks.fly_task` and reports the paper's
Ep, Er, Eo, Ef per wingbeat, whether the bird got lost, and the scenario's own numbers
(collisions, steering range, the push table, ...). Plots (``options.plots_dir``): the
path against the flown trajectory in 3D and the metrics per wingbeat; videos
(``options.video_dir``): a chase camera.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np

from flapsim.bird.control.controller import database_dove, database_speed
from flapsim.bird.control.targets import GRAVITY
from flapsim.bird.flight.capture import DATA_FILE, load_capture
from flapsim.bird.flight.limits import turn_radius
from flapsim.bird.flight.video import dove_video
from flapsim.bird.tasks import path_shapes as paths
from flapsim.bird.tasks.config import PathControlConfig
from flapsim.bird.tasks.flight_tasks import Forest, PushSpec, Task, Tree, fly_task, wing_load_factor
from flapsim.bird.tasks.path_control import FlightPath, load_path
from flapsim.core.errors import InputError
from flapsim.fluid import flow
from flapsim.scenarios.plots import flight_plot, plot_stem
from flapsim.scenarios.registry import EvalOptions, Scenario, get, register

PUSH_FORCES_N = (3.0, 6.0, 8.0, 10.0, 12.0)
"""The paper pushed with 3-12 N (its Fig. 16); it withstood up to 8 N."""
PUSH_TUBE_M = 10.0
"""A push of 8 N for 0.1 s changes a 0.17 kg dove's velocity by 4.7 m/s (two thirds of its
speed): it is carried metres off whatever it does, so surviving means staying within this
tube, reaching the path's end and being back on it (:data:`PUSH_BACK_M`: the last wingbeat's end
from the path's line, :meth:`~flapsim.bird.tasks.path_control.FlightPath.off_path`)."""
PUSH_BACK_M = 1.5
LEFT_PLUCKS = {"plucked-3": (2, 5, 8), "plucked-4": (2, 5, 7, 8)}
"""Primaries plucked on the left wing, counted from the outermost (the paper's Fig. 15)."""
N_PRIMARIES = 10
CAPTURE_TOP_SPEED = 5.0
"""``sinusoid-slow``'s speed asked, m/s: about the fastest of the capture's flights (2.0-5.1 m/s,
the flight paper's sec. 7), which its steering range of -12.5..+7.0 deg per wingbeat was
flown at."""


def primary_name(side: str, from_outermost: int) -> str:
    """The model's name of the ``from_outermost``-th primary (1 = outermost = p10)."""
    return f"{side}_p{N_PRIMARIES + 1 - from_outermost}"


# -- shared helpers -------------------------------------------------------------------------

def _summary(r) -> dict:
    keep = ("Ep_per_wingbeat", "Er_per_wingbeat", "Eo_per_wingbeat", "Ef_per_wingbeat",
            "Ep", "Er", "Eo", "Ef", "max_path_distance", "wingbeats", "simulated_s", "progress_m",
            "path_length_m", "collisions", "steering_range_deg", "steering_range_in_tube_deg",
            "path_steering_range_deg",
            "elevation_range_deg",
            "real_time_factor", "way_speed_m_s", "min_tree_clearance")
    out = {k: r.metrics[k] for k in keep if k in r.metrics}
    if getattr(r, "refine", None) is not None:
        out["refine"] = r.refine  # the controller's simulated corrections per wingbeat
        out["refine_goal"] = getattr(r, "refine_goal", None)
    if getattr(r, "path_target", None):
        out["path_target"] = r.path_target  # the path target's settings, the dove's defaults resolved
    if getattr(r, "lookahead", None) is not None:
        # references simulated ahead on the second core, and on the spot (wall time only)
        out["lookahead_hits"], out["lookahead_misses"] = r.lookahead
    return out


def _fly(sc: Scenario, opt: EvalOptions, task, tag: str = "") -> tuple:
    r = _fly_task(task, opt, record=bool(opt.video_dir))
    files = _outputs(sc, opt, task, r, tag)
    return r, files


_TASK_OPTIONS = ("speed", "start_speed_change")


def _fly_task(task, opt: EvalOptions, record: bool):
    """:func:`~flapsim.bird.tasks.flight_tasks.fly_task` with the options' controller and
    path target."""
    # the options given (None: the task's own), by the same names on both
    given = {name: getattr(opt, name) for name in _TASK_OPTIONS if getattr(opt, name) is not None}
    task = dataclasses.replace(task, **given)
    task = (opt.path_control or PathControlConfig.for_dove(task.feathers)).apply(task)
    return fly_task(task, opt.db, method=opt.method, k=opt.k, mirror=opt.mirror, record=record,
                    predict=opt.predict, config=opt.controller)


def _outputs(sc: Scenario, opt: EvalOptions, task, r, tag: str = "", mates=()) -> list[str]:
    """The run's plot and video (``mates``: the other birds' (times, positions) tracks, drawn
    in the video)."""
    files: list[str] = []
    stem = plot_stem(sc.name, opt.path_file if sc.params.get("shape") == "file" else None, tag)
    if opt.plots_dir:
        out = Path(opt.plots_dir) / f"{stem}.png"
        flight_plot(task.path, r, out, title=f"{stem}: {r.status}", forest=task.forest)
        files.append(str(out))
    if opt.video_dir and r.qpos is not None and len(r.qpos):
        out = Path(opt.video_dir) / f"{stem}.mp4"
        path = task.path
        dove_video(database_dove(opt.db, opt.feathers), r.qpos, out, opt.fps, *opt.size,
                   slowmo=opt.slowmo, camera=opt.camera, min_seconds=0.0,
                   path_points=path.point(np.linspace(0.0, path.length, 600)),
                   forest=task.forest, wingbeat_times=r.times, mates=mates,
                   metric=("distance from path", path.distance))
        files.append(str(out))
    return files


def _result(r, files: list[str], **extra) -> dict:
    return {"status": r.status, "ok": r.ok, "reason": r.reason, "metrics": {**_summary(r), **extra},
            "files": files}


# -- path scenarios -------------------------------------------------------------------------

def run_path(sc: Scenario, opt: EvalOptions) -> dict:
    """Follow ``sc.params['shape']`` (a :mod:`flapsim.bird.tasks.path_shapes` function and its
    arguments), or the user's ``options.path_file``."""

    p = dict(sc.params)
    if p.get("shape") == "file":
        if not opt.path_file:
            raise InputError("the path scenario needs a path file: flapsim eval --path FILE")
        path = load_path(opt.path_file)
    else:
        shape = getattr(paths, p["shape"])
        args = dict(p.get("args", {}))
        if opt.quick and "quick_args" in p:
            args.update(p["quick_args"])
        path = shape(**args)
    task = Task(path, wind=tuple(p.get("wind", (0.0, 0.0, 0.0))), flow=_flow(p.get("flow", ())),
                plucked=tuple(p.get("plucked", ())), tube_m=p.get("tube_m", 3.0),
                feathers=opt.feathers,
                speed=float(p.get("speed", database_speed(opt.db, opt.feathers))))
    r, files = _fly(sc, opt, task)
    geometry = path.geometry()
    extra = {"path_geometry": geometry.as_dict()}
    if p.get("mirror_too"):
        extra.update(_mirror_flight(sc, opt, task, r, files))
    if np.isfinite(geometry.sustained_radius_m):
        # the level turn's load factor at the speed flown: sqrt(1 + (v^2 / (g r))^2)

        v = opt.speed if opt.speed is not None else task.speed
        extra["sustained_turn_load_factor"] = float(
            np.hypot(1.0, v**2 / (GRAVITY * geometry.sustained_radius_m)))
        extra["speed_asked"] = float(v)
        if opt.feathers == "rigid":
            # what the wing holds there (measured for rigid feathers only): a path that asks
            # more can be followed only by slowing into its turns

            n = wing_load_factor(v)
            if n is not None:
                extra["wing_load_factor"] = n
                extra["wing_min_turn_radius_m"] = turn_radius(n, v)
    if "capture_steering_deg" in p:
        capture = capture_steering_range()
        extra["capture_steering_range_deg"] = capture
        # while following the path (a lost bird stalls and swings its heading), both ways
        # where the path was mirrored too
        tube = (extra.get("steering_range_in_tube_both_ways_deg")
                or r.metrics.get("steering_range_in_tube_deg"))
        if tube:
            extra["steering_wider_than_capture"] = {"right": bool(tube[0] < capture[0]),
                                                    "left": bool(tube[1] > capture[1])}
    return _result(r, files, **extra)


def _mirror_flight(sc: Scenario, opt: EvalOptions, task, r, files: list[str]) -> dict:
    """The task's path mirrored left for right, flown too: a path turning one way first asks
    each side's extreme turn at another moment of the flight, so the controller's steering
    range to either side is measured over both (the dove and the regression's samples are
    mirror images of themselves: each flight is the other's mirror wherever they meet the
    same request). ``files`` gets the mirror flight's."""


    mirrored = dataclasses.replace(task, path=FlightPath(np.asarray(task.path.points, float)
                                                         * np.array([1.0, -1.0, 1.0])))
    rm, more = _fly(sc, opt, mirrored, tag="mirror")
    files.extend(more)
    keys = ("steering_range_deg", "steering_range_in_tube_deg", "path_steering_range_deg")
    out = {"mirror": {"status": rm.status, "reason": rm.reason,
                      **{k: rm.metrics.get(k) for k in keys}}}
    for key, both in (("steering_range_deg", "steering_range_both_ways_deg"),
                      ("steering_range_in_tube_deg", "steering_range_in_tube_both_ways_deg")):
        ranges = [x for x in (r.metrics.get(key), rm.metrics.get(key)) if x]
        if ranges:
            out[both] = [min(a for a, _ in ranges), max(b for _, b in ranges)]
    return out


def _flow(spec) -> tuple:
    return tuple(getattr(flow, kind)(**kw) for kind, kw in spec)


def capture_steering_range() -> list[float]:
    """Smallest and largest steering per wingbeat in the bundled capture set, deg."""

    cap = load_capture(DATA_FILE)
    return [float(np.min(cap.steering_deg)), float(np.max(cap.steering_deg))]


# -- pushes ---------------------------------------------------------------------------------

def run_pushes(sc: Scenario, opt: EvalOptions) -> dict:
    """Level straight flight pushed once at 1 s, for each force of the table; survived =
    never farther than :data:`PUSH_TUBE_M` from the 60 m path, and back within
    :data:`PUSH_BACK_M` of it at its end."""

    direction = sc.params["direction"]
    forces = (8.0,) if opt.quick else PUSH_FORCES_N
    table, files, worst, sim = [], [], None, 0.0
    speed = database_speed(opt.db, opt.feathers)  # the database's header, read once
    for f in forces:
        task = Task(paths.straight(40.0 if opt.quick else 60.0),
                    pushes=(PushSpec(1.0, f, direction),), tube_m=PUSH_TUBE_M,
                    feathers=opt.feathers, speed=speed)
        r = _fly_task(task, opt, record=bool(opt.video_dir))
        files += _outputs(sc, opt, task, r, tag=f"{f:g}N")
        sim += r.metrics["simulated_s"]
        back = task.path.off_path(r.positions[-1])
        survived = r.ok and back <= PUSH_BACK_M
        table.append({"newtons": f, "status": r.status, "survived": survived,
                      "max_path_distance": r.metrics.get("max_path_distance"),
                      "final_path_distance": back,
                      "reason": r.reason or ("" if survived else f"ended {back:.1f} m off the path")})
        if not survived and worst is None:
            worst = f
    survived_8 = all(row["survived"] for row in table if row["newtons"] <= 8.0)
    strongest = max([row["newtons"] for row in table if row["survived"]], default=0.0)
    why = "" if worst is None else table[forces.index(worst)]["reason"]
    return {"status": "completed" if survived_8 else "lost", "ok": survived_8,
            "reason": "" if survived_8 else f"not survived at {worst:g} N ({why})",
            "metrics": {"direction": direction, "strongest_survived_N": strongest,
                        "first_lost_N": worst, "table": table, "simulated_s": sim},
            "files": files}


# -- flock ----------------------------------------------------------------------------------

def run_flock(sc: Scenario, opt: EvalOptions) -> dict:
    """A leader on a path and followers on perturbed copies of it (the paper: control points
    moved randomly within 1 m), each flown by its own controller; collisions between birds
    are trunks closer than one span (0.51 m) at the same instant."""

    p = sc.params
    rng = np.random.default_rng([opt.seed, 7])
    # few control points, as the paper's B-spline: a 1 m jitter on points ~25 m apart bends
    # the path gently
    leader = paths.figure8(**(p["quick_args"] if opt.quick else p["args"]), n=13)
    birds = p["quick_birds"] if opt.quick else p["birds"]
    offsets = p["offsets"][:birds]
    results, files, tracks, tasks = [], [], [], []
    speed = database_speed(opt.db, opt.feathers)  # the database's header, read once
    for i, off in enumerate(offsets):
        path = leader if i == 0 else paths.perturbed_copy(leader, off, p["jitter_m"], rng,
                                                          horizontal=True)
        task = Task(path, feathers=opt.feathers, speed=speed)
        r = _fly_task(task, opt, record=True)
        results.append(r)
        tracks.append(_track(r))
        tasks.append(task)
        if not opt.video_dir:
            r.qpos = None  # every step's full state (~100 MB a bird) is only needed for a video
    for i, (task, r) in enumerate(zip(tasks, results, strict=True)):
        # after every bird has flown: each bird's video shows its flock mates
        files += _outputs(sc, opt, task, r, tag=f"bird{i}", mates=tracks[:i] + tracks[i + 1:])
        r.qpos = None
    sep = min_separation(tracks)
    collided = bool(sep < p["collision_m"])
    ok = all(r.ok for r in results) and not collided
    lost = [i for i, r in enumerate(results) if not r.ok]
    reason = "; ".join(([f"bird(s) {lost} lost"] if lost else [])
                       + ([f"birds came {sep:.2f} m close"] if collided else []))
    return {"status": "completed" if ok else "lost", "ok": ok, "reason": reason,
            "metrics": {"birds": len(results), "min_separation_m": sep, "collisions": int(collided),
                        "simulated_s": float(sum(r.metrics["simulated_s"] for r in results)),
                        "Ef_per_wingbeat": float(np.mean([r.metrics.get("Ef_per_wingbeat", np.nan)
                                                          for r in results])),
                        "birds_lost": len(lost)},
            "files": files}


def _track(r) -> tuple[np.ndarray, np.ndarray]:
    """(times, positions) of every step (recorded) of a flown task."""
    n = len(r.qpos)
    t = r.times[0] + (np.arange(n) + 1) * (r.times[-1] - r.times[0]) / n
    return t, r.qpos[:, 0:3].copy()


def min_separation(tracks: list[tuple[np.ndarray, np.ndarray]]) -> float:
    """Smallest distance between any two birds at the same instant (interpolated onto the
    shortest common time grid)."""
    best = np.inf
    for i in range(len(tracks)):
        for j in range(i + 1, len(tracks)):
            (ti, pi), (tj, pj) = tracks[i], tracks[j]
            hi = min(ti[-1], tj[-1])
            t = np.arange(max(ti[0], tj[0]), hi, 0.01)
            if len(t) == 0:
                continue
            a = np.stack([np.interp(t, ti, pi[:, c]) for c in range(3)], 1)
            b = np.stack([np.interp(t, tj, pj[:, c]) for c in range(3)], 1)
            best = min(best, float(np.min(np.linalg.norm(a - b, axis=1))))
    return best


# -- forest ---------------------------------------------------------------------------------

def make_forest(path, seed: int, n_trees: int = 60, clearance_m: float = 2.5):
    """Trees on the 50 x 50 m ground around ``path``: random positions (seeded), each kept
    ``clearance_m`` plus its crown from the path, heights 8-15 m."""

    rng = np.random.default_rng([seed, 263])
    trees, tries = [], 0
    while len(trees) < n_trees and tries < 20000:
        tries += 1
        x, y = rng.uniform(-25.0, 25.0, 2)
        h = rng.uniform(8.0, 15.0)
        tree = Tree(float(x), float(y), float(h), float(rng.uniform(0.15, 0.35)),
                    float(rng.uniform(1.0, 2.5)))
        probe = Forest((tree,), bird_radius_m=0.0)
        if np.min(probe.clearance(path._pts)) > clearance_m:
            trees.append(tree)
    return Forest(tuple(trees))


def run_forest(sc: Scenario, opt: EvalOptions) -> dict:
    path = paths.forest_path()
    if opt.quick:  # its first ~60 m
        path = FlightPath(path.points[:5])
    forest = make_forest(path, opt.seed)
    task = Task(path, forest=forest, feathers=opt.feathers,
                speed=database_speed(opt.db, opt.feathers))
    r, files = _fly(sc, opt, task)
    return _result(r, files, trees=len(forest.trees))


# -- registration ---------------------------------------------------------------------------

def _register() -> None:
    P = run_path
    entries = [
        ("figure8", "figure of eight, 35 m lobes, rising 2 m on one lobe and descending on the "
         "other (ascending and descending turns, the paper's Table I path; climbs up to 2.3 deg)", P,
         {"shape": "figure8", "args": {"lobe_m": 35.0, "rise_m": 2.0},
          "quick_args": {"lobe_m": 10.0, "rise_m": 0.5}}),
        ("figure8-rise3", "the same figure of eight rising and falling 3 m (climbs up to 3.5 deg "
         "while turning)", P,
         {"shape": "figure8", "args": {"lobe_m": 35.0, "rise_m": 3.0},
          # 1.5x figure8's quick rise, as its whole rise is 1.5x figure8's: another quick run
          "quick_args": {"lobe_m": 10.0, "rise_m": 0.75}}),
        ("figure8-level", "figure of eight, 35 m lobes, level", P,
         {"shape": "figure8", "args": {"lobe_m": 35.0, "rise_m": 0.0},
          "quick_args": {"lobe_m": 10.0}}),
        ("sinusoid", "rapid side-to-side turns: y = 4 sin(2 pi x / 40 m), 4 waves (steering range "
         "per wingbeat against the capture set's)", P,
         {"shape": "sinusoid", "args": {}, "quick_args": {"waves": 1.0},
          "capture_steering_deg": True}),
    ]
    for inc in (0, 15, 30, 45):
        entries.append((f"climb-turn-{inc}", f"circle of radius 3.6 m inclined {inc} deg, 1.25 turns",
                        P, {"shape": "inclined_circle", "args": {"incline_deg": float(inc)},
                            "quick_args": {"turns": 0.5}, "tube_m": 2.0}))
    for name, plucked in LEFT_PLUCKS.items():
        entries.append((name, f"level figure of eight with primaries {plucked} (from the outermost) "
                        "plucked on the left wing", P,
                        {"shape": "figure8", "args": {"lobe_m": 35.0, "rise_m": 0.0},
                         "quick_args": {"lobe_m": 10.0},
                         "plucked": [primary_name("l", i) for i in plucked]}))
    entries += [
        ("wind-steady", "40 m straight with a steady 1 m/s crosswind from the right", P,
         {"shape": "straight", "args": {"length_m": 40.0}, "quick_args": {"length_m": 20.0},
          "wind": (0.0, 1.0, 0.0)}),
        ("wind-steady-2", "40 m straight with a steady 2 m/s crosswind from the right (16 deg "
         "of crab at 7 m/s)", P,
         {"shape": "straight", "args": {"length_m": 40.0}, "quick_args": {"length_m": 20.0},
          "wind": (0.0, 2.0, 0.0)}),
        ("wind-breeze", "40 m straight in a breeze swinging 1.5 m/s side to side at 0.3 Hz", P,
         {"shape": "straight", "args": {"length_m": 40.0}, "quick_args": {"length_m": 20.0},
          "flow": [("Breeze", {"direction": (0.0, 1.0, 0.0), "amplitude": 1.5,
                               "frequency": 0.3})]}),
        ("wind-gusts", "40 m straight with 1-cosine gusts of 3 m/s (0.5 s) from the side and "
         "from above", P,
         {"shape": "straight", "args": {"length_m": 40.0}, "quick_args": {"length_m": 20.0},
          "flow": [("Gust", {"direction": (0.0, 1.0, 0.0), "amplitude": 3.0, "start": 1.0,
                             "duration": 0.5}),
                   ("Gust", {"direction": (0.0, 0.0, -1.0), "amplitude": 3.0, "start": 3.0,
                             "duration": 0.5})]}),
    ]
    # rough wall seconds on one idle core (from a whole-suite run; pushes fly five paths)
    costs = {"figure8": 35.0, "figure8-rise3": 10.0, "figure8-level": 35.0, "plucked-3": 2.0,
             "plucked-4": 2.0, "sinusoid": 15.0, "wind-steady-2": 4.0}
    for name, summary, runner, params in entries:
        register(Scenario(name, "flight", summary, runner, params,
                          cost=costs.get(name, 3.0)))
    # what the dove can steer, not what a path asks, each flown and mirrored (see
    # _mirror_flight) and flown on after leaving the tube (up to the 15 m at which a flight
    # stops): turns of 3.4 m radius ask ~12 deg per wingbeat at 7 m/s, the capture set's
    # extreme; turns of 0.8 m radius ask ~30, more than the dove can follow (what it steers
    # when asked for more, as the paper's steering range is)
    for name, wavelength, what, cost in (
            ("sinusoid-rapid", 20.0, "turns of 3.4 m radius (~12 deg per wingbeat at 7 m/s; "
             "beyond the dove)", 12.0),
            ("sinusoid-sharp", 10.0, "turns of 0.8 m radius (~30 deg per wingbeat)", 10.0)):
        register(Scenario(name, "flight", f"y = 3 sin(2 pi x / {wavelength:g} m), 4 waves: {what}; "
                          "measures the steering range, flown and mirrored; not in 'all'", P,
                          {"shape": "sinusoid", "args": {"amplitude_m": 3.0, "wavelength_m": wavelength},
                           "quick_args": {"waves": 1.0}, "capture_steering_deg": True,
                           "mirror_too": True},
                          cost=cost, in_all=False))
    # the capture's steering range (-12.5..+7.0 deg per wingbeat) was flown at 2.0-5.1 m/s (the
    # flight paper, sec. 7); a wingbeat's turn is the lateral acceleration times its duration
    # over the speed, so the same bank turns a slower bird further in one wingbeat
    register(Scenario("sinusoid-slow", "flight", "sinusoid-sharp's path flown at 5 m/s, the top of "
                      "the capture's 2.0-5.1 m/s: the steering range at the speeds the capture's "
                      "was measured at, flown and mirrored; not in 'all'", P,
                      dict(get("sinusoid-sharp").params, speed=CAPTURE_TOP_SPEED),
                      cost=12.0, in_all=False))
    for d in ("front", "back", "left", "right", "up", "down"):
        register(Scenario(f"push-{d}", "flight", f"level flight pushed {d} at the trunk's centre of "
                          f"mass for 0.1 s, {'/'.join(f'{f:g}' for f in PUSH_FORCES_N)} N",
                          run_pushes, {"direction": d}, cost=15.0))
    register(Scenario("forest", "flight", "263 m through a 50 x 50 x 15 m wood of 60 trees: climbs, "
                      "glides, turns both ways (collisions counted)", run_forest, {},
                      cost=12.0))
    register(Scenario("flock", "flight", "5 birds: a leader on a 40 m-lobe figure of eight and 4 "
                      "followers on copies 2.5 and 5 m above and below, their control points moved "
                      "within 1 m horizontally (no collisions)",
                      run_flock,
                      {"birds": 5, "jitter_m": 1.0, "collision_m": 0.51,
                       "offsets": [(0, 0, 0), (0, 0, 2.5), (0, 0, -2.5), (0, 0, 5.0), (0, 0, -5.0)],
                       "args": {"lobe_m": 40.0, "rise_m": 0.0},
                       "quick_args": {"lobe_m": 10.0, "rise_m": 0.0}, "quick_birds": 2},
                      cost=130.0))
    register(Scenario("path", "flight", "a user's path file (flapsim eval --path FILE)", run_path,
                      {"shape": "file"}, in_all=False))


_register()
