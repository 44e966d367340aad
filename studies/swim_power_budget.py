"""Where a stroke's muscle power goes: per joint group, per segment's water work, over the
stroke's phases, against the towed drag's power.

Swims a stroke from rest (all layers, as ``flapsim swim`` does) with the water budget on
(:mod:`flapsim.swim.budget`) and every joint dof's power recorded
(:func:`flapsim.swim.simulate.step_joint_powers`), then prints, over the settled swim:

* per joint group (shoulders, elbows, wrists, trunk and neck, hips, knees, ankles): the
  muscles' net power, its positive part and the negative work the muscles absorb (a joint
  braking: energy taken out of the limb's motion or out of the water pushing the limb,
  then spent again), the share of the net that the PD's velocity term (the joint damping)
  gives, and the joint limits' work;
* per segment group: the power given to the water, its thrust power (the work against
  the body's progress, negated) and the slip; the arms' and legs' Froude efficiency;
* the energy balance (net muscle power = water + limits + d(kinetic + potential)/dt),
  the internal kinetic energy (relative to the centre of mass) and its churn (the mean
  rate at which it rises: the limbs' motion made and unmade each cycle);
* the left arm's water work and thrust over ten phase bins, with the time its hand is
  above the water (the recovery in the air), and the legs' cost against their thrust;
* the towed drag's power at the swum speed (``flapsim.swim.tow``, the streamlined body at
  the surface): what a perfect propeller would pay.

    python studies/swim_power_budget.py --body rounded --stroke crawl --seconds 30 \\
        --json budget.json
"""

from __future__ import annotations

import argparse
import json
import sys

import mujoco
import numpy as np

from flapsim.swim.budget import (
    ARMS,
    GROUPS,
    LEGS,
    dof_groups,
    ideal_paddle,
    summarize,
    summarize_joints,
)
from flapsim.swim.model import SEGMENTS, Swimmer, SwimmerParams
from flapsim.swim.simulate import swim
from flapsim.swim.strokes import load_stroke, stroke_for_body
from flapsim.swim.tow import tow_drag

PHASE_BINS = 10
#: the speed asked of the crawl at a swimmer's effort [m/s] (the bound is also taken there)
TARGET_SPEED = 1.2


def paddle_geometry(model: mujoco.MjModel) -> tuple[float, float]:
    """(paddle area [m^2], pull path [m]) of a generous ideal arm: the hand's and the
    forearm's plan areas (their boxes' two larger sides) as if both moved at the hand's
    speed, and a path of twice the shoulder-to-hand-centre reach (from straight ahead to
    straight behind the shoulder)."""
    area = 0.0
    for name in ("hand_l", "forearm_l"):
        h = np.sort(model.geom_size[mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, name)])
        area += 4.0 * h[1] * h[2]
    body = {n: mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, n)
            for n in ("forearm_l", "hand_l")}
    gh = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, "hand_l")
    reach = (abs(model.body_pos[body["forearm_l"]][2]) + abs(model.body_pos[body["hand_l"]][2])
             + abs(model.geom_pos[gh][2]))
    return area, 2.0 * reach


def arm_phases(res, side: str = "l") -> list[dict[str, float]]:
    """The arm's (upper arm, forearm, hand of ``side``) mean water power and thrust power
    [W] and the hand's time above the water, over :data:`PHASE_BINS` bins of the stroke
    phase (settled swim; the left hand enters the water at phase 0)."""
    sel = res._steady()
    seg = [SEGMENTS.index(f"{n}_{side}") for n in ("upper_arm", "forearm", "hand")]
    w = res.water_rates_segments[sel][:, seg]
    ph = res.phase[sel]
    hand = res.limbs[sel][:, 0 if side == "l" else 1] - res.water_level
    b = np.minimum((ph * PHASE_BINS).astype(int), PHASE_BINS - 1)
    rows = []
    for k in range(PHASE_BINS):
        m = b == k
        if not m.any():
            rows.append({"phase": k / PHASE_BINS, "water_w": float("nan"),
                         "thrust_w": float("nan"), "hand_in_air": float("nan")})
            continue
        rows.append({"phase": k / PHASE_BINS,
                     "water_w": float(w[m, :, 0].sum(axis=1).mean()),
                     "thrust_w": float(-w[m, :, 1].sum(axis=1).mean()),
                     "hand_in_air": float((hand[m] > 0.0).mean())})
    return rows


def budget(stroke: str, body: str, seconds: float, rate: float | None, layers: str,
           seed: int = 0) -> dict:
    """Swim and measure; the JSON of the study (see the module docstring)."""
    _ = seed  # the swim is deterministic; kept for the CLI convention
    params = SwimmerParams(body_shape=body)
    sw = Swimmer(params)
    # a bundled stroke's own tuning for this body, as flapsim swim takes it
    st = load_stroke(stroke_for_body(stroke, body))
    res = swim(st, seconds, swimmer=sw, rate_hz=rate, layers=layers, budget=True)
    s = res.summary()
    sel = res._steady()
    joints = summarize_joints(res.joint_power[sel], dof_groups(sw.model))["groups"]
    water = summarize(res.water_rates[sel])
    v = s["speed_m_s"]
    tow = tow_drag([max(v, 0.05)], params)[0]
    # energy: potential (gravity) from the centre of mass's height; kinetic from the samples
    t = res.times[sel]
    ke = res.kinetic[sel]
    g = float(np.linalg.norm(sw.model.opt.gravity))
    pe = sw.mass * g * res.com[sel, 2]
    span = t[-1] - t[0]
    de_dt = float((ke[-1, 0] + pe[-1] - ke[0, 0] - pe[0]) / span) if span > 0 else 0.0
    rise = np.diff(ke[:, 1])
    churn = float(rise[rise > 0].sum() / span) if span > 0 else 0.0
    net = float(res.joint_power[sel][:, :, 0].sum(axis=1).mean())
    pos = float(res.joint_power[sel][:, :, 1].sum(axis=1).mean())
    limits = float(res.joint_power[sel][:, :, 3].sum(axis=1).mean())
    # the least any two drag-based paddles of this hand and forearm could pay (flapsim.swim.
    # budget.ideal_paddle): at the swum speed against the towed drag and against the drag
    # the arms carried (their thrust power / speed: the towed body's plus what the limbs
    # and the roll add), and at TARGET_SPEED with both scaled as v^2
    area, path = paddle_geometry(sw.model)
    carried = water["arms_thrust_power_w"] / v if v > 0 else float("nan")
    tow_target = tow_drag([TARGET_SPEED], params)[0]
    bounds = {}
    for label, speed, drag in (("swum_towed", v, tow), ("swum_carried", v, carried),
                               ("target_towed", TARGET_SPEED, tow_target),
                               ("target_carried", TARGET_SPEED,
                                carried * (TARGET_SPEED / v) ** 2)):
        for rate_hz in (s["stroke_rate_hz"], 0.7):
            if drag > 0:
                bounds[f"{label}_{rate_hz:.2f}hz"] = {
                    "speed_m_s": speed, "drag_n": drag, "rate_hz": rate_hz,
                    **ideal_paddle(speed, drag, rate_hz, area, path,
                                   cd=params.cd_normal, density=params.water_density)}
    legs_joint = sum(joints[g_]["net_w"] for g_ in ("hips", "knees", "ankles"))
    legs_pos = sum(joints[g_]["positive_w"] for g_ in ("hips", "knees", "ankles"))
    return {
        "stroke": st.name, "body": body, "seconds": seconds, "layers": layers,
        "speed_m_s": v, "stroke_rate_hz": s["stroke_rate_hz"],
        "distance_per_stroke_m": s["distance_per_stroke_m"],
        "muscle_power_mean_w": s["muscle_power_mean_w"],
        "muscle_power_positive_mean_w": s["muscle_power_positive_mean_w"],
        "roll_shoulders_deg": s.get("roll_shoulders_deg"),
        "roll_hips_deg": s.get("roll_hips_deg"), "trunk_incline_deg": s.get("trunk_incline_deg"),
        "towed_drag_n": tow, "towed_drag_power_w": tow * v,
        "towed_share_of_muscle_power": tow * v / s["muscle_power_mean_w"],
        "joints": joints,
        "joints_net_w": net, "joints_positive_w": pos, "joints_negative_w": pos - net,
        "water": water,
        "energy": {"muscle_net_w": net, "water_w": water["water_w"], "limits_w": limits,
                   "d_energy_dt_w": de_dt,
                   "balance_residual_w": net + limits - water["water_w"] - de_dt,
                   "internal_kinetic_mean_j": float(ke[:, 1].mean()),
                   "internal_kinetic_churn_w": churn},
        "legs": {"joint_net_w": legs_joint, "joint_positive_w": legs_pos,
                 "thrust_w": water["legs_thrust_power_w"], "water_w": water["legs_water_w"],
                 "thigh_water_w": water["segments"]["thigh"]["water_w"]},
        "left_arm_phases": arm_phases(res, "l"),
        "ideal_paddle": {"area_m2": area, "path_m": path, "cd": params.cd_normal,
                         "drag_carried_by_arms_n": carried, "bounds": bounds},
        "groups": {"arms": list(ARMS), "legs": list(LEGS), "segments": list(GROUPS)},
    }


def print_report(b: dict) -> None:
    print(f"{b['stroke']} on the {b['body']} body, {b['seconds']:g} s ({b['layers']} layers): "
          f"{b['speed_m_s']:.3f} m/s at {b['stroke_rate_hz']:.2f} Hz, "
          f"{b['distance_per_stroke_m']:.2f} m/stroke; muscle power "
          f"{b['muscle_power_mean_w']:.0f} W net, {b['muscle_power_positive_mean_w']:.0f} W "
          f"positive; roll {b['roll_shoulders_deg']:.0f}/{b['roll_hips_deg']:.0f} deg, "
          f"incline {b['trunk_incline_deg']:.0f} deg")
    print(f"towed drag at this speed {b['towed_drag_n']:.1f} N: {b['towed_drag_power_w']:.1f} W "
          f"({100 * b['towed_share_of_muscle_power']:.0f} % of the net muscle power)\n")
    print(f"{'joints':<12}{'net W':>8}{'pos W':>8}{'neg W':>8}{'damp W':>8}{'limit W':>9}")
    for g, r in b["joints"].items():
        print(f"{g:<12}{r['net_w']:8.1f}{r['positive_w']:8.1f}{r['negative_w']:8.1f}"
              f"{r['damping_w']:8.1f}{r['limits_w']:9.2f}")
    print(f"{'all':<12}{b['joints_net_w']:8.1f}{b['joints_positive_w']:8.1f}"
          f"{b['joints_negative_w']:8.1f}\n")
    w = b["water"]
    print(f"{'water':<12}{'into W':>8}{'thrust W':>10}{'slip W':>8}")
    for g, r in w["segments"].items():
        print(f"{g:<12}{r['water_w']:8.1f}{-r['against_progress_w']:10.1f}{r['slip_w']:8.1f}")
    print(f"{'all':<12}{w['water_w']:8.1f}{'':>10}{w['slip_w']:8.1f}")
    for n in ("arms", "legs"):
        eff = w[f"{n}_froude_efficiency"]
        print(f"{n}: thrust {w[f'{n}_thrust_power_w']:.1f} of {w[f'{n}_water_w']:.1f} W, "
              f"Froude efficiency {'-' if eff is None else f'{eff:.2f}'}")
    e = b["energy"]
    print(f"\nenergy: muscles {e['muscle_net_w']:.1f} W + limits {e['limits_w']:.1f} = water "
          f"{e['water_w']:.1f} + d(KE+PE)/dt {e['d_energy_dt_w']:.1f} (residual "
          f"{e['balance_residual_w']:.1f} W); internal KE {e['internal_kinetic_mean_j']:.1f} J "
          f"mean, churned at {e['internal_kinetic_churn_w']:.1f} W")
    lg = b["legs"]
    print(f"legs: joints {lg['joint_net_w']:.1f} W net ({lg['joint_positive_w']:.1f} positive) "
          f"for {lg['thrust_w']:.1f} W of thrust ({lg['water_w']:.1f} W into the water by "
          f"shanks and feet, thighs {lg['thigh_water_w']:.1f})\n")
    print(f"{'left arm':<10}{'water W':>9}{'thrust W':>10}{'hand in air':>13}")
    for r in b["left_arm_phases"]:
        print(f"{r['phase']:<10.1f}{r['water_w']:9.1f}{r['thrust_w']:10.1f}"
              f"{100 * r['hand_in_air']:12.0f}%")
    ip = b["ideal_paddle"]
    print(f"\nideal paddles (hand + forearm {ip['area_m2']:.3f} m^2 at CD {ip['cd']:g}, "
          f"{ip['path_m']:.2f} m straight back; the arms carried "
          f"{ip['drag_carried_by_arms_n']:.1f} N):")
    print(f"{'case':<28}{'v m/s':>7}{'drag N':>8}{'Hz':>6}{'slip':>7}{'eff':>6}{'arms W':>8}")
    for k, r in ip["bounds"].items():
        print(f"{k:<28}{r['speed_m_s']:7.2f}{r['drag_n']:8.1f}{r['rate_hz']:6.2f}"
              f"{r['slip_m_s']:7.2f}{r['froude_efficiency']:6.2f}{r['power_w']:8.0f}")


def parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--stroke", default="crawl", help="a bundled stroke or a stroke file")
    ap.add_argument("--body", choices=("box", "rounded"), default="rounded")
    ap.add_argument("--seconds", type=float, default=30.0)
    ap.add_argument("--rate", type=float, default=None, help="stroke rate [cycles/s]")
    ap.add_argument("--layers", choices=("basic", "cycle", "all"), default="all")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--json", help="write the budget here")
    return ap


def main(argv: list[str] | None = None) -> int:
    a = parser().parse_args(argv)
    b = budget(a.stroke, a.body, a.seconds, a.rate, a.layers, a.seed)
    print_report(b)
    if a.json:
        with open(a.json, "w") as fh:
            json.dump(b, fh, indent=1)
    return 0


if __name__ == "__main__":
    sys.exit(main())
