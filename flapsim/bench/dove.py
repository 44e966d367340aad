"""``flapsim bench dove``: simulated seconds per wall second of the dove's base controller.

Three measurements in one run, all on one core at the default settings (2400 Hz,
264 feather polygons, paper PD servos):

* ``rollout``: the flight as ``flapsim fly`` runs it (controls precomputed per wingbeat,
  steps inside ``mujoco.rollout``; forces from the compiled callback);
* ``python_loop``: the same flight stepped by ``mj_step`` from a Python loop;
* ``bare``: ``mj_step`` of the same model with no feather forces (lower bound).

The ratios (real-time factors, and flight cost over the bare step) come from the same
run, so machine load affects them alike. With ``--feathers modal`` the modal/rigid cost ratio
comes from interleaved one-wingbeat rollouts in CPU time (:func:`_interleaved_step_cost`): the
wall-time runs of the two doves are reported too but swing with machine load. The paper ran at
0.3-0.5x real time.
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import platform
import tempfile
import time

import mujoco
import numpy as np
from mujoco import rollout

from flapsim import scenarios
from flapsim.bird.body.model import Dove
from flapsim.bird.control.controller import (
    BaseController,
    attach_predictor,
    database_dove,
    database_pitch,
    database_speed,
    database_table,
    fly_controlled,
    load_controller,
    make_lookahead,
    start_cruise,
)
from flapsim.bird.control.prediction import CoarsePredictor
from flapsim.bird.control.targets import CruiseTarget, trim_of_base_flight
from flapsim.bird.flight import cycle
from flapsim.bird.flight.dove_flight import DoveFlight, FlightConfig, fly
from flapsim.bird.flight.wingbeat import control_table, p0, with_tail_bias
from flapsim.bird.training.sampling import SampleWorker, SamplingConfig
from flapsim.bird.training.train import train
from flapsim.scenarios import runner


def _measure(dove: Dove, seconds: float) -> dict:
    """Rollout, Python-loop and bare-step timings of one dove model (see the module doc)."""
    dt = float(dove.model.opt.timestep)
    fly(dove, 1)  # warm-up: numba kernels and the callback compile once
    t0 = time.perf_counter()
    fly(dove, 2)
    per_wb = (time.perf_counter() - t0) / 2
    n_wb = max(2, int(seconds / per_wb))
    res = {}
    for name, use_rollout in (("rollout", True), ("python_loop", False)):
        f = fly(dove, n_wb, FlightConfig(), use_rollout=use_rollout, keep_qpos=False)
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
    return res


def _interleaved_step_cost(doves: dict, repeats: int = 7) -> dict:
    """CPU microseconds per flight step of each dove, for the modal/rigid ratio: one wingbeat
    of the base controller from the same cruise state (after one wingbeat) in ``rollout``, the
    doves taken in turn, the least of ``repeats`` tries in this thread's CPU time. Wall times of
    separate runs swing by 30-80 % on a shared machine (another process's turns count); this
    ratio stays within a few per cent."""


    cfg = FlightConfig()
    p = with_tail_bias(p0(), cfg.tail_bias_deg)
    spec = mujoco.mjtState.mjSTATE_FULLPHYSICS
    runs = {}
    try:
        for k, dove in doves.items():
            fl = DoveFlight(dove)
            fl.reset(cfg, p)
            fl.run_cycle(p, record=False)
            m, d = fl.model, fl.data
            s0 = np.empty(mujoco.mj_stateSize(m, spec))
            mujoco.mj_getState(m, d, s0, spec)
            ctrl = control_table(fl.ref, p, m.opt.timestep, fl.kp, fl.kv)[0]
            runs[k] = (fl, s0, ctrl)
        best = {k: np.inf for k in runs}
        for _ in range(repeats):
            for k, (fl, s0, ctrl) in runs.items():
                t0 = time.thread_time()
                rollout.rollout(fl.model, fl.data, s0[None], ctrl[None])
                best[k] = min(best[k], 1e6 * (time.thread_time() - t0) / len(ctrl))
    finally:
        for fl, _, _ in runs.values():
            fl.close()
    return best


def run(args: argparse.Namespace) -> dict:
    """``--feathers rigid`` (default) or ``modal``: modal is measured together with
    rigid in the same run, for the cost ratio."""
    seconds = args.seconds or 2.0
    feathers = getattr(args, "feathers", None) or "rigid"
    kinds = ("rigid",) if feathers == "rigid" else ("rigid", "modal")
    doves = {k: Dove.load(feathers=k) for k in kinds}
    dove = doves[kinds[-1]]
    dt = float(dove.model.opt.timestep)
    per = {k: _measure(doves[k], seconds) for k in kinds}
    res = per[kinds[-1]]
    m = dove.model
    out = {
        "target": "dove",
        "feathers": kinds[-1],
        "timestep": dt,
        "polygons": int(len(dove.feather_triangles()[0])),
        "nv": int(m.nv),
        "real_time_factor": res["rollout"]["real_time_factor"],
        "cost_over_bare_step": res["rollout"]["us_per_step"] / res["bare"]["us_per_step"],
        "measurements": res,
        "machine": platform.processor() or platform.machine(),
        "paper_real_time_factor": [0.3, 0.5],
    }
    if "modal" in per:
        r, mo = per["rigid"], per["modal"]
        out["rigid_measurements"] = r
        out["modal_cost_over_rigid_wall"] = mo["rollout"]["us_per_step"] / r["rollout"]["us_per_step"]
        out["modal_bare_over_rigid_bare"] = mo["bare"]["us_per_step"] / r["bare"]["us_per_step"]
        cpu = _interleaved_step_cost(doves)
        out["cpu_us_per_step"] = cpu
        out["modal_cost_over_rigid"] = cpu["modal"] / cpu["rigid"]
    for k in kinds:
        r = per[k]
        print(f"dove base controller, {k} feathers, at {1 / dt:.0f} Hz, nv {doves[k].model.nv}")
        for name in ("rollout", "python_loop", "bare"):
            print(f"  {name:12s} {r[name]['real_time_factor']:6.1f}x real time "
                  f"({r[name]['us_per_step']:.1f} us/step)")
        print(f"  flight step costs {r['rollout']['us_per_step'] / r['bare']['us_per_step']:.2f}x "
              "a bare mj_step (paper: 0.3-0.5x real time)")
    if "modal" in per:
        cpu = out["cpu_us_per_step"]
        print(f"modal feathers cost {out['modal_cost_over_rigid']:.2f}x rigid per flight step "
              f"({cpu['modal']:.1f} vs {cpu['rigid']:.1f} us of CPU time, interleaved, least of 7; "
              f"{1e6 / cpu['modal'] * dt:.1f}x vs {1e6 / cpu['rigid'] * dt:.1f}x real time); "
              f"wall-time runs above: {out['modal_cost_over_rigid_wall']:.2f}x, "
              f"bare step {out['modal_bare_over_rigid_bare']:.2f}x")
    return out


def run_train(args: argparse.Namespace) -> dict:
    """``flapsim bench train``: phase-1 samples per second on W worker processes, against
    the same sampler in this process (parallel efficiency) and against bare ``mj_step``
    (what a sample costs in steps of the bare model)."""


    workers = getattr(args, "workers", None) or min(2, os.cpu_count() or 1)
    n = getattr(args, "samples", None) or 150 * workers
    w = SampleWorker(SamplingConfig(seed=12345))
    w.run_chunk(0, 1)  # warm-up (numba kernels)
    t0 = time.perf_counter()
    one = w.run_chunk(1, 9)
    per_sample = (time.perf_counter() - t0) / 8
    cycles = 3 * len(one.index) + sum(one.rejected.values())  # pre-simulation, P0, P0 + dP
    m = w.dove.model
    steps_per_cycle = w.ref.duration(w.P0) / float(m.opt.timestep)
    d = mujoco.MjData(m)
    nstep = int(steps_per_cycle * 3)
    t0 = time.perf_counter()
    mujoco.mj_step(m, d, nstep=nstep)
    bare_per_sample = time.perf_counter() - t0
    w.close()
    with tempfile.TemporaryDirectory() as tmp:
        s = train(SamplingConfig(seed=12345), os.path.join(tmp, "bench.db"), n, SampleWorker,
                  workers=workers, chunk_size=8, progress=False, kind="dove-phase1")
    # steady rate: the pool's start (spawning, importing, compiling the model once per
    # worker) is paid once per run and reported apart
    rate = s["samples"] / max(s["wall_s"] - s["startup_s"], 1e-9)
    out = {
        "target": "train",
        "workers": workers,
        "samples": s["samples"],
        "samples_per_s": rate,
        "samples_per_s_with_startup": s["samples_per_s"],
        "wall_s": s["wall_s"],
        "startup_s": s["startup_s"],
        "in_process_samples_per_s": 1.0 / per_sample,
        "parallel_efficiency": rate / (workers / per_sample),
        "cost_over_bare_steps": per_sample / bare_per_sample,
        "cycles_per_sample": cycles / 8,
        "minutes_for_10000": 10000 / rate / 60,
    }
    print(f"phase-1 sampling on {workers} worker process{'es' if workers > 1 else ''}: "
          f"{rate:.1f} samples/s after a {s['startup_s']:.1f} s start-up ({s['samples']} samples, "
          f"{s['samples_per_s']:.1f}/s with it)")
    print(f"  in this process {out['in_process_samples_per_s']:.1f} samples/s: parallel efficiency "
          f"{out['parallel_efficiency']:.2f}")
    print(f"  a sample costs {out['cost_over_bare_steps']:.2f}x its {3 * steps_per_cycle:.0f} bare "
          "mj_steps (3 wingbeats: pre-simulation, P0, P0 + dP)")
    print(f"  10,000 samples: {out['minutes_for_10000']:.1f} min (target <= 5 min; paper: hours)")
    return out


def run_controller(args: argparse.Namespace) -> dict:
    """``flapsim bench controller [--feathers modal]``: the learned controller's cruise in
    real-time factor: the default (for the rigid dove S0 simulated on a 1600 Hz copy and the
    corrections stopped at the first candidate near enough), without the stop, with S0 on the
    flight and every correction simulated (alone and with the look-ahead on a second core),
    ``predict="coarse"`` and ``predict="regression"``, and with 0, 1 and 2 corrections; what a
    controlled wingbeat costs against a base wingbeat; and each against a bare
    ``mujoco.rollout`` of P0 (the floor: no controller, no Python), all in the same run."""

    n = max(4, int(getattr(args, "wingbeats", None) or 20))
    db = getattr(args, "db", None)
    feathers = getattr(args, "feathers", None) or "rigid"
    # the database's own dove, feather table, speed and pitch (a cruise database's dove has its
    # induced flow and flies at 8.5 m/s)
    dove = database_dove(db, feathers)
    cfg = FlightConfig(table=database_table(db, feathers), speed=database_speed(db, feathers),
                       pitch_deg=database_pitch(db, feathers))
    fl = DoveFlight(dove, table=cfg.table)
    try:
        ctl = load_controller(fl, db)
        coarse = load_controller(fl, db, predict="coarse")
        reg = attach_predictor(load_controller(fl, db), db)
        # the same regression (one database load), 0, 1 and 2 corrections, and the default's
        # corrections without the stop (every one simulated)
        refined = [(f"learned_refine{r}", dataclasses.replace(ctl, refine=r)) for r in (0, 1, 2)]
        refined.append(("learned_no_stop", dataclasses.replace(ctl, refine_stop=0.0)))
        # the paper's S0 (simulated on the flight at its own rate) and every correction
        # simulated (at least one: the look-ahead runs beside them)
        ahead_refine = max(ctl.refine, 1)
        # (without the lateral regulator, which needs each wingbeat's start: the look-ahead
        # cannot run beside it)
        every = dataclasses.replace(ctl, predictor=None, refine=ahead_refine, refine_stop=0.0,
                                    _predict="simulate", lateral=None)
        # with the next wingbeat's reference simulated on a second core: the same flight, sooner
        ahead = dataclasses.replace(every, lookahead=make_lookahead(fl, "on", ahead_refine, "simulate"))
        flown, per_wingbeat = {}, {}
        trim = trim_of_base_flight(fl, ctl.P0, cfg)
        target = dict(altitude=cfg.height, speed=cfg.speed)
        res = {}
        for name, c in (("learned", ctl), ("learned_every_correction", every),
                        ("learned_lookahead", ahead), ("learned_coarse", coarse),
                        ("learned_regression", reg), *refined, ("base", BaseController(fl, ctl.P0))):
            start_cruise(fl, ctl.P0, cfg)
            fly_controlled(c, CruiseTarget(trim, **target), 1)  # warm-up: the coarse twin
            start_cruise(fl, ctl.P0, cfg)
            if hasattr(c, "reset"):
                c.reset()  # the same start for every variant: their flights compare to the bit
            f = fly_controlled(c, CruiseTarget(trim, **target), n)
            flown[name] = f.positions
            # wingbeats' worth of steps simulated per wingbeat flown: the reference (where
            # simulated: the look-ahead's on its own core; on a coarser copy, its share of the
            # flight's steps) and every candidate (the flown one among them)
            pr = getattr(c, "predictor", None)
            ref_cost = pr.rate_hz * float(fl.model.opt.timestep) if isinstance(pr, CoarsePredictor) else 1.0
            per_wingbeat[name] = float(np.mean([
                s.simulated + ref_cost * (s.reference is not s.end and not s.reference.predicted)
                for s in f.steps]))
            res[name] = {"wingbeats": n, "simulated_s": f.simulated_s, "wall_s": f.wall_time,
                         "real_time_factor": f.simulated_s / f.wall_time}
        start_cruise(fl, ctl.P0, cfg)
        snap = cycle.snapshot(fl)
        m = fl.model
        ctrl, _, _ = control_table(fl.ref, ctl.P0, m.opt.timestep, fl.kp, fl.kv)
        t0 = time.perf_counter()
        for _ in range(n):
            rollout.rollout(m, fl.data, snap.physics[None], ctrl[None],
                            initial_warmstart=snap.warmstart[None])
        wall = time.perf_counter() - t0
        res["bare_rollout"] = {"wingbeats": n, "simulated_s": n * len(ctrl) * float(m.opt.timestep),
                               "wall_s": wall}
        res["bare_rollout"]["real_time_factor"] = res["bare_rollout"]["simulated_s"] / wall
        x = np.zeros(8)
        t0 = time.perf_counter()
        for _ in range(200):
            ctl.regressor.predict(x)
        query_ms = (time.perf_counter() - t0) / 200 * 1e3
    finally:
        fl.close()
    bare = res["bare_rollout"]["real_time_factor"]
    twin = "learned_every_correction"
    lookahead_same = bool(np.array_equal(flown[twin], flown["learned_lookahead"]))
    out = {
        "target": "controller",
        "feathers": feathers,
        "db": str(db) if db else "bundled",
        "lateral_regulator": ctl.lateral is not None,
        "speed": cfg.speed,
        "database_samples": ctl.regressor.n,
        "method": ctl.regressor.method,
        "k": ctl.regressor.k,
        "real_time_factor": res["learned"]["real_time_factor"],
        "real_time_factor_lookahead": res["learned_lookahead"]["real_time_factor"],
        "lookahead_refine": ahead_refine,
        "lookahead_speedup": (res["learned_lookahead"]["real_time_factor"]
                              / res[twin]["real_time_factor"]),
        "lookahead_same_flight": lookahead_same,
        "lookahead_hits": [ahead.lookahead.hits, ahead.lookahead.misses],
        "real_time_factor_coarse": res["learned_coarse"]["real_time_factor"],
        "real_time_factor_regression": res["learned_regression"]["real_time_factor"],
        "refine": ctl.refine,
        "refine_stop": ctl.refine_stop,
        "timestep": float(m.opt.timestep),
        "reference_hz": (ctl.predictor.rate_hz if isinstance(ctl.predictor, CoarsePredictor)
                         else 1.0 / float(m.opt.timestep)),
        "real_time_factor_no_stop": res["learned_no_stop"]["real_time_factor"],
        "real_time_factor_every_correction": res[twin]["real_time_factor"],
        "real_time_factor_refine": {r: res[f"learned_refine{r}"]["real_time_factor"] for r in (0, 1, 2)},
        "cost_over_base": res["base"]["real_time_factor"] / res["learned"]["real_time_factor"],
        "over_bare_rollout": {k: v["real_time_factor"] / bare for k, v in res.items()},
        "threads": {"learned": 1, "learned_lookahead": 2},
        "wingbeats_simulated_per_flown": per_wingbeat,
        # the most a controller that simulates these one after another on one thread can reach
        "ceiling_over_bare_rollout": {k: 1.0 / v for k, v in per_wingbeat.items()},
        "regression_ms": query_ms,
        "measurements": res,
    }
    r = out["over_bare_rollout"]
    print(f"learned controller, {feathers} feathers ({out['method']}, k={out['k']}, "
          f"{out['database_samples']} samples{', lateral regulator' if ctl.lateral else ''}, "
          f"{cfg.speed:g} m/s): "
          f"{out['real_time_factor']:.1f}x real time, {out['cost_over_base']:.2f}x the base "
          f"controller's cost per wingbeat; regression {query_ms:.2f} ms per wingbeat")
    print(f"  S0 at the flight's rate and every correction simulated ({ahead_refine}): "
          f"{out['real_time_factor_every_correction']:.1f}x real time; with the look-ahead (the next "
          f"reference on a second core) {out['real_time_factor_lookahead']:.1f}x, "
          f"{out['lookahead_speedup']:.2f}x without it, "
          f"{'the same flight to the bit' if lookahead_same else 'A DIFFERENT FLIGHT (a bug)'}")
    print(f"  --predict coarse: {out['real_time_factor_coarse']:.1f}x real time; --predict regression: "
          f"{out['real_time_factor_regression']:.1f}x")
    rf = out["real_time_factor_refine"]
    print(f"  refine 0 / 1 / 2 (default {ctl.refine}, stopping within {ctl.refine_stop:g}): "
          f"{rf[0]:.1f}x / {rf[1]:.1f}x / {rf[2]:.1f}x real time; every correction simulated "
          f"(no stop) {out['real_time_factor_no_stop']:.1f}x")
    print(f"  against a bare rollout of the reference wingbeat ({bare:.1f}x real time): learned "
          f"{r['learned']:.2f} on one thread (every correction, S0 at the flight's rate: "
          f"{r['learned_every_correction']:.2f}; on two with the look-ahead {r['learned_lookahead']:.2f}), "
          f"--predict coarse {r['learned_coarse']:.2f}, --predict regression "
          f"{r['learned_regression']:.2f}, "
          f"base {r['base']:.2f}")
    w = per_wingbeat["learned"]
    print(f"  the learned controller simulates {w:.2f} wingbeats' worth of steps per wingbeat "
          f"flown (S0 at {out['reference_hz']:.0f} Hz, corrections stopped within "
          f"{ctl.refine_stop:g}), each waiting for the one before: at most {1 / w:.2f} of a bare "
          f"rollout on one thread")
    return out


def run_eval(args: argparse.Namespace) -> dict:
    """``flapsim bench eval``: the whole flight evaluation suite (``flapsim eval --scenario
    all``) on ``--workers`` processes (default 2): its wall time, the simulated seconds per
    wall second, and the parallel speed-up (the runs' own wall times summed over the suite's)
    measured in the same run."""
    workers = int(getattr(args, "workers", None) or 2)
    quick = bool(getattr(args, "quick", False))
    opts = scenarios.EvalOptions(db=getattr(args, "db", None), predict=getattr(args, "predict", "simulate"),
                                 quick=quick)
    names = scenarios.names(family="flight", all_only=True)
    if quick:  # a smoke run: the two cheapest scenarios, in their short variants
        names = sorted(names, key=lambda n: scenarios.get(n).cost)[:2]
    runs = [(n, opts) for n in names]
    t0 = time.perf_counter()
    results = runner.execute(runs, workers)
    wall = time.perf_counter() - t0
    busy = float(sum(r["wall_s"] for r in results))
    sim = 0.0
    for r in results:
        m = r.get("metrics", {})
        sim += float(m.get("simulated_s") or 0.0)
    out = {"target": "eval", "workers": workers, "runs": len(results), "wall_s": wall,
           "runs_wall_s": busy, "speedup": busy / wall, "parallel_efficiency": busy / wall / workers,
           "simulated_s": sim, "simulated_per_wall_s": sim / wall,
           "failed": [r["scenario"] for r in results if not r.get("ok")],
           "statuses": {r["scenario"]: r.get("status") for r in results}, "predict": opts.predict,
           "quick": quick}
    print(f"flight evaluation suite (S0: {opts.predict}): {len(results)} runs in {wall:.0f} s on "
          f"{workers} workers "
          f"(speed-up {out['speedup']:.2f}, efficiency {out['parallel_efficiency']:.2f}); "
          f"{sim:.0f} s simulated, {out['simulated_per_wall_s']:.1f} simulated s per wall s")
    return out
