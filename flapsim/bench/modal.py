"""Benchmarks ``flapsim bench modal`` and ``flapsim bench creatures``.

* modal: analysis time of a generated ~80-dof quadruped-like tree (free root, ball-joint
  spine and neck, ball/hinge legs, hinge tail) against a bare ``mj_forward`` +
  ``mj_fullM`` of the same model, both measured in this run (target: < 0.2 s).
* creatures: real-time factor (simulated seconds per wall second) of the loop and
  linear creatures under the two-mode controller, and the controller's cost as a
  fraction of ``mj_step`` time, both timed in the same run.
"""

from __future__ import annotations

import argparse
import math
import platform
import time

import mujoco
import numpy as np

from flapsim.core.loading import load_model
from flapsim.modal.analysis import analyze, fix_body_orientation
from flapsim.modal.creatures import CREATURES, analyze_creature, load_creature
from flapsim.modal.dynamic import ModalController, two_mode_drives

MODAL_TARGET_S = 0.2


def tree_xml(spine: int = 13, leg_hinges: int = 3, tail: int = 5) -> str:
    """A quadruped-like articulated tree with stiff joints (nv = 6 + 3*spine + 3*2 neck
    + 4*(3 + leg_hinges) + tail); the defaults give 80 dofs."""
    parts = [
        '<mujoco model="bench_tree"><option gravity="0 0 -9.81"/>',
        '<default><joint stiffness="20" damping="0.2"/>'
        '<geom type="capsule" size="0.02" density="1000"/></default><worldbody>',
        '<body name="pelvis" pos="0 0 0.5"><freejoint/><geom fromto="0 0 0 0.1 0 0"/>',
    ]
    close = ["</body>"]

    def leg(prefix: str, y: float) -> str:
        s = f'<body name="{prefix}" pos="0 {y} 0"><joint type="ball"/>'
        s += '<geom fromto="0 0 0 0 0 -0.12"/>'
        depth = 1
        for _k in range(leg_hinges):
            s += '<body pos="0 0 -0.12"><joint axis="0 1 0"/><geom fromto="0 0 0 0 0 -0.1"/>'
            depth += 1
        s += f'<site name="{prefix}_foot" pos="0 0 -0.1"/>'
        return s + "</body>" * depth

    parts.append(leg("hind_l", 0.06) + leg("hind_r", -0.06))
    for _k in range(tail):
        parts.append('<body pos="-0.05 0 0"><joint axis="0 1 0"/><geom fromto="0 0 0 -0.05 0 0"/>')
    parts.append("</body>" * tail)
    for k in range(spine):
        parts.append(f'<body name="spine{k}" pos="0.1 0 0"><joint type="ball"/>'
                     '<geom fromto="0 0 0 0.1 0 0"/>')
        close.append("</body>")
    parts.append(leg("fore_l", 0.06) + leg("fore_r", -0.06))
    parts.append('<body name="neck" pos="0.1 0 0.02"><joint type="ball"/>'
                 '<geom fromto="0 0 0 0.08 0 0.08"/><body name="head" pos="0.08 0 0.08">'
                 '<joint type="ball"/><geom type="sphere" size="0.05"/>'
                 '<site name="nose" pos="0.05 0 0"/></body></body>')
    parts.extend(reversed(close))
    parts.append("</worldbody></mujoco>")
    return "".join(parts)


def _time_repeated(fn, budget_s: float, min_reps: int = 3) -> tuple[float, int]:
    """Median wall time of ``fn`` over repetitions filling ``budget_s``."""
    times = []
    t_end = time.perf_counter() + budget_s
    while len(times) < min_reps or time.perf_counter() < t_end:
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
        if len(times) > 100000:
            break
    return float(np.median(times)), len(times)


def run_modal(args: argparse.Namespace) -> dict:
    budget = args.seconds if args.seconds else 2.0
    model = load_model(tree_xml(), is_xml=True)
    data = mujoco.MjData(model)
    M = np.zeros((model.nv, model.nv))

    def bare() -> None:
        mujoco.mj_forward(model, data)
        mujoco.mj_fullM(model, data, M)

    t_bare, n_bare = _time_repeated(bare, budget / 3)
    t_free, n_free = _time_repeated(lambda: analyze(model), budget / 3)
    t_con, n_con = _time_repeated(
        lambda: analyze(model, constraints=[fix_body_orientation("head")]), budget / 3
    )
    res = analyze(model)
    out = {
        "benchmark": "modal",
        "nv": model.nv,
        "n_modes": res.n_modes,
        "n_rigid": res.n_rigid,
        "analysis_s": t_free,
        "analysis_head_constrained_s": t_con,
        "bare_forward_fullM_s": t_bare,
        "ratio_analysis_vs_bare": t_free / t_bare,
        "target_s": MODAL_TARGET_S,
        "meets_target": bool(t_free < MODAL_TARGET_S),
        "repetitions": {"bare": n_bare, "analysis": n_free, "constrained": n_con},
        "machine": platform.processor() or platform.machine(),
    }
    print(f"modal analysis of a {model.nv}-dof tree: {t_free * 1e3:.2f} ms "
          f"(head orientation fixed: {t_con * 1e3:.2f} ms), target < {MODAL_TARGET_S * 1e3:.0f} ms")
    print(f"bare mj_forward + mj_fullM: {t_bare * 1e6:.1f} us -> analysis costs "
          f"{t_free / t_bare:.0f}x that")
    return out


def run_creatures(args: argparse.Namespace) -> dict:
    budget = args.seconds if args.seconds else 2.0
    out: dict = {"benchmark": "creatures", "creatures": {}}
    for name, spec in CREATURES.items():
        model = load_creature(name)
        analysis = analyze_creature(model)
        gait = spec.gait
        drives = two_mode_drives(
            analysis, gait.amplitude_rad, phase_rad=math.radians(gait.phase_deg),
            freq_hz=gait.freq_hz,
        )
        data = mujoco.MjData(model)
        data.qpos[:] = analysis.rest_qpos
        ctl = ModalController(model, analysis, drives, ramp_s=gait.ramp_s)
        steps, t_ctl, t_step = 0, 0.0, 0.0
        clock = time.perf_counter
        t0 = clock()
        while clock() - t0 < budget / len(CREATURES):
            for _ in range(500):
                a = clock()
                ctl.apply(data)
                b = clock()
                mujoco.mj_step(model, data)
                t_ctl += b - a
                t_step += clock() - b
            steps += 500
        wall = clock() - t0
        sim = steps * model.opt.timestep
        out["creatures"][name] = {
            "timestep_s": model.opt.timestep,
            "simulated_s": sim,
            "realtime_factor": sim / wall,
            "realtime_factor_physics_only": sim / t_step,
            "controller_vs_mj_step": t_ctl / t_step,
        }
        print(f"{name}: {sim / wall:.1f} simulated s per wall s ({sim:.1f} s simulated); "
              f"controller costs {100 * t_ctl / t_step:.0f}% of an mj_step")
    return out
