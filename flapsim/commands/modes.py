"""``flapsim modes MODEL.xml``: vibration modes of any MJCF model (Kry et al. 2009)."""

from __future__ import annotations

import argparse
import logging
import time
from pathlib import Path

from flapsim.errors import InputError

HELP = "modal analysis of an MJCF model: lowest vibration modes, JSON, optional video/GIF"

log = logging.getLogger(__name__)


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("model", help="MJCF file (any path; meshes resolve relative to it)")
    p.add_argument("--keyframe", help="rest pose from this keyframe (name or index) "
                   "instead of the joints' springref (qpos_spring)")
    p.add_argument("--fix-root", action="store_true",
                   help="freeze the floating root (free joints attached to the world)")
    p.add_argument("--constrain", action="append", default=[], metavar="KIND:NAMES",
                   help="extra constraint (repeatable): orient:BODY, pin:SITE, "
                   "contact:SITE[,SITE], sliding-contact:SITE[,SITE], joint:JOINT")
    p.add_argument("--no-equality", action="store_true",
                   help="ignore the model's equality constraints (closed loops)")
    p.add_argument("--stiffness", type=float, default=None, metavar="K",
                   help="uniform joint stiffness for every non-free joint, N m/rad "
                   "(default: the model's own stiffness)")
    p.add_argument("--stiffness-scale", type=float, default=1.0,
                   help="multiply all joint and tendon stiffness by this (default 1)")
    p.add_argument("--actuator-stiffness", action="store_true",
                   help="include position-servo stiffness (kp) of actuators")
    p.add_argument("--count", type=int, default=10,
                   help="how many of the lowest vibration modes to print (default 10)")
    p.add_argument("--shapes", action="store_true",
                   help="include every mode shape (max-normalised, nv numbers) in the JSON")
    p.add_argument("--video", metavar="PATH",
                   help="write an .mp4 or .gif of the printed modes oscillating one after another")
    p.add_argument("--video-modes", metavar="I,J,...",
                   help="which modes the video shows (default: the printed ones)")
    p.add_argument("--amplitude-deg", type=float, default=20.0,
                   help="video amplitude: excursion of the most-moving joint, deg (default 20)")
    p.add_argument("--cycles", type=float, default=2.0,
                   help="video cycles per mode (default 2; every mode shown at 1 cycle/s)")


def _parse_modes(text: str) -> list[int]:
    try:
        return [int(x) for x in text.split(",") if x.strip()]
    except ValueError:
        raise InputError(f"--video-modes must be comma-separated integers, got {text!r}") from None


def run(args: argparse.Namespace) -> dict:
    import math

    import numpy as np

    from flapsim.modal.analysis import analyze, fix_root, parse_constraint
    from flapsim.sim.loading import load_model

    if args.count < 1:
        raise InputError("--count must be at least 1")
    if not math.isfinite(args.stiffness_scale) or args.stiffness_scale <= 0:
        raise InputError("--stiffness-scale must be a positive number")
    if args.stiffness is not None and (not math.isfinite(args.stiffness) or args.stiffness <= 0):
        raise InputError("--stiffness must be a positive number of N m/rad")
    if not math.isfinite(args.amplitude_deg) or args.cycles <= 0:
        raise InputError("--amplitude-deg must be finite and --cycles positive")
    if args.video:
        from flapsim.modal.video import check_video_path

        check_video_path(args.video)
    constraints = [parse_constraint(c) for c in args.constrain]

    path = Path(args.model).expanduser().resolve()
    model = load_model(path)
    if args.fix_root:
        constraints = fix_root(model) + constraints
    t0 = time.perf_counter()
    result = analyze(
        model,
        keyframe=args.keyframe,
        constraints=constraints,
        use_equality=not args.no_equality,
        stiffness=args.stiffness,
        stiffness_scale=args.stiffness_scale,
        actuator_stiffness=args.actuator_stiffness,
    )
    elapsed = time.perf_counter() - t0

    rows = result.table(args.count)
    print(f"{path.name}: {model.nv} dofs, constraints remove {result.constraint_rank}, "
          f"{result.n_modes} modes ({result.n_rigid} rigid), analysed in {elapsed * 1e3:.1f} ms")
    if result.constraint_labels:
        print("constraints: " + ", ".join(result.constraint_labels))
    if not rows:
        print("no vibration modes: every admissible direction is rigid")
    else:
        print(f"{'mode':>5} {'freq_Hz':>10} {'zeta':>7}  dominant joints")
        for r in rows:
            z = "-" if r["damping_ratio"] is None else f"{r['damping_ratio']:.3f}"
            print(f"{r['mode']:>5} {r['freq_hz']:>10.4g} {z:>7}  {', '.join(r['dominant_joints'])}")

    out = {"model": str(path), "analysis_s": elapsed, **result.to_dict(shapes=args.shapes)}
    if args.video:
        from flapsim.modal.video import mode_poses, render_poses

        modes = _parse_modes(args.video_modes) if args.video_modes else [r["mode"] for r in rows]
        for i in modes:
            result._check_mode(i)
        if not modes:
            raise InputError("no modes to show in the video")
        poses = mode_poses(
            model, result, modes, amplitude_rad=float(np.radians(args.amplitude_deg)),
            cycles=args.cycles,
        )
        n = render_poses(model, poses, args.video)
        print(f"video: modes {', '.join(map(str, modes))} ({n} frames, 1 cycle/s) -> {args.video}")
        out["video"] = {"path": str(args.video), "modes": modes, "frames": n,
                        "display_cycle_s": 1.0, "amplitude_deg": args.amplitude_deg}
    return out
