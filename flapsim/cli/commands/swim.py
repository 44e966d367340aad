"""``flapsim swim``: swim a stroke and report speed, stroke rate, distance per stroke and
floating height (optionally a video)."""

from __future__ import annotations

import argparse
import contextlib
import os

import numpy as np

from flapsim.core.errors import InputError
from flapsim.core.io import atomic_video, save_npz
from flapsim.core.validate import add_input_arg, add_output_arg, quantity, vector
from flapsim.fluid.flow import FlowField, Source, Vortex
from flapsim.swim.arrival import Approach
from flapsim.swim.dive import UNDER_WATER_STROKE, SurfaceDive
from flapsim.swim.goals import (
    Circle,
    Heading,
    Path,
    Point,
    Waypoints,
    figure_eight,
    load_path,
    load_trajectory,
)
from flapsim.swim.interactive import SwimViewer, check_display
from flapsim.swim.model import Swimmer, SwimmerParams
from flapsim.swim.per_cycle import calibrate, load_table
from flapsim.swim.plots import track_plot
from flapsim.swim.simulate import swim
from flapsim.swim.strokes import load_stroke, stroke_for_body
from flapsim.swim.tow import NARITA_K, tow

HELP = "swim breaststroke, crawl or treading water; report speed, stroke rate and floating height"
SEED_HELP = "accepted for uniformity; swimming is deterministic, --seed changes nothing"


def _vec(text: str, what: str, n: int) -> tuple[float, ...]:
    """``n`` comma-separated finite numbers, or a one-line error naming ``what``."""
    if isinstance(text, tuple):  # already parsed by the argument's type (flapsim.core.validate)
        return text
    count = {2: "two", 3: "three", 4: "four"}.get(n, str(n))
    try:
        v = tuple(float(x) for x in text.split(","))
    except ValueError:
        raise InputError(f"{what} must be {count} comma-separated numbers, got {text!r}") from None
    if len(v) != n or not np.all(np.isfinite(v)):
        raise InputError(f"{what} must be {count} finite comma-separated numbers, got {text!r}")
    return v


def add_target_arguments(p: argparse.ArgumentParser) -> None:
    """What to steer for (shared with ``flapsim sweep``)."""
    g = p.add_mutually_exclusive_group()
    g.add_argument("--target", metavar="X,Y[,Z]", type=_target_arg,
                   help="swim to this point [m] (start: origin, facing +x); crawl/breaststroke "
                        "slow down, stop and tread water there. A Z below the surface (< 0) is "
                        "reached by a surface dive (breathe out, pike, swim on under water, "
                        "the crawler with the breaststroke's pull; breathe in there and come "
                        "up)")
    add_input_arg(g, "--path", metavar="FILE",
                  help="follow a path: a text file of 'x, y' points [m], one per line")
    g.add_argument("--figure8", type=quantity("radius"), metavar="R",
                   help="follow a figure of eight of loop radius R [m] (>= ~4 m: the crawl's "
                        "turning circle is ~3.5 m)")
    g.add_argument("--moving-target", metavar="X,Y,VX,VY",
                   type=vector(("position", "position", "velocity", "velocity"), 4),
                   help="swim after a point starting at X,Y [m] moving at VX,VY [m/s]")
    g.add_argument("--circling-target", metavar="CX,CY,R,V",
                   type=vector(("position", "position", "radius", "velocity"), 4),
                   help="swim after a point circling CX,CY [m] anticlockwise on a circle of R "
                        "[m] at V [m/s], starting on its -y side (R below the centre)")
    add_input_arg(g, "--trajectory", metavar="FILE",
                  help="swim after a target moving along a timed trajectory: a text file of "
                       "'t, x, y' or 't, x, y, z' lines [s, m]")
    g.add_argument("--heading", type=quantity("angle_deg"), metavar="DEG",
                   help="hold this heading [deg from +x towards +y] (default: hold the start "
                        "heading)")
    p.add_argument("--lookahead", type=quantity("lookahead"), default=2.0,
                   help="path following: steer at the point this far along the path [m]")


def add_arguments(p: argparse.ArgumentParser) -> None:
    add_input_arg(p, "--stroke", may_be_name=True, default="breaststroke",
                  help="breaststroke, crawl, treading, or a stroke .toml file (default breaststroke)")
    p.add_argument("--seconds", type=quantity("seconds"), default=20.0,
                   help="simulated time [s] (default 20)")
    p.add_argument("--rate", type=quantity("rate"), default=None,
                   help="stroke rate [cycles/s] (default: the stroke file's)")
    p.add_argument("--speed", type=float, default=None, metavar="M_S",
                   help="hold this speed [m/s, 0.5..1.6] by the stroke rate, set once per cycle "
                        "by the per-cycle layer (crawl, breaststroke)")
    p.add_argument("--density", type=quantity("density"), default=None,
                   help="water density [kg/m^3] (default 1025, the paper's 91 kg buoyancy)")
    p.add_argument("--lungs", type=quantity("lungs"), default=None,
                   help="extra lung volume [L] (default 3, the paper's floater)")
    p.add_argument("--friction", type=quantity("friction"), default=None,
                   help="skin-friction coefficient eta [N s/m^3] (default 2)")
    p.add_argument("--body", choices=("box", "rounded"), default="box",
                   help="hydrodynamic surface: the paper's 16 boxes (default; the strokes are "
                        "tuned on them) or rounded segments (a towed person's drag, drawn "
                        "rounded too)")
    p.add_argument("--buoyancy", choices=("exact", "linear"), default="exact",
                   help="submerged fraction: exact spherical cap or the paper's linear rule")
    p.add_argument("--r-min", type=quantity("flow_ratio"), default=0.0,
                   help="swimmer-induced flow ratio rMin of the paper's eq. 5 (default 0: off)")
    p.add_argument("--r-max", type=quantity("flow_ratio"), default=0.0,
                   help="swimmer-induced flow ratio rMax of the paper's eq. 5 (default 0: off)")
    p.add_argument("--current", default=(0.0, 0.0, 0.0), type=vector("current", 3),
                   help="uniform water current vx,vy,vz [m/s]")
    p.add_argument("--source", action="append", default=[], metavar="X,Y,Z,Q",
                   type=vector(("position",) * 3 + ("source",), 4),
                   help="add a point source at X,Y,Z of strength Q [m^3/s] (repeatable)")
    p.add_argument("--vortex", action="append", default=[], metavar="X,Y,GAMMA",
                   type=vector(("position", "position", "circulation"), 3),
                   help="add a vertical line vortex at X,Y of circulation GAMMA [m^2/s]")
    add_target_arguments(p)
    p.add_argument("--no-approach", action="store_true",
                   help="swim at the stroke's own speed to a target: do not slow down for a "
                        "fixed one and tread water there, nor match a moving one's speed "
                        "(prone strokes with the per-cycle layer approach by default)")
    p.add_argument("--viewer", action="store_true",
                   help="watch and steer in the MuJoCo viewer, in real time: a double-click "
                        "places the target (default 10 m ahead), arrow keys move it 1 m, "
                        "PgUp/PgDn change the stroke rate, End "
                        "switches the layers; needs a display")
    p.add_argument("--layers", choices=("basic", "cycle", "all"), default=None,
                   help="control layers (the paper's Fig. 2): basic = the stroke alone; cycle = "
                        "+ the per-cycle layer (steering); all = + the continuous layer (palm "
                        "and reach rules, treading's balance). Default all")
    p.add_argument("--no-feedback", action="store_true",
                   help="the same as --layers basic (treading water then tips over)")
    p.add_argument("--calibrate", action="store_true",
                   help="instead of swimming: make the stroke's per-cycle weight tables by "
                        "pre-simulation in still water (parallel, resumable; written next to "
                        "the stroke file, or to --table)")
    p.add_argument("--tow", metavar="V1,V2,...", default=None,
                   help="instead of swimming: tow the body in a streamlined glide at these "
                        "speeds [m/s], at the surface and 0.5 m under it, and report the drag "
                        "(its wave-making part apart) and the fitted D = K v^2 "
                        "(tow_drag_coefficient, the submerged one; people 23.5, Narita et al. "
                        "2017)")
    p.add_argument("--power", action="store_true",
                   help="also report where the power goes in the water: per segment, the part "
                        "that moves the body and the slip that only stirs the water, and the "
                        "arms' Froude efficiency (swimmers' crawl: 0.44-0.61); and per joint "
                        "group the muscles' net power and the braking they absorb")
    p.add_argument("--table", metavar="FILE.json", default=None,
                   help="per-cycle calibration table to use (or, with --calibrate, to write); "
                        "default: <stroke>.cycle.json next to the stroke file")
    p.add_argument("--workers", type=int, default=None,
                   help="--calibrate: parallel processes (default: one per CPU core)")
    p.add_argument("--timestep", type=quantity("timestep"), default=None,
                   help="physics step [s] (default 0.004)")
    add_output_arg(p, "--video", kinds=(".mp4",), renders=True, nargs="?", const="swim.mp4",
                   default=None, help="also write an mp4 video (default file swim.mp4)")
    add_output_arg(p, "--out", kinds=(".npz",),
                   help="write the track (.npz: time, com, head, muscle_power [SI], and "
                        "target_path, the path followed, if any)")
    add_output_arg(p, "--plot", kinds=(".png",),
                   help="write a top view of the track (and the path/target) as PNG")
    p.add_argument("--fps", type=quantity("fps"), default=30.0, help="video frames per second (default 30)")


def _flow(args: argparse.Namespace) -> FlowField:
    prims = []
    for s in args.source:
        parts = _vec(s, "--source X,Y,Z,Q", 4)
        prims.append(Source(parts[:3], parts[3], core=0.3))
    for s in args.vortex:
        parts = _vec(s, "--vortex X,Y,GAMMA", 3)
        prims.append(Vortex((parts[0], parts[1], 0.0), (0, 0, 1), parts[2], core=0.3))
    return FlowField(prims)


#: how close the head or the pelvis must come to a point below the surface [m] (the
#: swim-dive scenario's radius)
DIVE_RADIUS_M = 0.75


def _target_xyz(text) -> tuple[float, ...]:
    """--target X,Y or X,Y,Z: finite numbers, Z -50..0.5 m; a one-line error otherwise."""
    parts = text if isinstance(text, tuple) else tuple(str(text).split(","))
    try:
        v = tuple(float(x) for x in parts)
    except ValueError:
        raise InputError(f"--target must be X,Y or X,Y,Z in metres, got {text!r}") from None
    if len(v) not in (2, 3) or not np.all(np.isfinite(v)):
        raise InputError(f"--target must be two or three finite numbers X,Y[,Z], got {text!r}")
    if len(v) == 3 and not -50.0 <= v[2] <= 0.5:
        raise InputError(f"--target depth Z must be -50..0.5 m (0: the surface), got {v[2]:g}")
    return v


def _target_arg(text: str) -> tuple[float, ...]:
    """argparse's type for --target: the numbers, or its one-line usage error."""
    try:
        return _target_xyz(text)
    except InputError as e:
        raise argparse.ArgumentTypeError(str(e)) from None


def target_from_args(args: argparse.Namespace):
    """The target the target arguments name, or None."""

    if args.target is not None:
        v = _target_xyz(args.target)
        if len(v) == 3 and v[2] < 0.0:
            # the point below, then the surface above it: come up for air there
            return Waypoints(np.array([v, (v[0], v[1], 0.0)]), radius=DIVE_RADIUS_M)
        return Point(v[0], v[1])
    if args.moving_target is not None:
        x, y, vx, vy = _vec(args.moving_target, "--moving-target", 4)
        return Point(x, y, vx=vx, vy=vy)
    if getattr(args, "circling_target", None) is not None:
        cx, cy, r, v = _vec(args.circling_target, "--circling-target", 4)
        if v < 0:
            raise InputError(f"--circling-target speed must be >= 0 m/s, got {v:g}")
        return Circle((cx, cy), r, v, -np.pi / 2)
    if args.path is not None:
        return load_path(args.path, args.lookahead)
    if args.figure8 is not None:
        return figure_eight(args.figure8, lookahead=args.lookahead)
    if getattr(args, "trajectory", None) is not None:
        traj = load_trajectory(args.trajectory)
        if traj.is_3d and float(traj.table[:, 3].min()) < 0.0:
            raise InputError(f"{args.trajectory}: a depth below the surface (z < 0) cannot be "
                             "followed along a trajectory (the floating swimmer only pitches "
                             "towards it); give z >= 0, or dive to a fixed point with "
                             "--target X,Y,Z")
        return traj
    if args.heading is not None:
        if not np.isfinite(args.heading):
            raise InputError("--heading must be a finite angle in degrees")
        return Heading(np.radians(args.heading))
    return None


def _layers(args: argparse.Namespace) -> str:
    if args.no_feedback and args.layers not in (None, "basic"):
        raise InputError(f"--no-feedback means --layers basic; it contradicts --layers {args.layers}")
    return "basic" if args.no_feedback else (args.layers or "all")


def calibrate_command(args: argparse.Namespace, params: SwimmerParams) -> dict:
    """``flapsim swim --calibrate --stroke NAME``: the per-cycle tables (see
    :func:`flapsim.swim.per_cycle.calibrate`)."""


    if args.table is not None and not str(args.table).endswith(".json"):
        raise InputError(f"--table must name a .json file, got {args.table!r}")
    workers = args.workers or os.cpu_count() or 1
    if workers < 1:
        raise InputError("--workers must be >= 1")
    base = SwimmerParams()
    changed = {k: getattr(params, k) for k in params.__dataclass_fields__
               if getattr(params, k) != getattr(base, k)}
    tables, out = calibrate(args.stroke, args.table, workers=workers, params=changed,
                            progress=True)
    print(f"per-cycle tables for {args.stroke} written to {out}")
    rows = {}
    for mode, t in tables.items():
        hold = int((t.provenance.get("config") or {}).get("hold", 1))
        print(f"  layers {mode}: turn per cycle at weight {t.weights[-1]:g} [deg], at "
              + ", ".join(f"{v:.2f}" for v in t.speeds) + " m/s"
              + (f" (yaw: held {hold} cycles, per cycle after the first)" if hold > 1 else ""))
        for name, a in t.angles.items():
            print(f"    {name:11s} " + "  ".join(f"{x:6.1f}" for x in np.degrees(a[:, -1])))
        rows[mode] = t.to_dict()
    return {"stroke": args.stroke, "table": str(out), "tables": rows}


def tow_command(args: argparse.Namespace, params: SwimmerParams) -> dict:
    """``flapsim swim --tow V1,V2,...``: passive drag in a streamlined glide
    (:func:`flapsim.swim.tow.tow`)."""
    try:
        speeds = [float(x) for x in str(args.tow).split(",")]
    except ValueError:
        raise InputError(f"--tow must be comma-separated speeds in m/s, e.g. 1.0,1.5,2.0; got "
                         f"{args.tow!r}") from None
    r = tow(speeds, params)
    s = r.summary()
    s["params"] = {k: getattr(params, k) for k in params.__dataclass_fields__}
    print(f"towed in a streamlined glide ({params.body_shape} body); people: {NARITA_K} v^2 N "
          "(Narita et al. 2017)")
    print(f"{'v [m/s]':>8} {'surface [N]':>12} {'(waves)':>8} {f'{r.depth_m:g} m under [N]':>15} "
          f"{'(waves)':>8} {'people [N]':>11}")
    for v, a, wa, b, wb in zip(r.speeds, r.surface_n, r.wave_surface_n, r.submerged_n,
                               r.wave_submerged_n, strict=True):
        print(f"{v:8.2f} {a:12.1f} {wa:8.1f} {b:15.1f} {wb:8.1f} {NARITA_K * v * v:11.1f}")
    print(f"tow_drag_coefficient {r.k_submerged:.1f} N s^2/m^2 {r.depth_m:g} m under the surface "
          f"({r.k_submerged / NARITA_K:.2f}x people), {r.k_surface:.1f} at the surface with the "
          "waves the body makes")
    return s


def _t(v: float | None) -> str:
    return "never" if v is None else f"at {v:.1f} s"


def _print_budget(b: dict) -> None:
    """The water budget's lines: the whole body, then each segment group taking over 1 W."""
    def eff(name: str) -> str:
        e = b[f"{name}_froude_efficiency"]
        return (f"{name}' thrust power {b[f'{name}_thrust_power_w']:.0f} of "
                f"{b[f'{name}_water_w']:.0f} W (Froude efficiency {'n/a' if e is None else f'{e:.2f}'})")

    print(f"  into the water   {b['water_w']:.0f} W (surface engine), {b['slip_w']:.0f} W of it "
          f"slip; {eff('arms')} (swimmers' crawl 0.44-0.61), {eff('legs')}")
    rows = sorted(b["segments"].items(), key=lambda kv: -kv[1]["water_w"])
    print("                   " + ", ".join(
        f"{g} {r['water_w']:.0f} W ({r['slip_w']:.0f} slip)" for g, r in rows if r["water_w"] > 1.0))


def _print_joints(j: dict) -> None:
    """The muscles' budget per joint group taking over 1 W (net, and the braking absorbed)."""
    rows = sorted(j["groups"].items(), key=lambda kv: -abs(kv[1]["net_w"]))
    print(f"  joints           {j['net_w']:.0f} W net, {j['negative_w']:.0f} W absorbed braking; "
          + ", ".join(f"{g} {r['net_w']:.0f} W ({r['negative_w']:.0f} absorbed)" for g, r in rows
                      if abs(r["net_w"]) > 1.0 or r["negative_w"] > 1.0))


def run(args: argparse.Namespace) -> dict:
    layers = _layers(args)
    kw = {"buoyancy_method": args.buoyancy, "r_min": args.r_min, "r_max": args.r_max,
          "body_shape": getattr(args, "body", "box")}
    for name, key in (("density", "water_density"), ("lungs", "lung_volume_l"),
                      ("friction", "friction"), ("timestep", "timestep")):
        if getattr(args, name) is not None:
            kw[key] = getattr(args, name)
    params = SwimmerParams(**kw)
    # a bundled stroke tuned on this body (the rounded one has its own) is swum instead
    args.stroke = stroke_for_body(args.stroke, params.body_shape)
    if args.calibrate and args.tow is not None:
        raise InputError("--calibrate and --tow are two different jobs: give one")
    if args.calibrate:
        return calibrate_command(args, params)
    if args.tow is not None:
        return tow_command(args, params)
    cycle_table = None
    if args.table is not None:
        cycle_table = load_table(load_stroke(args.stroke), args.table,
                                 layers="all" if layers == "all" else "cycle",
                                 body_shape=params.body_shape)
    video = args.video
    target = target_from_args(args)
    flow = _flow(args)
    current = _vec(args.current, "--current", 3)
    viewer = None
    swimmer = None
    dive = None
    if isinstance(target, Waypoints):
        stroke = load_stroke(args.stroke)
        if stroke.posture != "prone" or not any(k.startswith("yaw") for k in stroke.cycle):
            raise InputError(f"a target below the surface is reached by a surface dive, which "
                             f"the prone strokes swim (crawl, breaststroke), not "
                             f"{args.stroke!r}")
        if args.viewer:
            raise InputError("the viewer's target stays on the surface: give --target X,Y")
        if layers == "basic":
            raise InputError("a dive needs the per-cycle layer (it pitches towards the point "
                             "below): --layers cycle or all")
        dive = SurfaceDive(target, lungs_l=params.lung_volume_l,
                           under_stroke=UNDER_WATER_STROKE.get(stroke.name))
    approach = None
    if (isinstance(target, (Point, Circle)) and not args.viewer and layers != "basic"
            and not getattr(args, "no_approach", False)):
        stroke = load_stroke(args.stroke)
        if stroke.posture == "prone" and stroke.cycle:
            approach = Approach(target)
    if args.viewer:
        check_display()
        if target is not None and not isinstance(target, Point):
            raise InputError("the viewer steers for a point you move: use --target X,Y (or "
                             "nothing: 10 m ahead), not --path/--figure8/--heading")
        steers = any(k.startswith("yaw") for k in load_stroke(args.stroke).cycle)
        marker = target if target is not None else Point(10.0, 0.0)
        # the target stays the swimmer's even at --layers basic: a key switches layers
        target = marker if steers else None
        swimmer = Swimmer(params, flow)
        viewer = SwimViewer(swimmer, marker)
    with contextlib.ExitStack() as stack:
        on_frame = None
        if video:  # frames stream into a temporary file, renamed only when the swim succeeded

            on_frame = stack.enter_context(atomic_video(video, fps=args.fps, codec="libx264",
                                                        quality=7))
        try:
            result = swim(args.stroke, args.seconds, params, rate_hz=args.rate, flow=flow,
                          current=current, video_fps=args.fps if video else 0.0,
                          progress=viewer is None, layers=layers, target=target,
                          swimmer=swimmer, control_hook=viewer if viewer is not None else dive,
                          on_frame=on_frame,
                          cycle_table=cycle_table, speed=args.speed, approach=approach,
                          budget=bool(getattr(args, "power", False)))
        finally:
            if viewer is not None:
                viewer.close()
    s = result.summary()
    s["params"] = {k: getattr(params, k) for k in params.__dataclass_fields__}
    if dive is not None:
        head = result.head[:, 2] - result.water_level
        reached = dive.events["reached"]
        up = np.flatnonzero((result.times > reached) & (head > 0.0)) if reached else []
        s["dive"] = {"events_s": dict(dive.events), "closest_to_point_m": dive.closest_m,
                     "deepest_head_m": float(head.min()),
                     "head_resurfaced_s": float(result.times[up[0]]) if len(up) else None}
    if args.plot:
        track_plot(result, args.plot)
        s["plot"] = str(args.plot)
    if viewer is not None:
        rates = [e["rate_hz"] for e in viewer.events if "rate_hz" in e]
        s["viewer"] = {"events": viewer.events,
                       "final_target": [viewer.target.x, viewer.target.y],
                       "final_rate_hz": rates[-1] if rates else s["stroke_rate_hz"],
                       "final_layers": s["layers_mode"]}
    if args.out:
        extra = {}
        if isinstance(result.target, Path):
            extra["target_path"] = result.target.points
        save_npz(args.out, time=result.times, com=result.com, head=result.head,
                 muscle_power=result.power, **extra)
        s["out"] = str(args.out)
    if video:
        s["video"] = str(video)
    print(f"{s['stroke']}: {s['seconds']:.1f} s simulated in {s['wall_s']:.1f} s "
          f"({s['realtime_factor']:.1f}x real time)")
    print(f"  speed            {s['speed_m_s']:.3f} m/s (after {2} cycles; whole run "
          f"{s['mean_speed_whole_run_m_s']:.3f} m/s, {s['distance_m']:.2f} m)")
    if "target" in s:
        print(f"  track speed      {s['track_speed_m_s']:.3f} m/s (along the swum track)")
    print(f"  stroke rate      {s['stroke_rate_hz']:.3f} cycles/s ({s['cycles']} cycles)")
    print(f"  distance/stroke  {s['distance_per_stroke_m']:.3f} m")
    print(f"  head centre      {s['head_height_mean_m']:+.3f} m mean, "
          f"{s['head_height_min_m']:+.3f}..{s['head_height_max_m']:+.3f} m "
          f"(above water {100 * s['head_above_water_fraction']:.0f}% of the time, in "
          f"{100 * s['breathing_cycles_fraction']:.0f}% of the cycles)")
    print(f"  centre of mass   {s['com_height_mean_m']:+.3f} m mean relative to the surface")
    print(f"  head drift       {s['head_horizontal_drift_max_m']:.3f} m max horizontally")
    print(f"  muscle power     {s['muscle_power_mean_w']:.0f} W mean (joint torques x speeds, "
          f"net; {s['muscle_power_positive_mean_w']:.0f} W if no joint's braking is paid back)")
    if "roll_shoulders_deg" in s:
        print(f"  carriage         roll +-{s['roll_shoulders_deg']:.0f} deg shoulders, "
              f"+-{s['roll_hips_deg']:.0f} deg hips; trunk incline {s['trunk_incline_deg']:.0f} deg")
    if "water_budget" in s:
        _print_budget(s["water_budget"])
    if "joint_budget" in s:
        _print_joints(s["joint_budget"])
    print(f"  layers           {' + '.join(s['layers'])}")
    if "target" in s:
        t = s["target"]
        if t["kind"] == "point":
            reached = (f"reached at {s['target_reached_s']:.1f} s" if s["target_reached_s"]
                       is not None else "not reached")
            print(f"  target           ({t['x_m']:g}, {t['y_m']:g}) m: {reached}; closest "
                  f"{s['target_distance_min_m']:.2f} m, at the end {s['target_distance_end_m']:.2f} m")
        elif t["kind"] == "circle":
            print(f"  target           circling ({t['centre_m'][0]:g}, {t['centre_m'][1]:g}) m "
                  f"on {t['orbit_m']:g} m at {t['speed_m_s']:g} m/s: closest "
                  f"{s['target_distance_min_m']:.2f} m")
        elif t["kind"] == "path":
            done = (f"completed at {s['path_completed_s']:.1f} s" if s["path_completed_s"]
                    is not None else f"{100 * s['path_completed_fraction']:.0f}% done")
            print(f"  path             {t['name']} ({t['length_m']:.1f} m): {done}; distance "
                  f"from it {s['path_error_mean_m']:.2f} m mean, {s['path_error_max_m']:.2f} m max")
        elif t["kind"] == "heading":
            print(f"  heading          held at {t['heading_deg']:.1f} deg")
        else:
            print(f"  target           {t['kind']}")
        if "distance_to_target_mean_m" in s:
            reached = (f"first within {t.get('radius_m', 0.5):g} m at {s['time_to_reach_s']:.1f} s"
                       if s["time_to_reach_s"] is not None else "never within reach")
            print(f"  to target        {s['distance_to_target_mean_m']:.2f} m mean, "
                  f"{s['distance_to_target_max_m']:.2f} m max; {reached}")
        if s.get("target_distance_after_reached_mean_m") is not None:
            print(f"  held             {s['target_distance_after_reached_mean_m']:.2f} m mean "
                  "from the target after first reaching it")
        if "heading_error_mean_deg" in s:
            print(f"  heading error    {s['heading_error_mean_deg']:.1f} deg mean")
    if s.get("approach"):
        a = s["approach"]
        sw = ", ".join(f"{e['to']} at {e['t']:.1f} s" for e in a["switches"]) or "no switch"
        print(f"  approach         speed asked from the distance; {sw}")
    for name, w in (s.get("feedback_weights") or {}).items():
        print(f"    {name:14s} weight mean {w['mean']:+.2f}, |w| {w['mean_abs']:.2f}, "
              f"saturated {100 * w['saturated_fraction']:.0f}% of the time")
    if dive is not None:
        dv = s["dive"]
        print(f"  dive             started {_t(dv['events_s']['dive'])}, point reached "
              f"{_t(dv['events_s']['reached'])} (closest {dv['closest_to_point_m']:.2f} m, head "
              f"down to {dv['deepest_head_m']:+.2f} m), head up again {_t(dv['head_resurfaced_s'])}")
    if video:
        print(f"  video            {video}")
    if args.out:
        print(f"  track            {args.out}")
    if args.plot:
        print(f"  plot             {args.plot}")
    return s
