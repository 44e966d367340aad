"""``flapsim creature [MODEL.xml] --model loop|linear|PATH``: a creature driven by its two
lowest modes (the paper's dynamic creatures), bundled or any model with actuated joints."""

from __future__ import annotations

import argparse
import math

from flapsim.core.errors import InputError
from flapsim.core.validate import add_output_arg, quantity
from flapsim.modal.creatures import (
    CREATURES,
    creature_file,
    is_model_file,
    load_creature,
    run_creature,
    with_gait,
)
from flapsim.modal.video import render_poses

HELP = "simulate a creature (loop, linear or your MJCF) driven by its two lowest modes"
SEED_HELP = "accepted for uniformity; the creature is deterministic, --seed changes nothing"


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("model_file", nargs="?", default=None, metavar="MODEL.xml",
                   help="your own MJCF with a motor on each joint the modes move "
                   "(same as --model PATH)")
    p.add_argument("--model", default=None,
                   help="which creature: loop, linear or an MJCF path (default loop)")
    p.add_argument("--seconds", type=quantity("seconds"), default=10.0,
                   help="simulated seconds of driven motion (default 10)")
    p.add_argument("--amplitude-deg", type=quantity("angle_deg"), default=None,
                   help="set-point amplitude of the most-moving joint per mode, deg "
                   "(default: the creature's gait)")
    p.add_argument("--freq", type=quantity("freq"), default=None,
                   help="drive frequency of both modes, Hz (default: 5.25 loop = its natural "
                   "frequency, 5 linear, as in the paper)")
    p.add_argument("--phase-deg", type=quantity("angle_deg"), default=None,
                   help="phase of the second mode relative to the first, deg (default 90; "
                   "-90 travels the other way)")
    add_output_arg(p, "--video", kinds=(".mp4", ".gif"), renders=True,
                   help="write an .mp4 or .gif of the run")
    p.add_argument("--no-progress", action="store_true", help="hide the progress bar")


def run(args: argparse.Namespace) -> dict:
    if args.model_file and args.model and args.model_file != args.model:
        raise InputError("give the model once: MODEL.xml or --model, not both")
    args.model = args.model_file or args.model or "loop"
    if args.model not in CREATURES and not is_model_file(args.model):
        raise InputError(f"unknown creature {args.model!r}; choose one of {', '.join(CREATURES)} "
                         "or give an MJCF file")
    gait = with_gait(
        args.model,
        amplitude_rad=None if args.amplitude_deg is None else math.radians(args.amplitude_deg),
        freq_hz=args.freq,
        phase_deg=args.phase_deg,
    )
    fps = 30.0
    model = load_creature(args.model)
    every = max(int(round(1.0 / (fps * model.opt.timestep))), 1) if args.video else 0
    result = run_creature(
        args.model, args.seconds, gait, progress=not args.no_progress, record_every=every,
        model=model,
    )
    frames = result.pop("_frames", None)
    r = result
    print(
        f"{r['creature']} creature: modes {r['modes_driven']} "
        f"({', '.join(f'{f:.3g}' for f in r['mode_freqs_hz'])} Hz) driven at "
        f"{r['drive_freq_hz']:.3g} Hz, amplitude {math.degrees(r['amplitude_rad']):.3g} deg, "
        f"phase {r['phase_deg']:+.0f} deg"
    )
    print(
        f"travelled {r['distance_x_m']:+.3f} m along x = {r['distance_x_body_lengths']:+.2f} "
        f"body lengths ({r['body_length_definition']} = {r['body_length_m']:.3f} m) in "
        f"{r['simulated_s']:.3g} s; horizontal {r['distance_horizontal_body_lengths']:.2f} BL; "
        f"mean speed {r['mean_speed_m_s']:+.3f} m/s"
    )
    if r["model_file"] not in ("loop.xml", "linear.xml"):
        print(f"model: {r['model_file']}")
    print(f"real-time factor {r['realtime_factor']:.1f} (simulated s per wall s)")
    if args.video and frames is not None:
        n = render_poses(model, list(frames), args.video, source=creature_file(args.model),
                         fps=fps, progress=not args.no_progress)
        print(f"video: {n} frames -> {args.video}")
        result["video"] = {"path": str(args.video), "frames": n, "fps": fps}
    return result
