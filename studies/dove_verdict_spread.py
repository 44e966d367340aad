"""How firm a flight scenario's verdict is: the scenario flown N times, each start's forward
speed changed by a draw far below anything physical (default +-1 mm/s), and the verdicts
counted. ``flapsim eval --starts N`` does the same for any scenario or path file; this script
adds the ten held-out user paths (``user``) and any evaluation option (``--set``).

A controlled flight is chaotic: near the limits of what the dove can do, one run's verdict
turns on last-bit differences (session 18: the same commit lost ``climb-turn-15`` here where
session 15 had followed it; see :mod:`flapsim.core.environment`). A completion rate over
perturbed starts says what one verdict cannot: whether the scenario is within reach, at its
edge, or beyond it.

    python studies/dove_verdict_spread.py NAME[,NAME...]|user [--n 10]
        [--jitter 0.001] [--workers 2] [--refine-goal full|reachable] [--set NAME=VALUE ...]
        [--patch FILE.py ...] [--json out.json]

NAME: a path scenario (``flapsim eval --list``: figure8*, sinusoid*, climb-turn-*, plucked-*,
wind-*) or one of :data:`flapsim.bird.tasks.path_shapes.USER_PATHS` (``user``: all ten). The draws are
reproducible (``--seed``); the first start is the unperturbed one. About half a run's flight
time per run on 2 workers.

``--patch FILE.py`` runs that file in every worker before its first flight: an experiment that
changes the package's behaviour without changing the package (the patches behind the flight
log's "Tried, not kept" entries are in ``scripts/experiments/``).
"""

from __future__ import annotations

import argparse
import multiprocessing as mp
import time
from pathlib import Path

from flapsim.bird.tasks.path_shapes import USER_PATHS
from flapsim.core.io import write_json

_PATCHED: set[str] = set()


def _apply_patches(patches: tuple[str, ...]) -> None:
    """Run each patch file once in this process (a pool worker flies many jobs)."""
    import runpy

    for path in patches:
        if path not in _PATCHED:
            runpy.run_path(path, run_name="flapsim_patch")
            _PATCHED.add(path)


def _fly(job: tuple[str, float, dict, tuple[str, ...]]) -> dict:
    name, dv, options, patches = job
    _apply_patches(patches)
    from flapsim import scenarios

    # the start's forward speed changed by dv: the speed, not the direction
    opt = scenarios.EvalOptions(**options, start_speed_change=dv)
    if name in USER_PATHS:
        from flapsim.bird.tasks.flight_tasks import Task
        from flapsim.scenarios.flight import _fly_task  # the options applied as eval applies them

        t = _fly_task(Task(USER_PATHS[name]()), opt, False)
        m = t.metrics
        return {"name": name, "dv_m_s": dv, "status": t.status, "note": m.get("note", ""),
                "max_distance_m": m.get("max_path_distance"), "Ef_m": m.get("Ef_per_wingbeat")}
    sc = scenarios.get(name)
    r = sc.runner(sc, opt)
    m = r.get("metrics", {})
    return {"name": name, "dv_m_s": dv, "status": r.get("status"), "note": r.get("reason", ""),
            "max_distance_m": m.get("max_path_distance"), "Ef_m": m.get("Ef_per_wingbeat")}


def _value(text: str) -> int | float | str:
    """A ``--set`` value: a number where it reads as one (refine=3, carry=0.3), else the text
    (db=seed1.db, refine_goal=reachable)."""
    for kind in (int, float):
        try:
            return kind(text)
        except ValueError:
            pass
    return text


def parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("scenario")
    ap.add_argument("--n", type=int, default=10, help="perturbed starts (default 10)")
    ap.add_argument("--jitter", type=float, default=0.001,
                    help="largest change of the start's speed, m/s (default 0.001)")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--refine-goal", choices=("full", "reachable"), default=None)
    ap.add_argument("--set", action="append", default=[], metavar="NAME=VALUE",
                    help="an evaluation option (flapsim.scenarios.EvalOptions), e.g. "
                         "bank_lead_s=0.4, carry=0.3, refine=3, db=seed1.db; repeatable")
    ap.add_argument("--patch", action="append", default=[], metavar="FILE.py",
                    help="run this Python file in every worker before it flies (an experiment's "
                         "change to the package); repeatable")
    ap.add_argument("--json")
    return ap


def main(argv: list[str] | None = None) -> None:
    ap = parser()
    a = ap.parse_args(argv)
    options: dict = {"refine_goal": a.refine_goal}
    for item in a.set:
        key, _, value = item.partition("=")
        options[key] = _value(value)
    from flapsim import scenarios

    names = [n for token in a.scenario.split(",")
             for n in (list(USER_PATHS) if token == "user" else [token])]
    for name in names:
        if name in USER_PATHS:
            continue
        sc = scenarios.get(name)
        if sc.family != "flight" or sc.runner.__name__ != "run_path":
            raise SystemExit(f"{name}: not a path scenario (see the module docstring)")
    dvs = scenarios.start_speed_changes(a.n, a.jitter, a.seed)  # as flapsim eval --starts draws
    patches = []
    for f in a.patch:
        if not Path(f).is_file():
            raise SystemExit(f"--patch {f}: no such file")
        patches.append(str(Path(f).resolve()))
    jobs = [(name, float(dv), options, tuple(patches)) for name in names for dv in dvs]
    t0 = time.perf_counter()
    with mp.get_context("spawn").Pool(a.workers) as pool:
        rows = pool.map(_fly, jobs, chunksize=1)
    wall = time.perf_counter() - t0
    counts = {}
    for r in rows:
        print(f"{r['name']:22s} dv {r['dv_m_s'] * 1e3:+7.3f} mm/s  {r['status']:9s}  largest "
              f"{r['max_distance_m'] if r['max_distance_m'] is not None else float('nan'):5.2f} m  "
              f"{r['note']}")
        counts[r["name"]] = counts.get(r["name"], 0) + (r["status"] == "completed")
    for name, done in counts.items():
        lo, hi = scenarios.completion_interval(done, len(dvs))
        print(f"{name}: completed {done} of {len(dvs)} starts within +-{a.jitter * 1e3:g} mm/s "
              f"({100 * lo:.0f}-{100 * hi:.0f} % at 95 %)")
    print(f"{sum(counts.values())} of {len(rows)} in all ({wall:.0f} s)")
    if a.json:
        write_json(a.json, {"scenarios": names, "jitter_m_s": a.jitter, "seed": a.seed,
                            "completed": counts, "runs": rows, "wall_s": wall,
                            "options": options, "patches": patches})


if __name__ == "__main__":
    main()
