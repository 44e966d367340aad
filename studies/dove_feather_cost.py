"""Where a modal dove's simulation step spends its time, against the rigid dove's, measured in
one run.

    python studies/dove_feather_cost.py [--wingbeats 1] [--json out.json]

For each of ``rigid`` and ``modal`` feathers, from the same flight state (the base controller
after two wingbeats), per simulation step:

* ``flight``: ``DoveFlight.run_cycle`` (``mujoco.rollout`` with the compiled callback), as
  ``flapsim fly`` steps;
* ``bare``: the same rollout (same start, same controls) with the force providers removed;
* ``kernels``: each force kernel called in a compiled loop at the recorded state (modal: the
  whole kernel, and its warp/vertex stage alone, i.e. with no triangles);
* ``mj_*``: MuJoCo's stages of the bare step called one by one (Python overhead included,
  ~0.3 us each), to see what the mode DOF cost.

Each time is the least of 7 tries in this thread's CPU time; it still varies with machine load
(caches, shared cores): compare ratios from the same run.
"""

from __future__ import annotations

import argparse
import json
import time

import mujoco
import numpy as np
from mujoco import rollout
from numba import njit

from flapsim.bird.body.feather_dynamics import FI, modal_engine, modal_kernel
from flapsim.bird.body.model import Dove
from flapsim.bird.flight.dove_flight import DoveFlight, FlightConfig
from flapsim.bird.flight.wingbeat import control_table, p0, with_tail_bias
from flapsim.fluid.surfaces import surface_kernel


@njit(cache=False)
def _loop_modal(n, w, *args):
    for _ in range(n):
        modal_kernel(w, *args)


@njit(cache=False)
def _loop_engine(n, w, *args):
    for _ in range(n):
        modal_engine(w, *args)


@njit(cache=False)
def _loop_surface(n, w, *args):
    for _ in range(n):
        surface_kernel(w, *args)


def _best(fn, repeat: int = 7) -> float:
    """Fastest of ``repeat`` calls, seconds of this thread's CPU time (on a shared machine,
    wall time counts other processes' turns)."""
    best = np.inf
    for _ in range(repeat):
        t = time.thread_time()
        fn()
        best = min(best, time.thread_time() - t)
    return best


def measure(kind: str, wingbeats: int) -> dict:
    dove = Dove.load(feathers=kind)
    fl = DoveFlight(dove)
    m, d = fl.model, fl.data
    cfg = FlightConfig()
    p = with_tail_bias(p0(), cfg.tail_bias_deg)
    fl.reset(cfg, p)
    for _ in range(2):
        fl.run_cycle(p, record=False)
    spec = mujoco.mjtState.mjSTATE_FULLPHYSICS
    s0 = np.empty(mujoco.mj_stateSize(m, spec))
    mujoco.mj_getState(m, d, s0, spec)
    ctrl = control_table(fl.ref, p, m.opt.timestep, fl.kp, fl.kv)[0]
    ctrl = np.tile(ctrl, (wingbeats, 1))
    n = len(ctrl)
    out: dict = {"nv": int(m.nv), "nbody": int(m.nbody)}

    def roll():
        mujoco.mj_setState(m, d, s0, spec)
        rollout.rollout(m, d, s0[None], ctrl[None])

    roll()
    out["flight_us"] = 1e6 * _best(roll) / n
    # kernels at the recorded state
    mujoco.mj_setState(m, d, s0, spec)
    mujoco.mj_forward(m, d)
    reps = 2000
    w = np.zeros(6 * m.nbody)
    args = list(fl.aero.arrays(m, d))
    _loop_surface(1, w, *args)
    out["trunk_or_rigid_kernel_us"] = 1e6 * _best(lambda: _loop_surface(reps, w, *args)) / reps
    if fl.modal is not None:
        margs = list(fl.modal.arrays(m, d))
        # the engine's kernel (its modes' step and the twist hinges included) or the joints'
        loop, qf, fi = ((_loop_engine, fl.modal.QFRC_ARG_ENGINE, 5) if fl.modal.engine else
                        (_loop_modal, 7, 8))
        margs[qf] = d.qfrc_passive.copy()
        if fl.modal.engine:
            margs[-1] = d.userdata.copy()  # repeated calls at one time: the same work each
        loop(1, w, *margs)
        out["modal_kernel_us"] = 1e6 * _best(lambda: loop(reps, w, *margs)) / reps
        fint = margs[fi].copy().reshape(-1, FI)
        fint[:, 8] = 0  # no triangles: the warp and the vertex stage alone
        margs[fi] = fint.ravel()
        loop(1, w, *margs)
        out["modal_warp_stage_us"] = 1e6 * _best(lambda: loop(reps, w, *margs)) / reps
        out["modal_triangle_stage_us"] = out["modal_kernel_us"] - out["modal_warp_stage_us"]
    # bare: no providers
    fl.close()
    roll()
    out["bare_us"] = 1e6 * _best(roll) / n
    # MuJoCo stages of the bare step (the python-call overhead included)
    mujoco.mj_setState(m, d, s0, spec)
    mujoco.mj_forward(m, d)
    stages = {}
    for name in ("mj_kinematics", "mj_comPos", "mj_camlight", "mj_flex", "mj_tendon", "mj_crb",
                 "mj_factorM", "mj_collision", "mj_makeConstraint", "mj_transmission",
                 "mj_fwdVelocity", "mj_fwdActuation", "mj_fwdAcceleration", "mj_fwdConstraint",
                 "mj_implicit", "mj_passive", "mj_comVel", "mj_subtreeVel"):
        fn = getattr(mujoco, name, None)
        if fn is None:
            continue
        r = 3000

        def call(fn=fn, r=r):
            for _ in range(r):
                fn(m, d)

        stages[name] = 1e6 * _best(call, 3) / r
        mujoco.mj_setState(m, d, s0, spec)
        mujoco.mj_forward(m, d)
    out["stages_us"] = stages
    return out


def parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--wingbeats", type=int, default=1, help="wingbeats of controls per timed rollout")
    ap.add_argument("--json", default=None, help="write every time here")
    return ap


def main(argv: list[str] | None = None) -> dict:
    ap = parser()
    a = ap.parse_args(argv)
    res = {k: measure(k, a.wingbeats) for k in ("rigid", "modal")}
    r, mo = res["rigid"], res["modal"]
    res["ratio_flight"] = mo["flight_us"] / r["flight_us"]
    res["ratio_bare"] = mo["bare_us"] / r["bare_us"]
    for k in ("rigid", "modal"):
        x = res[k]
        print(f"{k:6s} nv {x['nv']:3d}: flight {x['flight_us']:6.1f} us/step  bare {x['bare_us']:6.1f}"
              f"  trunk/rigid kernel {x['trunk_or_rigid_kernel_us']:5.1f}"
              + (f"  modal kernel {x['modal_kernel_us']:5.1f} (warp stage {x['modal_warp_stage_us']:5.1f},"
                 f" triangles {x['modal_triangle_stage_us']:5.1f})" if k == "modal" else ""))
    print("stage            rigid   modal (us, one call each)")
    for s in r["stages_us"]:
        print(f"  {s:18s} {r['stages_us'][s]:6.2f} {mo['stages_us'][s]:6.2f}")
    print(f"modal/rigid: flight {res['ratio_flight']:.2f}x, bare {res['ratio_bare']:.2f}x; "
          f"real time: rigid {1e6 / r['flight_us'] / 2400:.1f}x, modal {1e6 / mo['flight_us'] / 2400:.1f}x")
    if a.json:
        with open(a.json, "w") as fh:
            json.dump(res, fh, indent=1)
    return res


if __name__ == "__main__":
    main()
