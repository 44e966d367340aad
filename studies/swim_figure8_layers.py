"""How well the swimmer follows the figure of eight, layer by layer (the layered-swimming
paper's Fig. 15 ordering), with continuous-layer settings of your choice.

    python studies/swim_figure8_layers.py --stroke crawl --radius 5 --layers cycle,all
        --set curvature_slowdown=0 --set turn_slowdown=1.5

Prints, per run, the mean / max distance from the path [m], the fraction completed,
the distance swum and the time to complete (as ``flapsim eval`` reports them).
``--set FIELD=VALUE`` sets a field of :class:`flapsim.swim.continuous.HandRuleParams`.
"""

from __future__ import annotations

import argparse
import dataclasses
import json

from flapsim.scenarios import get
from flapsim.swim.continuous import HandRuleParams
from flapsim.swim.goals import figure_eight
from flapsim.swim.per_cycle import load_table
from flapsim.swim.simulate import swim
from flapsim.swim.strokes import load_stroke


def figure8_setup(a: argparse.Namespace) -> tuple:
    """(scenario, loop radius m, seconds, HandRuleParams) from ``--stroke``, ``--radius`` and
    ``--set field=value`` (the run lasts longer in proportion to a larger radius)."""
    sc = get(f"swim-figure8-{a.stroke}")
    r0 = float(sc.params["radius_m"])
    radius = r0 if a.radius is None else a.radius
    seconds = float(sc.params["seconds"]) * max(1.0, radius / r0)
    kw = {}
    for item in a.set:
        k, v = item.split("=", 1)
        kw[k] = float(v)
    return sc, radius, seconds, dataclasses.replace(HandRuleParams(), **kw)


def parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--stroke", default="crawl")
    ap.add_argument("--radius", type=float, default=None, help="loop radius [m] (default: the scenario's)")
    ap.add_argument("--layers", default="cycle,all")
    ap.add_argument("--set", action="append", default=[], help="HandRuleParams field=value")
    ap.add_argument("--table", default=None, help="per-cycle calibration table (default: the stroke's)")
    ap.add_argument("--rules", default=None, help="continuous rules, comma-separated (default both)")
    ap.add_argument("--json", action="store_true")
    return ap


def main(argv: list[str] | None = None) -> None:
    ap = parser()
    a = ap.parse_args(argv)
    sc, radius, seconds, hp = figure8_setup(a)
    for layers in a.layers.split(","):
        table = None
        if a.table and layers != "basic":
            table = load_table(load_stroke(a.stroke), a.table, layers="all" if layers == "all" else "cycle")
        r = swim(a.stroke, seconds, target=figure_eight(radius), layers=layers, hand_params=hp,
                 cycle_table=table, rules=None if a.rules is None else tuple(a.rules.split(",")))
        s = r.summary()  # the figure of eight is a path: its metrics are the distance from it
        row = {"stroke": a.stroke, "radius_m": radius, "layers": layers, "set": a.set, "rules": a.rules,
               "mean_m": s["path_error_mean_m"], "max_m": s["path_error_max_m"],
               "done": s["path_completed_fraction"], "swum_m": s["distance_swum_m"],
               "time_s": s["path_completed_s"]}
        if a.json:
            print(json.dumps(row))
        else:
            print(f"{a.stroke:13s} r={radius:4.1f} {layers:5s} {a.rules or ''} {a.set} "
                  f"mean {row['mean_m']:.2f} "
                  f"max {row['max_m']:.2f} done {row['done']:.2f} swum {row['swum_m']:.1f} "
                  f"t {row['time_s']}")


if __name__ == "__main__":
    main()
