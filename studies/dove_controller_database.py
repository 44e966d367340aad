"""How well a controller database flies the dove: cruise, one-wingbeat steering, steering range.

    python studies/dove_controller_database.py DB [--method lwlr|knn] [--k K]
        [--states 20] [--wingbeats 100] [--skip cruise,table,range] [--json out.json]

* cruise: ``--wingbeats`` wingbeats from a 2 deg roll error holding altitude, 7 m/s and
  heading (a database passes within 0.5 m, 0.5 m/s and 5 deg);
* the one-wingbeat steering table: alpha in {-8, 0, 8} deg x beta in {-5, 0, 5} deg from
  ``--states`` start states (near cruise, or phase-1 random with ``--start random``), the
  controller's state error against the base controller's (P0 from the same state), and the
  steering/elevation achieved;
* the sustained steering range per wingbeat (asked +-30 deg per wingbeat for 12 beats).
"""

from __future__ import annotations

import argparse
import json

import numpy as np

from flapsim.bird.body.model import Dove
from flapsim.bird.control.controller import cruise_metrics, fly_controlled, load_controller, start_cruise
from flapsim.bird.control.database import load_database, read_header
from flapsim.bird.control.targets import CruiseTarget, fit_steering_signature, trim_of_base_flight
from flapsim.bird.flight.dove_flight import DoveFlight
from flapsim.bird.training.sampling import SampleWorker, SamplingConfig
from flapsim.bird.training.steering import steering_range, steering_table
from flapsim.core.io import write_json


def parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("db", help="the controller database (.db) to evaluate")
    ap.add_argument("--method", default="lwlr", choices=("knn", "lwlr"), help="the regression")
    ap.add_argument("--k", type=int, default=None, help="neighbours (default: the controller's)")
    ap.add_argument("--states", type=int, default=20, help="start states per steering command")
    ap.add_argument("--wingbeats", type=int, default=100, help="wingbeats of the cruise")
    ap.add_argument("--target", default="turn", choices=("path", "turn", "signature"),
                    help="one-wingbeat command: a coordinated turn (default), turn the flight path, "
                         "or the database's steering signature S0 + D (alpha, beta)")
    ap.add_argument("--start", default="cruise", choices=("cruise", "random"),
                    help="one-wingbeat start states: near cruise (default) or phase-1 random")
    ap.add_argument("--skip", default="", help="comma list of parts to skip: cruise,table,range")
    ap.add_argument("--json", default=None, help="write every number here")
    return ap


def main(argv: list[str] | None = None) -> None:
    ap = parser()
    a = ap.parse_args(argv)
    skip = set(filter(None, a.skip.split(",")))
    out: dict = {"db": a.db, "method": a.method}
    dove = Dove.load()
    fl = DoveFlight(dove)
    ctl = load_controller(fl, a.db, method=a.method, k=a.k)
    out["samples"], out["k"] = ctl.regressor.n, ctl.regressor.k
    trim = trim_of_base_flight(fl, ctl.P0)
    print(f"{a.db}: {ctl.regressor.n} samples, {a.method}, k = {ctl.regressor.k}")
    if "cruise" not in skip:
        start_cruise(fl, ctl.P0, roll_deg=2.0)
        tgt = CruiseTarget(trim, altitude=10.0)
        m = cruise_metrics(fly_controlled(ctl, tgt, a.wingbeats), tgt)
        out["cruise"] = m
        print(f"cruise {a.wingbeats} wingbeats from 2 deg roll: "
              f"altitude {m['max_altitude_deviation']:.2f} m, "
              f"speed {m['max_speed_deviation']:.2f} m/s, heading {m['max_heading_deviation_deg']:.1f} "
              f"deg, roll <= {m['max_abs_roll_deg']:.1f} deg")
    if "table" not in skip:
        cfg = read_header(a.db).get("config") or {}
        sampler = SampleWorker(SamplingConfig.from_dict({**cfg, "source": "capture",
                                                         "extrapolate": 0.0}))
        cmds = [(al, be) for al in (-8.0, 0.0, 8.0) for be in (-5.0, 0.0, 5.0)]
        arr = load_database(a.db).arrays
        D = fit_steering_signature(arr["dS"], arr["alpha"], arr["beta"])
        rows = steering_table(ctl, sampler, trim, cmds, n_states=a.states, target=a.target,
                              start=a.start, signature=D)
        sampler.close()
        out["steering_table"] = [r.__dict__ for r in rows]
        print("| alpha deg | beta deg | error controller | error base | better | error (db metric) "
              "controller / base | achieved alpha | achieved beta |")
        print("|---|---|---|---|---|---|---|---|")
        for r in rows:
            print(f"| {r.alpha_deg:+.0f} | {r.beta_deg:+.0f} | {r.error_controller:.3f} | "
                  f"{r.error_base:.3f} | {r.better:.0%} | {r.error_controller_db:.2f} / "
                  f"{r.error_base_db:.2f} | {r.achieved_alpha_deg:+.2f} | {r.achieved_beta_deg:+.2f} |")
        ec = np.mean([r.error_controller for r in rows])
        eb = np.mean([r.error_base for r in rows])
        ecn = np.mean([r.error_controller_db for r in rows])
        ebn = np.mean([r.error_base_db for r in rows])
        out["steering_mean_error"] = {"controller": ec, "base": eb, "controller_db_metric": ecn,
                                      "base_db_metric": ebn}
        print(f"mean state error: controller {ec:.3f}, base {eb:.3f} (paper W, SI units); "
              f"{ecn:.2f} vs {ebn:.2f} in the database metric")
    if "range" not in skip:
        r = steering_range(ctl, trim)
        out["steering_range"] = r
        print(f"sustained steering per wingbeat: {r['range_deg'][0]:+.1f} .. {r['range_deg'][1]:+.1f} "
              f"deg (in control: right {r['right']['in_control']}, left {r['left']['in_control']})")
    fl.close()
    if a.json:
        write_json(a.json, out)
    print(json.dumps({k: v for k, v in out.items() if k in ("samples", "k")}))


if __name__ == "__main__":
    main()
