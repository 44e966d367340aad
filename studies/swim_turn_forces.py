"""Where in the stroke cycle the water's forces on the arms help or oppose a turn, layer
by layer (why the hand rules cost the breaststroke its turning).

    python studies/swim_turn_forces.py --stroke breaststroke --layers cycle,all
    python studies/swim_turn_forces.py --stroke breaststroke --layers cycle,all --steady 30

Swims the figure of eight and, at every control step (50 Hz) of the cycles in which the
per-cycle layer turns hard (yaw weight >= --min-weight), records the water's yaw moment
about the centre of mass [N m] on the arms (upper arm, forearm, hand), on the rest of the
body, and the arms' force along the body line [N], signed so that + helps the turn. Prints
them in phase bins of the stroke cycle, with the turn rate and speed in those cycles.

``--steady B``: instead, a steady turn: the target always lies B degrees left of the
swimmer's velocity (2 m look-ahead); prints the mean turn rate, speed and yaw weight after
12 s of 40 s.
"""

from __future__ import annotations

import argparse
import dataclasses
import math

import numpy as np

from flapsim.scenarios import get
from flapsim.swim.continuous import HandRuleParams
from flapsim.swim.goals import figure_eight
from flapsim.swim.simulate import swim

ARMS = ("upper_arm_l", "forearm_l", "hand_l", "upper_arm_r", "forearm_r", "hand_r")


def figure8_setup(a: argparse.Namespace) -> tuple[float, float, HandRuleParams]:
    """(loop radius m, seconds, HandRuleParams) from ``--stroke``, ``--radius`` and ``--set
    field=value``: the stroke's figure-of-eight scenario, lasting longer in proportion to a
    larger radius (as ``studies/swim_figure8_layers.py`` flies it)."""
    sc = get(f"swim-figure8-{a.stroke}")
    r0 = float(sc.params["radius_m"])
    radius = r0 if a.radius is None else a.radius
    seconds = float(sc.params["seconds"]) * max(1.0, radius / r0)
    kw = {k: float(v) for k, _, v in (item.partition("=") for item in a.set)}
    return radius, seconds, dataclasses.replace(HandRuleParams(), **kw)


def measure(stroke: str, layers: str, radius: float, seconds: float, hp: HandRuleParams,
            rules: tuple[str, ...] | None, min_weight: float, bins: int) -> dict:
    rec: list[tuple] = []

    def hook(sw, layer) -> bool:
        d = sw.data
        cyc = layer.stack.cycle if layers != "basic" else None
        if cyc is None or not cyc.weights:
            return True
        wl, wr = cyc.weights.get("yaw_left", 0.0), cyc.weights.get("yaw_right", 0.0)
        w = max(wl, wr)
        if w < min_weight:
            return True
        s = 1.0 if wl >= wr else -1.0
        rep = sw.hydro.evaluate(d)
        com = d.subtree_com[sw.body["pelvis"]]
        tz = rep.body_torque[:, 2] - (com[0] * rep.body_force[:, 1] - com[1] * rep.body_force[:, 0])
        arms = [sw.body[n] for n in ARMS]
        line = d.xpos[sw.body["head"]] - d.xpos[sw.body["pelvis"]]
        line[2] = 0.0
        line /= max(1e-9, float(np.linalg.norm(line)))
        rot = d.xmat[sw.body["pelvis"]].reshape(3, 3)
        yaw_rate = float((rot @ d.qvel[3:6])[2])  # the free joint's angular velocity is local
        rec.append((layer.phase, s * tz[arms].sum(), s * (tz.sum() - tz[arms].sum()),
                    float(rep.body_force[arms, :2].sum(axis=0) @ line[:2]), s * yaw_rate,
                    float(np.linalg.norm(sw.com_velocity()[:2]))))
        return True

    swim(stroke, seconds, target=figure_eight(radius), layers=layers, hand_params=hp, rules=rules,
         control_hook=hook)
    a = np.asarray(rec)
    edges = np.linspace(0, 1, bins + 1)
    rows = []
    for k in range(bins):
        m = (a[:, 0] >= edges[k]) & (a[:, 0] < edges[k + 1])
        rows.append((edges[k], *a[m, 1:4].mean(axis=0)))
    return {"rows": rows, "arm_mz": float(a[:, 1].mean()), "body_mz": float(a[:, 2].mean()),
            "arm_fwd": float(a[:, 3].mean()), "turn_deg_s": math.degrees(float(a[:, 4].mean())),
            "speed": float(a[:, 5].mean()), "samples": len(a)}


class Bearing:
    """A target always ``deg`` to the left of the swimmer's velocity (a steady turn)."""

    lookahead = 2.0

    def __init__(self, deg: float) -> None:
        self.th = math.radians(deg)

    def heading(self, com_xy: np.ndarray, vel_xy: np.ndarray, t: float = 0.0) -> float:
        return math.atan2(vel_xy[1], vel_xy[0]) + self.th if np.hypot(*vel_xy) > 0.05 else self.th

    def describe(self) -> dict:
        return {"kind": "bearing", "deg": math.degrees(self.th)}


def steady(stroke: str, layers: str, deg: float, hp: HandRuleParams, rules: tuple[str, ...] | None
           ) -> dict:
    rate, speed, weight = [], [], []

    def hook(sw, layer) -> bool:
        d = sw.data
        if d.time >= 12.0:
            rot = d.xmat[sw.body["pelvis"]].reshape(3, 3)
            rate.append(float((rot @ d.qvel[3:6])[2]))
            speed.append(float(np.linalg.norm(sw.com_velocity()[:2])))
            cyc = layer.stack.cycle
            weight.append(cyc.weights.get("yaw_left", 0.0) if cyc is not None else 0.0)
        return True

    swim(stroke, 40.0, target=Bearing(deg), layers=layers, hand_params=hp, rules=rules, control_hook=hook)
    w = float(np.mean(weight))
    return {"turn_deg_s": math.degrees(float(np.mean(rate))), "speed": float(np.mean(speed)),
            "weight": w}


def parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--stroke", default="breaststroke")
    ap.add_argument("--radius", type=float, default=None)
    ap.add_argument("--layers", default="cycle,all")
    ap.add_argument("--rules", default=None)
    ap.add_argument("--set", action="append", default=[], help="HandRuleParams field=value")
    ap.add_argument("--min-weight", type=float, default=0.5)
    ap.add_argument("--bins", type=int, default=10)
    ap.add_argument("--steady", type=float, default=None, help="a steady turn, target this many deg left")
    return ap


def main(argv: list[str] | None = None) -> None:
    ap = parser()
    a = ap.parse_args(argv)
    radius, seconds, hp = figure8_setup(a)
    rules = None if a.rules is None else tuple(x for x in a.rules.split(",") if x)
    for layers in a.layers.split(","):
        if a.steady is not None:
            r = steady(a.stroke, layers, a.steady, hp, rules)
            per = r["turn_deg_s"] / r["weight"] if r["weight"] > 0 else float("nan")
            print(f"{a.stroke} steady turn, target {a.steady:g} deg left, {layers} rules={a.rules} {a.set}: "
                  f"{r['turn_deg_s']:.1f} deg/s at {r['speed']:.2f} m/s, yaw weight {r['weight']:.2f} "
                  f"({per:.1f} deg/s per unit weight)")
            continue
        r = measure(a.stroke, layers, radius, seconds, hp, rules, a.min_weight, a.bins)
        print(f"{a.stroke} r={radius:g} {layers} rules={a.rules} {a.set}: turn {r['turn_deg_s']:.1f} deg/s "
              f"at {r['speed']:.2f} m/s; arms' yaw moment {r['arm_mz']:+.2f} N m, rest {r['body_mz']:+.2f}, "
              f"arms' forward force {r['arm_fwd']:+.1f} N ({r['samples']} samples)")
        print("   phase   arms Mz   body Mz   arms fwd")
        for ph, mz, bz, fw in r["rows"]:
            print(f"   {ph:4.2f}   {mz:+7.2f}   {bz:+7.2f}   {fw:+7.1f}")


if __name__ == "__main__":
    main()
