"""A dove's lateral wingbeat-to-wingbeat map, linearised, and a once-a-beat regulator on it.

By the bird's left-right symmetry the lateral part of its state (the trunk's roll, body-frame
sideways velocity, roll rate and yaw rate, and each wing DOF pair's angle and rate difference,
which the servos' lag carries from one wingbeat into the next) decouples to first order from the
longitudinal part, so flying the reference wingbeat P0 from a settled cruise state

    x_{k+1} = A x_k + B u_k

with u the antisymmetric parts of the wing DOFs' scales and translations (the left wing's
parameter up, the right's down: 12 inputs, each in steps of :data:`SCALE_STEP` or
:data:`SHIFT_STEP`). :func:`linearise` measures (A, B) by central differences, one wingbeat
per difference; :func:`lqr` is the discrete linear-quadratic regulator on them, and
:class:`LateralRegulator` adds its ``-K x`` to the wingbeat the learned controller starts from
(:attr:`~flapsim.bird.control.config.ControllerConfig.lateral`). Only the wingbeat's
parameters change, once a beat: the forces are still the feathers' and the servos' torques at
the joints. docs/design/flight.md, "The lateral wingbeat map, and a once-a-beat regulator on
it", gives the numbers.
"""

from __future__ import annotations

import mujoco
import numpy as np

from flapsim.bird.body.params import DOF_NAMES
from flapsim.bird.control import wingbeat_map
from flapsim.bird.flight import cycle
from flapsim.bird.flight.dove_flight import DoveFlight, FlightConfig

#: The trunk's lateral components in the reduced state: roll, v_y, omega_x, omega_z.
TRUNK = (1, 3, 5, 7)
#: The wing DOFs whose left-right differences are states and inputs.
WING_DOFS = ("shoulder_flap", "shoulder_sweep", "shoulder_twist", "elbow_flex", "elbow_twist",
             "wrist_flex")
N_STATE = len(TRUNK) + 2 * len(WING_DOFS)
#: One input step: 2 % of a DOF's stroke (scale) or 1 deg (translation), left up, right down.
SCALE_STEP, SHIFT_STEP = 0.02, np.radians(1.0)
#: Central-difference steps of the state: 1 deg, 0.05 m/s, 0.1 rad/s, 0.1 rad/s for the trunk
#: (small against a push's 0.5-5 m/s, large against round-off), 0.5 deg and 1 rad/s for the
#: DOF pairs (the servos track within a few degrees, at rates of ~50 rad/s).
STATE_STEP = np.concatenate([[np.radians(1.0), 0.05, 0.1, 0.1],
                             np.full(len(WING_DOFS), np.radians(0.5)),
                             np.full(len(WING_DOFS), 1.0)])
#: The regulator's state scales: 10 deg of roll, 0.5 m/s sideways, 1 rad/s of roll and yaw
#: rate cost as much as one input step times ``r`` (the DOF pairs' differences cost nothing).
STATE_SCALE = np.array([np.radians(10.0), 0.5, 1.0, 1.0])
#: The largest input, in steps (10 deg of twist between the wings, 20 % of a stroke).
U_MAX = wingbeat_map.U_MAX
#: Wingbeats flown from the cruise start before the map is measured.
SETTLE = 4


def _pairs() -> list[tuple[int, int]]:
    return [(DOF_NAMES.index(f"l_{n}"), DOF_NAMES.index(f"r_{n}")) for n in WING_DOFS]


def input_directions(n_params: int) -> tuple[list[str], np.ndarray]:
    """Names and wingbeat-parameter directions (12, n_params) of one step of each input."""
    names, rows = [], []
    for il, ir in _pairs():
        for part, off, step in (("scale", 0, SCALE_STEP), ("shift", 1, SHIFT_STEP)):
            e = np.zeros(n_params)
            e[2 * il + off], e[2 * ir + off] = step, -step
            names.append(f"{DOF_NAMES[il][2:]}.{part}")
            rows.append(e)
    return names, np.array(rows)


def lateral_state(fl: DoveFlight) -> np.ndarray:
    """x (:data:`N_STATE`,): the trunk's roll, v_y, omega_x, omega_z, then each wing DOF pair's
    half difference (left minus right) of angle, then of rate."""
    d, dv = fl.data, fl.dove
    pairs = _pairs()
    dq = [(d.qpos[dv.qadr[il]] - d.qpos[dv.qadr[ir]]) / 2 for il, ir in pairs]
    dqd = [(d.qvel[dv.dadr[il]] - d.qvel[dv.dadr[ir]]) / 2 for il, ir in pairs]
    return np.concatenate([fl.reduced_state()[list(TRUNK)], dq, dqd])


def perturb(fl: DoveFlight, j: int, eps: float) -> None:
    """Move component ``j`` of :func:`lateral_state` by ``eps``, the trunk's body-frame
    velocities kept."""
    m, d = fl.model, fl.data
    R = np.zeros(9)
    mujoco.mju_quat2Mat(R, d.qpos[3:7])
    R = R.reshape(3, 3)
    nw = len(WING_DOFS)
    if j == 0:  # roll: the trunk turned about its own forward axis, its body-frame velocity kept
        v_body = R.T @ d.qvel[0:3]
        q = np.zeros(4)
        mujoco.mju_mulQuat(q, d.qpos[3:7], np.array([np.cos(eps / 2), np.sin(eps / 2), 0, 0]))
        d.qpos[3:7] = q
        R2 = np.zeros(9)
        mujoco.mju_quat2Mat(R2, q)
        d.qvel[0:3] = R2.reshape(3, 3) @ v_body
    elif j == 1:
        d.qvel[0:3] += eps * R[:, 1]
    elif j < 4:
        d.qvel[3 if j == 2 else 5] += eps
    else:
        il, ir = _pairs()[(j - 4) % nw]
        arr, adr = (d.qpos, fl.dove.qadr) if j < 4 + nw else (d.qvel, fl.dove.dadr)
        arr[adr[il]] += eps
        arr[adr[ir]] -= eps
    mujoco.mj_forward(m, d)


def linearise(fl: DoveFlight, P: np.ndarray, start: cycle.Snapshot) -> tuple[np.ndarray, np.ndarray]:
    """(A (N_STATE, N_STATE), B (N_STATE, 12)) of the lateral map flying ``P`` from ``start``
    (by central differences: 2 wingbeats per state and per input)."""
    return wingbeat_map.linearise(fl, P, start, lateral_state, perturb, STATE_STEP,
                                  input_directions(len(P))[1])


def lqr(A: np.ndarray, B: np.ndarray, r: float) -> np.ndarray:
    """K (12, N_STATE) of the discrete LQR, u = -K x, with the trunk's states costing
    1 / :data:`STATE_SCALE`^2 and each input step ``r``."""
    return wingbeat_map.lqr(A, B, r, STATE_SCALE)


class LateralRegulator(wingbeat_map.MapRegulator):
    """The once-a-beat lateral regulator (:class:`~flapsim.bird.control.wingbeat_map.MapRegulator`)."""


def build_regulator(fl: DoveFlight, P0: np.ndarray, cfg: FlightConfig, r: float) -> LateralRegulator:
    """Measure the map on a twin of ``fl`` (its own state untouched) flying ``P0`` from
    ``cfg``'s start after :data:`SETTLE` wingbeats, and design the regulator with input cost
    ``r`` (> 0)."""
    tw = wingbeat_map.settled_twin(fl, P0, cfg, SETTLE, "lateral", r)
    A, B = linearise(tw, P0, cycle.snapshot(tw))
    K = wingbeat_map.gain(A, B, r, STATE_SCALE, "lateral")
    return LateralRegulator(K, input_directions(len(P0))[1], A, B)
