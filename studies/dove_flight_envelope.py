"""What paths the learned dove can follow: level circles of shrinking radius and straight
climbs of growing angle, each flown once with the bundled database (or --db), judged as
``flapsim eval`` judges (lost = farther than 3 m from the path).

    python studies/dove_flight_envelope.py [--db DB] [--feathers modal] [--speed V]
        [--aoa-per-g DEG] [--turn-g N [--turn-speed-floor V]] [--both-ways] [--json out.json]

``--both-ways`` flies each circle turning left and its mirror image turning right: near the
controller's limits a verdict can flip with a change of a few hundredths of a m/s in the speed
asked, so one flight per radius says little.
"""

from __future__ import annotations

import argparse

import numpy as np

from flapsim.bird.tasks.flight_tasks import Task, fly_task
from flapsim.bird.tasks.path_control import FlightPath
from flapsim.bird.tasks.path_shapes import START_HEIGHT, inclined_circle
from flapsim.core.io import write_json


def climb(angle_deg: float, length_m: float = 80.0) -> FlightPath:
    a = np.radians(angle_deg)
    return FlightPath(np.array([[0.0, 0.0, START_HEIGHT],
                                [length_m * np.cos(a), 0.0, START_HEIGHT + length_m * np.sin(a)]]))


def parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--db", default=None)
    ap.add_argument("--radii", default="8,10,12,15,20")
    ap.add_argument("--climbs", default="1,2,3,5")
    ap.add_argument("--speed", type=float, default=7.0, help="flight speed asked, m/s (default 7)")
    ap.add_argument("--aoa-per-g", type=float, default=None, metavar="DEG",
                    help="the path target's extra angle of attack per g (default: the dove's, "
                         "30 rigid, 0 modal)")
    ap.add_argument("--turn-g", type=float, default=0.0, metavar="N",
                    help="slow down ahead of turns needing more than N g (default 0: never)")
    ap.add_argument("--turn-speed-floor", type=float, default=None, metavar="V",
                    help="with --turn-g, the lowest speed asked, m/s (default 6.5)")
    ap.add_argument("--both-ways", action="store_true",
                    help="fly each circle turning left and, mirrored, turning right")
    ap.add_argument("--json", default=None)
    ap.add_argument("--feathers", choices=("rigid", "modal"), default="rigid",
                    help="the dove (and, without --db, its bundled database)")
    return ap


def main(argv: list[str] | None = None) -> None:
    ap = parser()
    a = ap.parse_args(argv)
    rows = []
    cases = [("circle", float(r)) for r in a.radii.split(",")]
    if a.both_ways:
        cases += [("circle-right", float(r)) for r in a.radii.split(",")]
    cases += [("climb", float(c)) for c in a.climbs.split(",")]
    for kind, x in cases:
        if kind == "climb":
            path = climb(x)
        else:
            path = inclined_circle(radius_m=x, turns=1.0)
            if kind == "circle-right":
                path = FlightPath(path.points * np.array([1.0, -1.0, 1.0]))
        r = fly_task(Task(path, speed=a.speed, feathers=a.feathers, aoa_per_g_deg=a.aoa_per_g,
                          turn_load_factor=a.turn_g, turn_speed_floor=a.turn_speed_floor), a.db)
        m = r.metrics
        bank = np.degrees(np.arctan(a.speed ** 2 / (9.81 * x))) if kind != "climb" else 0.0
        row = {"kind": kind, "value": x, "speed": a.speed, "turn_g": a.turn_g, "bank_needed_deg": bank,
               "status": r.status,
               "reason": r.reason, "max_path_distance": m.get("max_path_distance"),
               "Ef_per_wingbeat": m.get("Ef_per_wingbeat"), "progress_m": m["progress_m"],
               "length_m": path.length}
        rows.append(row)
        what = (f"climb {x:g} deg" if kind == "climb"
                else f"radius {x:g} m{' right' if kind == 'circle-right' else ''} (bank {bank:.0f} deg)")
        print(f"{what:<28} {r.status:<10} max {row['max_path_distance']:.2f} m, "
              f"{row['progress_m']:.0f}/{path.length:.0f} m  {r.reason}", flush=True)
    if a.json:
        write_json(a.json, {"envelope": rows})


if __name__ == "__main__":
    main()
