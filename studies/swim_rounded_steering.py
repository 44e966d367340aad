"""How well a crawl steers: held to a heading 45 deg to each side, holding the start
heading, and through the swim scenarios, on the rounded body by default.

    python studies/swim_rounded_steering.py                      # the rounded crawl
    python studies/swim_rounded_steering.py --body box           # the box crawl
    python studies/swim_rounded_steering.py --stroke old.toml    # another crawl file (its
                                                                 # table beside it)

Prints, with all layers unless ``--layers`` says otherwise:

* per heading asked (+45, -45 deg): the mean |heading error| of the body line (pelvis to
  head, what ``flapsim swim`` reports) over the last 10 s of the swim, and the error of the
  track's direction there (the centre of mass's displacement over those 10 s: a bent neck
  moves the body line, not the track);
* holding the start heading: the sideways drift at the end and the largest one, the
  speed after two cycles, the muscle power, the roll of the shoulders and hips;
* per scenario (``--scenarios``; ``none`` skips them): the mean / max distance from the
  target or path [m], how much of a path was done, the mean distance after a circling
  target was reached (as ``flapsim eval --body BODY`` reports them).
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math

import numpy as np

from flapsim.scenarios import EvalOptions, get
from flapsim.swim.goals import Heading
from flapsim.swim.model import SwimmerParams
from flapsim.swim.simulate import swim
from flapsim.swim.strokes import stroke_for_body

SCENARIOS = ("swim-figure8-crawl", "swim-cross-current", "swim-trajectory",
             "swim-moving-target", "swim-circling-target")
#: the last part of a heading swim that is judged [s] (the turn to 45 deg takes ~10 s)
JUDGED_S = 10.0


def heading_errors(r: object, heading: float) -> tuple[float, float]:
    """(body line's mean |error|, the track's |error|) [deg] over the last
    :data:`JUDGED_S` of swim ``r`` held to ``heading`` [rad]."""
    sel = r.times >= r.times[-1] - JUDGED_S
    body = np.abs((heading - r.body_yaw[sel] + math.pi) % (2 * math.pi) - math.pi)
    d = r.com[sel][-1, :2] - r.com[sel][0, :2]
    track = abs((heading - math.atan2(d[1], d[0]) + math.pi) % (2 * math.pi) - math.pi)
    return math.degrees(float(body.mean())), math.degrees(track)


def parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--stroke", default="crawl",
                    help="crawl (the body's own tuning) or a stroke .toml file")
    ap.add_argument("--body", choices=("box", "rounded"), default="rounded")
    ap.add_argument("--layers", choices=("basic", "cycle", "all"), default="all")
    ap.add_argument("--seconds", type=float, default=30.0, help="each heading swim [s]")
    ap.add_argument("--heading", type=float, default=45.0, help="heading asked, +- [deg]")
    ap.add_argument("--scenarios", default=",".join(SCENARIOS),
                    help="comma-separated scenario names, or 'none'")
    ap.add_argument("--json", default=None, metavar="PATH", help="write the rows as JSON")
    return ap


def main(argv: list[str] | None = None) -> None:
    a = parser().parse_args(argv)
    stroke = stroke_for_body(a.stroke, a.body)
    params = SwimmerParams(body_shape=a.body)
    out: dict = {"stroke": stroke, "body": a.body, "layers": a.layers, "headings": []}
    for deg in (a.heading, -a.heading):
        r = swim(stroke, a.seconds, params=params, target=Heading(math.radians(deg)),
                 layers=a.layers)
        body, track = heading_errors(r, math.radians(deg))
        out["headings"].append({"heading_deg": deg, "body_line_error_deg": body,
                                "track_error_deg": track})
        print(f"heading {deg:+5.1f} deg: last {JUDGED_S:g} s body line off by {body:5.1f} deg "
              f"(mean), track {track:5.1f} deg")
    r = swim(stroke, a.seconds, params=params, target=Heading(0.0), layers=a.layers)
    s = r.summary()
    y = r.com[:, 1] - r.com[0, 1]
    hold = {"drift_end_m": float(y[-1]), "drift_max_m": float(np.abs(y).max()),
            "speed_m_s": s["speed_m_s"], "muscle_power_w": s["muscle_power_mean_w"],
            "roll_shoulders_deg": s["roll_shoulders_deg"], "roll_hips_deg": s["roll_hips_deg"]}
    out["hold"] = hold
    print(f"start heading held: drift {hold['drift_end_m']:+.2f} m at the end "
          f"({hold['drift_max_m']:.2f} max), {hold['speed_m_s']:.3f} m/s, "
          f"{hold['muscle_power_w']:.0f} W, roll shoulders / hips {hold['roll_shoulders_deg']:.0f}"
          f" / {hold['roll_hips_deg']:.0f} deg")
    opt = EvalOptions(layers=a.layers, body=a.body)
    out["scenarios"] = []
    for name in ([] if a.scenarios == "none" else a.scenarios.split(",")):
        sc = get(name)
        if a.stroke != "crawl":  # the same task swum with the stroke file given
            sc = dataclasses.replace(sc, params={**sc.params, "stroke": a.stroke})
        res = sc.runner(sc, opt)
        m = res["metrics"]
        row = {"scenario": name, "status": res["status"],
               "mean_m": m.get("distance_to_target_mean_m"),
               "max_m": m.get("distance_to_target_max_m"),
               "done": m.get("path_completed_fraction"),
               "after_reached_mean_m": m.get("distance_after_reached_mean_m")}
        out["scenarios"].append(row)
        extra = "" if row["done"] is None else f", {100 * row['done']:.0f}% done"
        if row["after_reached_mean_m"] is not None:
            extra += f", {row['after_reached_mean_m']:.2f} m after reaching it"
        print(f"{name:22s} {res['status']:9s} mean {row['mean_m']:.2f} m, max {row['max_m']:.2f} m"
              f"{extra}")
    if a.json:
        with open(a.json, "w") as f:
            json.dump(out, f, indent=1)


if __name__ == "__main__":
    main()
