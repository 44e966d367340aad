"""Can the cruise dove hold a steady banked turn, and on what wingbeat?

A bird turns by banking: in a level, coordinated turn at bank phi its lift is the weight
over cos(phi) and its heading turns at g tan(phi) / V. For the learned controller to fly
the paper's turns with a dove's power, such turns must exist within the wingbeat family (the
paper's 29 numbers) at all. This study searches, for each bank asked, the wingbeat that
holds it: the cruise dove (bird-wing section, induced flow, cruise wingbeat) settled in
level cruise, then rolled to the bank with the turn's yaw rate, flies one wingbeat again and
again; differential evolution moves ten knobs of it (five on both wings alike, five the
left wing against the right) until each wingbeat's end repeats the bank, the height, the
speed and a sideslip-free heading. Every force is the feathers', the trunk's and gravity;
the knobs stay inside the joint ranges (each wingbeat projected into them).

    python studies/dove_turn_trim.py --bank 15,30,45 --json turn.json
"""

from __future__ import annotations

import argparse
import sys
import time

import mujoco
import numpy as np
from scipy.optimize import differential_evolution

from flapsim.bird.body.model import Dove
from flapsim.bird.body.params import DOF_NAMES, dof_ranges
from flapsim.bird.control import lateral
from flapsim.bird.flight import cycle
from flapsim.bird.flight.dove_flight import CRUISE, DoveFlight
from flapsim.bird.flight.wingbeat import (
    control_table,
    p0,
    project_to_ranges,
    reference_wingbeat,
    with_tail_bias,
)
from flapsim.core.errors import SimulationError
from flapsim.core.io import write_json

G = 9.81
#: wingbeats flown to settle level cruise before rolling into the turn
SETTLE = 4

#: (name, DOF stem or tail DOF, "scale" / "offset" / "timewarp", "sym" or "anti", lo, hi);
#: offsets in deg. "anti": +x on the left wing, -x on the right (a left-wing-up knob rolls
#: the dove right).
KNOBS = (
    ("flap_scale", "shoulder_flap", "scale", "sym", 0.8, 1.4),
    ("flap_offset_deg", "shoulder_flap", "offset", "sym", -10.0, 15.0),
    ("pronation_deg", "shoulder_twist", "offset", "sym", -10.0, 15.0),
    ("tail_bend_deg", "tail_bend", "offset", "sym", -15.0, 20.0),
    ("timewarp", None, "timewarp", "sym", 0.85, 1.15),
    ("d_flap_scale", "shoulder_flap", "scale", "anti", -0.2, 0.2),
    ("d_flap_offset_deg", "shoulder_flap", "offset", "anti", -10.0, 10.0),
    ("d_pronation_deg", "shoulder_twist", "offset", "anti", -10.0, 10.0),
    ("d_hand_twist_deg", "elbow_twist", "offset", "anti", -10.0, 10.0),
    ("d_sweep_deg", "shoulder_sweep", "offset", "anti", -10.0, 10.0),
)


def wingbeat(x: np.ndarray, base: np.ndarray, lo: np.ndarray, hi: np.ndarray, ref) -> np.ndarray:
    """The 29-number wingbeat of knob values ``x`` on ``base``, projected into the ranges."""
    p = base.copy()
    for (_, dof, kind, sym, _, _), v in zip(KNOBS, x, strict=True):
        if kind == "timewarp":
            p[-1] = base[-1] * v
            continue
        if dof == "tail_bend":
            sides = [(dof, 1.0)]
        else:
            sides = [(f"l_{dof}", 1.0), (f"r_{dof}", 1.0 if sym == "sym" else -1.0)]
        for n, sgn in sides:
            i = DOF_NAMES.index(n)
            if kind == "scale":  # the symmetric and the left-right factors compose
                p[2 * i] *= v if sym == "sym" else 1.0 + sgn * v
            else:
                p[2 * i + 1] += sgn * np.radians(v)
    return project_to_ranges(ref, p, lo, hi)


def fly_turn(fl: DoveFlight, start: cycle.Snapshot, p: np.ndarray, wingbeats: int) -> dict:
    """``wingbeats`` of ``p`` from ``start``: each end's roll and pitch (deg), height (m),
    speed (m/s), the centre of mass's heading (deg, + left) and body-frame sideways speed."""
    snap = start
    out: dict[str, list[float]] = {k: [] for k in ("roll", "pitch", "z", "speed", "heading",
                                                   "v_side", "t")}
    for _ in range(wingbeats):
        end = cycle.fly_cycle(fl, snap, p)
        snap = None
        v = end.com_vel
        out["roll"].append(float(np.degrees(end.S[1])))
        out["pitch"].append(float(np.degrees(end.S[0])))
        out["z"].append(float(end.trunk_pos[2]))
        out["speed"].append(float(np.linalg.norm(v)))
        out["heading"].append(float(np.degrees(np.arctan2(v[1], v[0]))))
        out["v_side"].append(float(end.S[3]))
        out["t"].append(float(fl.data.time))
    out["heading"] = list(np.degrees(np.unwrap(np.radians(out["heading"]))))
    return out


def turn_cost(tr: dict, bank_deg: float, speed: float, skip: int) -> tuple[float, dict]:
    """How far the flight ``tr`` is from the steady turn asked (each term in units of what a
    path follower tolerates a wingbeat: 5 deg of bank, 0.1 m/s of climb, 0.3 m/s^2 of speed
    change, 20 % of the turn rate, 0.3 m/s of sideslip) and the measured figures."""
    t = np.array(tr["t"])
    span = t[-1] - t[skip - 1]
    roll = np.array(tr["roll"][skip:])
    climb = (tr["z"][-1] - tr["z"][skip - 1]) / span
    accel = (tr["speed"][-1] - tr["speed"][skip - 1]) / span
    rate = (tr["heading"][-1] - tr["heading"][skip - 1]) / span  # deg/s, + left
    asked = -np.degrees(G * np.tan(np.radians(bank_deg)) / speed)
    side = float(np.abs(tr["v_side"][skip:]).mean())
    terms = {"bank": float(np.abs(roll - bank_deg).mean()) / 5.0,
             "climb": abs(climb) / 0.1, "accel": abs(accel) / 0.3,
             "rate": abs(rate - asked) / max(0.2 * abs(asked), 2.0), "sideslip": side / 0.3}
    figures = {"roll_deg": roll.tolist(), "climb_m_s": climb, "accel_m_s2": accel,
               "turn_rate_deg_s": rate, "turn_rate_asked_deg_s": asked, "sideslip_m_s": side}
    return float(sum(terms.values())), {"terms": terms, **figures}


def servo_power(fl: DoveFlight, start: cycle.Snapshot, p: np.ndarray, wingbeats: int,
                skip: int) -> float:
    """The servos' mean power over wingbeats ``skip``.. of ``p`` from ``start`` (W): their
    generalized force times each step's mean velocity, as ``flapsim fly --power`` counts."""
    m, d = fl.model, fl.data
    cycle.restore(fl, start)
    ctrl, _, _ = control_table(fl.ref, p, m.opt.timestep, fl.kp, fl.kv)
    work, n = 0.0, 0
    for wb in range(wingbeats):
        for k in range(len(ctrl)):
            d.ctrl[:] = ctrl[k]
            before = d.qvel.copy()
            mujoco.mj_step(m, d)
            if wb >= skip:
                work += float(d.qfrc_actuator @ (0.5 * (before + d.qvel)))
                n += 1
    return work / max(n, 1)


def parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--bank", default="15,30,45", help="banks asked, deg (comma list; + right)")
    ap.add_argument("--wingbeats", type=int, default=6, help="wingbeats flown per candidate")
    ap.add_argument("--skip", type=int, default=2, help="wingbeats flown before measuring")
    ap.add_argument("--maxiter", type=int, default=20, help="differential-evolution generations")
    ap.add_argument("--popsize", type=int, default=6, help="population per knob")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--json", default=None)
    return ap


def main(argv: list[str] | None = None) -> int:
    a = parser().parse_args(argv)
    dove = Dove.load(induced=True)
    fl = DoveFlight(dove, ref=reference_wingbeat("cruise"), table=CRUISE.table, use_rollout=True)
    lo, hi = dof_ranges(dove.params)
    base = with_tail_bias(p0(), CRUISE.tail_bias_deg)
    fl.reset(CRUISE, base)
    for _ in range(SETTLE):
        cycle.fly_cycle(fl, None, base)
    level = cycle.snapshot(fl)
    speed = float(np.linalg.norm(fl.data.qvel[0:3]))
    results = []
    for bank in (float(b) for b in a.bank.split(",")):
        start = lateral.bank_state(fl, level, bank)
        t0 = time.perf_counter()

        def cost(x: np.ndarray, start=start, bank=bank) -> float:
            try:
                tr = fly_turn(fl, start, wingbeat(x, base, lo, hi, fl.ref), a.wingbeats)
            except SimulationError:
                return 1e3
            return turn_cost(tr, bank, speed, a.skip)[0]

        x0 = np.array([1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0])
        none = turn_cost(fly_turn(fl, start, base, a.wingbeats), bank, speed, a.skip)
        res = differential_evolution(cost, [(k[4], k[5]) for k in KNOBS], maxiter=a.maxiter,
                                     popsize=a.popsize, seed=a.seed, polish=False, tol=1e-4,
                                     x0=x0)
        p = wingbeat(res.x, base, lo, hi, fl.ref)
        c, fig = turn_cost(fly_turn(fl, start, p, a.wingbeats), bank, speed, a.skip)
        watts = servo_power(fl, start, p, a.wingbeats, a.skip)
        watts_level = servo_power(fl, level, base, a.wingbeats, a.skip)
        out = {"bank_deg": bank, "speed_m_s": speed, "cost": c, "cost_reference_wingbeat": none[0],
               "reference_wingbeat": none[1], "knobs": dict(zip([k[0] for k in KNOBS],
                                                               map(float, res.x), strict=True)),
               "servo_power_w": watts, "servo_power_level_w": watts_level,
               "evaluations": int(res.nfev), "wall_s": time.perf_counter() - t0, **fig,
               "wingbeat": p.tolist()}
        results.append(out)
        print(f"bank {bank:+.0f} deg at {speed:.2f} m/s: cost {c:.2f} (reference wingbeat "
              f"{none[0]:.2f}); roll " + " ".join(f"{r:+.0f}" for r in fig["roll_deg"])
              + f" deg, climb {fig['climb_m_s']:+.2f} m/s, speed change "
              f"{fig['accel_m_s2']:+.2f} m/s^2, turn {fig['turn_rate_deg_s']:+.0f} deg/s "
              f"(asked {fig['turn_rate_asked_deg_s']:+.0f}), sideslip {fig['sideslip_m_s']:.2f} "
              f"m/s, servos {watts:.2f} W (level {watts_level:.2f}); knobs "
              + ", ".join(f"{k} {v:+.2f}" for k, v in out["knobs"].items())
              + f"; {res.nfev} evaluations, {out['wall_s']:.0f} s", flush=True)
    fl.close()
    if a.json:
        write_json(a.json, {"study": "dove_turn_trim", "command": "python studies/dove_turn_trim.py "
                            + " ".join(argv if argv is not None else sys.argv[1:]),
                            "P0": base.tolist(), "knobs": [k[0] for k in KNOBS],
                            "wingbeats": a.wingbeats, "skip": a.skip, "results": results})
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
