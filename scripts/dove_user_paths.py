"""Paths that are not among the scenarios, as a user's path file would give them: level circles
of 3-4 m both ways, helices climbing and descending, an S-curve of two 3.5 m half circles and
a climb into a wide turn, each flown with the learned controller and judged as ``flapsim eval
--path`` judges (lost = farther than 3 m from the path, or the end not reached in the time
allowed).

    PYTHONPATH=. python scripts/dove_user_paths.py [--db bundled,seed1.db,...] [--refine N]
        [--only NAME,...] [--json out.json]

The paths are :data:`flapsim.bird.tasks.path_shapes.USER_PATHS` (held out of the scenarios; see there how
they start). The table prints the tightest radius and the steepest climb and descent of each
path as :meth:`~flapsim.bird.tasks.path_control.FlightPath.geometry` measures them. About 2 minutes a
database on one core.
"""

from __future__ import annotations

import argparse

from flapsim.bird.tasks.flight_tasks import Task, build_flight, fly_task
from flapsim.bird.tasks.path_shapes import USER_PATHS as PATHS
from flapsim.bird.tasks.path_shapes import helix
from flapsim.core.io import write_json


def study(db: str | None, refine: int | None, names: list[str]) -> list[dict]:
    fl, ctl = build_flight(Task(helix(4.0, 0.0, 1.0)), db, refine=refine)
    rows = []
    try:
        for name in names:
            path = PATHS[name]()
            g = path.geometry()
            t = fly_task(Task(path), db, controller=ctl)
            rows.append({"db": db or "bundled", "refine": ctl.refine, "path": name,
                         "length_m": path.length, "min_radius_m": g.min_radius_m,
                         "max_climb_deg": g.max_climb_deg, "max_descent_deg": g.max_descent_deg,
                         "status": t.status, "reason": t.reason,
                         "max_path_distance": t.metrics["max_path_distance"],
                         "Ef_per_wingbeat": t.metrics.get("Ef_per_wingbeat")})
            r = rows[-1]
            print(f"{r['db']:<12} {name:<22} r>={g.min_radius_m:4.2f} m climb {g.max_climb_deg:4.1f}"
                  f"/{g.max_descent_deg:4.1f} deg  {t.status:<9} largest distance "
                  f"{r['max_path_distance']:.2f} m  {t.reason}", flush=True)
    finally:
        fl.close()
    return rows


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--db", default="bundled", help="comma-separated databases (bundled: the bundled one)")
    ap.add_argument("--refine", type=int, default=None, help="simulated corrections (default: the dove's)")
    ap.add_argument("--only", default=None, help=f"comma-separated paths of {', '.join(PATHS)}")
    ap.add_argument("--json", default=None)
    a = ap.parse_args()
    names = a.only.split(",") if a.only else list(PATHS)
    unknown = [n for n in names if n not in PATHS]
    if unknown:
        ap.error(f"unknown path(s) {', '.join(unknown)}; choose from {', '.join(PATHS)}")
    rows = []
    for db in a.db.split(","):
        rows += study(None if db == "bundled" else db, a.refine, names)
    done = {}
    for r in rows:
        done.setdefault(r["db"], []).append(r["status"] == "completed")
    for db, ok in done.items():
        print(f"{db}: {sum(ok)} of {len(ok)} completed")
    if a.json:
        write_json(a.json, {"user_paths": rows})


if __name__ == "__main__":
    main()
