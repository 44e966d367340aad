"""Paths that are not among the scenarios, as a user's path file would give them: level circles
of 3-4 m both ways, helices climbing and descending, an S-curve of two 3.5 m half circles and
a climb into a wide turn, each flown with the learned controller and judged as ``flapsim eval
--path`` judges (lost = farther than 3 m from the path, or the end not reached in the time
allowed).

    PYTHONPATH=. python scripts/dove_user_paths.py [--db bundled,seed1.db,...] [--refine N]
        [--only NAME,...] [--json out.json]

The paths start where they start turning (no straight lead-in), as a point list a user draws
would: the dove enters at 7 m/s and must roll into the turn on its first wingbeats. The
natural spline through the points overshoots a circle's curvature near its ends (a 3 m helix
has 2.4 m there; the table prints the tightest radius and the steepest climb and descent of
each path as :meth:`~flapsim.bird.path.FlightPath.geometry` measures them). About 2 minutes a
database on one core.
"""

from __future__ import annotations

import argparse

import numpy as np

from flapsim.bird.path import FlightPath
from flapsim.bird.paths import START_HEIGHT as H
from flapsim.bird.tasks import Task, build_flight, fly_task
from flapsim.io import write_json


def helix(radius_m: float, climb_deg: float, turns: float, side: float = 1.0) -> np.ndarray:
    """Points of a helix turning left (``side`` -1: right) from heading +x, climbing at
    ``climb_deg`` (negative: descending)."""
    t = np.linspace(0.0, 2 * np.pi * turns, int(48 * turns) + 1)
    z = H + radius_m * t * np.tan(np.radians(climb_deg))
    return np.stack([radius_m * np.sin(t), side * radius_m * (1 - np.cos(t)), z], 1)


def s_curve(radius_m: float) -> np.ndarray:
    """A half circle to the left, then one to the right, with 6 m straight ends."""
    t = np.linspace(0.0, np.pi, 25)
    left = np.stack([radius_m * np.sin(t), radius_m * (1 - np.cos(t))], 1)
    right = np.stack([-radius_m * np.sin(t), 2 * radius_m + radius_m * (1 - np.cos(t))], 1)
    xy = np.vstack([[[-6.0, 0.0], [-3.0, 0.0]], left, right[1:],
                    [[3.0, 4 * radius_m], [6.0, 4 * radius_m]]])
    return np.c_[xy, np.full(len(xy), H)]


def climb_then_turn() -> np.ndarray:
    """A 5 deg climb of 30 m, a wide right-about turn and a gentle descent back."""
    return np.array([[0, 0, H], [15, 0, H + 1.3], [30, 0, H + 2.6], [40, 4, H + 2.6],
                     [44, 12, H + 2.6], [40, 20, H + 2.6], [30, 22, H + 2.0], [20, 22, H + 1.0]],
                    dtype=float)


PATHS = {
    "circle-3-left": lambda: helix(3.0, 0.0, 1.0),
    "circle-3-right": lambda: helix(3.0, 0.0, 1.0, -1.0),
    "circle-4-left": lambda: helix(4.0, 0.0, 1.0),
    "circle-4-right": lambda: helix(4.0, 0.0, 1.0, -1.0),
    "helix-3-up-3-right": lambda: helix(3.0, 3.0, 1.5, -1.0),
    "helix-4-up-5": lambda: helix(4.0, 5.0, 1.5),
    "helix-5-up-8": lambda: helix(5.0, 8.0, 1.25),
    "helix-3-down-10-right": lambda: helix(3.0, -10.0, 1.5, -1.0),
    "s-curve-3.5": lambda: s_curve(3.5),
    "climb-then-turn": climb_then_turn,
}


def study(db: str | None, refine: int | None, names: list[str]) -> list[dict]:
    fl, ctl = build_flight(Task(FlightPath(helix(4.0, 0.0, 1.0))), db, refine=refine)
    rows = []
    try:
        for name in names:
            path = FlightPath(PATHS[name]())
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
