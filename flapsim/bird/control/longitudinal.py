"""A dove's longitudinal wingbeat-to-wingbeat map, linearised, and a once-a-beat regulator on it.

The symmetric counterpart of :mod:`flapsim.bird.control.lateral`: by the bird's left-right
symmetry its longitudinal state (the trunk's pitch, body-frame forward and normal velocity and
pitch rate, each wing DOF pair's mean angle and rate, and the tail's bend) decouples
to first order from the lateral one, so flying the reference wingbeat P0 from a settled cruise
state ``x*`` is

    x_{k+1} - x* = A (x_k - x*) + B u_k

with u the symmetric parts of the wing DOFs' scales and translations (both wings' parameter
moved the same way), the tail's, and the timewarp: 15 inputs, each in steps of
:data:`SCALE_STEP`, :data:`SHIFT_STEP` or :data:`TIMEWARP_STEP`. :func:`linearise` measures
(A, B) by central differences, one wingbeat per difference; :func:`lqr` is the discrete
linear-quadratic regulator on them, and :class:`LongitudinalRegulator` adds its ``-K (x - x_t)``
to the wingbeat the learned controller starts from
(:attr:`~flapsim.bird.control.config.ControllerConfig.longitudinal`). Only the wingbeat's
parameters change, once a beat: the forces are still the feathers' and the servos' torques at
the joints. docs/design/flight.md, "A longitudinal regulator beside it", gives the numbers.
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np

from flapsim.bird.body.params import DOF_NAMES
from flapsim.bird.control import wingbeat_map
from flapsim.bird.flight import cycle
from flapsim.bird.flight.dove_flight import DoveFlight, FlightConfig

#: The trunk's longitudinal components in the reduced state: pitch, v_x, v_z, omega_y.
TRUNK = (0, 2, 4, 6)
#: The wing DOFs whose left-right means are states and inputs.
WING_DOFS = ("shoulder_flap", "shoulder_sweep", "shoulder_twist", "elbow_flex", "elbow_twist",
             "wrist_flex")
#: The tail's bend; its spread barely moves the trunk within a wingbeat (a step of it changes
#: the next start state 0.002 as much as the bend's) and its angle carries over unchanged (an
#: eigenvalue of 1 the regulator cannot move), so it is neither a state nor an input.
TAIL_DOFS = ("tail_bend",)
N_DOF_STATES = len(WING_DOFS) + len(TAIL_DOFS)
N_STATE = len(TRUNK) + 2 * N_DOF_STATES
#: One input step: 2 % of a DOF's stroke (scale), 1 deg (translation), 1 % of the period.
SCALE_STEP, SHIFT_STEP, TIMEWARP_STEP = 0.02, np.radians(1.0), 0.01
#: Central-difference steps of the state: 1 deg, 0.05 m/s, 0.05 m/s, 0.1 rad/s for the trunk,
#: 0.5 deg and 1 rad/s for the DOFs (as the lateral map's).
STATE_STEP = np.concatenate([[np.radians(1.0), 0.05, 0.05, 0.1],
                             np.full(N_DOF_STATES, np.radians(0.5)),
                             np.full(N_DOF_STATES, 1.0)])
#: The regulator's state scales: 10 deg of pitch, 0.5 m/s forward and normal, 1 rad/s of pitch
#: rate cost as much as one input step times ``r`` (the DOFs' means cost nothing).
STATE_SCALE = np.array([np.radians(10.0), 0.5, 0.5, 1.0])
#: The largest input, in steps (10 deg of twist on both wings, 20 % of a stroke, 10 % of the
#: period).
U_MAX = wingbeat_map.U_MAX
#: Wingbeats flown from the cruise start before the map is measured.
SETTLE = 4


def _dofs() -> list[tuple[int, ...]]:
    """Each state's DOF indices: a wing pair (left, right) or one tail DOF."""
    return ([(DOF_NAMES.index(f"l_{n}"), DOF_NAMES.index(f"r_{n}")) for n in WING_DOFS]
            + [(DOF_NAMES.index(n),) for n in TAIL_DOFS])


def input_directions(n_params: int) -> tuple[list[str], np.ndarray]:
    """Names and wingbeat-parameter directions (15, n_params) of one step of each input."""
    names, rows = [], []
    for idx in _dofs():
        for part, off, step in (("scale", 0, SCALE_STEP), ("shift", 1, SHIFT_STEP)):
            e = np.zeros(n_params)
            for i in idx:
                e[2 * i + off] = step
            names.append(f"{DOF_NAMES[idx[0]].removeprefix('l_')}.{part}")
            rows.append(e)
    e = np.zeros(n_params)
    e[-1] = TIMEWARP_STEP
    names.append("timewarp")
    rows.append(e)
    return names, np.array(rows)


def longitudinal_state(fl: DoveFlight) -> np.ndarray:
    """x (:data:`N_STATE`,): the trunk's pitch, v_x, v_z, omega_y, then each wing DOF pair's
    mean angle and the tail's, then their rates."""
    d, dv = fl.data, fl.dove
    q = [np.mean([d.qpos[dv.qadr[i]] for i in idx]) for idx in _dofs()]
    qd = [np.mean([d.qvel[dv.dadr[i]] for i in idx]) for idx in _dofs()]
    return np.concatenate([fl.reduced_state()[list(TRUNK)], q, qd])


def perturb(fl: DoveFlight, j: int, eps: float) -> None:
    """Move component ``j`` of :func:`longitudinal_state` by ``eps``, the trunk's body-frame
    velocities kept."""
    m, d = fl.model, fl.data
    R = np.zeros(9)
    mujoco.mju_quat2Mat(R, d.qpos[3:7])
    R = R.reshape(3, 3)
    if j == 0:  # pitch: the trunk turned nose up about its own left axis, body velocity kept
        v_body = R.T @ d.qvel[0:3]
        q = np.zeros(4)
        # the body's y axis points left; nose up is a negative rotation about it
        mujoco.mju_mulQuat(q, d.qpos[3:7], np.array([np.cos(eps / 2), 0, -np.sin(eps / 2), 0]))
        d.qpos[3:7] = q
        R2 = np.zeros(9)
        mujoco.mju_quat2Mat(R2, q)
        d.qvel[0:3] = R2.reshape(3, 3) @ v_body
    elif j == 1:
        d.qvel[0:3] += eps * R[:, 0]
    elif j == 2:
        d.qvel[0:3] += eps * R[:, 2]
    elif j == 3:
        d.qvel[4] += eps
    else:
        k = j - len(TRUNK)
        idx = _dofs()[k % N_DOF_STATES]
        arr, adr = (d.qpos, fl.dove.qadr) if k < N_DOF_STATES else (d.qvel, fl.dove.dadr)
        for i in idx:
            arr[adr[i]] += eps
    mujoco.mj_forward(m, d)


def linearise(fl: DoveFlight, P: np.ndarray, start: cycle.Snapshot) -> tuple[np.ndarray, np.ndarray]:
    """(A (N_STATE, N_STATE), B (N_STATE, 15)) of the longitudinal map flying ``P`` from
    ``start`` (by central differences: 2 wingbeats per state and per input)."""
    return wingbeat_map.linearise(fl, P, start, longitudinal_state, perturb, STATE_STEP,
                                  input_directions(len(P))[1])


def lqr(A: np.ndarray, B: np.ndarray, r: float) -> np.ndarray:
    """K (15, N_STATE) of the discrete LQR, u = -K x, with the trunk's states costing
    1 / :data:`STATE_SCALE`^2 and each input step ``r``."""
    return wingbeat_map.lqr(A, B, r, STATE_SCALE)


@dataclass(frozen=True)
class LongitudinalRegulator(wingbeat_map.MapRegulator):
    """The once-a-beat longitudinal regulator
    (:class:`~flapsim.bird.control.wingbeat_map.MapRegulator`), the DOFs' part of its target the
    settled cruise's (:attr:`trim`)."""

    trim: np.ndarray
    """x* (:data:`N_STATE`,): the settled cruise's state at a wingbeat's start."""

    def target(self, trunk: np.ndarray | None) -> np.ndarray:
        """The state regulated toward: the trunk's ``trunk`` (pitch, v_x, v_z, omega_y; None:
        the trim's), the DOFs' the trim's."""
        xt = self.trim.copy()
        if trunk is not None:
            xt[:len(TRUNK)] = trunk
        return xt


def build_regulator(fl: DoveFlight, P0: np.ndarray, cfg: FlightConfig, r: float) -> LongitudinalRegulator:
    """Measure the map on a twin of ``fl`` (its own state untouched) flying ``P0`` from
    ``cfg``'s start after :data:`SETTLE` wingbeats, and design the regulator with input cost
    ``r`` (> 0)."""
    tw = wingbeat_map.settled_twin(fl, P0, cfg, SETTLE, "longitudinal", r)
    start = cycle.snapshot(tw)
    A, B = linearise(tw, P0, start)
    # the map's fixed point from one more wingbeat: its slowest mode (a phugoid of ~40
    # wingbeats' period) has not settled after SETTLE of them
    cycle.restore(tw, start)
    x0 = longitudinal_state(tw)
    cycle.fly_cycle(tw, None, P0, tw.ref)
    x1 = longitudinal_state(tw)
    trim = x0 - np.linalg.solve(A - np.eye(len(A)), x1 - x0)
    K = wingbeat_map.gain(A, B, r, STATE_SCALE, "longitudinal")
    return LongitudinalRegulator(K, input_directions(len(P0))[1], A, B, trim)
