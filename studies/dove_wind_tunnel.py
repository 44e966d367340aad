"""Fixed-trunk "wind tunnel": cycle-averaged lift/weight, thrust-drag, pitch moment and
lift-to-drag ratio of the reference wingbeat (+17 deg tail bias) in a headwind, per
coefficient table; and each table's static L/D at 10, 20, 30 deg.

    python studies/dove_wind_tunnel.py [--json out.json]

Measure weight support here before free flight (REFERENCE_DATA). Thrust > 0 means the
flapping wings out-pull their own drag and the body's (the trunk carries bluff-body drag
polygons, ``flapsim.bird.flight.dove_flight.body_polygons``).

Cycle L/D: the lift terms over the drag terms of every feather polygon, as magnitudes
summed over the last cycle (``sum |L_i| / sum |D_i|``): the force-weighted mean L/D the
feathers work at, comparable with a table's static CL/CD.
"""

from __future__ import annotations

import argparse

import mujoco
import numpy as np

from flapsim.bird.body.model import Dove, build_xml
from flapsim.bird.body.params import DoveParams
from flapsim.bird.flight.dove_flight import BODY_TABLE, DoveFlight, FlightConfig, wind_tunnel
from flapsim.bird.flight.wingbeat import control_table, p0, reference_wingbeat, with_tail_bias
from flapsim.core.io import write_json
from flapsim.core.loading import load_model
from flapsim.fluid.coefficients import get_table

TABLES = ("dickinson1999_profile", "dickinson1999_lowdrag", "dickinson1999", "wang2004",
          "feather_stall", "flat_plate")


def cycle_lift_to_drag(params: DoveParams, p: np.ndarray, speed: float, pitch_deg: float,
                       table: str, cycles: int = 3) -> float:
    """Feathers' sum |lift| / sum |drag| over the last of ``cycles`` wingbeats, welded trunk
    (the same set-up as :func:`flapsim.bird.flight.dove_flight.wind_tunnel`)."""
    model = load_model(build_xml(params, fixed_trunk_pitch_deg=pitch_deg), is_xml=True)
    fl = DoveFlight(Dove.from_model(model, params), reference_wingbeat(), table,
                    (-speed, 0.0, 0.0), use_rollout=False)
    try:
        fl.reset(FlightConfig(speed=0.0), p)
        m, d = fl.model, fl.data
        ctrl, _, _ = control_table(fl.ref, p, m.opt.timestep, fl.kp, fl.kv)
        for _ in range(cycles - 1):
            for k in range(len(ctrl)):
                d.ctrl[:] = ctrl[k]
                mujoco.mj_step(m, d)
        feathers = fl.polygons.table != BODY_TABLE
        lift = drag = 0.0
        for k in range(len(ctrl)):
            d.ctrl[:] = ctrl[k]
            mujoco.mj_step(m, d)
            rep = fl.aero.evaluate(d)
            lift += float(np.linalg.norm(rep.lift[feathers], axis=1).sum())
            drag += float(np.linalg.norm(rep.drag[feathers], axis=1).sum())
        return lift / drag
    finally:
        fl.close()


def parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--speeds", default="6,7,8", help="headwinds, m/s")
    ap.add_argument("--pitches", default="0,5,10", help="trunk pitches, deg")
    ap.add_argument("--tables", default=",".join(TABLES), help="coefficient tables (default: all six)")
    ap.add_argument("--json", default=None, help="write every run here")
    return ap


def main(argv: list[str] | None = None) -> None:
    ap = parser()
    args = ap.parse_args(argv)
    params = DoveParams.load()
    p = with_tail_bias(p0(), 17.0)
    rows = []
    for table in args.tables.split(","):
        t = get_table(table)
        static = {f"{a}": float(np.divide(*t.at(float(a)))) for a in (10, 20, 30)}
        print(f"table {table}: static L/D " + ", ".join(f"{a} deg {v:.2f}"
                                                        for a, v in static.items()))
        for pitch in (float(x) for x in args.pitches.split(",")):
            cells = []
            for speed in (float(x) for x in args.speeds.split(",")):
                r = wind_tunnel(params, p, speed, pitch, cycles=3, table=table)
                ld = cycle_lift_to_drag(params, p, speed, pitch, table)
                rows.append({"table": table, "speed": speed, "pitch_deg": pitch,
                             "lift_per_weight": r.lift_per_weight,
                             "thrust_per_weight": r.thrust_per_weight,
                             "pitch_moment": r.pitch_moment, "cycle_lift_to_drag": ld,
                             "upstroke_area_ratio": r.upstroke_area_ratio,
                             "static_lift_to_drag": static})
                cells.append(f"{speed:.0f} m/s L/W {r.lift_per_weight:4.2f} T/W "
                             f"{r.thrust_per_weight:+.2f} L/D {ld:4.2f}")
            print(f"  pitch {pitch:4.1f} deg: " + " | ".join(cells))
    if args.json:
        write_json(args.json, {"wingbeat": "P0 + 17 deg tail bias", "runs": rows})


if __name__ == "__main__":
    main()
