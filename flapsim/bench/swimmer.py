"""``flapsim bench swimmer``: simulated seconds per wall second for the swimmer, with its
force providers and PD, against a bare ``mj_step`` of the same model in the same run."""

from __future__ import annotations

import argparse
import time

import mujoco

from flapsim.swim.goals import figure_eight
from flapsim.swim.layers import BasicStrokeLayer, FeedbackLayer
from flapsim.swim.model import Swimmer
from flapsim.swim.strokes import load_stroke


def run(args: argparse.Namespace) -> dict:
    seconds = float(args.seconds or 5.0)
    sw = Swimmer()
    stroke = load_stroke("breaststroke")
    layer = BasicStrokeLayer(sw, stroke)
    m, d = sw.model, sw.data
    dt = m.opt.timestep

    chunk = max(1, int(round(1.0 / dt)))  # 1 s from the start pose, then reset

    def bare(n: int) -> None:
        mujoco.mj_step(m, d, nstep=n)

    def stepper(basic: BasicStrokeLayer, fb: FeedbackLayer | None):
        """The simulate loop of flapsim.swim.simulate.swim, without its recording."""
        def run_steps(n: int) -> None:
            for i in range(n):
                if i % 5 == 0:
                    sw.update_flow()
                    if fb is not None:
                        fb.update(d)
                basic.apply(d, dt)
                mujoco.mj_step(m, d)
        return run_steps

    tread = BasicStrokeLayer(sw, load_stroke("treading"))
    crawl = BasicStrokeLayer(sw, load_stroke("crawl"))
    balance = FeedbackLayer(tread)
    steering = FeedbackLayer(crawl, target=figure_eight(6.0))
    # label -> (posture, basic layer, step function)
    cases = {
        "bare_mj_step": ("prone", layer, bare),
        "swimmer": ("prone", layer, stepper(layer, None)),
        "treading_feedback": ("upright", tread, stepper(tread, balance)),
        "crawl_figure8": ("prone", crawl, stepper(crawl, steering)),
    }

    def start(label: str) -> None:
        posture, basic, _ = cases[label]
        sw.reset(posture, qpos_joints=basic.start_pose(0.0))
        basic.phase = 0.0
        for fb in (balance, steering):
            fb.reset()

    out = {}
    for label, (_, _, fn) in cases.items():
        providers = label != "bare_mj_step"
        if providers:
            sw.attach()
        start(label)
        fn(50)  # warm-up (numba compile, caches)
        steps, wall = 0, 0.0
        while wall < seconds / 4:
            # every chunk restarts from the same pose, so all runs see the same states
            # (a limp, unforced swimmer would otherwise sink onto the pool floor)
            start(label)
            t0 = time.perf_counter()
            fn(chunk)
            wall += time.perf_counter() - t0
            steps += chunk
        sim = steps * dt
        out[label] = {"steps": steps, "sim_s": sim, "wall_s": wall, "realtime_factor": sim / wall,
                      "us_per_step": 1e6 * wall / steps}
        if providers:
            sw.detach()
    ratio = out["swimmer"]["us_per_step"] / out["bare_mj_step"]["us_per_step"]
    ratio_fb = out["treading_feedback"]["us_per_step"] / out["bare_mj_step"]["us_per_step"]
    ratio_st = out["crawl_figure8"]["us_per_step"] / out["bare_mj_step"]["us_per_step"]
    result = {
        "benchmark": "swimmer",
        "timestep_s": dt,
        "polygons": len(sw.polygons),
        "ellipsoids": len(sw.buoyancy.volumes),
        "bare": out["bare_mj_step"],
        "swimmer": out["swimmer"],
        "treading_feedback": out["treading_feedback"],
        "cost_vs_bare_step": ratio,
        "treading_feedback_cost_vs_bare_step": ratio_fb,
        "crawl_figure8": out["crawl_figure8"],
        "crawl_figure8_cost_vs_bare_step": ratio_st,
        "target_realtime_factor": 20.0,
    }
    print(f"swimmer: {len(sw.polygons)} polygons, {result['ellipsoids']} buoyancy ellipsoids, "
          f"dt {dt * 1e3:g} ms, breaststroke with PD every step")
    print(f"  bare mj_step     {out['bare_mj_step']['us_per_step']:.1f} us/step "
          f"({out['bare_mj_step']['realtime_factor']:.0f}x real time)")
    print(f"  full swimmer     {out['swimmer']['us_per_step']:.1f} us/step "
          f"({out['swimmer']['realtime_factor']:.1f}x real time; target >= 20x)")
    print(f"  cost vs bare     {ratio:.2f}x")
    print(f"  treading + feedback layer (50 Hz) {out['treading_feedback']['us_per_step']:.1f} "
          f"us/step ({out['treading_feedback']['realtime_factor']:.1f}x real time, "
          f"{ratio_fb:.2f}x bare)")
    print(f"  crawl steering along a figure of eight {out['crawl_figure8']['us_per_step']:.1f} "
          f"us/step ({out['crawl_figure8']['realtime_factor']:.1f}x real time, "
          f"{ratio_st:.2f}x bare)")
    return result
