"""Does a larger time step than the paper's 2400 Hz give the same flight?

    python studies/dove_timestep.py [--wingbeats 10] [--rates 2400,1600,1200,800,600]
        [--json out.json]

Flies the base controller from the standard cruise start at several step rates and
compares the trunk trajectory with the first rate's (2400 Hz) at the same times. A rate
passes when its 10-wingbeat trajectory stays within 2 cm. Also reports the speed-up.
"""

from __future__ import annotations

import argparse
import dataclasses
import json

import numpy as np

from flapsim.bird.body.model import Dove
from flapsim.bird.body.params import DoveParams
from flapsim.bird.flight.dove_flight import flight_metrics, fly
from flapsim.core.io import write_json


def parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--wingbeats", type=int, default=10, help="wingbeats flown at each rate")
    ap.add_argument("--rates", default="2400,1600,1200,800,600",
                    help="step rates, Hz; the first is the reference")
    ap.add_argument("--json", default=None, help="write every run here")
    return ap


def main(argv: list[str] | None = None) -> None:
    ap = parser()
    args = ap.parse_args(argv)
    base = DoveParams.load()
    rates = [float(r) for r in args.rates.split(",")]
    runs = {}
    for rate in rates:
        params = dataclasses.replace(base, timestep=1.0 / rate)
        dove = Dove.from_params(params)
        try:
            f = fly(dove, args.wingbeats)
            runs[rate] = (f, flight_metrics(f))
        except Exception as exc:  # noqa: BLE001 - a diverging step rate is a result here
            runs[rate] = (None, {"error": f"{type(exc).__name__}: {exc}"})
    ref_f = runs[rates[0]][0]
    rows = []
    for rate in rates:
        f, met = runs[rate]
        row = {"rate_hz": rate, **{k: met.get(k) for k in ("mean_speed", "max_vertical_deviation",
                                                            "mean_lift_per_weight",
                                                            "real_time_factor", "error")}}
        if f is not None and ref_f is not None:
            t_end = min(f.time[-1], ref_f.time[-1])
            sel = ref_f.time <= t_end
            interp = np.stack([np.interp(ref_f.time[sel], f.time, f.trunk_pos[:, i])
                               for i in range(3)], axis=1)
            row["max_trajectory_difference_m"] = float(
                np.linalg.norm(interp - ref_f.trunk_pos[sel], axis=1).max())
            row["same_within_2cm"] = row["max_trajectory_difference_m"] <= 0.02
        rows.append(row)
        print(json.dumps(row))
    if args.json:
        write_json(args.json, {"wingbeats": args.wingbeats, "runs": rows})


if __name__ == "__main__":
    main()
