"""How little power a trimmed wingbeat needs under a given wing model: a search over a
symmetric change of the reference wingbeat (flap amplitude and offset, shoulder and elbow
pronation, the hand's twist amplitude, wrist amplitude, tail bend, wingbeat rate) for the
least servo power at which the free-flying dove holds its height and speed.

Each candidate is projected into the joint ranges and flown free from the cruise start
(``flapsim.bird.flight.power.wingbeat_balance``); its cost is the servos' mean power plus
30 W per m/s of climb or sink and 6 W per m/s^2 of speed change (a trimmed wingbeat pays
nothing extra). The best is then measured by ``power_budget`` (lift/weight, the share of
the feathers' dissipation at 30-60 deg angle of attack, cost of transport).

    python studies/dove_trim_power.py --table bird_wing --induced --speed 8.5 --json trim.json
    python studies/dove_trim_power.py --cruise --speed 7 --json trim7.json   # the cruise dove
    python studies/dove_trim_power.py --induced --tail-bias-deg 35 --speed 5 --climb-target 2.5 \
        --bound flap_scale=0.5:2 --bound timewarp=0.7:1.8   # the least power of a steady climb

``--climb-target V`` asks a steady climb of V m/s instead of level flight (the climb's cost
counts from V).
"""

from __future__ import annotations

import argparse
import time
from collections.abc import Sequence

import numpy as np
from scipy.optimize import differential_evolution

from flapsim.bird.body.model import Dove
from flapsim.bird.body.params import DOF_NAMES, dof_ranges
from flapsim.bird.flight.dove_flight import CRUISE, DoveFlight, FlightConfig
from flapsim.bird.flight.power import power_budget, wingbeat_balance
from flapsim.bird.flight.wingbeat import p0, project_to_ranges, reference_wingbeat, with_tail_bias
from flapsim.core.io import write_json

#: (name, DOF on both sides or the tail, "scale" or "offset", low, high); offsets in deg
KNOBS = (
    ("flap_scale", "shoulder_flap", "scale", 0.5, 1.3),
    ("flap_offset_deg", "shoulder_flap", "offset", -20.0, 20.0),
    ("shoulder_pronation_deg", "shoulder_twist", "offset", -30.0, 40.0),
    ("elbow_pronation_deg", "elbow_twist", "offset", -30.0, 40.0),
    ("hand_twist_scale", "elbow_twist", "scale", 0.0, 2.5),
    ("wrist_scale", "wrist_flex", "scale", 0.3, 1.5),
    ("tail_bend_deg", "tail_bend", "offset", -15.0, 25.0),
    ("timewarp", None, "timewarp", 0.8, 1.3),
)


def parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--table", default="bird_wing", help="feather coefficient table")
    ap.add_argument("--induced", action="store_true", help="wings see their own downwash")
    ap.add_argument("--cruise", action="store_true",
                    help="around the cruise dove's wingbeat (the cruise capture's reference and "
                         "tail bias, bird-wing section, induced flow) instead of the paper's")
    ap.add_argument("--speed", type=float, default=8.5, help="cruise start speed, m/s")
    ap.add_argument("--wingbeats", type=int, default=8, help="wingbeats flown per candidate")
    ap.add_argument("--skip", type=int, default=3, help="wingbeats flown before measuring")
    ap.add_argument("--maxiter", type=int, default=25, help="differential-evolution generations")
    ap.add_argument("--popsize", type=int, default=8, help="population per parameter")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--climb-weight", type=float, default=30.0,
                    help="W added per m/s of climb or sink (default 30)")
    ap.add_argument("--climb-target", type=float, default=0.0,
                    help="the steady climb asked, m/s (default 0: level)")
    ap.add_argument("--tail-bias-deg", type=float, default=None,
                    help="the paper's dove's tail bias (default 17; --cruise: its own 26)")
    ap.add_argument("--trim-weight", type=float, default=6.0,
                    help="W added per m/s^2 of speed change (default 6: a wingbeat slowing "
                         "0.1 m/s^2 may save 0.6 W; 20 holds the speed)")
    ap.add_argument("--bound", action="append", default=[], metavar="KNOB=LO:HI",
                    help="a knob's search range instead of the default (repeatable), e.g. "
                         "flap_offset_deg=-30:20; every wingbeat is still projected into the "
                         "joint ranges")
    ap.add_argument("--json", help="write the best wingbeat and its budget here")
    return ap


def wingbeat(x: np.ndarray, lo: np.ndarray, hi: np.ndarray, ref, bias: float = 17.0) -> np.ndarray:
    """The 29-number wingbeat of knob values ``x`` (tail bias ``bias`` deg under the tail knob)."""
    p = with_tail_bias(p0(), bias)
    for (_, dof, kind, _, _), v in zip(KNOBS, x, strict=True):
        if kind == "timewarp":
            p[-1] = v
            continue
        names = [dof] if dof == "tail_bend" else [f"l_{dof}", f"r_{dof}"]
        for n in names:
            i = DOF_NAMES.index(n)
            if kind == "scale":
                p[2 * i] = v
            else:
                p[2 * i + 1] += np.radians(v)
    return project_to_ranges(ref, p, lo, hi)


def knob_bounds(overrides: Sequence[str]) -> list[tuple[float, float]]:
    """Each knob's (low, high), with ``NAME=LO:HI`` overrides."""
    bounds = {k[0]: (k[3], k[4]) for k in KNOBS}
    for item in overrides:
        name, _, rng = item.partition("=")
        lo_s, _, hi_s = rng.partition(":")
        if name not in bounds:
            raise SystemExit(f"--bound: no knob {name!r} (knobs: {', '.join(bounds)})")
        try:
            lo_v, hi_v = float(lo_s), float(hi_s)
        except ValueError:
            raise SystemExit(f"--bound {item!r}: write NAME=LO:HI with numbers") from None
        if not lo_v < hi_v:
            raise SystemExit(f"--bound {item!r}: LO must be below HI")
        bounds[name] = (lo_v, hi_v)
    return [bounds[k[0]] for k in KNOBS]


def main(argv: Sequence[str] | None = None) -> int:
    args = parser().parse_args(argv)
    bounds = knob_bounds(args.bound)
    if args.cruise:
        args.table, args.induced = CRUISE.table, True
    if args.cruise and args.tail_bias_deg is not None:
        raise SystemExit("--cruise has its own tail bias: leave out --tail-bias-deg")
    bias = CRUISE.tail_bias_deg if args.cruise else (
        FlightConfig.tail_bias_deg if args.tail_bias_deg is None else args.tail_bias_deg)
    ref = reference_wingbeat("cruise" if args.cruise else "slow")
    dove = Dove.load(induced=args.induced)
    fl = DoveFlight(dove, ref, table=args.table, use_rollout=False)
    lo, hi = dof_ranges(dove.params)
    evals = [0]

    def cost(x: np.ndarray) -> float:
        evals[0] += 1
        b = wingbeat_balance(fl, wingbeat(x, lo, hi, fl.ref, bias), args.wingbeats, args.skip, args.speed)
        if b is None:
            return 1e3
        return (b["power_W"] + args.climb_weight * abs(b["climb_m_s"] - args.climb_target)
                + args.trim_weight * abs(b["accel_m_s2"]))

    t0 = time.perf_counter()
    res = differential_evolution(cost, bounds, maxiter=args.maxiter,
                                 popsize=args.popsize, seed=args.seed, polish=False, tol=1e-4)
    best = wingbeat(res.x, lo, hi, fl.ref, bias)
    bal = wingbeat_balance(fl, best, args.wingbeats, args.skip, args.speed)
    fl.close()
    budget = power_budget(args.wingbeats, args.skip, table=args.table, p=best, speed=args.speed,
                          induced=args.induced, ref=ref)
    bins = budget["drag_feathers_by_aoa_W"]
    steep = (bins["30-45"] + bins["45-60"]) / max(budget["drag_feathers_W"], 1e-12)
    out = {"table": args.table, "induced": args.induced, "cruise": args.cruise,
           "speed_m_s": args.speed, "climb_weight": args.climb_weight,
           "climb_target_m_s": args.climb_target, "tail_bias_deg": bias,
           "trim_weight": args.trim_weight,
           "bounds": {k[0]: list(b) for k, b in zip(KNOBS, bounds, strict=True)},
           "knobs": {k[0]: float(v) for k, v in zip(KNOBS, res.x, strict=True)},
           "cost": float(res.fun), "evaluations": evals[0],
           "wall_s": time.perf_counter() - t0, "balance": bal, "budget": budget,
           "share_at_30_60_deg": steep, "wingbeat": best.tolist()}
    print(f"{args.table}{' + induced flow' if args.induced else ''} at {args.speed:g} m/s: "
          f"servos {bal['power_W']:.2f} W, climb {bal['climb_m_s']:+.3f} m/s, "
          f"speed change {bal['accel_m_s2']:+.3f} m/s^2; lift/weight "
          f"{budget['aero_up_per_weight']:.3f}, cost of transport {budget['cost_of_transport']:.2f}, "
          f"{steep:.0%} of the feather dissipation at 30-60 deg ({evals[0]} wingbeats searched)")
    for k, v in out["knobs"].items():
        print(f"  {k:24s} {v:8.3f}")
    if args.json:
        write_json(args.json, out)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
