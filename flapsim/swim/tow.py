"""Towing: the swimmer's passive drag held in a streamlined glide, against towed people.

The body is held still in a streamline (arms overhead, feet pointed, everything else
straight), face down and level, while the water streams past at each speed; the
hydrodynamic force against the swimming direction (the fluid model of
:class:`flapsim.swim.model.Swimmer`: every force the swim feels, from the same polygons)
is the passive drag. Two depths: at the surface (the prone start, the back at the water
line; a patch above it feels nothing) and with the body's axis ``depth`` under it.

Measured people (towed, streamlined): Narita, Nakashima & Takagi 2017 (J Biomech 54:123)
``Dp = 23.5 v^2`` N for 0.9-1.5 m/s; higher at the surface than 0.5 m under it, by the
waves the body makes (Vennell, Pease & Wilson 2006, J Biomech 39:664). The fluid model has
no wave drag: its surface figure is the submerged one less the dry patches.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import mujoco
import numpy as np

from flapsim.core.errors import InputError
from flapsim.swim.layers import BasicStrokeLayer
from flapsim.swim.model import Swimmer, SwimmerParams
from flapsim.swim.strokes import parse_stroke

#: the streamlined glide: arms overhead, palms together, feet pointed [deg]
STREAMLINE = {
    "posture": "prone",
    "pose": {"shoulder_l.flex": 180, "shoulder_r.flex": 180, "shoulder_l.abd": -8,
             "shoulder_r.abd": -8, "elbow_l.pronation": 90, "elbow_r.pronation": 90,
             "ankle_l.plantar": 70, "ankle_r.plantar": 70},
}
#: Narita et al. 2017: passive drag of towed swimmers, Dp = K v^2 [N s^2/m^2]
NARITA_K = 23.5
#: depth of the submerged tow [m] (Narita's and Vennell's "below the surface")
SUBMERGED_DEPTH = 0.5


@dataclass(frozen=True)
class TowResult:
    """Passive drag per speed at the surface and submerged, and the fitted D = K v^2."""

    #: tow speeds [m/s]
    speeds: tuple[float, ...]
    #: drag at the surface at each speed [N]
    surface_n: tuple[float, ...]
    #: drag with the body's axis SUBMERGED_DEPTH under the surface [N]
    submerged_n: tuple[float, ...]
    #: least-squares K of D = K v^2 at the surface [N s^2/m^2]
    k_surface: float
    #: the same, submerged [N s^2/m^2]
    k_submerged: float
    #: depth of the submerged tow [m]
    depth_m: float

    def summary(self) -> dict:
        return {
            "tow_speeds_m_s": list(self.speeds),
            "tow_drag_surface_n": list(self.surface_n),
            "tow_drag_submerged_n": list(self.submerged_n),
            "tow_depth_submerged_m": self.depth_m,
            "tow_drag_coefficient": self.k_surface,
            "tow_drag_coefficient_submerged": self.k_submerged,
            "tow_drag_coefficient_people_narita2017": NARITA_K,
            "tow_ratio_to_people": self.k_surface / NARITA_K,
            "wave_drag_modelled": False,
        }


def fit_k(speeds: Sequence[float], drag: Sequence[float]) -> float:
    """Least-squares K of D = K v^2 through the origin [N s^2/m^2]."""
    v2 = np.square(np.asarray(speeds, dtype=float))
    return float(v2 @ np.asarray(drag, dtype=float) / (v2 @ v2))


def tow_drag(speeds: Sequence[float], params: SwimmerParams | None = None,
             depth: float | None = None) -> list[float]:
    """Passive drag [N] of the streamlined swimmer at each speed [m/s]; ``depth`` None is
    at the surface (the prone start height), else the pelvis that far under it [m]."""
    sp = [float(v) for v in speeds]
    if not sp or any(not (np.isfinite(v) and 0.0 < v <= 5.0) for v in sp):
        raise InputError(f"tow speeds must be 0..5 m/s (people swim at most ~2.4), got {speeds}")
    sw = Swimmer(params or SwimmerParams())
    pose = BasicStrokeLayer(sw, parse_stroke(STREAMLINE, "<streamline>")).start_pose(0.0)
    level = sw.params.water_level
    sw.reset("prone", height=None if depth is None else level - depth, qpos_joints=pose)
    m, d = sw.model, sw.data
    out = []
    for v in sp:
        sw.set_current(np.array([-v, 0.0, 0.0]))  # the water streams towards the feet
        mujoco.mj_forward(m, d)
        r = sw.hydro.evaluate(d)
        out.append(float(-r.body_force[:, 0].sum()))  # the force against the swim direction
    return out


def tow(speeds: Sequence[float], params: SwimmerParams | None = None,
        depth: float = SUBMERGED_DEPTH) -> TowResult:
    """Tow at the surface and ``depth`` under it; fit D = K v^2 to each."""
    surface = tow_drag(speeds, params)
    under = tow_drag(speeds, params, depth)
    sp = tuple(float(v) for v in speeds)
    return TowResult(sp, tuple(surface), tuple(under), fit_k(sp, surface), fit_k(sp, under),
                     depth)
