"""``flapsim bench swimmer``: simulated seconds per wall second of the swimmer as
``flapsim swim`` runs it (:func:`flapsim.swim.simulate.swim`: force providers, PD, all
control layers, recording), against a bare ``mj_step`` of the same model in the same run.

Three swims, each restarted from rest every simulated second so that every repeat sees
the same states: breaststroke straight on, treading water (its balance feedback rules)
and the crawl steering along a figure of eight (the per-cycle steering layer)."""

from __future__ import annotations

import argparse
import time

import mujoco

from flapsim.swim.goals import figure_eight
from flapsim.swim.layers import BasicStrokeLayer
from flapsim.swim.model import Swimmer
from flapsim.swim.simulate import swim
from flapsim.swim.strokes import load_stroke

#: simulated seconds of one repeat: every repeat restarts from rest (a limp, unforced
#: swimmer would otherwise sink onto the pool floor in the bare case)
CHUNK_S = 1.0


def run(args: argparse.Namespace) -> dict:
    seconds = float(args.seconds or 5.0)
    sw = Swimmer()
    m, d = sw.model, sw.data
    dt = m.opt.timestep
    chunk = max(1, int(round(CHUNK_S / dt)))
    breast = load_stroke("breaststroke")
    start_pose = BasicStrokeLayer(sw, breast).start_pose(0.0)

    def bare() -> tuple[int, float]:
        sw.reset(breast.posture, qpos_joints=start_pose)
        t0 = time.perf_counter()
        mujoco.mj_step(m, d, nstep=chunk)
        return chunk, time.perf_counter() - t0

    def swimming(stroke: str, target=None):
        def one() -> tuple[int, float]:
            r = swim(stroke, CHUNK_S, swimmer=sw, target=target)
            return int(round(r.seconds / dt)), r.wall_s
        return one

    # label -> one repeat (steps, wall seconds)
    cases = {
        "bare_mj_step": bare,
        "swimmer": swimming("breaststroke"),
        "treading_feedback": swimming("treading"),
        "crawl_figure8": swimming("crawl", figure_eight(6.0)),
    }
    out = {}
    for label, one in cases.items():
        one()  # warm-up (numba compile, caches)
        steps, wall = 0, 0.0
        while wall < seconds / 4 or steps == 0:
            n, w = one()
            steps += n
            wall += w
        sim = steps * dt
        out[label] = {"steps": steps, "sim_s": sim, "wall_s": wall, "realtime_factor": sim / wall,
                      "us_per_step": 1e6 * wall / steps}
    bare_us = out["bare_mj_step"]["us_per_step"]
    ratio = out["swimmer"]["us_per_step"] / bare_us
    ratio_fb = out["treading_feedback"]["us_per_step"] / bare_us
    ratio_st = out["crawl_figure8"]["us_per_step"] / bare_us
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
          f"dt {dt * 1e3:g} ms, as flapsim swim runs it (all layers, recording)")
    print(f"  bare mj_step     {bare_us:.1f} us/step "
          f"({out['bare_mj_step']['realtime_factor']:.0f}x real time)")
    print(f"  breaststroke     {out['swimmer']['us_per_step']:.1f} us/step "
          f"({out['swimmer']['realtime_factor']:.1f}x real time; target >= 20x)")
    print(f"  cost vs bare     {ratio:.2f}x")
    print(f"  treading water (balance feedback) {out['treading_feedback']['us_per_step']:.1f} "
          f"us/step ({out['treading_feedback']['realtime_factor']:.1f}x real time, "
          f"{ratio_fb:.2f}x bare)")
    print(f"  crawl steering along a figure of eight {out['crawl_figure8']['us_per_step']:.1f} "
          f"us/step ({out['crawl_figure8']['realtime_factor']:.1f}x real time, "
          f"{ratio_st:.2f}x bare)")
    return result
