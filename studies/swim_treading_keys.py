"""Solve the treading stroke's sculling keys by inverse kinematics and print them as
stroke-file TOML (pasted into flapsim/swim/data/strokes/treading.toml).

The scull: both arms out to the sides, nearly straight, ``elev`` degrees below the
horizontal, sweeping forwards and backwards ``amp`` degrees about the side direction
(centre ``psi0``), palms down and pitched ``pitch`` degrees with the leading edge up in
both directions (a palm moving sideways makes lift only when pitched). Keeping the
lift beside the body, level with the shoulders, adds no pitching moment; the ``lean``
perturbation moves the sweep's centre ``lean`` degrees forwards, which the feedback
layer uses to keep the swimmer upright (open loop, the upright scull tips over
forwards or backwards within ~5 s: an unstable balance, as it is for people).

    python studies/swim_treading_keys.py            # default numbers
    python studies/swim_treading_keys.py --pitch 45 --amp 30
"""

from __future__ import annotations

import argparse
import math
import sys

import mujoco
import numpy as np
from scipy.optimize import least_squares

from flapsim.swim.model import Swimmer, SwimmerParams
from flapsim.swim.strokes import ANATOMY, ball_quat


class LeftArm:
    """Forward kinematics of the left arm of the upright swimmer (world = standing frame)."""

    def __init__(self) -> None:
        self.sw = Swimmer(SwimmerParams(world="bare"))
        self.sw.reset("upright")
        m = self.sw.model
        jq = lambda n: int(m.jnt_qposadr[mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, n)])  # noqa: E731
        self.shoulder, self.elbow, self.pron = jq("shoulder_l"), jq("elbow_flex_l"), jq("elbow_pron_l")
        self.signs = ANATOMY["shoulder_l"][3]

    def directions(self, flex: float, abd: float, rot: float, elbow: float, pron: float
                   ) -> tuple[np.ndarray, np.ndarray]:
        """(upper-arm direction, palm normal) in world axes for the given angles [deg]."""
        m, d = self.sw.model, self.sw.data
        d.qpos[self.shoulder:self.shoulder + 4] = ball_quat(flex, abd, rot, self.signs)[0]
        d.qpos[self.elbow] = math.radians(elbow)
        d.qpos[self.pron] = math.radians(pron)
        mujoco.mj_kinematics(m, d)
        upper = -d.xmat[self.sw.body["upper_arm_l"]].reshape(3, 3)[:, 2]
        palm = -d.xmat[self.sw.body["hand_l"]].reshape(3, 3)[:, 1]
        return upper, palm


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v)


def solve(arm: LeftArm, amp: float, elev: float, pitch: float, psi0: float = 0.0,
          nkeys: int = 8, elbow: float = 0.0, pron: float = 0.0) -> np.ndarray:
    """Shoulder (flex, abd, rot) [deg] at phases k/nkeys; the hand is forwardmost at 0.25."""
    x = np.array([0.0, 70.0, 0.0])
    out = []
    for k in range(nkeys):
        ph = 2 * math.pi * k / nkeys
        psi = math.radians(psi0 + amp * math.sin(ph))  # + = forwards of the side direction
        moving = math.cos(ph)  # + = sweeping forwards
        e = math.radians(elev)
        upper = np.array([math.sin(psi) * math.cos(e), math.cos(psi) * math.cos(e), -math.sin(e)])
        motion = np.array([math.cos(psi), -math.sin(psi), 0.0]) * np.sign(moving)
        tilt = math.radians(pitch) * min(1.0, 2.0 * abs(moving))
        palm = _unit(np.array([0.0, 0.0, -1.0]) * math.cos(tilt) + motion * math.sin(tilt))

        def residual(v: np.ndarray, upper: np.ndarray = upper, palm: np.ndarray = palm) -> np.ndarray:
            u, p = arm.directions(v[0], v[1], v[2], elbow, pron)
            return np.concatenate([3.0 * (u - upper), 1.5 * (p - palm)])

        best = None
        for turn in (0.0, 45.0, -45.0, 90.0, -90.0):  # rot is periodic: try a few starts
            lo, hi = np.array([-90.0, -30.0, -180.0]), np.array([180.0, 180.0, 180.0])
            start = np.clip(x + np.array([0.0, 0.0, turn]), lo, hi)
            r = least_squares(residual, start, bounds=(lo, hi))
            if best is None or r.cost < best.cost:
                best = r
        x = best.x
        out.append(x.copy())
    return np.asarray(out)


def _keys(phases: np.ndarray, values: np.ndarray) -> str:
    return "[" + ", ".join(f"[{p:.3f}, {v:.0f}]" for p, v in zip(phases, values, strict=True)) + "]"


def parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--amp", type=float, default=35.0, help="sweep half-angle [deg]")
    ap.add_argument("--elev", type=float, default=10.0, help="arm below horizontal [deg]")
    ap.add_argument("--pitch", type=float, default=55.0, help="palm pitch [deg]")
    ap.add_argument("--lean", type=float, default=25.0, help="lean perturbation [deg]")
    ap.add_argument("--keys", type=int, default=8)
    return ap


def main(argv: list[str] | None = None) -> int:
    ap = parser()
    a = ap.parse_args(argv)
    arm = LeftArm()
    phases = np.arange(a.keys) / a.keys
    fwd = solve(arm, a.amp, a.elev, a.pitch, a.lean, a.keys)
    back = solve(arm, a.amp, a.elev, a.pitch, -a.lean, a.keys)
    # one perturbation, weight -1..1: keys and offsets are the mean and half the
    # difference of the two solved sculls, so that keys + w * offsets is exactly the
    # forward (w = 1) or backward (w = -1) scull
    base = 0.5 * (fwd + back)
    off = 0.5 * (fwd - back)
    print("[keys.shoulder_l]")
    for j, dof in enumerate(("flex", "abd", "rot")):
        print(f"{dof} = {_keys(phases, base[:, j])}")
    print("\n[perturb.lean.keys.shoulder_l]")
    for j, dof in enumerate(("flex", "abd", "rot")):
        print(f"{dof} = {_keys(phases, off[:, j])}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
