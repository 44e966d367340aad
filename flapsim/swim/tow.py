"""Towing: the swimmer's passive drag held in a streamlined glide, against towed people.

The body is held still in a streamline (arms overhead, feet pointed, everything else
straight), face down and level, while the water streams past at each speed; the
hydrodynamic force against the swimming direction (the fluid model of
:class:`flapsim.swim.model.Swimmer`: every force the swim feels, from the same polygons)
is the passive drag. Two depths: at the surface (the prone start, the back at the water
line; a patch above it feels nothing) and with the body's axis ``depth`` under it.

Measured people (towed, streamlined): Narita, Nakashima & Takagi 2017 (J Biomech 54:123)
``Dp = 23.5 v^2`` N for 0.9-1.5 m/s; higher at the surface than 0.5 m under it, by the
waves the body makes (Vennell, Pease & Wilson 2006, J Biomech 39:664). The drag is the
surface engine's (pressure and friction) plus the wave-making resistance of
:mod:`flapsim.fluid.waves` on the same polygons, whose one coefficient
:func:`calibrate_waves` fits to people's wave drag at speed (Toussaint, van Stralen & Stevens
2002, ISBS Proceedings 20:279: 11.5 N at 1.89 m/s). The headline ``tow_drag_coefficient`` is
the submerged one, the body's own shape against Narita's; the surface one adds the waves.
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
#: Toussaint, van Stralen & Stevens 2002: wave drag [N] at the mean speed [m/s] of their
#: front crawl swimmers (12.1 % of the active drag); negligible below 1.6 m/s
TOUSSAINT_WAVE_N = 11.5
TOUSSAINT_SPEED = 1.89


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
    #: the wave-making part of surface_n [N]
    wave_surface_n: tuple[float, ...] = ()
    #: the wave-making part of submerged_n [N]
    wave_submerged_n: tuple[float, ...] = ()

    def summary(self) -> dict:
        return {
            "tow_speeds_m_s": list(self.speeds),
            "tow_drag_surface_n": list(self.surface_n),
            "tow_drag_submerged_n": list(self.submerged_n),
            "tow_wave_drag_surface_n": list(self.wave_surface_n),
            "tow_wave_drag_submerged_n": list(self.wave_submerged_n),
            "tow_wave_share_surface": [w / t if t > 0 else 0.0 for w, t in
                                       zip(self.wave_surface_n, self.surface_n, strict=True)],
            "tow_depth_submerged_m": self.depth_m,
            "tow_drag_coefficient": self.k_submerged,
            "tow_drag_coefficient_is": f"submerged ({self.depth_m:g} m under the surface)",
            "tow_drag_coefficient_surface": self.k_surface,
            "tow_drag_coefficient_submerged": self.k_submerged,
            "tow_drag_coefficient_people_narita2017": NARITA_K,
            "tow_ratio_to_people": self.k_submerged / NARITA_K,
            "wave_drag_modelled": bool(any(self.wave_surface_n)),
        }


def fit_k(speeds: Sequence[float], drag: Sequence[float]) -> float:
    """Least-squares K of D = K v^2 through the origin [N s^2/m^2]."""
    v2 = np.square(np.asarray(speeds, dtype=float))
    return float(v2 @ np.asarray(drag, dtype=float) / (v2 @ v2))


def tow_forces(speeds: Sequence[float], params: SwimmerParams | None = None,
               depth: float | None = None) -> tuple[list[float], list[float]]:
    """(surface engine's drag, wave drag) [N] of the streamlined swimmer at each speed
    [m/s]; ``depth`` None is at the surface (the prone start height), else the pelvis that
    far under it [m]."""
    sp = [float(v) for v in speeds]
    if not sp or any(not (np.isfinite(v) and 0.0 < v <= 5.0) for v in sp):
        raise InputError(f"tow speeds must be 0..5 m/s (people swim at most ~2.4), got {speeds}")
    sw = Swimmer(params or SwimmerParams())
    pose = BasicStrokeLayer(sw, parse_stroke(STREAMLINE, "<streamline>")).start_pose(0.0)
    level = sw.params.water_level
    sw.reset("prone", height=None if depth is None else level - depth, qpos_joints=pose)
    m, d = sw.model, sw.data
    hydro, waves = [], []
    for v in sp:
        sw.set_current(np.array([-v, 0.0, 0.0]))  # the water streams towards the feet
        mujoco.mj_forward(m, d)
        r = sw.hydro.evaluate(d)
        hydro.append(float(-r.body_force[:, 0].sum()))  # the force against the swim direction
        waves.append(float(-sw.waves.evaluate(d)[1][:, 0].sum()))
    return hydro, waves


def tow_drag(speeds: Sequence[float], params: SwimmerParams | None = None,
             depth: float | None = None) -> list[float]:
    """Passive drag [N], waves included, of the streamlined swimmer at each speed [m/s]
    (see :func:`tow_forces`)."""
    hydro, waves = tow_forces(speeds, params, depth)
    return [h + w for h, w in zip(hydro, waves, strict=True)]


def tow(speeds: Sequence[float], params: SwimmerParams | None = None,
        depth: float = SUBMERGED_DEPTH) -> TowResult:
    """Tow at the surface and ``depth`` under it; fit D = K v^2 to each."""
    hs, ws = tow_forces(speeds, params)
    hu, wu = tow_forces(speeds, params, depth)
    surface = [h + w for h, w in zip(hs, ws, strict=True)]
    under = [h + w for h, w in zip(hu, wu, strict=True)]
    sp = tuple(float(v) for v in speeds)
    return TowResult(sp, tuple(surface), tuple(under), fit_k(sp, surface), fit_k(sp, under),
                     depth, tuple(ws), tuple(wu))


def calibrate_waves(params: SwimmerParams | None = None) -> float:
    """The wave coefficient ``wave_c_hump`` that gives the rounded body towed at the
    surface Toussaint et al.'s wave drag at their swimmers' speed (the force is linear in
    it: one evaluation at a reference value)."""
    base = params or SwimmerParams(body_shape="rounded")
    ref = 0.01
    probe = SwimmerParams(**{**base.__dict__, "wave_c_hump": ref})
    wave = tow_forces([TOUSSAINT_SPEED], probe)[1][0]
    return ref * TOUSSAINT_WAVE_N / wave
