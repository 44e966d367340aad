"""``flapsim bench forces``: the surface-force callback against a bare ``mj_step``.

The test subject is a tree the size of the dove (29 bodies, 40 DOF: free trunk, two
3+2+1-DOF wings, a 2-DOF tail, 20 feather bodies on twist hinges; self-contacts off;
2400 Hz as in the flight paper) with polygons spread over its bodies. For each polygon
count the bare step and the step with forces are timed in alternating blocks within
one run (``mj_step(..., nstep=N)``, so no Python loop is timed), and the callback's cost
is their difference.
"""

from __future__ import annotations

import argparse
import platform
import time

import mujoco
import numpy as np

from flapsim.core.callbacks import DISPATCHER
from flapsim.core.loading import load_model
from flapsim.fluid.flow import FlowField, Uniform
from flapsim.fluid.surfaces import FluidParams, PolygonSet, SurfaceForces


def dove_sized_tree_xml() -> str:
    """MJCF of the benchmark tree (no contacts between its own geoms)."""
    feathers = []

    def wing(side: float) -> str:
        s = side
        fe = "".join(
            f'<body pos="{0.02 * k:.3f} {s * 0.03:.3f} 0"><joint type="hinge" axis="0 1 0" '
            f'stiffness="6e-5" damping="6e-6"/><geom type="box" size=".008 .05 .0005" mass=".0004"/>'
            f"</body>"
            for k in range(5)
        )
        feathers.append(fe)
        return f"""
        <body pos="0 {s * 0.03} 0.01"><joint type="ball" damping="0.002"/>
          <geom type="capsule" fromto="0 0 0 0 {s * 0.06} 0" size=".008" mass=".005"/>
          <body pos="0 {s * 0.06} 0"><joint type="hinge" axis="0 0 1" damping="0.002"/>
            <joint type="hinge" axis="1 0 0" damping="0.002"/>
            <geom type="capsule" fromto="0 0 0 0 {s * 0.07} 0" size=".006" mass=".009"/>{fe}
            <body pos="0 {s * 0.07} 0"><joint type="hinge" axis="1 0 0" damping="0.002"/>
              <geom type="capsule" fromto="0 0 0 0 {s * 0.06} 0" size=".005" mass=".006"/>{fe}
            </body></body></body>"""

    return f"""<mujoco model="bench_tree"><option timestep="{1 / 2400:.8f}"/>
      <default><geom contype="0" conaffinity="0"/></default><worldbody>
      <body name="trunk" pos="0 0 5"><freejoint/>
        <geom type="ellipsoid" size=".1 .04 .04" mass=".13"/>
        {wing(1.0)}{wing(-1.0)}
        <body pos="-0.1 0 0"><joint type="hinge" axis="0 1 0" damping="0.001"/>
          <joint type="hinge" axis="0 0 1" damping="0.001"/>
          <geom type="box" size=".04 .03 .002" mass=".003"/></body>
      </body></worldbody></mujoco>"""


def _polygons(model: mujoco.MjModel, n: int, rng: np.random.Generator) -> PolygonSet:
    bodies = np.arange(1, model.nbody)[np.arange(n) % (model.nbody - 1)]
    base = np.array([[0.0, 0.0, 0.0], [0.02, 0.0, 0.0], [0.0, 0.02, 0.0]])
    verts = base[None] + rng.normal(scale=0.005, size=(n, 3, 3))
    return PolygonSet.from_triangles(bodies, verts, forward=(1.0, 0.0, 0.0), table=0)


def _time_block(model, data, start_state, nstep: int) -> float:
    mujoco.mj_setState(model, data, start_state, mujoco.mjtState.mjSTATE_INTEGRATION)
    t0 = time.perf_counter()
    mujoco.mj_step(model, data, nstep=nstep)
    return (time.perf_counter() - t0) / nstep


def measure(n_polygons: int, seconds: float = 1.5, seed: int = 0) -> dict:
    """Cost per step with and without the surface forces on the benchmark tree."""
    rng = np.random.default_rng(seed)
    model = load_model(dove_sized_tree_xml(), is_xml=True)
    data = mujoco.MjData(model)
    data.qvel[6:] = rng.normal(scale=2.0, size=model.nv - 6)  # wings moving
    data.qvel[0] = 7.0  # cruising
    mujoco.mj_forward(model, data)
    size = mujoco.mj_stateSize(model, mujoco.mjtState.mjSTATE_INTEGRATION)
    start = np.empty(size)
    mujoco.mj_getState(model, data, start, mujoco.mjtState.mjSTATE_INTEGRATION)
    forces = SurfaceForces(model, _polygons(model, n_polygons, rng), ["dickinson1999"],
                           FluidParams(1.225), FlowField([Uniform((0.0, 0.0, 0.0))]))
    nstep = 240  # 0.1 s of simulated time per block: short enough that the state stays sane
    # warm up (compiles/loads the callback once)
    reg = forces.register(data)
    _time_block(model, data, start, nstep)
    reg.remove()
    bare, withf = [], []
    t_end = time.perf_counter() + seconds
    while time.perf_counter() < t_end or len(bare) < 5:
        bare.append(_time_block(model, data, start, nstep))
        reg = forces.register(data)
        withf.append(_time_block(model, data, start, nstep))
        DISPATCHER.check(data)
        reg.remove()
    # the minimum over blocks is the least disturbed by other load on a shared machine
    t_bare = float(np.min(bare))
    t_with = float(np.min(withf))
    cb = max(t_with - t_bare, 0.0)
    return {
        "polygons": n_polygons,
        "bodies": model.nbody,
        "dof": model.nv,
        "bare_step_us": t_bare * 1e6,
        "step_with_forces_us": t_with * 1e6,
        "callback_us": cb * 1e6,
        "callback_over_bare_step": cb / t_bare,
        "ns_per_polygon": cb * 1e9 / n_polygons,
        "realtime_factor_with_forces": model.opt.timestep / t_with,
        "blocks": len(bare),
    }


def run(args: argparse.Namespace) -> dict:
    counts = [50, 300, 1000]
    if args.polygons:
        counts = [int(c) for c in str(args.polygons).split(",")]
    seconds = args.seconds if args.seconds else 1.5
    rows = [measure(n, seconds, args.seed) for n in counts]
    print("surface forces on a dove-sized tree (29 bodies, 40 DOF, 2400 Hz), one core")
    print(f"{'polygons':>9} {'bare us':>9} {'with us':>9} {'cb us':>8} {'cb/bare':>8} "
          f"{'ns/poly':>8} {'x realtime':>10}")
    for r in rows:
        print(f"{r['polygons']:>9} {r['bare_step_us']:>9.2f} {r['step_with_forces_us']:>9.2f} "
              f"{r['callback_us']:>8.2f} {r['callback_over_bare_step']:>8.2f} "
              f"{r['ns_per_polygon']:>8.1f} {r['realtime_factor_with_forces']:>10.1f}")
    at300 = next((r for r in rows if r["polygons"] == 300), None)
    if at300:
        ok = at300["callback_over_bare_step"] <= 2.0 and at300["ns_per_polygon"] <= 30.0
        print(f"targets at 300 polygons (ratio <= 2.0, <= 30 ns/polygon): {'met' if ok else 'NOT met'}")
    return {
        "benchmark": "forces",
        "machine": {"python": platform.python_version(), "mujoco": mujoco.__version__,
                    "processor": platform.processor() or platform.machine()},
        "rows": rows,
    }
