"""A cruise wingbeat for the dove: the synthetic capture's kinematic model
(:class:`flapsim.bird.flight.synthetic_capture.Kinematics`) searched for the least servo
power at which the free dove holds its height and speed at a cruise speed, each parameter
inside the range published cruise kinematics allow (a dove of this size: about 8.3 Hz,
about 90 deg of stroke, Strouhal number 0.2-0.4, downstroke 50-55 % of the cycle, a stroke
plane tilted forward, a flexed upstroke; ``REFERENCE_DATA.md``, "Dove power").

Each candidate's noise-free cycle becomes a reference wingbeat
(:func:`~flapsim.bird.flight.synthetic_capture.kinematic_reference`), flown as the base
controller flies it (P0 with a tail bias, searched with it: the capture's tail bend stays the
captured dove's -10 deg) from the cruise start; its cost is the servos'
mean power plus 30 W per m/s of climb or sink, 6 W per m/s^2 of speed change and 0.05 W per
degree of pitch drift per wingbeat (``--trim-weight 20``: 20 W and 0.2 W; a trimmed wingbeat
pays nothing extra); a cycle that
comes closer than 14 deg to a joint's range at its capture's extreme conditions costs
100 W and more, one over Strouhal number 0.4 50 W and more.

With ``--roll-max-deg R`` the trimmed wingbeat must also ride out the flight suite's sideways
push (8 N for 0.1 s at the trunk, :data:`flapsim.scenarios.flight.PUSH_FORCES_N`'s middle):
flown on unchanged for two wingbeats, the trunk may roll at most R deg (0.1 W per degree
beyond). The learned controller acts once a wingbeat, so the roll a sideslip starts within
one must stay inside what its database covers: a stroke hung below the shoulders (flap mean
-5.5 deg) rolled the dove 81 deg in the wingbeat after the push, the paper's slow stroke (its
mean +13.5 deg above) 22 deg.

    python studies/dove_cruise_kinematics.py --speed 8 --json cruise.json
    python -m flapsim.bird.flight.synthetic_capture      # the capture from CRUISE, then
    python studies/dove_cruise_kinematics.py --speed 8 --trim-capture
"""

from __future__ import annotations

import argparse
import json
import time
from collections.abc import Sequence
from dataclasses import asdict, replace

import mujoco
import numpy as np
from scipy.optimize import differential_evolution, minimize_scalar

from flapsim.bird.body.model import Dove, wingspan
from flapsim.bird.body.params import dof_ranges
from flapsim.bird.flight.dove_flight import DoveFlight
from flapsim.bird.flight.power import wingbeat_balance
from flapsim.bird.flight.synthetic_capture import (
    CRUISE,
    Kinematics,
    Variation,
    cycle_angles,
    kinematic_reference,
)
from flapsim.bird.flight.wingbeat import (
    TAIL_BEND,
    control_table,
    p0,
    reference_wingbeat,
    with_tail_bias,
)
from flapsim.core.io import write_json

#: (Kinematics field, low, high): the cruise ranges searched (degrees unless named)
KNOBS = (
    ("frequency_hz", 7.0, 9.5),          # 0.84-1.14 of Pennycuick's 8.3 Hz (--max-hz lowers it)
    ("downstroke_fraction", 0.50, 0.56),
    ("flap_mean_deg", -15.0, 25.0),
    ("flap_amplitude_deg", 28.0, 58.0),  # 56-116 deg of stroke
    ("sweep_mean_deg", -20.0, 10.0),
    ("sweep_top_deg", 0.0, 25.0),        # stroke plane tilted forward
    ("sweep_mid_deg", -15.0, 5.0),
    ("pronation_mean_deg", -20.0, 25.0),
    ("pronation_deg", 0.0, 25.0),
    ("elbow_twist_mean_deg", -15.0, 25.0),
    ("elbow_twist_deg", 0.0, 28.0),      # the hand wing's twist against the arm wing
    ("elbow_flex_max_deg", 10.0, 60.0),  # the flexed upstroke
    ("wrist_flex_max_deg", 10.0, 65.0),
    ("flex_peak_phase", 0.6, 0.85),
    ("tail_spread_deg", 5.0, 30.0),
    ("tail_bias_deg", -10.0, 30.0),      # the tail bend added to the capture's (-10 deg)
)


#: Cruising birds' largest Strouhal number (Taylor, Nudds & Thomas 2003): a stroke wider
#: than this at the cycle's rate is refused
ST_MAX = 0.4


def parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--speed", type=float, default=8.0, help="cruise speed, m/s")
    ap.add_argument("--wingbeats", type=int, default=8, help="wingbeats flown per candidate")
    ap.add_argument("--skip", type=int, default=3, help="wingbeats flown before measuring")
    ap.add_argument("--maxiter", type=int, default=30, help="differential-evolution generations")
    ap.add_argument("--popsize", type=int, default=5, help="population per parameter")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--start", help="a JSON of an earlier search: its kinematics seed the population")
    ap.add_argument("--json", help="write the best kinematics and its budget here")
    ap.add_argument("--trim-weight", type=float, default=6.0,
                    help="W per m/s^2 of speed change (and 1/120 of it per deg of pitch drift a "
                         "wingbeat) added to the power (default 6; at 6 a search with "
                         "--roll-max-deg took a wingbeat slowing 0.34 m/s^2 for 0.4 W less: 20 "
                         "trims it)")
    ap.add_argument("--max-hz", type=float, default=None,
                    help="the highest wingbeat rate searched (default 9.5 Hz; 8.5 keeps the "
                         "capture's cycles, 3 %% noise and slower flights included, inside 1.15x "
                         "Pennycuick's 8.3 Hz)")
    ap.add_argument("--roll-max-deg", type=float, default=None,
                    help="also ride out an 8 N sideways push rolling at most this much over the "
                         "two wingbeats after it (default: not asked)")
    ap.add_argument("--trim-capture", action="store_true",
                    help="instead of searching: the tail bias at which the bundled capture's "
                         "average wingbeat (P0) holds height and speed best at --speed")
    return ap


def trim_capture(fl: DoveFlight, args: argparse.Namespace) -> int:
    """The tail bias trimming the bundled capture's reference wingbeat (a 1-D search)."""
    fl.ref = reference_wingbeat("cruise")

    def cost(bias: float) -> float:
        b = wingbeat_balance(fl, with_tail_bias(p0(), bias), args.wingbeats, args.skip, args.speed)
        return 1e3 if b is None else 30.0 * abs(b["climb_m_s"]) + 6.0 * abs(b["accel_m_s2"])

    grid = np.arange(-10.0, 30.5, 1.0)
    costs = [cost(b) for b in grid]
    k = int(np.argmin(costs))
    res = minimize_scalar(cost, bounds=(grid[max(k - 1, 0)], grid[min(k + 1, len(grid) - 1)]),
                          method="bounded", options={"xatol": 0.05})
    bias = float(res.x)
    b = wingbeat_balance(fl, with_tail_bias(p0(), bias), args.wingbeats, args.skip, args.speed)
    print(f"the capture's P0 at {args.speed:g} m/s trims with a tail bias of {bias:.2f} deg: servos "
          f"{b['power_W']:.2f} W, climb {b['climb_m_s']:+.3f} m/s, speed change "
          f"{b['accel_m_s2']:+.3f} m/s^2")
    if args.json:
        write_json(args.json, {"speed_m_s": args.speed, "tail_bias_deg": bias, "balance": b})
    return 0


def kinematics(x: np.ndarray, base: Kinematics) -> tuple[Kinematics, float]:
    """The kinematics and the tail bias (deg) of knob values ``x``."""
    values = {k[0]: float(v) for k, v in zip(KNOBS, x, strict=True)}
    bias = values.pop("tail_bias_deg")
    return replace(base, **values), bias


#: How far inside every joint range the capture's cycles must stay, deg: the 10 deg a
#: controller samples around them with (``tests/bird/body/test_model.py``), plus 4 deg for
#: the cycles' own noise (3 % of the stroke, 1.5 deg offsets) beyond their conditions' extremes
RANGE_MARGIN_DEG = 14.0


def range_excess_deg(kin: Kinematics, lo: np.ndarray, hi: np.ndarray, bias: float = 0.0,
                     var: Variation | None = None) -> float:
    """How far (deg, summed over DOF) the noise-free cycle at the capture's extreme conditions
    (every corner of its steering, climb and speed ranges; the tail with and without ``bias``)
    comes closer than :data:`RANGE_MARGIN_DEG` to the joint ranges."""
    var = var or CRUISE[1]
    phase = np.arange(96) / 96
    qs = [cycle_angles(phase, kin, st, cl, sp, var)
          for st in var.steering_range_deg for cl in var.elevation_range_deg
          for sp in var.speed_range]
    q = np.concatenate(qs)
    biased = q.copy()
    biased[:, TAIL_BEND] += np.radians(bias)
    q = np.concatenate([q, biased])
    margin = np.radians(RANGE_MARGIN_DEG)
    over = np.maximum(q - (hi - margin), 0).max(0) + np.maximum((lo + margin) - q, 0).max(0)
    return float(np.degrees(over[np.isfinite(over)]).sum())


def strouhal(kin: Kinematics, semispan: float, speed: float) -> float:
    """f A / V with A the wingtip's vertical excursion of a straight wing of ``semispan``."""
    a = np.radians(kin.flap_amplitude_deg)
    m = np.radians(kin.flap_mean_deg)
    excursion = semispan * (np.sin(m + a) - np.sin(m - a))
    return float(kin.frequency_hz * excursion / speed)


#: The sideways push the search asks the trimmed wingbeat to ride out: N, s
PUSH_N, PUSH_S = 8.0, 0.1


def push_roll_deg(fl: DoveFlight, p: np.ndarray, wingbeats: int = 2) -> float | None:
    """The largest |trunk roll| (deg) at the ends of ``wingbeats`` wingbeats of ``p`` flown
    on from the flight's state, the first starting with a sideways push of :data:`PUSH_N` for
    :data:`PUSH_S`; None when the flight diverges."""
    m, d = fl.model, fl.data
    trunk = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, "trunk")
    ctrl, _, _ = control_table(fl.ref, p, m.opt.timestep, fl.kp, fl.kv)
    steps = int(round(PUSH_S / m.opt.timestep))
    worst = 0.0
    try:
        for wb in range(wingbeats):
            for k in range(len(ctrl)):
                d.ctrl[:] = ctrl[k]
                d.xfrc_applied[trunk, 1] = PUSH_N if (wb == 0 and k < steps) else 0.0
                mujoco.mj_step(m, d)
                if not np.all(np.isfinite(d.qvel[0:6])):
                    return None
            worst = max(worst, abs(float(np.degrees(fl.reduced_state()[1]))))
    finally:
        d.xfrc_applied[trunk, :] = 0.0
    return worst


def main(argv: Sequence[str] | None = None) -> int:
    args = parser().parse_args(argv)
    dove = Dove.load(induced=True)
    fl = DoveFlight(dove, table="bird_wing", use_rollout=False)
    lo, hi = dof_ranges(dove.params)
    if args.trim_capture:
        return trim_capture(fl, args)
    base = replace(Kinematics(), speed_m_s=args.speed)
    semispan = 0.5 * wingspan(dove.params)
    evals = [0]

    def cost(x: np.ndarray) -> float:
        evals[0] += 1
        kin, bias = kinematics(x, base)
        excess = range_excess_deg(kin, lo, hi, bias)
        if excess > 0:
            return 100.0 + excess
        st = strouhal(kin, semispan, args.speed)
        if st > ST_MAX:
            return 50.0 + 100.0 * (st - ST_MAX)
        fl.ref = kinematic_reference(kin)
        b = wingbeat_balance(fl, with_tail_bias(p0(), bias), args.wingbeats, args.skip, args.speed)
        if b is None:
            return 1e3
        drift = abs(b["pitch_deg"][-1] - b["pitch_deg"][args.skip - 1]) / (args.wingbeats - args.skip)
        w = args.trim_weight
        c = (b["power_W"] + 30.0 * abs(b["climb_m_s"]) + w * abs(b["accel_m_s2"])
             + w / 120.0 * drift)
        if args.roll_max_deg is not None:
            roll = push_roll_deg(fl, with_tail_bias(p0(), bias))
            c += 1e3 if roll is None else 0.1 * max(roll - args.roll_max_deg, 0.0)
        return c

    x0 = None
    if args.start:
        prev = json.load(open(args.start))
        values = {**prev["kinematics"], "tail_bias_deg": prev.get("tail_bias_deg", 17.0)}
        # an older search's tail bend: the same tail as the capture's -10 deg with more bias
        values["tail_bias_deg"] += values.get("tail_bend_deg", -10.0) + 10.0
        x0 = np.clip([values[k[0]] for k in KNOBS], [k[1] for k in KNOBS], [k[2] for k in KNOBS])
    t0 = time.perf_counter()
    bounds = [(k[1], k[2]) for k in KNOBS]
    if args.max_hz is not None:
        bounds[0] = (bounds[0][0], float(args.max_hz))
        if x0 is not None:
            x0[0] = min(x0[0], float(args.max_hz))
    res = differential_evolution(cost, bounds, maxiter=args.maxiter,
                                 popsize=args.popsize, seed=args.seed, polish=False, tol=1e-4,
                                 x0=x0)
    best, bias = kinematics(res.x, base)
    fl.ref = kinematic_reference(best)
    bal = wingbeat_balance(fl, with_tail_bias(p0(), bias), args.wingbeats, args.skip, args.speed)
    roll = push_roll_deg(fl, with_tail_bias(p0(), bias))
    fl.close()
    out = {"speed_m_s": args.speed, "kinematics": asdict(best), "tail_bias_deg": bias,
           "cost": float(res.fun),
           "evaluations": evals[0], "wall_s": time.perf_counter() - t0, "balance": bal,
           "stroke_deg": 2 * best.flap_amplitude_deg,
           "strouhal": strouhal(best, semispan, args.speed), "push_roll_deg": roll}
    print(f"cruise kinematics at {args.speed:g} m/s: servos {bal['power_W']:.2f} W, climb "
          f"{bal['climb_m_s']:+.3f} m/s, speed change {bal['accel_m_s2']:+.3f} m/s^2, "
          f"pitch {bal['pitch_deg'][args.skip - 1]:+.1f} -> {bal['pitch_deg'][-1]:+.1f} deg; "
          f"stroke {out['stroke_deg']:.0f} deg, Strouhal {out['strouhal']:.2f} "
          f"({evals[0]} wingbeats searched in {out['wall_s']:.0f} s); rolled {roll:.0f} deg "
          f"after an {PUSH_N:g} N sideways push")
    for k, v in zip(KNOBS, res.x, strict=True):
        print(f"  {k[0]:24s} {v:8.3f}")
    if args.json:
        write_json(args.json, out)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
