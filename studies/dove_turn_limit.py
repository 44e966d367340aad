"""The tightest level turn and the steepest climb the dove's wing can sustain: a grid of
wingbeats (shoulder-flap scale, beat rate, shoulder twist) around the reference wingbeat,
each kept only if the dove flies it within its joint ranges (the database's acceptance
rule), flown in the fixed-trunk tunnel at a grid of pitches and speeds
(:mod:`flapsim.bird.flight.limits`). Prints, per speed, the largest load factor held at constant
speed, its turn radius (with that wingbeat's joint-range excess and its untrimmed pitch
moment: moment balance is not asked) and the steepest climb, and how many wingbeats stayed
within their ranges.

    python studies/dove_turn_limit.py [--workers 2] [--json limits.json]
"""

from __future__ import annotations

import argparse
import time
from concurrent.futures import ProcessPoolExecutor
from dataclasses import asdict

import numpy as np

from flapsim.bird.flight.limits import Candidate, best_sustained, load_factor_for_radius, search
from flapsim.core.io import write_json


def _floats(s: str) -> list[float]:
    return [float(x) for x in s.split(",")]


def _one_speed(job):
    cands, v, pitches = job
    return search(cands, [v], pitches)


def parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--speeds", default="5,6,7,8", help="m/s")
    ap.add_argument("--pitches", default="0,5,10,15,20", help="trunk pitch in the tunnel, deg")
    ap.add_argument("--flap", default="0.9,1.0,1.05,1.1,1.15,1.2", help="shoulder-flap scales")
    ap.add_argument("--timewarp", default="0.85,0.9,0.95,1.0", help="cycle durations over P0's")
    ap.add_argument("--twist", default="-6,-3,0,3", help="shoulder twist translations, deg")
    ap.add_argument("--thrust-floors", default="0,-0.05",
                    help="thrust - drag over the weight a wingbeat must keep to count as held "
                         "(0: constant speed; the reference cruise runs at -0.025..-0.05)")
    ap.add_argument("--workers", type=int, default=2, help="processes (one speed each)")
    ap.add_argument("--json", default=None, help="write the grid, the bests and every point here")
    return ap


def main(argv: list[str] | None = None) -> None:
    ap = parser()
    a = ap.parse_args(argv)
    cands = [Candidate(f, w, t) for f in _floats(a.flap) for w in _floats(a.timewarp)
             for t in _floats(a.twist)]
    speeds, pitches = _floats(a.speeds), _floats(a.pitches)
    t0 = time.perf_counter()
    with ProcessPoolExecutor(a.workers) as ex:
        points = [p for part in ex.map(_one_speed, [(cands, v, pitches) for v in speeds])
                  for p in part]
    wall = time.perf_counter() - t0
    print(f"{len(cands)} wingbeats x {len(speeds)} speeds x {len(pitches)} pitches in {wall:.0f} s")
    bests = [best_sustained(points, f) for f in _floats(a.thrust_floors)]
    for best in bests:
        _report(best, len(cands), speeds)
    if a.json:
        write_json(a.json, {"grid": {"speeds": speeds, "pitches_deg": pitches,
                                     "candidates": [asdict(c) for c in cands]},
                            "wall_s": wall, "best": bests,
                            "points": [asdict(p) for p in points
                                       if np.isfinite(p.lift_per_weight)]})


def _report(best: dict, n_cands: int, speeds: list[float]) -> None:
    print(f"held with thrust - drag >= {best['thrust_floor']:+.2f} of the weight:")
    print(f"{'speed':>6} {'in range':>9} {'max n held':>11} {'turn r':>8} "
          f"{'wingbeat (flap, w, twist, pitch)':>34} {'excess':>7} {'moment':>8} {'climb':>7}")
    for r in best["per_speed"]:
        tw = r["turn_wingbeat"]
        what = (f"{tw['flap_scale']:.2f}, {tw['timewarp']:.2f}, {tw['twist_deg']:+.0f}, "
                f"{tw['pitch_deg']:.0f} deg" if tw else "-")
        n = f"{r['max_load_factor']:.2f}" if r["max_load_factor"] else "-"
        rad = f"{r['tightest_turn_m']:.1f} m" if r["tightest_turn_m"] else "-"
        climb = f"{r['steepest_climb_deg']:+.1f}" if r["steepest_climb_deg"] is not None else "-"
        ex = f"{tw['range_excess_deg']:.1f} deg" if tw else "-"
        mo = f"{tw['pitch_moment'] * 1e3:+.0f} mN m" if tw else "-"
        print(f"{r['speed']:>6.1f} {r['wingbeats_in_range']:>5}/{n_cands:<3} {n:>11} {rad:>8} "
              f"{what:>34} {ex:>7} {mo:>8} {climb:>7}")
    if best["tightest_turn_m"]:
        print(f"tightest sustained level turn: {best['tightest_turn_m']:.1f} m at "
              f"{best['tightest_turn_speed']:g} m/s; a 3 m turn needs "
              + ", ".join(f"{load_factor_for_radius(3.0, v):.2f} g at {v:g} m/s" for v in speeds))


if __name__ == "__main__":
    main()
