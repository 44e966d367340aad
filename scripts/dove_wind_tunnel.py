"""Fixed-trunk "wind tunnel": cycle-averaged lift/weight, thrust-drag and pitch moment of
the reference wingbeat (+17 deg tail bias) in a 5-9 m/s headwind, per coefficient table.

    PYTHONPATH=. python scripts/dove_wind_tunnel.py [--json out.json]

Measure weight support here before free flight (REFERENCE_DATA). Thrust > 0 means the
flapping wings out-pull their own drag; the trunk has no drag polygons (as in the paper,
which computes aerodynamics on feathers only).
"""

from __future__ import annotations

import argparse
import dataclasses

from flapsim.bird.flight import wind_tunnel
from flapsim.bird.model import DoveParams
from flapsim.bird.wingbeat import p0, with_tail_bias

TABLES = ("dickinson1999_lowdrag", "dickinson1999", "wang2004", "feather_stall", "flat_plate")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--speeds", default="5,6,7,8,9")
    ap.add_argument("--pitches", default="0,5,10")
    ap.add_argument("--tables", default=",".join(TABLES))
    ap.add_argument("--json", default=None)
    args = ap.parse_args()
    params = DoveParams.load()
    p = with_tail_bias(p0(), 17.0)
    rows = []
    for table in args.tables.split(","):
        print(f"table {table}")
        for pitch in (float(x) for x in args.pitches.split(",")):
            cells = []
            for speed in (float(x) for x in args.speeds.split(",")):
                r = wind_tunnel(params, p, speed, pitch, cycles=3, table=table)
                rows.append({"table": table, **dataclasses.asdict(r)})
                cells.append(f"{speed:.0f} m/s L/W {r.lift_per_weight:4.2f} T/W "
                             f"{r.thrust_per_weight:+.2f} M {1e3 * r.pitch_moment:+5.1f} mNm")
            print(f"  pitch {pitch:4.1f} deg: " + " | ".join(cells))
        print(f"  upstroke/downstroke projected feather area {rows[-1]['upstroke_area_ratio']:.2f}")
    if args.json:
        from flapsim.io import write_json

        write_json(args.json, {"wingbeat": "P0 + 17 deg tail bias", "runs": rows})


if __name__ == "__main__":
    main()
