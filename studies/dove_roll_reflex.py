"""Does a roll reflex inside the wingbeat hold the cruise dove through a sideways push?

The learned controller chooses one wingbeat per beat; the cruise dove (bird-wing section,
induced flow, cruise wingbeat) rolls over within two beats of an 8 N sideways push (the
flight suite's), faster than one choice a beat can catch. This study adds, on top of the
cruise reference wingbeat, a reflex at every 2400 Hz step: the left and right servo targets
of one DOF pair moved apart by ``kd p + kr phi`` rad (p: the trunk's roll rate [rad/s], phi:
its roll [rad]), through the same PD servos and their torque limits (a torque at the actuated
joints, nothing on the trunk). It flies two beats, pushes 8 N to the left for 0.1 s at the
start of the third, flies on, and prints the trunk's roll at every wingbeat's end, the speed,
the height lost and the servos' mean power.

    python studies/dove_roll_reflex.py --dof shoulder_twist \
        --kd 0,0.01,0.02,0.04,-0.01,-0.02,-0.04 --kr 0,0.3,-0.3
"""

from __future__ import annotations

import argparse
import itertools

import mujoco
import numpy as np

from flapsim.bird.body.model import Dove
from flapsim.bird.body.params import DOF_NAMES
from flapsim.bird.flight.dove_flight import CRUISE, DoveFlight
from flapsim.bird.flight.wingbeat import control_table, p0, reference_wingbeat, with_tail_bias
from flapsim.core.io import write_json

PUSH_N, PUSH_S, PUSH_WINGBEAT = 8.0, 0.1, 2


def fly(fl: DoveFlight, ctrl: np.ndarray, pair: tuple[int, int], kd: float, kr: float,
        wingbeats: int) -> dict:
    """The cruise wingbeat ``ctrl`` flown ``wingbeats`` times from the cruise start with the
    reflex on DOF ``pair`` (left, right), the push at :data:`PUSH_WINGBEAT`."""
    m, d = fl.model, fl.data
    trunk = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, "trunk")
    steps = int(round(PUSH_S / m.opt.timestep))
    il, ir = pair
    fl.reset(CRUISE, with_tail_bias(p0(), CRUISE.tail_bias_deg))
    z0, rolls, work = float(d.qpos[2]), [], 0.0
    try:
        for wb in range(wingbeats):
            for k in range(len(ctrl)):
                S = fl.reduced_state()
                u = kd * S[5] + kr * S[1]
                c = ctrl[k].copy()
                # a target moved by u: the servo's ctrl is kp * target + kv * rate
                c[il] += fl.kp[il] * u
                c[ir] -= fl.kp[ir] * u
                d.ctrl[:] = c
                d.xfrc_applied[trunk, 1] = PUSH_N if (wb == PUSH_WINGBEAT and k < steps) else 0.0
                mujoco.mj_step(m, d)
                work += float(d.actuator_force @ d.actuator_velocity) * m.opt.timestep
                if not np.all(np.isfinite(d.qvel[:6])):
                    return {"kd": kd, "kr": kr, "diverged": True}
            rolls.append(float(np.degrees(fl.reduced_state()[1])))
    finally:
        d.xfrc_applied[trunk, :] = 0.0
    after = np.abs(rolls[PUSH_WINGBEAT:])
    return {"kd": kd, "kr": kr, "roll_deg": rolls, "max_roll_after_push_deg": float(after.max()),
            "speed_m_s": float(np.linalg.norm(d.qvel[:3])), "height_change_m": float(d.qpos[2] - z0),
            "servo_power_w": work / float(d.time)}


def parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--dof", default="shoulder_twist",
                    help="the DOF pair moved apart (a name from DOF_NAMES without l_/r_)")
    ap.add_argument("--kd", default="0,0.02,-0.02", help="roll-rate gains, rad per rad/s")
    ap.add_argument("--kr", default="0", help="roll gains, rad per rad")
    ap.add_argument("--wingbeats", type=int, default=8)
    ap.add_argument("--json", default=None)
    return ap


def main(argv: list[str] | None = None) -> None:
    ap = parser()
    a = ap.parse_args(argv)
    if f"l_{a.dof}" not in DOF_NAMES:
        ap.error(f"--dof must be one of {sorted({n[2:] for n in DOF_NAMES if n[1] == '_'})}")
    fl = DoveFlight(Dove.load(induced=True), ref=reference_wingbeat("cruise"), table="bird_wing",
                    use_rollout=False)
    ctrl, _, _ = control_table(fl.ref, with_tail_bias(p0(), CRUISE.tail_bias_deg),
                               fl.model.opt.timestep, fl.kp, fl.kv)
    pair = (DOF_NAMES.index(f"l_{a.dof}"), DOF_NAMES.index(f"r_{a.dof}"))
    rows = []
    for kd, kr in itertools.product(*([float(v) for v in s.split(",")] for s in (a.kd, a.kr))):
        r = fly(fl, ctrl, pair, kd, kr, a.wingbeats)
        rows.append(r)
        if r.get("diverged"):
            print(f"{a.dof} kd {kd:+.3f} kr {kr:+.2f}: diverged")
            continue
        print(f"{a.dof} kd {kd:+.3f} kr {kr:+.2f}: roll at the wingbeats' ends "
              + " ".join(f"{x:+.0f}" for x in r["roll_deg"])
              + f" deg; {r['speed_m_s']:.1f} m/s, {r['height_change_m']:+.2f} m, "
                f"servos {r['servo_power_w']:.1f} W net", flush=True)
    if a.json:
        write_json(a.json, {"dof": a.dof, "push_n": PUSH_N, "runs": rows})


if __name__ == "__main__":
    main()
