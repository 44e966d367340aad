"""Tow the swimmer in a streamlined glide and compare its passive drag with people's.

The body is held still in a streamline (arms overhead, feet pointed, everything else
straight), face down and level, while the water streams past at speed v; the
hydrodynamic force along the body (the fluid model of flapsim.swim on the box faces:
AR-0.2 plate, friction, front-facing faces) is the passive drag. Two depths: at the
surface (the prone start height: the back at the water line, faces above it feel
nothing) and fully submerged (1 m down).

Measured people (towed, streamlined): Narita, Nakashima & Takagi 2017 (J Biomech
54:123) Dp = 23.5 v^2 N for 0.9-1.5 m/s; Haskins et al. 2024 (EJCM) tow tests 20 N at
1 m/s to 100 N at 2 m/s.

    python studies/swim_passive_drag.py [--json out.json]
"""

from __future__ import annotations

import argparse
import json
import sys

import mujoco
import numpy as np

from flapsim.swim.layers import BasicStrokeLayer
from flapsim.swim.model import Swimmer, SwimmerParams
from flapsim.swim.strokes import parse_stroke

STREAMLINE = {
    "posture": "prone",
    "pose": {"shoulder_l.flex": 180, "shoulder_r.flex": 180, "shoulder_l.abd": -8,
             "shoulder_r.abd": -8, "elbow_l.pronation": 90, "elbow_r.pronation": 90,
             "ankle_l.plantar": 70, "ankle_r.plantar": 70},
}
SPEEDS = (0.5, 1.0, 1.5, 2.0)
#: Narita et al. 2017: passive drag of towed swimmers, Dp = K v^2 [N]
NARITA_K = 23.5


def tow(depth: float | None) -> list[float]:
    """Drag [N] at each of SPEEDS; ``depth`` None = at the surface (the prone start)."""
    sw = Swimmer(SwimmerParams())
    pose = BasicStrokeLayer(sw, parse_stroke(STREAMLINE, "<streamline>")).start_pose(0.0)
    sw.reset("prone", height=None if depth is None else -depth, qpos_joints=pose)
    m, d = sw.model, sw.data
    out = []
    for v in SPEEDS:
        sw.set_current(np.array([-v, 0.0, 0.0]))  # the water streams towards the feet
        mujoco.mj_forward(m, d)
        r = sw.hydro.evaluate(d)
        out.append(float(-r.body_force[:, 0].sum()))  # force against the swim direction
    return out


def parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--json", help="write the numbers here")
    return ap


def main(argv: list[str] | None = None) -> int:
    ap = parser()
    a = ap.parse_args(argv)
    surface, submerged = tow(None), tow(1.0)
    rows = []
    print(f"{'v [m/s]':>8} {'surface [N]':>12} {'submerged [N]':>14} {'people [N]':>11}")
    for v, s, u in zip(SPEEDS, surface, submerged, strict=True):
        people = NARITA_K * v * v
        rows.append({"speed_m_s": v, "surface_n": s, "submerged_n": u, "people_n": people})
        print(f"{v:8.2f} {s:12.1f} {u:14.1f} {people:11.1f}")
    k_s = float(np.polyfit(np.square(SPEEDS), surface, 1)[0])
    k_u = float(np.polyfit(np.square(SPEEDS), submerged, 1)[0])
    print(f"fit D = K v^2: surface K = {k_s:.1f}, submerged K = {k_u:.1f}; people K = "
          f"{NARITA_K} (Narita et al. 2017): {k_s / NARITA_K:.1f}x / {k_u / NARITA_K:.1f}x")
    if a.json:
        with open(a.json, "w") as f:
            json.dump({"rows": rows, "K_surface": k_s, "K_submerged": k_u,
                       "K_people_narita2017": NARITA_K}, f, indent=1)
    return 0


if __name__ == "__main__":
    sys.exit(main())
