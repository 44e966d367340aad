"""State signals for the swimmer's feedback rules (the perturbation layers).

Every signal is measured in the world frame, whose +x is the swimmer's initial heading
(the simulation starts every stroke facing +x), relative to a reference point (the
start position, or a target):

* ``tilt_x``, ``tilt_y``: x and y components of the upper trunk's head-ward axis: the
  sine of an upright swimmer's forward and leftward lean [-];
* ``tilt_rate_x``, ``tilt_rate_y``: their time derivatives [1/s];
* ``offset_x``, ``offset_y``: centre of mass minus the reference [m];
* ``vel_x``, ``vel_y``: centre-of-mass velocity [m/s];
* ``heading_error``: the desired heading minus the swimmer's heading, wrapped to
  (-pi, pi] [rad]; positive = the swimmer should turn left. The heading is the
  horizontal direction of the trunk's forward axis (head-ward when prone, anterior
  when upright); the desired heading is the start heading (0) unless a target sets it
  (:mod:`flapsim.swim.goals`);
* ``heading_rate``: the trunk's turning rate about the vertical [rad/s], + = left.
"""

from __future__ import annotations

import math

import mujoco
import numpy as np

SIGNALS = ("tilt_x", "tilt_y", "tilt_rate_x", "tilt_rate_y", "offset_x", "offset_y",
           "vel_x", "vel_y", "heading_error", "heading_rate")


def wrap_angle(a: float) -> float:
    """``a`` wrapped to (-pi, pi] [rad]."""
    return float(math.pi - (math.pi - a) % (2.0 * math.pi))


def heading(data: mujoco.MjData, trunk: int, forward_axis: int) -> float:
    """Horizontal direction [rad, from +x towards +y] of body ``trunk``'s local axis
    ``forward_axis`` (0 = x, 2 = z)."""
    f = data.xmat[trunk].reshape(3, 3)[:, forward_axis]
    return float(math.atan2(f[1], f[0]))


def signals(model: mujoco.MjModel, data: mujoco.MjData, trunk: int, root: int,
            reference: np.ndarray, forward_axis: int = 2, desired_heading: float = 0.0
            ) -> dict[str, float]:
    """The :data:`SIGNALS` for body ``trunk`` (tilt, heading along its local axis
    ``forward_axis``) and the subtree of ``root`` (centre of mass) relative to
    ``reference`` (x, y) [m], steering towards ``desired_heading`` [rad]. Needs positions and velocities
    current (after a step or ``mj_forward``); computes subtree velocities itself."""
    axis = data.xmat[trunk].reshape(3, 3)[:, 2]
    # d(axis)/dt = omega x axis, omega = the trunk's world angular velocity
    omega = data.cvel[trunk][:3]
    rate = np.cross(omega, axis)
    mujoco.mj_subtreeVel(model, data)
    com = data.subtree_com[root]
    vel = data.subtree_linvel[root]
    return {
        "tilt_x": float(axis[0]), "tilt_y": float(axis[1]),
        "tilt_rate_x": float(rate[0]), "tilt_rate_y": float(rate[1]),
        "offset_x": float(com[0] - reference[0]), "offset_y": float(com[1] - reference[1]),
        "vel_x": float(vel[0]), "vel_y": float(vel[1]),
        "heading_error": wrap_angle(desired_heading - heading(data, trunk, forward_axis)),
        "heading_rate": float(omega[2]),
    }


def weight(gains: dict[str, float], bias: float, values: dict[str, float]) -> float:
    """``bias + sum(gain * signal)`` clipped to [-1, 1]."""
    w = bias + sum(g * values[k] for k, g in gains.items())
    return float(min(1.0, max(-1.0, w)))
