"""``flapsim fly``: the dove's base controller (reference wingbeat + tail bias) in straight flight."""

from __future__ import annotations

import argparse

import numpy as np

from flapsim.errors import InputError

HELP = ("fly the dove straight ahead (base controller, or the learned wingbeat controller holding "
        "altitude, speed and heading) and report speed, deviations, lift/weight")


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--wingbeats", type=int, default=10, help="wingbeats to fly (default 10)")
    p.add_argument("--controller", choices=("base", "learned"), default="base",
                   help="base: repeat the reference wingbeat (default); learned: the k-NN wingbeat "
                        "controller over a trained database, holding the start altitude, --speed "
                        "and heading")
    p.add_argument("--db", metavar="DB", help="controller database (default: the bundled one)")
    p.add_argument("--method", choices=("knn", "lwlr"), default="lwlr",
                   help="regression of the learned controller: lwlr (default; locally weighted "
                        "linear regression) or knn (the paper's k-NN average, which does not hold "
                        "this dove level: see the README)")
    p.add_argument("--k", type=int, default=None,
                   help="neighbours of the regression (default 0.5%% of the database)")
    p.add_argument("--roll-deg", type=float, default=0.0,
                   help="initial roll error, deg (+ right wing down)")
    p.add_argument("--video", metavar="PATH", help="write a chase-camera video (.mp4)")
    p.add_argument("--out", metavar="PATH", help="write the trajectory (.npz)")
    p.add_argument("--speed", type=float, default=7.0, help="initial speed, m/s (default 7)")
    p.add_argument("--pitch-deg", type=float, default=0.0, help="initial trunk pitch (default 0)")
    p.add_argument("--tail-bias-deg", type=float, default=17.0,
                   help="tail bend added to the reference wingbeat (paper: 17)")
    p.add_argument("--table", default=None,
                   help="feather coefficient table (default dickinson1999_lowdrag)")
    p.add_argument("--python-loop", action="store_true",
                   help="step in a Python loop instead of mujoco.rollout (same result)")
    p.add_argument("--fps", type=float, default=30.0, help="video frames per second")
    p.add_argument("--size", default="640x480", help="video size WxH (default 640x480)")


def run(args: argparse.Namespace) -> dict:
    from flapsim.bird.flight import FlightConfig, flight_metrics, fly
    from flapsim.bird.model import Dove
    from flapsim.io import save_npz

    if args.wingbeats < 1 or args.wingbeats > 10000:
        raise InputError(f"--wingbeats must be 1..10000, got {args.wingbeats}")
    if not (0.0 <= args.speed <= 30.0):
        raise InputError(f"--speed must be 0..30 m/s, got {args.speed}")
    if args.video and not args.video.lower().endswith((".mp4", ".gif", ".mkv", ".avi")):
        raise InputError(f"--video {args.video}: use a .mp4 (or .gif/.mkv/.avi) file name")
    try:
        width, height = (int(v) for v in args.size.lower().split("x"))
    except ValueError:
        raise InputError(f"--size must look like 640x480, got {args.size!r}") from None
    if not np.isfinite(args.roll_deg) or abs(args.roll_deg) > 90:
        raise InputError(f"--roll-deg must be within -90..90, got {args.roll_deg}")
    if args.k is not None and args.k < 1:
        raise InputError(f"--k must be >= 1, got {args.k}")
    cfg = FlightConfig(speed=args.speed, pitch_deg=args.pitch_deg, tail_bias_deg=args.tail_bias_deg,
                       **({"table": args.table} if args.table else {}))
    if args.controller == "learned" or args.db or args.roll_deg:
        return _run_controlled(args, cfg, width, height)
    dove = Dove.load()
    flight = fly(dove, args.wingbeats, cfg, use_rollout=not args.python_loop, progress=True)
    metrics = flight_metrics(flight)
    result = {
        "wingbeats": args.wingbeats,
        "model_hash": dove.hash(),
        "mass": dove.mass,
        "config": {"speed": cfg.speed, "pitch_deg": cfg.pitch_deg,
                   "tail_bias_deg": cfg.tail_bias_deg, "table": cfg.table,
                   "timestep": float(dove.model.opt.timestep)},
        **metrics,
    }
    print(f"dove base controller, {args.wingbeats} wingbeats ({metrics['simulated_s']:.2f} s "
          f"simulated, {metrics['real_time_factor']:.1f}x real time)")
    print(f"  mean speed {metrics['mean_speed']:.2f} m/s, wingbeat {metrics['wingbeat_hz']:.2f} Hz, "
          f"mean lift/weight {metrics['mean_lift_per_weight']:.3f}")
    print(f"  max deviation from the initial line: lateral {metrics['max_lateral_deviation']:.3f} m,"
          f" vertical {metrics['max_vertical_deviation']:.3f} m")
    pr, rr = metrics["pitch_range_deg"], metrics["roll_range_deg"]
    print(f"  pitch {pr[0]:.1f}..{pr[1]:.1f} deg, roll {rr[0]:.1f}..{rr[1]:.1f} deg")
    if args.out:
        save_npz(args.out, time=flight.time, trunk_pos=flight.trunk_pos,
                 trunk_quat=flight.trunk_quat, qpos14=flight.qpos14, states=flight.states,
                 model_hash=np.array(dove.hash()), seed=np.array(args.seed))
        print(f"trajectory written to {args.out}")
        result["out"] = args.out
    if args.video:
        from flapsim.render import ChaseCamera, render_video

        dt = float(dove.model.opt.timestep)
        stride = max(1, int(round(1.0 / (args.fps * dt))))
        n = render_video(dove.model, flight.qpos[::stride], args.video, fps=1.0 / (stride * dt),
                         camera=ChaseCamera("trunk"), width=width, height=height)
        print(f"video written to {args.video} ({n} frames)")
        result["video"] = args.video
    return result


def _run_controlled(args: argparse.Namespace, cfg, width: int, height: int) -> dict:
    """Cruise under the learned controller (or the base one, from a rolled start)."""
    from flapsim.bird.controller import (
        BaseController,
        CruiseTarget,
        cruise_metrics,
        fly_controlled,
        load_controller,
        start_cruise,
        trim_of_base_flight,
    )
    from flapsim.bird.flight import DoveFlight
    from flapsim.bird.model import Dove
    from flapsim.bird.wingbeat import p0, with_tail_bias
    from flapsim.io import save_npz

    dove = Dove.load()
    fl = DoveFlight(dove, table=cfg.table)
    try:
        if args.controller == "learned":
            ctl = load_controller(fl, args.db, method=args.method, k=args.k)
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
        "k": getattr(getattr(ctl, "regressor", None), "k", None),
        "database_samples": getattr(getattr(ctl, "regressor", None), "n", None),
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
    if args.out:
        save_npz(args.out, positions=flight.positions, velocities=flight.velocities,
                 states=flight.states, params=flight.params,
                 qpos=np.concatenate([s.end.qpos for s in flight.steps]),
                 model_hash=np.array(dove.hash()), seed=np.array(args.seed))
        print(f"trajectory written to {args.out}")
        result["out"] = args.out
    if args.video:
        from flapsim.render import ChaseCamera, render_video

        dt = float(dove.model.opt.timestep)
        stride = max(1, int(round(1.0 / (args.fps * dt))))
        qpos = np.concatenate([s.end.qpos for s in flight.steps])
        n = render_video(dove.model, qpos[::stride], args.video, fps=1.0 / (stride * dt),
                         camera=ChaseCamera("trunk"), width=width, height=height)
        print(f"video written to {args.video} ({n} frames)")
        result["video"] = args.video
    return result
