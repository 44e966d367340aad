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

import json
import os
from dataclasses import dataclass
from pathlib import Path

import mujoco
import numpy as np

from flapsim.bird.body.params import DOF_NAMES
from flapsim.bird.control import wingbeat_map
from flapsim.bird.flight import cycle
from flapsim.bird.flight.dove_flight import DoveFlight, FlightConfig
from flapsim.core.errors import DataFileError, InputError
from flapsim.core.io import read_regular

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


def rolled(quat: np.ndarray, angle: float) -> np.ndarray:
    """The orientation ``quat`` (w, x, y, z) turned by ``angle`` (rad) about its own forward
    (x) axis: + rolls the right wing down, as the reduced state's roll."""
    q = np.zeros(4)
    mujoco.mju_mulQuat(q, np.array(quat, float), np.array([np.cos(angle / 2), np.sin(angle / 2), 0, 0]))
    return q


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
        q = rolled(d.qpos[3:7], eps)
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


# -- the banked regulator: gains scheduled on the bank, integral action on the roll error ----

#: Where a bundled dove's turn trims live: ``<stem>_turn_trims.json`` beside the databases
#: (``studies/dove_turn_trim.py --json`` writes them).
TRIMS_DIR = Path(__file__).resolve().parent / "data"
#: Wingbeats of its trim flown from the banked start before the map is measured there.
BANK_SETTLE = 2


def bank_state(fl: DoveFlight, snap: cycle.Snapshot, bank_deg: float) -> cycle.Snapshot:
    """``snap`` rolled by ``bank_deg`` about the trunk's forward axis (+: right wing down, as
    the reduced state's roll) and turning at the coordinated rate g tan(phi) / V about the
    vertical (a right bank turns right), its joints and velocity as they were."""
    m, d = fl.model, fl.data
    cycle.restore(fl, snap)
    phi = np.radians(bank_deg)
    q = rolled(d.qpos[3:7], phi)
    d.qpos[3:7] = q
    R = np.zeros(9)
    mujoco.mju_quat2Mat(R, q)
    g = float(np.linalg.norm(m.opt.gravity))
    rate = -g * np.tan(phi) / max(float(np.linalg.norm(d.qvel[0:3])), 1e-9)
    d.qvel[3:6] = R.reshape(3, 3).T @ np.array([0.0, 0.0, rate])  # the body frame's
    mujoco.mj_forward(m, d)
    return cycle.snapshot(fl)


@dataclass(frozen=True)
class TurnTrims:
    """Wingbeats that hold a dove in steady banked turns (right banks; the left ones are their
    mirror images), searched by ``studies/dove_turn_trim.py`` around a reference wingbeat."""

    banks_deg: np.ndarray
    """(n,) banks, deg, increasing, > 0."""
    wingbeats: np.ndarray
    """(n, 29) the wingbeat holding each."""
    P0: np.ndarray
    """(29,) the reference wingbeat they were searched around (biases included)."""

    @classmethod
    def load(cls, path: str | os.PathLike) -> TurnTrims:
        """Read a trims file (one-line errors for a missing, foreign or malformed one)."""
        try:
            raw = json.loads(read_regular(path, "turn-trims file").decode())
            rows = sorted(raw["results"], key=lambda r: float(r["bank_deg"]))
            banks = np.array([float(r["bank_deg"]) for r in rows])
            wb = np.array([np.asarray(r["wingbeat"], float) for r in rows])
            p0_ = np.asarray(raw["P0"], float)
        except (OSError, ValueError, KeyError, TypeError) as e:
            raise DataFileError(f"{path}: not a turn-trims file ({e}); make one with python "
                                "studies/dove_turn_trim.py --json FILE") from None
        if (not len(banks) or wb.shape != (len(banks), p0_.size) or not np.all(banks > 0)
                or np.any(np.diff(banks) <= 0) or not np.all(np.isfinite(wb))
                or not np.all(np.isfinite(p0_))):
            raise DataFileError(f"{path}: a turn-trims file holds distinct banks > 0 deg, each "
                                "with a finite wingbeat of the reference's size")
        return cls(banks, wb, p0_)


def turn_trims_for(P0: np.ndarray) -> TurnTrims | None:
    """The bundled turn trims searched around ``P0`` (None where none are)."""
    for path in sorted(TRIMS_DIR.glob("*_turn_trims.json")):
        t = TurnTrims.load(path)
        if t.P0.shape == np.shape(P0) and np.allclose(t.P0, P0, rtol=0.0, atol=1e-9):
            return t
    return None


def integral_lqr(A: np.ndarray, B: np.ndarray, r: float, z_scale: float) -> np.ndarray:
    """K (12, N_STATE + 1) of the LQR on the map augmented by z, the roll error summed over the
    wingbeats (z' = z + roll), u = -K (x, z): z costs 1 / z_scale^2 beside the trunk's states
    (:func:`lqr`'s), so that a steady roll error, which a steady input needs under ``-K x``
    alone, is worked off."""
    n = len(A)
    Aa = np.zeros((n + 1, n + 1))
    Aa[:n, :n], Aa[n, 0], Aa[n, n] = A, 1.0, 1.0
    Ba = np.vstack([B, np.zeros((1, B.shape[1]))])
    Q = np.zeros((n + 1, n + 1))
    Q[:len(STATE_SCALE), :len(STATE_SCALE)] = np.diag(1.0 / STATE_SCALE ** 2)
    Q[n, n] = 1.0 / z_scale ** 2
    return wingbeat_map.lqr_q(Aa, Ba, Q, r)


@dataclass
class BankedRegulator:
    """The once-a-beat lateral regulator for a dove that banks to turn: its gain is designed
    on the lateral map measured around each of the dove's turn trims and interpolated on the
    trunk's roll at the wingbeat's start (the level map's gain, designed for level flight, does
    not hold the 30 and 45 deg turns: docs/design/flight.md), and it sums the roll error over
    the wingbeats (integral action: a bank is held only by a steady input).
    dP = directions^T clip(-K(roll) (x - x_target, z), +-:data:`U_MAX`)."""

    banks: np.ndarray
    """(n,) rad, increasing from 0 (level)."""
    K: np.ndarray
    """(n, 12, N_STATE + 1) the gain at each."""
    directions: np.ndarray
    A: np.ndarray
    """The level map (as :class:`LateralRegulator`'s)."""
    B: np.ndarray
    z_scale: float
    """The summed roll error [rad] that costs as much as 10 deg of roll now."""
    z: float = 0.0

    def reset(self) -> None:
        """A new flight: nothing summed."""
        self.z = 0.0

    def gain(self, roll: float) -> np.ndarray:
        """K at bank ``|roll|`` (rad), linear between the trims, held beyond the last."""
        a = min(abs(float(roll)), float(self.banks[-1]))
        i = min(int(np.searchsorted(self.banks, a, side="right")) - 1, len(self.banks) - 2)
        w = (a - self.banks[i]) / (self.banks[i + 1] - self.banks[i])
        return (1.0 - w) * self.K[i] + w * self.K[i + 1]

    def offset(self, x: np.ndarray, x_target: np.ndarray) -> np.ndarray:
        """The wingbeat-parameter change for state ``x`` against ``x_target``; sums this
        wingbeat's start error into z (held within 3 z scales: no wind-up)."""
        u = np.clip(-self.gain(x[0]) @ np.append(x - x_target, self.z), -U_MAX, U_MAX)
        self.z = float(np.clip(self.z + (x[0] - x_target[0]), -3 * self.z_scale, 3 * self.z_scale))
        return u @ self.directions


def build_banked_regulator(fl: DoveFlight, P0: np.ndarray, cfg: FlightConfig, r: float,
                           trims: TurnTrims, z_scale: float) -> BankedRegulator:
    """Measure the lateral map in level cruise (as :func:`build_regulator`) and around each
    turn trim (its wingbeat flown :data:`BANK_SETTLE` wingbeats from the level state rolled
    into its bank), and design each gain with input cost ``r`` and integral scale ``z_scale``
    (rad). The maps are measured on ``fl``'s dove in still air with every feather, where the
    trims were searched: rolled into a bank in a crosswind or with plucked primaries, the trims
    are no turns, and the gains designed there lost the steady crosswinds."""
    if not (np.isfinite(z_scale) and z_scale > 0):
        raise InputError(f"the banked regulator's integral scale must be > 0, got {z_scale!r}")
    if not (np.isfinite(r) and r > 0):
        raise InputError(f"the lateral regulator's input cost must be > 0, got {r!r}")
    tw = DoveFlight(fl.dove, ref=fl.ref, table=fl.table)
    try:
        return _banked(tw, P0, cfg, r, trims, z_scale)
    finally:
        tw.close()


def _banked(tw: DoveFlight, P0: np.ndarray, cfg: FlightConfig, r: float, trims: TurnTrims,
            z_scale: float) -> BankedRegulator:
    tw.reset(cfg, P0)
    for _ in range(SETTLE):
        cycle.fly_cycle(tw, None, P0, tw.ref)
    level = cycle.snapshot(tw)
    A0, B0 = linearise(tw, P0, level)
    gains = [integral_lqr(A0, B0, r, z_scale)]
    for bank, P in zip(trims.banks_deg, trims.wingbeats, strict=True):
        cycle.restore(tw, bank_state(tw, level, float(bank)))
        for _ in range(BANK_SETTLE):
            cycle.fly_cycle(tw, None, P, tw.ref)
        A, B = linearise(tw, P, cycle.snapshot(tw))
        gains.append(integral_lqr(A, B, r, z_scale))
    return BankedRegulator(np.radians(np.concatenate([[0.0], trims.banks_deg])), np.array(gains),
                           input_directions(len(P0))[1], A0, B0, float(z_scale))
