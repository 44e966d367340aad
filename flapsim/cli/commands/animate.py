"""``flapsim animate [MODEL.xml] --gait NAME``: kinematic modal gaits of the dog, the human
or any legged MJCF (Kry et al. 2009, sections 4.2-4.3 and 5.1, Fig. 3), with modes picked
by heuristics A-G or read from a gait file."""

from __future__ import annotations

import argparse
import dataclasses
import math
import os
from pathlib import Path

import mujoco
import numpy as np

from flapsim.core.errors import InputError
from flapsim.core.validate import add_input_arg, add_output_arg, quantity
from flapsim.modal import animate as anim_mod
from flapsim.modal.browser import ModeBrowser, contact_sheet
from flapsim.modal.bvh import write_bvh
from flapsim.modal.gaits import (
    GAITS,
    MODELS,
    cycle_seconds,
    gait,
    gait_file_of,
    head_orientation_error,
    model_file,
    plan_from_file,
    plan_gait,
    resolve_model,
)
from flapsim.modal.heuristics import CATEGORY_NAMES, has_convention_labels
from flapsim.modal.own import (
    GaitFile,
    apply_stiffness_edits,
    feet_of,
    foot_phases_deg,
    foot_tracks,
    parse_stiffness_edits,
    prepare,
    travel_root,
)
from flapsim.modal.stiffness import tune_stiffness
from flapsim.modal.video import render_poses

HELP = "kinematic modal gait (walk, run, trot, ...) of the dog, human or any legged MJCF"
SEED_HELP = "accepted for uniformity; the animation is deterministic, --seed changes nothing"

#: The most frames one animation may have (--seconds x --fps): the trajectory is held in
#: memory (about 1 kB a frame for the human) and every frame is rendered for a video.
MAX_FRAMES = 100_000


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("model_file", nargs="?", default=None, metavar="MODEL.xml",
                   help="your own legged MJCF: legs, knees and hips are found from its tree "
                   "(same as --model PATH)")
    p.add_argument("--gait", default=None,
                   help="gait: trot, amble, gallop (dog, quadrupeds); walk, run, jump, "
                   "jumping_jacks, run_head, push_cart (human, bipeds); 'list' shows them "
                   "(default walk; trot for your own quadruped)")
    add_input_arg(p, "--labels", default=None, metavar="TOML",
                  help="label file overriding the feet, knees, hands, head or forward found "
                  "from the tree")
    p.add_argument("--flex-knees-deg", type=quantity("angle_deg"), default=None,
                   help="flex the knees of your own model's rest pose by this much (0: keep "
                   "its pose; default: 30 when straight legs give the feet no vertical motion)")
    p.add_argument("--no-tune", action="store_true",
                   help="your own model: skip the stiffness scaling that carries its weight")
    p.add_argument("--stiffness", action="append", default=None, metavar="JOINT=SCALE",
                   help="multiply one joint's stiffness (repeatable; the paper's style edits)")
    add_output_arg(p, "--save-gait", kinds=(".toml",), metavar="TOML",
                   help="write the gait (modes, amplitudes, phases, offsets, stride, hip sway, "
                   "posture) as a gait file to edit")
    add_input_arg(p, "--gait-file", default=None, metavar="TOML",
                  help="play an (edited) gait file instead of the heuristics' choice")
    p.add_argument("--travel", action="store_true",
                   help="move the root from the stance feet so the creature travels (npz, "
                   "BVH and video carry it); reports each foot's slip")
    add_input_arg(p, "--model", may_be_name=True, default=None,
                  help="dog, human, human_cart or an MJCF path with the labels the heuristics "
                   "read (default: the gait's own creature)")
    p.add_argument("--seconds", type=quantity("seconds"), default=2.0,
                   help=f"animation length, s (default 2; at most {MAX_FRAMES} frames in all)")
    p.add_argument("--fps", type=quantity("fps"), default=30.0, help="frames per second (default 30)")
    p.add_argument("--amplitude-scale", type=quantity("scale"), default=1.0,
                   help="multiply every mode amplitude and offset (stride length; default 1)")
    p.add_argument("--freq", type=quantity("freq"), default=None,
                   help="gait frequency, Hz (default: the paper's 2 Hz)")
    p.add_argument("--soft-limit-deg", type=quantity("soft_limit_deg"), default=5.0,
                   help="dtheta_soft: the most a joint may pass its limit, deg (default 5)")
    p.add_argument("--stiffness-scale", type=quantity("scale"), default=1.0,
                   help="multiply the joint stiffness before the analysis (default 1)")
    p.add_argument("--tune-stiffness", action="store_true",
                   help="first find the smallest uniform stiffness scale that holds the rest "
                   "pose under gravity in simulation, and analyse with it")
    p.add_argument("--project", action="store_true",
                   help="pull every frame back onto the constraints (closed loops, fixed head); "
                   "otherwise they hold to first order only, as in the paper")
    add_output_arg(p, "--npz", kinds=(".npz",), help="write the joint trajectory (times, qpos)")
    add_output_arg(p, "--video", kinds=(".mp4", ".gif"), renders=True,
                   help="write an .mp4 or .gif of the animation")
    add_output_arg(p, "--bvh", kinds=(".bvh",), help="write the animation as BVH (cm, z up)")
    add_output_arg(p, "--sheet", kinds=(".png",), metavar="PNG",
                   help="write an offscreen contact sheet of one cycle (mode browser view)")
    p.add_argument("--browse", action="store_true",
                   help="open the interactive mode browser (sliders per mode; needs a display)")


def _list() -> dict:
    print(f"{'gait':<14} {'model':<11} {'selection':<11} description")
    for g in GAITS.values():
        print(f"{g.name:<14} {g.model:<11} {g.selection:<11} {g.description}")
    return {"gaits": {g.name: {"model": g.model, "selection": g.selection,
                               "description": g.description} for g in GAITS.values()}}


def _own_or_bundled(args: argparse.Namespace, gfile: GaitFile | None):
    """The model, its label and whether it goes through the own-creature setup."""
    if args.model_file and args.model and args.model_file != args.model:
        raise InputError("give the model once: MODEL.xml or --model, not both")
    spec = args.model_file or args.model
    if spec is None:
        name = args.gait or (gfile.name if gfile and gfile.name in GAITS else "walk")
        spec = gait(name).model if name != "list" else "human"
    model, label = resolve_model(spec)
    own = spec not in MODELS and (args.labels is not None or not has_convention_labels(model))
    return model, label, spec, own


def run(args: argparse.Namespace) -> dict:
    if args.gait == "list":
        return _list()
    frames = int(round(args.seconds * args.fps))
    if frames > MAX_FRAMES:
        raise InputError(f"--seconds {args.seconds:g} at --fps {args.fps:g} is {frames} frames; at "
                         f"most {MAX_FRAMES} (the trajectory is held in memory): shorten it or "
                         "lower --fps")
    gfile = GaitFile.read(args.gait_file) if args.gait_file else None
    model, label, spec, own_flow = _own_or_bundled(args, gfile)
    edits = dict(gfile.stiffness) if gfile else {}
    for k, v in parse_stiffness_edits(args.stiffness).items():
        edits[k] = edits.get(k, 1.0) * v
    if args.labels and not own_flow:
        raise InputError("--labels applies to your own model file, not a bundled creature")

    own = None
    scale = args.stiffness_scale
    tuning = None
    if own_flow:
        flex = gfile.knee_flex_deg if gfile else args.flex_knees_deg
        own = prepare(model, label_file=args.labels, knee_flex_deg=flex,
                      tune=not (args.no_tune or gfile), stiffness_edits=edits)
        scale = gfile.stiffness_scale if gfile else scale * own.stiffness_scale
        tuning = own.tuning
        kind = "quadruped" if own.legs.quadruped else "biped"
        print(f"{label}: a {kind}; feet " + ", ".join(
            f"{g.role} {g.foot_name} (knee {g.knee}, hip {'/'.join(g.hip)})" for g in own.legs.legs))
        print(f"rest pose: {own.flex_reason}")
        if own.tuning is not None:
            if own.tuning["holds"]:
                print(f"stiffness: x{own.stiffness_scale:.3g} is the smallest uniform scale that "
                      f"carries its weight ({own.tuning['trials']} simulations)")
            else:
                print(f"stiffness: no scale up to 64x holds the pose ({own.tuning['why']}); "
                      "kept x1 (the gait is kinematic)")
        if own.stiffness_edits:
            print("stiffness edits: " + ", ".join(f"{k} x{v:g}" for k, v in edits.items()))
    else:
        apply_stiffness_edits(model, edits)
        if gfile is not None:
            scale = gfile.stiffness_scale

    if own is not None:
        default = "trot" if own.legs.quadruped else "walk"
    else:
        default = "walk"
    g = gait(args.gait or (gfile.name if gfile and gfile.name in GAITS else default))
    if own is not None:
        kind = "quadruped" if own.legs.quadruped else "biped"
        if g.kind != kind:
            names = [n for n, x in GAITS.items()
                     if x.kind == kind and not x.constraints and x.model != "human_cart"]
            raise InputError(f"gait {g.name!r} is for a {g.kind}, and {label} is a {kind} "
                             f"({len(own.legs.legs)} feet): use {', '.join(names)}")
    elif spec in MODELS and spec != g.model and not (spec == "human_cart" and g.model == "human"):
        raise InputError(f"gait {g.name!r} is for --model {g.model}, not {spec}")

    if args.tune_stiffness and not own_flow:
        keyframe = g.keyframe if g.keyframe and _has_key(model, g.keyframe) else None
        res = tune_stiffness(model, keyframe=keyframe)
        scale *= res.scale
        tuning = {"scale": res.scale, "failing_scale": res.failing_scale,
                  "trials": [{"scale": t.scale, "max_dev_deg": math.degrees(t.max_dev_rad),
                              "worst_joint": t.worst_joint, "holds": t.holds}
                             for t in res.trials]}
        print(f"stiffness tuning: smallest scale holding the rest pose = {res.scale:.3g} "
              f"(x{res.failing_scale:.3g} sags more than 10 deg), {len(res.trials)} simulations")

    labels = own.labels if own is not None else None
    if gfile is not None:
        plan = plan_from_file(model, g, gfile, scale, labels, args.amplitude_scale)
    else:
        plan = plan_gait(model, g, stiffness_scale=scale, amplitude_scale=args.amplitude_scale,
                         freq_hz=args.freq, labels=labels)
    a = plan.analysis
    n = max(int(round(args.seconds * args.fps)), 2)
    times = np.arange(n) / args.fps
    limits = anim_mod.SoftLimits(soft_rad=math.radians(args.soft_limit_deg))
    projector = (anim_mod.ConstraintProjector(model, a.rest_qpos, plan.constraints)
                 if args.project else None)
    anim = anim_mod.animate(model, a.rest_qpos, plan.components, times, limits, projector)
    checks = constraint_checks(model, plan, anim)

    print(f"{label}: gait {g.name} ({g.selection}; paper: {g.paper})")
    print(f"analysis: {a.nv} dofs, {a.n_modes} modes ({a.n_rigid} rigid)"
          + (f", constraints {', '.join(a.constraint_labels)}" if a.constraint_labels else ""))
    print(f"{'mode':>5} {'f_nat_Hz':>9} {'alpha':>6} {'gamma':>6} {'f_Hz':>5}  categories")
    for c in plan.chosen:
        cats = "; ".join(f"{k} {CATEGORY_NAMES.get(k, 'rigid vertical bounce')}"
                         for k in c["categories"])
        print(f"{c['mode']!s:>5} {c['freq_hz_natural']:>9.3g} {c['amplitude']:>6.2f} "
              f"{c['phase_deg']:>6.0f} {c['freq_hz']:>5.2g}  {cats}")
    rejected = [{"mode": m, "freq_hz": float(a.freqs_hz[m]), "why": why}
                for m, why in plan.rejected().items()]
    shown = [r for r in rejected if "twist" in r["why"] or "jack" in r["why"]][:4]
    for r in shown:
        print(f"rejected mode {r['mode']} ({r['freq_hz']:.3g} Hz): {r['why']}")
    print(f"{n} frames at {args.fps:g} fps; largest joint-limit overshoot "
          f"{math.degrees(anim.max_limit_overshoot_rad):.2f} deg (soft limit "
          f"{args.soft_limit_deg:g} deg)")
    for k, v in checks.items():
        print(f"{k}: {v:.3g}")

    out = {
        "model": label,
        "gait": g.name,
        "selection": g.selection,
        "paper_parameters": g.paper,
        "nv": a.nv,
        "n_modes": a.n_modes,
        "n_rigid": a.n_rigid,
        "constraints": list(a.constraint_labels),
        "stiffness_scale": scale,
        "stiffness_tuning": tuning,
        "chosen": [dict(c, category_names=[CATEGORY_NAMES.get(k, "rigid vertical bounce")
                                           for k in c["categories"]]) for c in plan.chosen],
        "merged": plan.merged,
        "best_per_category": {k: v[0] for k, v in plan.selection.best.items()},
        "rejected": rejected,
        "frames": n,
        "fps": args.fps,
        "max_limit_overshoot_deg": math.degrees(anim.max_limit_overshoot_rad),
        "soft_limit_deg": args.soft_limit_deg,
        "constraint_residual": anim.constraint_residual,
        "checks": checks,
    }
    if spec not in MODELS:
        out["model_file"] = str(Path(spec).resolve())
    if own is not None:
        out["own_creature"] = own.report(model)
    out["modes_used"] = [{k: c[k] for k in ("mode", "categories", "mode_sign", "amplitude",
                                            "phase_deg", "freq_hz", "beta")} for c in plan.chosen]
    out["substituted"] = plan.substituted
    lab = plan.selection.labels
    tracks, roots = foot_tracks(model, anim.qpos, feet_of(lab), lab.root_body)
    fwd_rel = (tracks - roots[:, None, :]) @ lab.forward
    period = cycle_seconds(plan)
    phases = foot_phases_deg(times, fwd_rel, 1.0 / period)
    out["foot_phase_deg"] = {name: float(ph) for name, ph in zip(lab.foot_names, phases, strict=True)}
    out["stride_m"] = {name: float(np.ptp(fwd_rel[:, i])) for i, name in enumerate(lab.foot_names)}
    print("foot phase (deg, when the foot is farthest forward): " + ", ".join(
        f"{k} {v:.0f}" for k, v in out["foot_phase_deg"].items()))
    if args.travel:
        tr = travel_root(model, anim.qpos, lab, a.rest_qpos)
        anim = dataclasses.replace(anim, qpos=tr.qpos)
        out["travel"] = {"distance_m": tr.distance_m, "max_slip_m": tr.max_slip_m,
                         "max_leg_correction_deg": math.degrees(tr.max_leg_correction_rad),
                         "slip_per_foot_m": dict(zip(lab.foot_names, tr.slip_per_foot_m, strict=True)),
                         "stance_fraction": dict(zip(lab.foot_names, tr.stance_fraction, strict=True))}
        print(f"travel: root moved {tr.distance_m:+.3f} m; largest stance-foot slip "
              f"{100 * tr.max_slip_m:.2f} cm (legs corrected by up to "
              f"{math.degrees(tr.max_leg_correction_rad):.1f} deg)")
    if args.save_gait:
        # a played gait file's amplitudes already carry --amplitude-scale
        gf = gait_file_of(plan, 1.0 if gfile else args.amplitude_scale,
                          knee_flex_deg=own.knee_flex_deg if own else 0.0,
                          stiffness_scale=scale, stiffness=edits)
        gf.write(args.save_gait)
        print(f"gait file -> {args.save_gait}")
        out["gait_file"] = args.save_gait
    if args.npz:
        anim_mod.save_trajectory(args.npz, model, anim)
        print(f"trajectory -> {args.npz}")
        out["npz"] = args.npz
    if args.bvh:
        ch = write_bvh(args.bvh, model, anim.qpos, 1.0 / args.fps)
        print(f"BVH ({ch} channels) -> {args.bvh}")
        out["bvh"] = args.bvh
    if args.sheet:
        info = contact_sheet(plan, model, args.sheet)
        print(f"contact sheet ({info['frames']} frames of one {info['period_s']:.2g} s cycle) "
              f"-> {args.sheet}")
        out["sheet"] = args.sheet
    if args.video:
        frames = render_poses(model, list(anim.qpos), args.video, source=model_file(spec),
                               fps=args.fps)
        print(f"video ({frames} frames) -> {args.video}")
        out["video"] = args.video
    if args.browse:
        if not os.environ.get("DISPLAY"):
            raise InputError("--browse needs a display (DISPLAY is not set); use --sheet PNG")

        ModeBrowser(plan, model).show()
    return out


def _has_key(model, name: str) -> bool:
    return mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_KEY, name) >= 0


def constraint_checks(model, plan, anim) -> dict:
    """First-order and finite-amplitude checks of the gait's constraints."""


    a = plan.analysis
    out: dict[str, float] = {}
    if a.constraint_jacobian.shape[0]:
        # First order: G phi for every used shape, relative to |phi| (0 = respected).
        worst = 0.0
        for c in plan.components:
            phi = np.asarray(c.shape)
            worst = max(worst, float(np.linalg.norm(a.constraint_jacobian @ phi))
                        / max(float(np.linalg.norm(phi)), 1e-300))
        out["first_order_constraint_violation"] = worst
    for c in plan.constraints:
        if c.kind == "orientation":
            out[f"max_{c.names[0]}_rotation_deg"] = math.degrees(
                head_orientation_error(model, anim.qpos, a.rest_qpos, c.names[0]))
    if model.neq:
        d = mujoco.MjData(model)
        gap = 0.0
        for q in anim.qpos:
            d.qpos[:] = q
            mujoco.mj_forward(model, d)
            for e in range(model.neq):
                if model.eq_type[e] == mujoco.mjtEq.mjEQ_CONNECT and model.eq_objtype[e] == \
                        mujoco.mjtObj.mjOBJ_SITE:
                    s1, s2 = model.eq_obj1id[e], model.eq_obj2id[e]
                    gap = max(gap, float(np.linalg.norm(d.site_xpos[s1] - d.site_xpos[s2])))
        out["max_hand_handle_gap_m"] = gap
    return out
