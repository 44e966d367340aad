"""Induced flow: the air a lifting surface pushes down, seen by its own polygons.

Blade-element momentum theory (as in Parslew & Crowther 2010, J Biomech 43:3191): a group of
polygons (one wing) acts on the air through an actuator disk of area ``A`` (per wing half of
the span's disk, ``pi b^2 / 8``). Momentum theory in forward flight (Glauert) gives the air's
velocity at the disk, opposed to the group's force ``F_perp`` normal to the free stream
``V``,

    ``w = -F_perp / (2 rho A |V + w|)``,

the uniform downwash of an elliptically loaded wing: a glide then pays the induced drag
``L^2 / (q pi b^2)`` (span efficiency 1). Every polygon of the group sees ``w`` added to the
fluid's velocity, so its angle of attack, lift and drag follow, and so does the power.

The downwash builds up over a time ``tau`` (the wake's response; :data:`TAU_S`) rather than
at once: it is the velocity of a DOF of its own, three slide joints (world x, y, z) of a
small body hung from the world per group, with damping ``c = m / tau``. The force engine
pushes that DOF with ``c w`` (the momentum value from the group's force this step), so
MuJoCo integrates ``tau dw/dt = w_momentum - w`` implicitly, and snapshots,
``mujoco.rollout`` and repeated ``mj_forward`` calls carry the downwash like any state (the
trick :mod:`flapsim.fluid.hinges` uses for the feather twist). The slide joints' positions
(the integrated downwash) mean nothing.
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np
from numba import njit

from flapsim.core.errors import InputError, ModelError

#: Time constant of the downwash's response to a change of lift, s: a tenth of the dove's
#: wingbeat (the wake leaves a 0.1 m chord in ~0.015 s at 7 m/s); short enough that the
#: downwash follows the stroke, long enough to be integrated stably at the flight's 2400 Hz.
TAU_S = 0.01
#: Mass of each downwash body, kg: it only sets the damping (m / tau); gravity is compensated.
MASS_KG = 1e-3
#: Floor of the speed through the disk, m/s, so that a bird at rest starts with finite downwash.
MIN_SPEED = 0.5
AXES = "xyz"


def induced_xml(groups: tuple[str, ...], tau_s: float = TAU_S, mass_kg: float = MASS_KG) -> str:
    """MJCF bodies (inside ``<worldbody>``) holding each group's downwash: per group a body
    ``{group}_induced`` on three slide joints ``{group}_induced_{x,y,z}`` with damping
    ``mass / tau``, no contact, weight compensated."""
    if not (np.isfinite(tau_s) and tau_s > 0 and np.isfinite(mass_kg) and mass_kg > 0):
        raise ModelError(f"induced flow needs tau > 0 and mass > 0, got {tau_s}, {mass_kg}")
    c = mass_kg / tau_s
    out = []
    for g in groups:
        out.append(f'    <body name="{g}_induced" gravcomp="1">')
        out.append(f'      <inertial pos="0 0 0" mass="{mass_kg:.6g}" diaginertia="1e-9 1e-9 1e-9"/>')
        for ax, vec in zip(AXES, ("1 0 0", "0 1 0", "0 0 1"), strict=True):
            out.append(f'      <joint name="{g}_induced_{ax}" type="slide" axis="{vec}" '
                       f'limited="false" damping="{c:.6g}"/>')
        out.append("    </body>")
    return "\n".join(out) + "\n"


@dataclass(frozen=True)
class InducedFlow:
    """Which polygons push which downwash.

    ``groups``: group names (their MJCF bodies from :func:`induced_xml`); ``polygon_group``:
    per polygon the index of its group, -1 for a polygon that neither pushes nor sees
    induced flow (a trunk, a tail); ``disk_area``: per group the actuator disk's area, m^2;
    ``reference_body``: the body whose velocity is the free stream (a bird's trunk)."""

    groups: tuple[str, ...]
    polygon_group: np.ndarray
    disk_area: tuple[float, ...]
    reference_body: str

    def __post_init__(self) -> None:
        g = np.ascontiguousarray(self.polygon_group, dtype=np.int64)
        object.__setattr__(self, "polygon_group", g)
        if len(self.disk_area) != len(self.groups) or not self.groups:
            raise InputError("InducedFlow needs one disk area per group, and at least one group")
        if not all(np.isfinite(a) and a > 0 for a in self.disk_area):
            raise InputError(f"InducedFlow disk areas must be > 0 m^2, got {self.disk_area}")
        if g.ndim != 1 or g.size == 0 or g.min() < -1 or g.max() >= len(self.groups):
            raise InputError(f"InducedFlow.polygon_group must hold -1..{len(self.groups) - 1}")

    def tables(self, model: mujoco.MjModel) -> tuple[np.ndarray, np.ndarray]:
        """(ints, floats) for the kernel: per group its three DOF addresses, then the
        reference body; per group its disk area."""
        ints = []
        for g in self.groups:
            for ax in AXES:
                j = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, f"{g}_induced_{ax}")
                if j < 0 or model.jnt_type[j] != mujoco.mjtJoint.mjJNT_SLIDE:
                    raise ModelError(f"the model has no slide joint {g}_induced_{ax} for the "
                                     f"induced flow; build it with its induced-flow bodies")
                if model.dof_damping[model.jnt_dofadr[j]] <= 0:
                    raise ModelError(f"{g}_induced_{ax} needs damping (mass / tau)")
                ints.append(int(model.jnt_dofadr[j]))
        ref = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, self.reference_body)
        if ref < 0:
            raise ModelError(f"no body {self.reference_body!r} for the induced flow's free stream")
        ints.append(int(ref))
        return (np.array(ints, dtype=np.int64),
                np.array([float(a) for a in self.disk_area], dtype=float))


@njit(cache=True, inline="always")
def momentum_downwash(fx, fy, fz, vx, vy, vz, wx, wy, wz, rho, area):
    """The momentum-theory downwash of a disk of ``area`` pushing the air with ``-f`` (``f``:
    the force on the surfaces) in the free stream ``v`` (air relative to the surfaces), with
    the present downwash ``w`` in the speed through the disk: ``-f_perp / (2 rho A |v + w|)``."""
    sp2 = vx * vx + vy * vy + vz * vz
    px, py, pz = fx, fy, fz
    if sp2 > 1e-12:
        fv = (fx * vx + fy * vy + fz * vz) / sp2
        px -= fv * vx
        py -= fv * vy
        pz -= fv * vz
    sx, sy, sz = vx + wx, vy + wy, vz + wz
    s = max(np.sqrt(sx * sx + sy * sy + sz * sz), MIN_SPEED)
    k = -1.0 / (2.0 * rho * area * s)
    return k * px, k * py, k * pz
