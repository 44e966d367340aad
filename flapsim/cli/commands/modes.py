"""``flapsim modes MODEL.xml``: vibration modes of any MJCF model (Kry et al. 2009)."""

from __future__ import annotations

import argparse
import logging
import time
from pathlib import Path

import numpy as np

from flapsim.core.errors import InputError
from flapsim.core.loading import load_model
from flapsim.core.validate import add_input_arg, add_output_arg, integer, quantity
from flapsim.modal.analysis import analyze, fix_root, parse_constraint
from flapsim.modal.video import mode_poses, render_poses

HELP = "modal analysis of an MJCF model: lowest vibration modes, JSON, optional video/GIF"
SEED_HELP = "accepted for uniformity; the analysis is deterministic, --seed changes nothing"

log = logging.getLogger(__name__)


def add_arguments(p: argparse.ArgumentParser) -> None:
    add_input_arg(p, "model", help="MJCF file (any path; meshes resolve relative to it)")
    p.add_argument("--keyframe", help="rest pose from this keyframe (name or index) "
                   "instead of the joints' springref (qpos_spring)")
    p.add_argument("--fix-root", action="store_true",
                   help="freeze the floating root (a free joint attached to the world, or the "
                   "slide joints of a planar root); an error if the model has none")
    p.add_argument("--constrain", action="append", default=[], metavar="KIND:NAMES",
                   help="extra constraint (repeatable): orient:BODY, pin:SITE, "
                   "contact:SITE[,SITE], sliding-contact:SITE[,SITE], joint:JOINT")
    p.add_argument("--no-equality", action="store_true",
                   help="ignore the model's equality constraints (closed loops)")
    p.add_argument("--stiffness", type=quantity("stiffness"), default=None, metavar="K",
                   help="uniform joint stiffness for every joint but the floating root's, N m/rad "
                   "(default: the model's own stiffness)")
    p.add_argument("--stiffness-scale", type=quantity("scale"), default=1.0,
                   help="multiply all joint and tendon stiffness by this (default 1)")
    p.add_argument("--actuator-stiffness", action="store_true",
                   help="include position-servo stiffness (kp) of actuators")
    p.add_argument("--count", type=integer(1, 100000), default=10,
                   help="how many of the lowest vibration modes to print (default 10)")
    p.add_argument("--shapes", action="store_true",
                   help="include every mode shape (max-normalised, nv numbers) in the JSON")
    add_output_arg(p, "--video", kinds=(".mp4", ".gif"), renders=True,
                   help="write an .mp4 or .gif of the printed modes oscillating one after another")
    p.add_argument("--video-modes", metavar="I,J,...",
                   help="which modes the video shows (default: the printed ones)")
    p.add_argument("--amplitude-deg", type=quantity("angle_deg"), default=20.0,
                   help="video amplitude: excursion of the most-moving joint, deg (default 20)")
    p.add_argument("--cycles", type=quantity("cycles"), default=2.0,
                   help="video cycles per mode (default 2; every mode shown at 1 cycle/s)")


def _parse_modes(text: str) -> list[int]:
    try:
        return [int(x) for x in text.split(",") if x.strip()]
    except ValueError:
        raise InputError(f"--video-modes must be comma-separated integers, got {text!r}") from None


def run(args: argparse.Namespace) -> dict:
    video_modes = _parse_modes(args.video_modes) if args.video_modes else None
    constraints = [parse_constraint(c) for c in args.constrain]

    path = Path(args.model).expanduser().resolve()
    model = load_model(path)
    if args.fix_root:
        try:
            constraints = fix_root(model) + constraints
        except InputError as exc:
            raise InputError(f"--fix-root: {path.name}: {exc}") from None
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
            note = "  (overdamped: does not oscillate)" if r.get("overdamped") else ""
            print(f"{r['mode']:>5} {r['freq_hz']:>10.4g} {z:>7}  {', '.join(r['dominant_joints'])}"
                  f"{note}")
        if any(r.get("overdamped") for r in rows):
            print("zeta >= 1: overdamped modes return to rest without oscillating; freq_Hz is "
                  "their undamped frequency")

    out = {"model": str(path), "analysis_s": elapsed, **result.to_dict(shapes=args.shapes)}
    if args.video:
        modes = video_modes if video_modes is not None else [r["mode"] for r in rows]
        for i in modes:
            result._check_mode(i)
        if not modes:
            raise InputError("no modes to show in the video")
        poses = mode_poses(
            model, result, modes, amplitude_rad=float(np.radians(args.amplitude_deg)),
            cycles=args.cycles,
        )
        n = render_poses(model, poses, args.video, source=path)
        print(f"video: modes {', '.join(map(str, modes))} ({n} frames, 1 cycle/s) -> {args.video}")
        out["video"] = {"path": str(args.video), "modes": modes, "frames": n,
                        "display_cycle_s": 1.0, "amplitude_deg": args.amplitude_deg}
    return out
