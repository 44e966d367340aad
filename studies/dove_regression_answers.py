"""How well each database's regression answers the requests of tight turns, in one shot.

    python studies/dove_regression_answers.py [--db seed1.db,seed3.db,...] [--json out.json]

The bundled database flies four tight paths (the S of 3.5 m half circles, a 3 m circle and the
paper's 3.6 m circles at 0 and 15 deg); every wingbeat's start state, reference end and target
are logged. Then each database answers each logged request from the same state, with the same
carried base, and the answer is flown once, without corrections. The error is the corrections'
ranking error (the bundled database's weights for all, so that the numbers compare), overall,
without the forward speed (which no wingbeat reaches in a tight turn), and the roll alone.
About a minute a database on one core.
"""

from __future__ import annotations

import argparse

import numpy as np

from flapsim.bird.control import controller as C
from flapsim.bird.flight import cycle
from flapsim.bird.tasks import path_shapes as paths
from flapsim.bird.tasks.flight_tasks import Task, build_flight, fly_task
from flapsim.core.errors import SimulationError
from flapsim.core.io import write_json

FLIGHTS = {"s-curve-3.5": (lambda: paths.s_curve(3.5), 3.0),
           "circle-3-left": (lambda: paths.helix(3.0, 0.0, 1.0), 3.0),
           "climb-turn-0": (lambda: paths.inclined_circle(incline_deg=0.0), 2.0),
           "climb-turn-15": (lambda: paths.inclined_circle(incline_deg=15.0), 2.0)}


class RequestLog:
    """A controller that flies as ``ctl`` does and logs every wingbeat's request: its start, its
    reference end, its target and the carried base (``fly_task``'s ``controller``; every other
    attribute is ``ctl``'s)."""

    def __init__(self, ctl) -> None:
        self.ctl = ctl
        self.log: list[dict] = []

    def __getattr__(self, name: str):
        return getattr(self.ctl, name)

    def choose(self, target, snap=None, record=False, push=None):
        start = snap or cycle.snapshot(self.ctl.flight)
        base = self.ctl.reference_params().copy()

        def logged(e0):
            S_t = np.asarray(target(e0), float)
            self.log.append({"snap": start, "S0": e0.S.copy(), "S_t": S_t.copy(), "base": base,
                             "surplus": float(getattr(target, "speed_surplus", 0.0))})
            return S_t

        return self.ctl.choose(logged, snap, record, push)


def log_requests(ctl) -> list[dict]:
    """Every wingbeat's start, reference end, target and carried base over :data:`FLIGHTS`."""
    logger = RequestLog(ctl)
    for name, (shape, tube) in FLIGHTS.items():
        n0 = len(logger.log)
        r = fly_task(Task(shape(), tube_m=tube), controller=logger)
        for e in logger.log[n0:]:
            e["path"] = name
        print(f"bundled flight {name}: {r.status}, {len(logger.log) - n0} wingbeats logged", flush=True)
    return logger.log


def answer_errors(ctl, fl, log: list[dict], w: np.ndarray) -> dict:
    """Each logged request answered by ``ctl``'s regression and flown once from its state."""
    sw = np.sqrt(np.where(C.REFINE_COMPONENTS, w, 0.0))
    rows = []
    for e in log:
        P, _ = ctl._answer(e["S_t"] - e["S0"], None, e["base"])
        try:
            end = cycle.fly_cycle(fl, e["snap"], P, ctl.ref)
        except SimulationError:
            rows.append(np.full(8, np.nan))
            continue
        rows.append(np.abs(end.S - C.correction_goal(e["S_t"], e["S0"], e["surplus"])) * sw)
    comp = np.array(rows)
    total = np.sqrt(np.sum(comp**2, axis=1))
    no_speed = np.sqrt(np.sum(comp[:, [0, 1, 3, 4]] ** 2, axis=1))
    roll_deg = np.degrees(comp[:, 1] / np.sqrt(w[1]))
    return {"error_median": float(np.nanmedian(total)),
            "error_without_forward_speed_median": float(np.nanmedian(no_speed)),
            "roll_error_deg_median": float(np.nanmedian(roll_deg)),
            "roll_error_deg_p90": float(np.nanpercentile(roll_deg, 90)),
            "component_error_median": [float(x) for x in np.nanmedian(comp, axis=0)[:5]],
            "diverged": int(np.isnan(total).sum())}


def parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--db", default="", help="comma-separated databases to compare with the bundled one")
    ap.add_argument("--json", default=None, help="write the errors per database here")
    return ap


def main(argv: list[str] | None = None) -> None:
    ap = parser()
    a = ap.parse_args(argv)
    fl, ctl = build_flight(Task(paths.helix(4.0, 0.0, 1.0)))
    try:
        log = log_requests(ctl)
        w = ctl.regressor.w
        out = {}
        for db in [None] + [d for d in a.db.split(",") if d]:
            c = C.load_controller(fl, db) if db else ctl
            r = out[db or "bundled"] = answer_errors(c, fl, log, w)
            print(f"{db or 'bundled':<24} error {r['error_median']:.3f} (without forward speed "
                  f"{r['error_without_forward_speed_median']:.3f}); roll off by "
                  f"{r['roll_error_deg_median']:.2f} deg at the median, {r['roll_error_deg_p90']:.2f} "
                  f"at 90 %", flush=True)
    finally:
        fl.close()
    if a.json:
        write_json(a.json, {"requests": len(log), "databases": out})


if __name__ == "__main__":
    main()
