"""``flapsim fly``: the dove's base controller (reference wingbeat + tail bias) in straight flight."""

from __future__ import annotations

import argparse
import dataclasses

import numpy as np

from flapsim.bird.body.model import Dove
from flapsim.bird.control.controller import (
    BaseController,
    cruise_metrics,
    database_dove,
    database_pitch,
    database_speed,
    database_table,
    fly_controlled,
    load_controller,
    start_cruise,
)
from flapsim.bird.control.targets import CruiseTarget, trim_of_base_flight
from flapsim.bird.flight.dove_flight import CRUISE, DoveFlight, FlightConfig, flight_metrics, fly
from flapsim.bird.flight.power import power_budget
from flapsim.bird.flight.video import dove_video
from flapsim.bird.flight.wingbeat import p0, reference_wingbeat, with_tail_bias
from flapsim.bird.tasks.flight_tasks import Task, fly_task
from flapsim.bird.tasks.path_control import FlightPath, load_path
from flapsim.cli.options import (
    add_controller_arguments,
    add_video_arguments,
    controller_options,
    video_options,
)
from flapsim.core.errors import InputError
from flapsim.core.io import save_npz
from flapsim.core.validate import add_input_arg, add_output_arg, quantity

SEED_HELP = "accepted for uniformity (stored in --out); flight is deterministic, --seed changes nothing"
HELP = ("fly the dove straight ahead (base controller, or the learned wingbeat controller holding "
        "altitude, speed and heading) and report speed, deviations, lift/weight")


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--wingbeats", type=int, default=None,
                   help="wingbeats to fly (default 10; with --path: at most, default the tasks' time "
                        "budget, 1.5x the path's flight time at --speed or its length at 3 m/s, "
                        "whichever is longer, plus five reference wingbeats)")
    add_input_arg(p, "--path", metavar="FILE", default=None,
                  help="follow a 3D path (CSV with header x,y,z, or JSON list of [x,y,z]) with "
                        "the learned controller: look-ahead, Hermite recovery, banked turns")
    p.add_argument("--controller", choices=("base", "learned"), default="base",
                   help="base: repeat the reference wingbeat (default); learned: the k-NN wingbeat "
                        "controller over a trained database, holding the start altitude, --speed "
                        "and heading")
    add_controller_arguments(p)
    p.add_argument("--roll-deg", type=quantity("roll_deg"), default=0.0,
                   help="initial roll error, deg (+ right wing down)")
    add_output_arg(p, "--video", kinds=(".mp4", ".gif"), renders=True,
                   help="write a chase-camera video (.mp4 or .gif)")
    add_output_arg(p, "--out", kinds=(".npz",), help="write the trajectory (.npz)")
    p.add_argument("--speed", type=quantity("speed"), default=None,
                   help="initial speed, m/s (default 7; --cruise: 8.5; --db: the speed its "
                        "samples were drawn around)")
    p.add_argument("--pitch-deg", type=quantity("pitch_deg"), default=None,
                   help="initial trunk pitch, deg (default 0; a learned "
                        "controller: the pitch its database's pre-states were centred at)")
    p.add_argument("--tail-bias-deg", type=quantity("tail_bias_deg"), default=None,
                   help="tail bend added to the reference wingbeat (default 17, the paper's; "
                        "--cruise: 26)")
    p.add_argument("--table", default=None,
                   help="feather coefficient table (default dickinson1999_profile; a learned "
                        "controller's default: the table its database was sampled with)")
    p.add_argument("--python-loop", action="store_true",
                   help="step in a Python loop instead of mujoco.rollout (same result)")
    p.add_argument("--feathers", choices=("rigid", "modal"), default="rigid",
                   help="rigid feather plates (default) or modal feathers that bend and twist "
                        "(4 modes each, the paper's sec. 6: slower)")
    p.add_argument("--induced", action="store_true",
                   help="the wings see the air their own lift pushes down (momentum theory, "
                        "flapsim.fluid.induced; base controller, rigid feathers; not the default: "
                        "the bundled wingbeat and databases were made without it)")
    p.add_argument("--cruise", action="store_true",
                   help="the cruise dove: a bird wing's section, its induced flow, the cruise "
                        "capture's reference wingbeat with its tail bias, from 8.5 m/s (base "
                        "controller; options given beside it win; docs/flight.md)")
    p.add_argument("--power", action="store_true",
                   help="also the base flight's energy balance: the servos' power, where the air "
                        "and the dampers take it (feather drag by stroke and angle of attack), "
                        "the cost of transport (flapsim.bird.flight.power; rigid feathers; the flight "
                        "is flown again step by step for it)")
    add_video_arguments(p, slowmo_default="at least 3 s of video")


def run(args: argparse.Namespace) -> dict:
    if args.path:
        args.flight_path = load_path(args.path)  # one-line DataFileError before any work
        # without --wingbeats the path is flown for the tasks' time budget in seconds, as eval
        # allows it: a count of reference wingbeats gave shorter learned wingbeats less time
    elif args.wingbeats is None:
        args.wingbeats = 10
    if args.wingbeats is not None and not 1 <= args.wingbeats <= 10000:
        raise InputError(f"--wingbeats must be 1..10000, got {args.wingbeats}")
    if args.speed is not None and not (0.0 <= args.speed <= 30.0):
        raise InputError(f"--speed must be 0..30 m/s, got {args.speed}")
    try:
        width, height = (int(v) for v in args.size.lower().split("x"))
    except ValueError:
        raise InputError(f"--size must look like 640x480, got {args.size!r}") from None
    if not (16 <= width <= 4096 and 16 <= height <= 4096):
        raise InputError(f"--size must be 16..4096 pixels each way, got {args.size!r}")
    if not np.isfinite(args.roll_deg) or abs(args.roll_deg) > 90:
        raise InputError(f"--roll-deg must be within -90..90, got {args.roll_deg}")
    args.controller_config, args.path_control = controller_options(args)
    if args.cruise:
        if args.path or args.controller == "learned" or args.db or args.roll_deg or \
                args.feathers != "rigid":
            raise InputError("--cruise flies the base controller with rigid feathers (a learned "
                             "cruise flight: --db with a database trained with train --cruise)")
        args.induced = True
        # the cruise dove's start and tail bias, where the command line gave none
        args.speed = CRUISE.speed if args.speed is None else args.speed
        args.pitch_deg = CRUISE.pitch_deg if args.pitch_deg is None else args.pitch_deg
        args.tail_bias_deg = CRUISE.tail_bias_deg if args.tail_bias_deg is None else args.tail_bias_deg
        args.table = args.table or CRUISE.table
    learned = args.controller == "learned" or bool(args.db)
    if args.speed is None:
        # a database's flights are asked the speed it was sampled around
        args.speed = database_speed(args.db, args.feathers) if args.db else FlightConfig.speed
    if args.pitch_deg is None:
        # ... and start at the trunk pitch its pre-states were centred at
        args.pitch_deg = database_pitch(args.db, args.feathers) if learned else FlightConfig.pitch_deg
    if args.tail_bias_deg is None:
        args.tail_bias_deg = FlightConfig.tail_bias_deg
    cfg = FlightConfig(speed=args.speed, pitch_deg=args.pitch_deg, tail_bias_deg=args.tail_bias_deg,
                       **({"table": args.table} if args.table else {}))
    if args.power:  # checked before anything is flown
        if args.path or args.controller == "learned" or args.db or args.roll_deg:
            raise InputError("--power measures the base controller's flight (the reference "
                             "wingbeat repeated): drop --controller learned, --path, --db and "
                             "--roll-deg")
        if args.speed < 1.0:
            raise InputError(f"--power needs a start of 1-30 m/s, got --speed {args.speed}")
        if args.feathers != "rigid":
            raise InputError("--power needs rigid feathers (the modal feathers' forces are not "
                             "split by polygon)")
    if args.induced and (args.path or args.controller == "learned" or args.db or args.roll_deg
                         or args.feathers != "rigid"):
        raise InputError("--induced flies the base controller with rigid feathers (the "
                         "databases were sampled without the downwash): drop --controller "
                         "learned, --path, --db, --roll-deg and --feathers modal")
    if args.path:
        if args.controller != "learned":
            raise InputError("--path needs --controller learned (the base controller cannot steer)")
        return _run_path(args, cfg, width, height)
    if args.controller == "learned" or args.db or args.roll_deg:
        return _run_controlled(args, cfg, width, height)
    dove = Dove.load(feathers=args.feathers, induced=args.induced)
    ref = reference_wingbeat("cruise" if args.cruise else "slow")
    flight = fly(dove, args.wingbeats, cfg, use_rollout=not args.python_loop, progress=True,
                 keep_qpos=bool(args.video), ref=ref)
    metrics = flight_metrics(flight)
    result = {
        "wingbeats": args.wingbeats,
        "feathers": args.feathers,
        "induced": bool(args.induced),
        "capture": "cruise" if args.cruise else "slow",
        "model_hash": dove.hash(),
        "mass": dove.mass,
        "config": {"speed": cfg.speed, "pitch_deg": cfg.pitch_deg,
                   "tail_bias_deg": cfg.tail_bias_deg, "table": cfg.table,
                   "timestep": float(dove.model.opt.timestep)},
        **metrics,
    }
    print(f"dove base controller, {args.feathers} feathers, {args.wingbeats} wingbeats "
          f"({metrics['simulated_s']:.2f} s "
          f"simulated, {metrics['real_time_factor']:.1f}x real time)")
    print(f"  mean speed {metrics['mean_speed']:.2f} m/s, wingbeat {metrics['wingbeat_hz']:.2f} Hz, "
          f"mean lift/weight {metrics['mean_lift_per_weight']:.3f}")
    print(f"  max deviation from the initial line: lateral {metrics['max_lateral_deviation']:.3f} m,"
          f" vertical {metrics['max_vertical_deviation']:.3f} m")
    pr, rr = metrics["pitch_range_deg"], metrics["roll_range_deg"]
    print(f"  pitch {pr[0]:.1f}..{pr[1]:.1f} deg, roll {rr[0]:.1f}..{rr[1]:.1f} deg")
    if args.power:
        skip = min(2, args.wingbeats - 1)  # the start's transient out, where there is more
        pw = power_budget(args.wingbeats, skip, config=cfg, induced=args.induced, ref=ref)
        down = pw["drag_feathers_downstroke_W"] / pw["drag_feathers_W"]
        bins = pw["drag_feathers_by_aoa_W"]
        steep = (bins["30-45"] + bins["45-60"]) / pw["drag_feathers_W"]
        print(f"  power over wingbeats {skip + 1}-{args.wingbeats}: servos {pw['muscle_W']:.2f} W "
              f"(cost of transport {pw['cost_of_transport']:.2f}); feather drag "
              f"{pw['drag_feathers_W']:.2f} W ({down:.0%} in the downstroke, {steep:.0%} at 30-60 "
              f"deg angle of attack), body drag {pw['drag_body_W']:.2f} W, dampers "
              f"{pw['dampers_W']:.2f} W; mechanical energy changing at "
              f"{pw['mechanical_energy_rate_W']:+.2f} W")
        result["power"] = pw
    if args.out:
        save_npz(args.out, time=flight.time, trunk_pos=flight.trunk_pos,
                 trunk_quat=flight.trunk_quat, qpos14=flight.qpos14, states=flight.states,
                 model_hash=np.array(dove.hash()), seed=np.array(args.seed))
        print(f"trajectory written to {args.out}")
        result["out"] = args.out
    if args.video:
        n = dove_video(dove, flight.qpos, args.video, args.fps, width, height,
                       **video_options(args), wingbeat_times=np.arange(args.wingbeats)
                       / metrics["wingbeat_hz"])
        print(f"video written to {args.video} ({n} frames)")
        result["video"] = args.video
    return result


def _run_controlled(args: argparse.Namespace, cfg, width: int, height: int) -> dict:
    """Cruise under the learned controller (or the base one, from a rolled start)."""

    dove = database_dove(args.db, args.feathers) if args.controller == "learned" else \
        Dove.load(feathers=args.feathers)
    if args.controller == "learned" and not args.table:
        cfg = dataclasses.replace(cfg, table=database_table(args.db, args.feathers))
    fl = DoveFlight(dove, table=cfg.table)
    try:
        if args.controller == "learned":
            ctl = load_controller(fl, args.db, method=args.method, k=args.k, predict=args.predict,
                                  mirror=args.mirror, config=args.controller_config)
        else:
            ctl = BaseController(fl, with_tail_bias(p0(), cfg.tail_bias_deg))
        trim = trim_of_base_flight(fl, ctl.P0, cfg)
        start_cruise(fl, ctl.P0, cfg, args.roll_deg)
        target = CruiseTarget(trim, altitude=cfg.height, speed=cfg.speed)
        flight = fly_controlled(ctl, target, args.wingbeats, progress=True,
                                record=bool(args.video or args.out))
    finally:
        fl.close()
    m = cruise_metrics(flight, target)
    result = {
        "controller": args.controller,
        "wingbeats": args.wingbeats,
        "model_hash": dove.hash(),
        "mass": dove.mass,
        "db": str(args.db) if args.db else ("bundled" if args.controller == "learned" else None),
        "method": args.method if args.controller == "learned" else None,
        "mirror": args.mirror if args.controller == "learned" else None,
        "controller_config": (args.controller_config.to_dict() if args.controller == "learned"
                              else None),
        "predict": getattr(ctl, "predict", None),
        "k": getattr(getattr(ctl, "regressor", None), "k", None),
        "database_samples": getattr(getattr(ctl, "regressor", None), "n", None),
        "refine": getattr(ctl, "refine", None),
        "refine_goal": getattr(ctl, "refine_goal", None),
        "lookahead": _lookahead_counts(getattr(ctl, "lookahead", None)),
        "config": {"speed": cfg.speed, "pitch_deg": cfg.pitch_deg, "roll_deg": args.roll_deg,
                   "tail_bias_deg": cfg.tail_bias_deg, "table": cfg.table,
                   "altitude": cfg.height, "timestep": float(dove.model.opt.timestep)},
        **m,
    }
    print(f"dove, {args.controller} controller, {args.wingbeats} wingbeats from a "
          f"{args.roll_deg:g} deg roll ({m['simulated_s']:.2f} s simulated, "
          f"{m['real_time_factor']:.1f}x real time)")
    print(f"  target: altitude {cfg.height:g} m, speed {cfg.speed:g} m/s, heading 0 deg")
    print(f"  largest deviations: altitude {m['max_altitude_deviation']:.2f} m, speed "
          f"{m['max_speed_deviation']:.2f} m/s, heading {m['max_heading_deviation_deg']:.1f} deg; "
          f"largest roll {m['max_abs_roll_deg']:.1f} deg")
    _write_outputs(args, dove, flight, result, width, height)
    return result


def _lookahead_counts(la) -> dict | None:
    """The look-ahead's references simulated ahead (hits) and on the spot (misses)."""
    return None if la is None else {"hits": la.hits, "misses": la.misses}


def _run_path(args: argparse.Namespace, cfg, width: int, height: int) -> dict:
    """Follow ``--path`` under the learned controller; the paper's Ep, Er, Eo, Ef."""

    path = args.flight_path
    task = args.path_control.apply(Task(path, speed=cfg.speed, max_wingbeats=args.wingbeats,
                                        feathers=args.feathers))
    predict = args.predict
    r = fly_task(task, args.db, method=args.method, k=args.k, mirror=args.mirror, progress=True,
                 record=bool(args.video or args.out), predict=predict,
                 config=args.controller_config)
    m = r.metrics
    completed = r.status == "completed"
    result = {
        "controller": "learned", "path": args.path, "path_length": path.length,
        "completed": completed, "status": r.status, "reason": r.reason,
        "progress": m["progress_m"], "model_hash": r.model_hash, "method": args.method, "mirror": args.mirror,
        "predict": predict, "controller_config": args.controller_config.to_dict(),
        "path_control": args.path_control.to_dict(),
        "k": r.k, "database_samples": r.database_samples, "refine": r.refine,
        "refine_goal": r.refine_goal,
        "lookahead": None if r.lookahead is None else {"hits": r.lookahead[0], "misses": r.lookahead[1]},
        "db": str(args.db) if args.db else "bundled", **m,
    }
    print(f"dove, learned controller along {args.path} ({path.length:.1f} m): "
          f"{'completed' if completed else r.status + ': ' + r.reason} in {m['wingbeats']} "
          f"wingbeats ({m['simulated_s']:.2f} s simulated, {m['real_time_factor']:.1f}x real time, "
          f"S0 by {predict})")
    print(f"  distance to the path: mean {m['Ef_per_wingbeat']:.2f} m, largest "
          f"{m['max_path_distance']:.2f} m")
    print(f"  per wingbeat: Ep {m['Ep_per_wingbeat']:.3f} m, Er {m['Er_per_wingbeat']:.3f} rad, "
          f"Eo {m['Eo_per_wingbeat']:.3f} rad, Ef {m['Ef_per_wingbeat']:.3f} m")
    _write_task_outputs(args, r, result, width, height, path_points=path.points)
    return result


def _write_task_outputs(args: argparse.Namespace, r, result: dict, width: int, height: int,
                        **extra: np.ndarray) -> None:
    """``--out`` / ``--video`` of a flown task (:class:`~flapsim.bird.tasks.flight_tasks.TaskResult`)."""

    if args.out:
        save_npz(args.out, positions=r.positions, quats=r.quats, times=r.times,
                 steering_deg=r.steering_deg, qpos=r.qpos, model_hash=np.array(r.model_hash),
                 seed=np.array(args.seed), **extra)
        print(f"trajectory written to {args.out}")
        result["out"] = args.out
    if args.video:
        path_points = extra.get("path_points")
        path = FlightPath(path_points) if path_points is not None else None
        n = dove_video(database_dove(args.db, args.feathers), r.qpos, args.video, args.fps, width, height,
                       **video_options(args), path_points=None if path is None else
                       path.point(np.linspace(0.0, path.length, 600)), wingbeat_times=r.times,
                       metric=None if path is None else ("distance from path", path.distance))
        print(f"video written to {args.video} ({n} frames)")
        result["video"] = args.video


def _write_outputs(args: argparse.Namespace, dove, flight, result: dict, width: int, height: int,
                   **extra: np.ndarray) -> None:
    """``--out`` (per-wingbeat record and every step's positions, npz) and ``--video`` of a
    controlled flight; adds their paths to ``result``."""

    if not (args.out or args.video):
        return
    qpos = np.concatenate([s.end.qpos for s in flight.steps])
    if args.out:
        save_npz(args.out, positions=flight.positions, velocities=flight.velocities,
                 states=flight.states, params=flight.params, qpos=qpos,
                 model_hash=np.array(dove.hash()), seed=np.array(args.seed), **extra)
        print(f"trajectory written to {args.out}")
        result["out"] = args.out
    if args.video:
        n = dove_video(dove, qpos, args.video, args.fps, width, height, **video_options(args),
                       wingbeat_times=getattr(flight, "times", None))
        print(f"video written to {args.video} ({n} frames)")
        result["video"] = args.video
