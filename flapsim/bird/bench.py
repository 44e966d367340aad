"""``flapsim bench dove``: simulated seconds per wall second of the dove's base controller.

Three measurements in one run, all on one core at the default settings (2400 Hz,
264 feather polygons, paper PD servos):

* ``rollout``: the flight as ``flapsim fly`` runs it (controls precomputed per wingbeat,
  steps inside ``mujoco.rollout``; forces from the compiled callback);
* ``python_loop``: the same flight stepped by ``mj_step`` from a Python loop;
* ``bare``: ``mj_step`` of the same model with no feather forces (lower bound).

The ratios (real-time factors, and flight cost over the bare step) come from the same
run, so machine load affects them alike. The paper ran at 0.3-0.5x real time.
"""

from __future__ import annotations

import argparse
import platform
import time

import mujoco

from flapsim.bird.flight import FlightConfig, fly
from flapsim.bird.model import Dove


def run(args: argparse.Namespace) -> dict:
    seconds = args.seconds or 2.0
    dove = Dove.load()
    dt = float(dove.model.opt.timestep)
    fly(dove, 1)  # warm-up: numba kernels and the callback compile once
    t0 = time.perf_counter()
    fly(dove, 2)
    per_wb = (time.perf_counter() - t0) / 2
    n_wb = max(2, int(seconds / per_wb))
    res = {}
    for name, rollout in (("rollout", True), ("python_loop", False)):
        f = fly(dove, n_wb, FlightConfig(), use_rollout=rollout)
        sim = len(f.time) * dt
        res[name] = {"wingbeats": n_wb, "simulated_s": sim, "wall_s": f.wall_time,
                     "real_time_factor": sim / f.wall_time,
                     "us_per_step": 1e6 * f.wall_time / len(f.time)}
    m = dove.model
    d = mujoco.MjData(m)
    nstep = int(res["rollout"]["simulated_s"] / dt)
    t0 = time.perf_counter()
    mujoco.mj_step(m, d, nstep=nstep)
    wall = time.perf_counter() - t0
    res["bare"] = {"simulated_s": nstep * dt, "wall_s": wall,
                   "real_time_factor": nstep * dt / wall, "us_per_step": 1e6 * wall / nstep}
    out = {
        "target": "dove",
        "timestep": dt,
        "polygons": int(len(dove.feather_triangles()[0])),
        "nv": int(m.nv),
        "real_time_factor": res["rollout"]["real_time_factor"],
        "cost_over_bare_step": res["rollout"]["us_per_step"] / res["bare"]["us_per_step"],
        "measurements": res,
        "machine": platform.processor() or platform.machine(),
        "paper_real_time_factor": [0.3, 0.5],
    }
    print(f"dove base controller at {1 / dt:.0f} Hz, {out['polygons']} feather polygons, nv {m.nv}")
    for name in ("rollout", "python_loop", "bare"):
        r = res[name]
        print(f"  {name:12s} {r['real_time_factor']:6.1f}x real time ({r['us_per_step']:.1f} us/step)")
    print(f"  flight step costs {out['cost_over_bare_step']:.2f}x a bare mj_step (paper: 0.3-0.5x "
          "real time)")
    return out
