"""How firm a flight's verdict is: a path scenario or a held-out user path flown N times, each
start's forward speed changed by a draw far below anything physical (default +-1 mm/s), and
the completions counted.

    python studies/dove_verdict_spread.py NAME[,NAME...]|user [--n 10] [--jitter 0.001]
        [--seed 0] [--workers 2] [--db bundled,seed1.db,...] [--config FILE.toml]
        [--set NAME=VALUE ...] [--json out.json]

A controlled flight is chaotic: near the limits of what the dove can do, one run's verdict
turns on last-bit differences (another machine, another library build: see
:mod:`flapsim.core.environment`). A completion rate over perturbed starts says what one
verdict cannot: whether the path is within reach, at its edge, or beyond it.
``flapsim eval --starts N`` does the same for one scenario or path file; this study adds the ten
held-out user paths and several databases in one run.

NAME: a path scenario (``flapsim eval --list``: figure8*, sinusoid*, climb-turn-*, plucked-*,
wind-*) or one of :data:`flapsim.bird.tasks.path_shapes.USER_PATHS` (``user``: all ten, judged
as ``flapsim eval --path`` judges: lost farther than 3 m from the path, or the end not reached
in the time allowed; the table gives each path's tightest radius and steepest climb and
descent). ``--n 1`` flies each once, unperturbed: the plain verdict. The draws are
reproducible (``--seed``); the first start is the unperturbed one. ``--config``: a control
configuration file (``[controller]`` and ``[path]`` tables, as ``flapsim eval --config`` reads;
``flapsim list config`` prints the defaults); ``--set NAME=VALUE`` sets one field of either
table over it, e.g. ``--set bank_lead_s=0.4`` or ``--set refine=0``. About half a flight's time
per run on 2 workers.
"""

from __future__ import annotations

import argparse
import dataclasses
import multiprocessing as mp
import time

from flapsim import scenarios
from flapsim.bird.control.config import ControllerConfig
from flapsim.bird.tasks.config import PathControlConfig, load_control_config
from flapsim.bird.tasks.flight_tasks import Task, fly_task
from flapsim.bird.tasks.path_shapes import USER_PATHS
from flapsim.core.io import write_json


def _fly(job: tuple[str, str, float, ControllerConfig | None, PathControlConfig | None]) -> dict:
    """One run (in a worker): path or scenario ``name`` with database ``db``, the start's
    forward speed changed by ``dv`` m/s (the speed, not the direction), under the controllers'
    configurations (None: the dove's defaults)."""
    name, db, dv, controller, path_control = job
    db_path = None if db == "bundled" else db
    row = {"name": name, "db": db, "dv_m_s": dv}
    if name in USER_PATHS:
        path = USER_PATHS[name]()
        g = path.geometry()
        task = (path_control or PathControlConfig.for_dove()).apply(Task(path, start_speed_change=dv))
        t = fly_task(task, db_path, config=controller)
        m = t.metrics
        return {**row, "status": t.status, "note": t.reason,
                "max_distance_m": m.get("max_path_distance"), "Ef_m": m.get("Ef_per_wingbeat"),
                "min_radius_m": g.min_radius_m, "max_climb_deg": g.max_climb_deg,
                "max_descent_deg": g.max_descent_deg}
    sc = scenarios.get(name)
    r = sc.runner(sc, scenarios.EvalOptions(db=db_path, controller=controller, path_control=path_control,
                                            start_speed_change=dv))
    m = r.get("metrics", {})
    return {**row, "status": r.get("status"), "note": r.get("reason", ""),
            "max_distance_m": m.get("max_path_distance"), "Ef_m": m.get("Ef_per_wingbeat")}


def settings(controls: tuple[ControllerConfig, PathControlConfig], items: list[str]
             ) -> tuple[ControllerConfig, PathControlConfig]:
    """``controls`` with each ``NAME=VALUE`` of ``items`` set: NAME a field of
    :class:`ControllerConfig` or :class:`PathControlConfig` (their names differ), VALUE read as
    that field's type; the configurations check their ranges."""
    out = list(controls)
    for item in items:
        key, sep, text = item.partition("=")
        which = [i for i, c in enumerate(out) if key in {f.name for f in dataclasses.fields(c)}]
        if not sep or not which:
            known = sorted(f.name for c in out for f in dataclasses.fields(c))
            raise SystemExit(f"--set {item}: expected NAME=VALUE, NAME one of {', '.join(known)}")
        c = out[which[0]]
        kind = type(getattr(c, key))
        try:
            value = kind(text)
        except ValueError:
            raise SystemExit(f"--set {item}: {key} takes a {kind.__name__}") from None
        out[which[0]] = dataclasses.replace(c, **{key: value})
    return out[0], out[1]


def names(text: str) -> list[str]:
    """The runs' paths: ``user`` expands to the ten user paths; a scenario must fly a path."""
    out = [n for token in text.split(",") for n in (list(USER_PATHS) if token == "user" else [token])]
    for name in out:
        if name in USER_PATHS:
            continue
        sc = scenarios.get(name)
        if sc.family != "flight" or sc.runner.__name__ != "run_path":
            raise SystemExit(f"{name}: not a path scenario (see the module docstring)")
    return out


def parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("scenario", help="path scenarios and user paths, comma-separated (user: all ten)")
    ap.add_argument("--n", type=int, default=10, help="perturbed starts (default 10)")
    ap.add_argument("--jitter", type=float, default=0.001,
                    help="largest change of the start's speed, m/s (default 0.001)")
    ap.add_argument("--seed", type=int, default=0, help="the draw of the speed changes")
    ap.add_argument("--workers", type=int, default=2, help="processes flying the runs")
    ap.add_argument("--db", default="bundled",
                    help="comma-separated databases (bundled: the bundled one)")
    ap.add_argument("--config", default=None,
                    help="control configuration file (TOML; default: the dove's defaults)")
    ap.add_argument("--set", action="append", default=[], metavar="NAME=VALUE",
                    help="a field of the [controller] or [path] table over --config's, e.g. "
                         "bank_lead_s=0.4; repeatable")
    ap.add_argument("--json", help="write every run and the counts here")
    return ap


def main(argv: list[str] | None = None) -> None:
    a = parser().parse_args(argv)
    runs = names(a.scenario)
    dvs = scenarios.start_speed_changes(a.n, a.jitter, a.seed)  # as flapsim eval --starts draws
    # the configuration read once, here: a mistake in the file stops the study before any flight
    controls = (settings(load_control_config(a.config), a.set) if a.config or a.set
                else (None, None))
    jobs = [(name, db, float(dv), *controls) for db in a.db.split(",") for name in runs for dv in dvs]
    t0 = time.perf_counter()
    with mp.get_context("spawn").Pool(a.workers) as pool:
        rows = pool.map(_fly, jobs, chunksize=1)
    wall = time.perf_counter() - t0
    counts: dict[str, int] = {}
    for r in rows:
        shape = (f"r>={r['min_radius_m']:4.2f} m climb {r['max_climb_deg']:4.1f}/"
                 f"{r['max_descent_deg']:4.1f} deg  " if "min_radius_m" in r else "")
        largest = r["max_distance_m"] if r["max_distance_m"] is not None else float("nan")
        print(f"{r['db']:<12} {r['name']:22s} dv {r['dv_m_s'] * 1e3:+7.3f} mm/s  {shape}"
              f"{r['status']:9s}  largest {largest:5.2f} m  {r['note']}")
        key = f"{r['db']} {r['name']}"
        counts[key] = counts.get(key, 0) + (r["status"] == "completed")
    for key, done in counts.items():
        lo, hi = scenarios.completion_interval(done, len(dvs))
        print(f"{key}: completed {done} of {len(dvs)} starts within +-{a.jitter * 1e3:g} mm/s "
              f"({100 * lo:.0f}-{100 * hi:.0f} % at 95 %)")
    print(f"{sum(counts.values())} of {len(rows)} in all ({wall:.0f} s)")
    if a.json:
        write_json(a.json, {"scenarios": runs, "databases": a.db.split(","), "config": a.config,
                            "set": a.set,
                            "jitter_m_s": a.jitter, "seed": a.seed, "completed": counts, "runs": rows,
                            "wall_s": wall})


if __name__ == "__main__":
    main()
