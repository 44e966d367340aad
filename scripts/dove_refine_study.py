"""Wingbeats checked by simulation (``--refine N``): level circles, sideways/downward/backward
pushes and straight climbs, flown with and without the corrections over several databases.

    PYTHONPATH=. python scripts/dove_refine_study.py [--refine 0,2] [--db bundled,seed1.db,...]
        [--radii 3,4,5,6,8] [--json out.json]

Each circle is flown turning left and, mirrored, turning right (near the limits a verdict can
flip with a few hundredths of a m/s: one flight per radius says little); a push survives when
the bird never leaves the 10 m tube and ends within 1.5 m of the 60 m path (the suite's rule);
a climb is completed within the 3 m tube and the time allowed. About 2 minutes a database and
setting on one core (``--refine 2`` flies ~2x slower than 0).
"""

from __future__ import annotations

import argparse

import numpy as np

from flapsim.bird.tasks import path_shapes as paths
from flapsim.bird.tasks.flight_tasks import PushSpec, Task, fly_task
from flapsim.bird.tasks.path_control import FlightPath
from flapsim.core.io import write_json

PUSHES = (("left", 6.0), ("left", 8.0), ("right", 6.0), ("right", 8.0), ("down", 6.0),
          ("down", 8.0), ("back", 6.0), ("back", 8.0))


def _climb(deg: float) -> FlightPath:
    a = np.radians(deg)
    h = paths.START_HEIGHT
    return FlightPath(np.array([[0.0, 0.0, h], [80 * np.cos(a), 0.0, h + 80 * np.sin(a)]]))


def study(db, refine: int, radii: list[float], climbs: list[float]) -> dict:
    row = {"db": db or "bundled", "refine": refine, "circles": {}, "pushes": {}, "climbs": {}}
    for r in radii:
        for side, sign in (("left", 1.0), ("right", -1.0)):
            circle = paths.inclined_circle(radius_m=r, turns=1.0).points
            path = FlightPath(circle * np.array([1.0, sign, 1.0]))
            t = fly_task(Task(path), db, refine=refine)
            row["circles"][f"{r:g} m {side}"] = t.status == "completed"
    for d, f in PUSHES:
        task = Task(paths.straight(60.0), pushes=(PushSpec(1.0, f, d),), tube_m=10.0)
        t = fly_task(task, db, refine=refine)
        row["pushes"][f"{f:g} N {d}"] = bool(t.ok and task.path.distance(t.positions[-1]) <= 1.5)
    for c in climbs:
        t = fly_task(Task(_climb(c)), db, refine=refine)
        row["climbs"][f"{c:g} deg"] = t.status == "completed"
    return row


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--refine", default="0,2", help="settings to compare (default 0,2)")
    ap.add_argument("--db", default="bundled", help="comma-separated databases (bundled: the bundled one)")
    ap.add_argument("--radii", default="3,4,5,6,8")
    ap.add_argument("--climbs", default="5,7")
    ap.add_argument("--json", default=None)
    a = ap.parse_args()
    rows = []
    for db in a.db.split(","):
        for n in (int(x) for x in a.refine.split(",")):
            row = study(None if db == "bundled" else db, n, [float(x) for x in a.radii.split(",")],
                        [float(x) for x in a.climbs.split(",")])
            rows.append(row)
            parts = [f"{k}: {sum(v.values())} of {len(v)}" for k, v in
                     (("circles", row["circles"]), ("pushes", row["pushes"]), ("climbs", row["climbs"]))]
            followed = [k for k, ok in row["circles"].items() if ok]
            print(f"{row['db']:<24} --refine {n}: {', '.join(parts)}; circles followed: "
                  f"{', '.join(followed) or 'none'}", flush=True)
    if a.json:
        write_json(a.json, {"refine_study": rows})


if __name__ == "__main__":
    main()
