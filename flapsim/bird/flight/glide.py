"""The dove gliding in a wind tunnel: trunk welded at a pitch, wings held still and spread
(:data:`GLIDE_POSE_DEG`), the air blowing from ahead. What a gliding wing gives at an
angle of attack (lift, drag, each wing's force and downwash), against the published gliding
and momentum-theory numbers (:mod:`flapsim.fluid.induced`, :func:`~flapsim.fluid.coefficients.bird_wing`).
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np

from flapsim.bird.body.model import WING_GROUPS, Dove, build_xml, wing_group
from flapsim.bird.body.params import N_DOF, DoveParams
from flapsim.bird.flight.dove_flight import DoveFlight, FlightConfig
from flapsim.bird.flight.wingbeat import control_table, join, reference_wingbeat
from flapsim.core.errors import InputError
from flapsim.core.loading import load_model

#: The gliding pose, deg: every wing joint straight (no sweep, twist, flex or dihedral), the
#: tail level and its fan half open; tail spread is the last DOF.
GLIDE_POSE_DEG = np.array([0.0] * (N_DOF - 1) + [20.0])


@dataclass(frozen=True)
class GlideResult:
    """Forces on the gliding dove, averaged over the last fifth of the run (world frame: the
    air blows along -x, so lift is +z and drag is -x)."""

    speed: float
    """Air speed, m/s."""
    pitch_deg: float
    """Trunk pitch, nose up, deg."""
    lift_N: float
    """Whole bird's aerodynamic force along +z, N."""
    drag_N: float
    """Whole bird's aerodynamic force along the air's flow (-x), N."""
    wing_force_N: np.ndarray
    """(2, 3) each wing's aerodynamic force (left, right), N."""
    downwash_m_s: np.ndarray
    """(2, 3) each wing's induced air velocity (zeros for a dove without it), m/s."""
    weight_N: float
    """The dove's weight, N."""


def glide_tunnel(pitch_deg: float, speed: float = 10.0, table: str = "bird_wing",
                 induced: bool = False, seconds: float = 0.25,
                 params: DoveParams | None = None) -> GlideResult:
    """Glide at ``speed`` m/s with the trunk pitched ``pitch_deg`` nose up for ``seconds``
    (the feathers' twist and the downwash settle within ~0.05 s) and average the last fifth.
    ``induced``: the wings push and see their own downwash."""
    if not (np.isfinite(speed) and 1.0 <= speed <= 30.0):
        raise InputError(f"glide_tunnel: speed must be 1..30 m/s, got {speed}")
    if not (np.isfinite(pitch_deg) and -30.0 <= pitch_deg <= 45.0):
        raise InputError(f"glide_tunnel: pitch must be -30..45 deg, got {pitch_deg}")
    params = params or DoveParams.load()
    model = load_model(build_xml(params, fixed_trunk_pitch_deg=pitch_deg, induced=induced),
                       is_xml=True)
    dove = Dove.from_model(model, params)
    fl = DoveFlight(dove, reference_wingbeat(), table, (-speed, 0.0, 0.0), use_rollout=False)
    # scales 0: no stroke; translations move every DOF from the reference's mean to the pose
    hold = join(np.zeros(N_DOF), np.radians(GLIDE_POSE_DEG) - fl.ref.mean, 1.0)
    try:
        fl.reset(FlightConfig(speed=0.0, tail_bias_deg=0.0), hold)
        m, d = fl.model, fl.data
        ctrl, _, _ = control_table(fl.ref, hold, m.opt.timestep, fl.kp, fl.kv)
        n = max(10, int(round(seconds / m.opt.timestep)))
        keep = n // 5
        total = np.zeros(3)
        wings = np.zeros((2, 3))
        group = np.array([wing_group(lb) for lb in fl.polygons.labels])
        for k in range(n):
            d.ctrl[:] = ctrl[0]
            mujoco.mj_step(m, d)
            if k >= n - keep:
                rep = fl.aero.evaluate(d)
                total += rep.force.sum(axis=0)
                for g in range(2):
                    wings[g] += rep.force[group == g].sum(axis=0)
        down = (d.qvel[fl.aero.induced_dofs].reshape(len(WING_GROUPS), 3) if induced
                else np.zeros((2, 3)))
        total /= keep
        wings /= keep
        return GlideResult(speed, pitch_deg, float(total[2]), float(-total[0]), wings,
                           down.copy(), float(params.total_mass * 9.81))
    finally:
        fl.close()
