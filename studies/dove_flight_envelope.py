"""What paths the learned dove can follow: level circles of shrinking radius, straight climbs of
growing angle and, if asked, pushes from four sides, each flown once per database and control
configuration and judged as ``flapsim eval`` judges.

    python studies/dove_flight_envelope.py [--db bundled,seed1.db,...] [--config a.toml,b.toml]
        [--feathers rigid|modal] [--speed 7] [--radii 8,10,12,15,20] [--both-ways]
        [--climbs 1,2,3,5] [--pushes 6,8] [--json out.json]

A circle or a climb is followed when the dove reaches its end without leaving the 3 m tube; a
push (``--pushes``: newtons, each from the left, the right, below and behind, at 1 s of a 60 m
straight) is survived when the dove never leaves a 10 m tube and ends within 1.5 m of the path
(the flight suite's rule). ``--both-ways`` flies each circle turning left and, mirrored,
turning right: near the limits a verdict can flip with a few hundredths of a m/s in the speed
asked, so one flight per radius says little.

``--config`` compares control configurations (TOML files with ``[controller]`` and ``[path]``
tables, as ``flapsim eval --config`` reads; ``default``: the dove's defaults; ``flapsim list
config`` prints them): the bank, the angle of attack per g and slowing for tight turns are
``[path]`` keys, the simulated corrections ``[controller]`` ones. To compare the
simulated corrections per wingbeat, for example, write ``refine0.toml`` holding
``[controller]`` / ``refine = 0`` and run ``--config default,refine0.toml --radii 3,4,5,6,8
--both-ways --climbs 5,7 --pushes 6,8``: about 2 minutes a database and configuration on one
core (``refine = 2``, the rigid dove's default, flies ~2x slower than 0).
"""

from __future__ import annotations

import argparse

import numpy as np

from flapsim.bird.control.config import ControllerConfig
from flapsim.bird.tasks.config import PathControlConfig, load_control_config
from flapsim.bird.tasks.flight_tasks import PushSpec, Task, TaskResult, fly_task
from flapsim.bird.tasks.path_control import FlightPath
from flapsim.bird.tasks.path_shapes import START_HEIGHT, inclined_circle, straight
from flapsim.core.io import write_json

#: Push directions flown with ``--pushes``.
PUSH_SIDES = ("left", "right", "down", "back")
#: A pushed flight's tube and the largest distance from the path at its end, m (the suite's).
PUSH_TUBE_M, PUSH_BACK_M = 10.0, 1.5


def climb(angle_deg: float, length_m: float = 80.0) -> FlightPath:
    """A straight climb of ``angle_deg`` from the start height."""
    a = np.radians(angle_deg)
    return FlightPath(np.array([[0.0, 0.0, START_HEIGHT],
                                [length_m * np.cos(a), 0.0, START_HEIGHT + length_m * np.sin(a)]]))


def circle(radius_m: float, side: float = 1.0) -> FlightPath:
    """One level turn of ``radius_m``, to the left (``side`` 1) or mirrored to the right (-1)."""
    return FlightPath(inclined_circle(radius_m=radius_m, turns=1.0).points * np.array([1.0, side, 1.0]))


def fly(task: Task, db: str | None, controls: tuple[ControllerConfig, PathControlConfig]
        ) -> TaskResult:
    """``task`` flown with database ``db`` (None: the bundled one) under the wingbeat and path
    controllers' configurations ``controls``."""
    controller, path_control = controls
    return fly_task(path_control.apply(task), db, config=controller)


def cases(a: argparse.Namespace) -> list[tuple[str, float, Task]]:
    """(kind, value, task) for every flight asked."""
    kw = {"speed": a.speed, "feathers": a.feathers}
    out = []
    for r in _floats(a.radii):
        out.append(("circle", r, Task(circle(r), **kw)))
        if a.both_ways:
            out.append(("circle-right", r, Task(circle(r, -1.0), **kw)))
    out += [("climb", c, Task(climb(c), **kw)) for c in _floats(a.climbs)]
    for f in _floats(a.pushes):
        out += [(f"push-{side}", f, Task(straight(60.0), pushes=(PushSpec(1.0, f, side),),
                                         tube_m=PUSH_TUBE_M, **kw))
                for side in PUSH_SIDES]
    return out


def verdict(kind: str, task: Task, r: TaskResult) -> bool:
    """Followed (a circle or climb) or survived (a push)."""
    if kind.startswith("push"):
        return bool(r.ok and task.path.off_path(r.positions[-1]) <= PUSH_BACK_M)
    return r.ok


def _floats(text: str) -> list[float]:
    return [float(x) for x in text.split(",") if x]


def parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--db", default="bundled",
                    help="comma-separated databases (bundled: the feathers' bundled one)")
    ap.add_argument("--config", default="default",
                    help="comma-separated control configuration files (default: the dove's defaults)")
    ap.add_argument("--feathers", choices=("rigid", "modal"), default="rigid",
                    help="the dove (and, with --db bundled, its bundled database)")
    ap.add_argument("--speed", type=float, default=7.0, help="flight speed asked, m/s (default 7)")
    ap.add_argument("--radii", default="8,10,12,15,20", help="level circles, m")
    ap.add_argument("--both-ways", action="store_true",
                    help="fly each circle turning left and, mirrored, turning right")
    ap.add_argument("--climbs", default="1,2,3,5", help="straight climbs, deg")
    ap.add_argument("--pushes", default="", help="push forces, N, each from four sides (default: none)")
    ap.add_argument("--json", default=None, help="write every flight's verdict here")
    return ap


def main(argv: list[str] | None = None) -> None:
    a = parser().parse_args(argv)
    rows = []
    for db in a.db.split(","):
        for config in a.config.split(","):
            tag = f"{db} {config}"
            controls = load_control_config(None if config == "default" else config, a.feathers)
            for kind, x, task in cases(a):
                r = fly(task, None if db == "bundled" else db, controls)
                ok = verdict(kind, task, r)
                bank = (np.degrees(np.arctan(a.speed**2 / (9.81 * x))) if kind.startswith("circle")
                        else 0.0)
                rows.append({"db": db, "config": config, "kind": kind, "value": x, "speed": a.speed,
                             "bank_needed_deg": bank, "ok": ok, "status": r.status, "reason": r.reason,
                             "max_path_distance": r.metrics.get("max_path_distance"),
                             "Ef_per_wingbeat": r.metrics.get("Ef_per_wingbeat"),
                             "progress_m": r.metrics.get("progress_m"), "length_m": task.path.length})
                what = {"climb": f"climb {x:g} deg", "circle": f"radius {x:g} m (bank {bank:.0f} deg)",
                        "circle-right": f"radius {x:g} m right (bank {bank:.0f} deg)"}.get(
                    kind, f"{x:g} N {kind[5:]}")
                print(f"{tag:<28} {what:<30} {'yes' if ok else 'no':<4} {r.status:<10} largest "
                      f"{rows[-1]['max_path_distance']:.2f} m  {r.reason}", flush=True)
            mine = [x for x in rows if (x["db"], x["config"]) == (db, config)]
            kinds = sorted({x["kind"].split("-")[0] for x in mine})
            print(f"{tag}: " + ", ".join(f"{k} {sum(x['ok'] for x in mine if x['kind'].startswith(k))}"
                                          f" of {sum(x['kind'].startswith(k) for x in mine)}"
                                          for k in kinds), flush=True)
    if a.json:
        write_json(a.json, {"envelope": rows})


if __name__ == "__main__":
    main()
