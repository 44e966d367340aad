"""Cheaper ways to S0, the end of the reference wingbeat P0 that the learned controller
predicts every wingbeat (``predict="coarse"``: simulated at a coarser step;
``predict="regression"``: regressed from S, experimental). The default simulates P0 at the
flight's own step (:class:`flapsim.bird.control.controller.WingbeatController`)."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Protocol

import mujoco
import numpy as np

from flapsim.bird.control.regression import Regressor
from flapsim.bird.control.targets import rot_z
from flapsim.bird.flight import cycle
from flapsim.bird.flight.dove_flight import DoveFlight
from flapsim.core.errors import InputError


class FlyingController(Protocol):
    """What a predictor reads of the controller that owns it: the flight it steers (the
    controller itself sits a module above, so predictors name only this)."""

    flight: DoveFlight

PREDICT_MODES = ("simulate", "coarse", "regression")

#: Step rate of ``predict="coarse"``'s throw-away wingbeat, Hz (the flight's own is 2400).
COARSE_RATE_HZ = 1600.0


@dataclass
class S0Predictor:
    """S0 (where P0 would end) without simulating P0 on most wingbeats: EXPERIMENTAL, not
    robust (see below); the default is to simulate P0 every wingbeat.

    S alone does not determine S0: the full state also holds the joint angles and rates and
    the feather hinges, which S omits. Over the bundled database (start states after a random
    pre-wingbeat) an S -> S0 regression misses S0 by 10-35 % of dS's spread; along a
    controlled flight (start states after controlled wingbeats) it is biased (vy by 0.05 m/s,
    roll by 0.01 rad) but its error varies slowly. So: a locally weighted linear regression
    S -> S0 over the database's (S, S0) pairs, plus a bias measured by simulating P0 on the
    first ``warmup`` wingbeats after a (re)start (a new flight, or a state the flight did not
    reach by the last controlled wingbeat), then every ``every``-th, and on the next one too
    whenever a simulated wingbeat shows that the prediction would have missed by more than
    ``tolerance``; the bias is low-passed with ``gain``. The world quantities of a predicted
    end (centre-of-mass velocity, trunk position and orientation) are the start's plus the
    change P0 made in the last simulated prediction, in the start's heading frame.

    Measured (bundled database): cruise and the level figure of eight fly as with simulated
    S0 (level figure of eight Ep/Er/Eo/Ef 0.042/0.026/0.011/0.105 against 0.042/0.026/0.010/
    0.098) at 1.4-1.6x the speed, but the rising figure of eight is LOST (wingbeat ~160-250)
    with every variant tried (bias gain 0.5/1, tolerance halved: 212 of 305 wingbeats
    simulated); in its climbing lobe the regression's misses are correlated (vy 0.15-0.4
    m/s, pitch 0.05-0.18 rad). That path is on a knife edge even with S0 simulated: asked
    6.995-7.005 m/s it completes 6 of 7 runs (lost at 7.003), this predictor 2 of 7, and
    Gaussian errors of 1-100 % of the typical miss added to the simulated S0 lose it in 1-3
    of 3 seeds. An S0 model fitted online on the flight's own simulated wingbeats (joint state
    and the last wingbeat as inputs) halved the misses and completed 1 of 7, so it is not offered.
    """

    regressor: Regressor
    """S (8) -> S0 (8)."""
    every: int = 4
    gain: float = 0.5
    warmup: int = 8
    """Wingbeats simulated after a (re)start before predicting: the start's hidden state (a
    reset pose) is unlike a controlled flight's, and the bias moves fast while it settles."""
    tolerance: tuple = (0.02, 0.02, 0.1, 0.1, 0.1)
    """Largest acceptable miss of the prediction (pitch, roll rad; body velocity m/s): when a
    simulated wingbeat shows that the prediction would have missed S0 by more (its
    innovation), the next wingbeat is simulated too, until it would not."""
    _next: int = 0
    bias: np.ndarray = field(default_factory=lambda: np.zeros(8))
    count: int = 0
    """Wingbeats since the last restart (0: the next one simulates)."""
    _last_end: np.ndarray | None = None
    _delta: tuple | None = None

    def __post_init__(self) -> None:
        if int(self.every) < 1:
            raise InputError(f"the S0 prediction simulates every N-th wingbeat, N >= 1; got {self.every}")
        if int(self.warmup) < 1:
            raise InputError(f"the S0 prediction simulates >= 1 wingbeat after a start, got {self.warmup}")
        if not 0.0 < self.gain <= 1.0:
            raise InputError(f"the S0 bias gain must be in (0, 1], got {self.gain}")

    @classmethod
    def from_arrays(cls, S: np.ndarray, S0: np.ndarray, k: int = 200, **kw) -> S0Predictor:
        return cls(Regressor(S, S0, k=k, weights=(1.0, 1.0, 1.0), method="lwlr"), **kw)

    def reset(self) -> None:
        self.count, self.bias[:], self._last_end, self._delta, self._next = 0, 0.0, None, None, 0

    def reference(self, ctl: FlyingController, snap: cycle.Snapshot) -> cycle.CycleEnd:
        """P0's end from ``snap``: simulated (and the bias updated) or predicted."""

        fl = ctl.flight
        if self._last_end is None or not np.array_equal(snap.physics, self._last_end):
            self.reset()  # a new flight, or a state set from outside: measure the bias afresh
        cycle.restore(fl, snap)
        d = fl.data
        S = fl.reduced_state()
        pos, quat, vel = d.qpos[0:3].copy(), d.qpos[3:7].copy(), fl.com_velocity()
        R = rot_z(cycle.heading_and_climb(vel)[0])
        guess = self.regressor.predict(S)
        if self.count >= self._next:
            e0 = cycle.fly_cycle(fl, snap, ctl.P0, ctl.ref)
            miss = e0.S - guess
            innovation = miss - self.bias  # what the prediction would have missed by
            calm = self.count > 0 and bool(np.all(np.abs(innovation[:5]) <= self.tolerance))
            self.bias = miss if self.count == 0 else (1 - self.gain) * self.bias + self.gain * miss
            self._next = self.count + (self.every if calm and self.count + 1 >= self.warmup else 1)
            q_rel = np.empty(4)
            mujoco.mju_negQuat(q_rel, quat)
            mujoco.mju_mulQuat(q_rel, q_rel, e0.trunk_quat)
            self._delta = (R.T @ (e0.com_vel - vel), R.T @ (e0.trunk_pos - pos - e0.duration * vel),
                           q_rel, e0.duration)
        else:
            dv, dp, q_rel, T = self._delta
            q = np.empty(4)
            mujoco.mju_mulQuat(q, quat, q_rel)
            physics = snap.physics.copy()
            physics[0] += T
            e0 = cycle.CycleEnd(cycle.Snapshot(physics, snap.warmstart, snap.userdata), guess + self.bias,
                                pos + T * vel + R @ dp, q, vel + R @ dv, T, 0.0, predicted=True)
        self.count += 1
        return e0

    def flown(self, end: cycle.CycleEnd) -> None:
        """The wingbeat flown ended at ``end``: the next prediction continues from there."""
        self._last_end = end.snapshot.physics


@dataclass
class CoarsePredictor:
    """S0 from P0 simulated every wingbeat, as the paper does, but at a coarser step
    (``rate_hz``, default 1600 Hz against the flight's 2400) on a copy of the flight
    (:meth:`~flapsim.bird.flight.dove_flight.DoveFlight.twin`: the same forces, flows and plucked
    feathers), so the prediction costs 2/3 of a wingbeat instead of one. Only the prediction
    is coarse: the wingbeat flown is stepped at the flight's own rate.

    Measured along the rising figure of eight (bundled database; S0 at 1600 Hz against
    2400 Hz, every wingbeat): RMS differences 0.0016/0.0009 rad in pitch/roll, 0.003-0.016
    m/s in the body velocity, 0.014-0.036 rad/s in the angular velocity, 1-2 % of the
    database's dS spread; the rising figure of eight completes at all 7 asked speeds
    6.995-7.005 m/s, against 3 of 7 at 1400 Hz and none at 1300. At 1200 Hz the misses are
    5-10x larger and it is lost, with or without a bias correction from fine wingbeats;
    likely (inferred, not tested) because the servos of the light distal joints (kp 10
    N m/rad on the wrist's 2.4e-6 kg m^2 effective inertia: ~320 Hz) are then stepped at
    omega dt = 1.7, near the explicit position feedback's limit of 2 (0.84 at 2400 Hz, 1.3
    at 1600 Hz)."""

    rate_hz: float = COARSE_RATE_HZ
    _twin: object = None
    _of: object = None

    def reference(self, ctl: FlyingController, snap: cycle.Snapshot) -> cycle.CycleEnd:
        """P0's end from ``snap``, simulated on the coarse copy."""
        if self._twin is None or self._of is not ctl.flight:
            self._twin, self._of = ctl.flight.twin(self.rate_hz), ctl.flight
        return cycle.fly_cycle(self._twin, snap, ctl.reference_params(), ctl.ref)

    def flown(self, end: cycle.CycleEnd) -> None:
        """Nothing carries over between wingbeats."""

    def reset(self) -> None:
        """Nothing carries over between wingbeats."""
