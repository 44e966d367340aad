"""Targets for the learned controller: the state S a wingbeat should end in.

:class:`CruiseTarget` and :class:`SteerTarget` turn a task (hold altitude, speed and
heading; or steer by alpha and climb by beta in one wingbeat) into S_target: a
coordinated turn banks by atan(v omega / g) (the paper's eq. 5 with the centrifugal force
m v omega), the body keeps its trim angle of attack to the flight path, and the angular
velocity is the trim's plus the turn rate.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import mujoco
import numpy as np

from flapsim.bird.flight import cycle
from flapsim.bird.flight.dove_flight import DoveFlight, FlightConfig, pitch_roll

#: m/s^2
GRAVITY = 9.81


@dataclass(frozen=True)
class Trim:
    """The reduced state of steady level flight at the start of a wingbeat (pitch, angular
    velocity and velocity direction in the body frame oscillate within a wingbeat, so the
    target takes them at the same phase)."""

    S: np.ndarray
    """(8,) mean reduced state at wingbeat starts."""

    @property
    def pitch(self) -> float:
        return float(self.S[0])

    @property
    def aoa(self) -> float:
        """Body pitch above the flight path (velocity) at the wingbeat start, rad."""
        v = self.S[2:5]
        return float(-np.arctan2(v[2], v[0]))


def trim_of_base_flight(fl: DoveFlight, P0: np.ndarray, cfg: FlightConfig | None = None,
                        wingbeats: int = 6, skip: int = 2) -> Trim:
    """Mean start-of-wingbeat state of the base controller over ``wingbeats`` after ``skip``,
    flown in still air whatever the flight's wind: the target adds the wind to the air-relative
    trim (:func:`target_state`). Flown in a 2 m/s crosswind from a start along +x, the base
    flight sideslipped, and its mean body-frame velocity put the angle of attack at 8.2 deg
    against the still-air trim's 2.8: every wingbeat then asked 5.4 deg more angle of attack,
    the dove slowed to ~4.5 m/s and did not reach the 40 m path's end in time."""
    states = []
    with fl.flow.still():
        fl.reset(cfg or FlightConfig(), P0)
        for i in range(skip + wingbeats):
            cycle.fly_cycle(fl, None, P0)
            if i >= skip:
                states.append(fl.reduced_state())
    S = np.mean(states, axis=0)
    S[1] = 0.0
    S[3] = 0.0
    S[5] = 0.0
    S[7] = 0.0
    return Trim(S)


def target_state(trim: Trim, speed: float, heading: float, climb: float, turn_rate: float,
                 S_now: np.ndarray | None = None, settle_s: float = 0.2,
                 wind: np.ndarray | None = None, aoa_per_g: float = 0.0) -> np.ndarray:
    """S at the end of a wingbeat flying at ``speed`` along (``heading``, ``climb``) and
    turning at ``turn_rate`` (rad/s, + left) in a coordinated turn: banked by
    atan(v omega / g) toward the inside, nose ``trim.aoa`` above the flight path.

    ``wind`` (world, m/s): the heading, climb and speed then describe the velocity through
    the AIR, which the body's attitude follows (a bird crabs into a crosswind); S carries
    the body-frame velocity over the ground, as the reduced state measures it.

    The angular velocity asked is the trim's, plus the turn rate, plus the rates that would
    take the pitch and roll of ``S_now`` (where the reference wingbeat would leave the bird)
    to the target's in ``settle_s`` seconds: without them the target asks for an
    orientation while holding the rates that keep it from getting there.

    ``aoa_per_g`` (rad per g, default 0: the trim's angle of attack in any turn): the nose is
    asked ``aoa_per_g (n - 1)`` higher above the flight path in a turn of load factor
    n = 1 / cos(bank). A banked wing at the level trim's angle of attack carries only
    cos(bank) of the weight; quasi-steady lift grows with the angle of attack (the reference
    wingbeat at 7 m/s: 1.01 of the weight at 5 deg, 1.41 at 15 deg, ~25 deg per g).
    """

    bank = float(np.arctan2(speed * turn_rate, GRAVITY))
    # wind axes first (heading, climb, then the bank about the flight path), then the body's
    # angle of attack about its own y axis: the bank turns about the velocity, so the
    # body-frame velocity has no sideslip
    # (left wing down by ``bank`` is a rotation about the forward axis by -bank: y left)
    # the load factor of the coordinated turn (cos(bank) floored: a bank near 90 deg asks at
    # most 5 g's worth)
    aoa = trim.aoa + aoa_per_g * (1.0 / max(float(np.cos(bank)), 0.2) - 1.0)
    R = (rot_z(heading) @ rot_y(-climb) @ rot_x(-bank)
         @ rot_y(-aoa))
    v = speed * np.array([np.cos(climb) * np.cos(heading), np.cos(climb) * np.sin(heading),
                          np.sin(climb)])
    if wind is not None:
        v = v + np.asarray(wind, float)
    w_body = trim.S[5:8] + R.T @ np.array([0.0, 0.0, turn_rate])

    p, r = pitch_roll(R)
    if S_now is not None and settle_s <= 0:
        # no demand on the angular velocity: whatever the reference wingbeat would give
        w_body = S_now[5:8].copy()
    elif S_now is not None:
        # d(pitch)/dt = -w_y and d(roll)/dt = -w_x * ROLL_SIGN (body axes x fwd, y left, z up)
        w_body[1] -= (p - S_now[0]) / settle_s
        w_body[0] -= ROLL_RATE_SIGN * (r - S_now[1]) / settle_s
    return np.array([p, r, *(R.T @ v), *w_body])


def rot_x(a: float) -> np.ndarray:
    """Rotation by ``a`` rad about x (and :func:`rot_y`, :func:`rot_z` about y and z)."""
    c, s = np.cos(a), np.sin(a)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def rot_y(a: float) -> np.ndarray:
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def rot_z(a: float) -> np.ndarray:
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def _roll_rate_sign() -> float:
    """+1 if a positive body-x angular velocity decreases :func:`pitch_roll`'s roll, else -1."""

    q = np.array([np.cos(0.05), np.sin(0.05), 0.0, 0.0])  # small rotation about +x
    R = np.zeros(9)
    mujoco.mju_quat2Mat(R, q)
    return 1.0 if pitch_roll(R.reshape(3, 3))[1] < 0 else -1.0


ROLL_RATE_SIGN = _roll_rate_sign()


def bank_to_roll(bank_left: float) -> float:
    """The roll angle (in :func:`~flapsim.bird.flight.dove_flight.pitch_roll`'s convention) of a bank
    with the left wing down by ``bank_left`` rad (a left turn)."""

    # left wing down = rotation about +x (forward) by -bank in a right-handed frame with
    # y to the left: find which sign pitch_roll reports for it
    th = -bank_left
    q = np.array([np.cos(th / 2), np.sin(th / 2), 0.0, 0.0])
    R = np.zeros(9)
    mujoco.mju_quat2Mat(R, q)
    return pitch_roll(R.reshape(3, 3))[1]


@dataclass
class CruiseTarget:
    """Hold an altitude, a speed and a heading: the outer loop of the wingbeat controller.

    Proportional-integral on each error: the wingbeat controller reaches a requested state
    change only in part (the regression's gain is below one and biased), so a proportional
    loop alone leaves steady offsets (measured: +3.5 deg heading, -0.5 m/s speed over 100
    wingbeats); the integrals remove them. The integrals are the target's state (a new
    flight needs a new target, or :meth:`reset`).
    """

    trim: Trim
    altitude: float
    """m."""
    speed: float = FlightConfig.speed
    """m/s."""
    heading: float = 0.0
    """rad (+ left of +x)."""
    k_altitude: float = 0.6
    """Climb rate asked per metre of altitude error, 1/s."""
    ki_altitude: float = 0.15
    """... per metre-second of its integral, 1/s^2."""
    max_climb_deg: float = 8.0
    """Largest climb/descent angle asked, deg."""
    k_heading: float = 1.5
    """Turn rate asked per radian of heading error, 1/s."""
    ki_heading: float = 0.4
    """... per radian-second of its integral, 1/s^2."""
    max_bank_deg: float = 30.0
    """Largest bank asked, deg."""
    ki_speed: float = 0.3
    """Speed asked above the target per m/s-second of the speed error's integral, 1/s."""
    max_speed_offset: float = 2.0
    """Largest speed offset the integral may ask, m/s."""
    settle_s: float = 0.0
    """Time over which pitch and roll errors are asked to close through the angular velocity,
    s (see :func:`target_state`); 0 (default): ask no angular velocity, keep the reference
    wingbeat's. Measured with the bundled database (100 wingbeats from -10..10 deg of roll):
    0 held all six starts, 0.2 s four (an undamped roll oscillation in the others, also after
    ~150 wingbeats from 2 deg), 0.4 s four: the boundary angular velocity swings with every
    flap, and asking for it drags the regression off what matters."""
    integrals: np.ndarray = field(default_factory=lambda: np.zeros(3))
    """Running integrals of (altitude, heading, speed) errors."""
    speed_surplus: float = 0.0
    """The speed the last target asked above ``speed`` by its integral, m/s."""

    def simulates(self, count: int) -> bool:
        """Whether the ``count``-th wingbeat since a (re)start simulates P0."""
        return count < self.warmup or (count - self.warmup) % self.every == 0

    def reset(self) -> None:
        self.integrals[:] = 0.0

    def __call__(self, e0: cycle.CycleEnd) -> np.ndarray:
        dt = e0.duration
        h, _ = cycle.heading_and_climb(e0.com_vel)
        e_h = float(cycle.wrap(self.heading - h))
        e_z = float(e0.trunk_pos[2]) - self.altitude
        e_v = self.speed - float(np.linalg.norm(e0.com_vel))
        lim = np.array([self.speed * np.sin(np.radians(self.max_climb_deg)) / max(self.ki_altitude, 1e-9),
                        np.radians(self.max_bank_deg) / max(self.ki_heading, 1e-9),
                        self.max_speed_offset / max(self.ki_speed, 1e-9)])
        self.integrals[:] = np.clip(self.integrals + dt * np.array([e_z, e_h, e_v]), -lim, lim)
        iz, ih, iv = self.integrals
        max_rate = GRAVITY * np.tan(np.radians(self.max_bank_deg)) / self.speed
        rate = float(np.clip(self.k_heading * e_h + self.ki_heading * ih, -max_rate, max_rate))
        speed = self.speed + self.ki_speed * iv
        self.speed_surplus = self.ki_speed * iv  # what the refinement leaves to this loop
        vz = -self.k_altitude * e_z - self.ki_altitude * iz
        climb = float(np.clip(np.arcsin(np.clip(vz / speed, -1, 1)),
                              -np.radians(self.max_climb_deg), np.radians(self.max_climb_deg)))
        return target_state(self.trim, speed, h + rate * dt, climb, rate, e0.S, self.settle_s)


@dataclass
class SteerTarget:
    """Steer by ``alpha`` and climb by ``beta`` (rad) over one wingbeat, relative to where the
    reference wingbeat would have taken the bird, at its speed."""

    trim: Trim
    alpha: float
    beta: float
    settle_s: float = 0.2
    max_bank_deg: float = 60.0
    """Largest bank asked (a coordinated turn at alpha per wingbeat would ask
    atan(v alpha / (T g)): 74 deg for 30 deg per wingbeat)."""

    def __call__(self, e0: cycle.CycleEnd) -> np.ndarray:
        h, c = cycle.heading_and_climb(e0.com_vel)
        speed = float(np.linalg.norm(e0.com_vel))
        max_rate = GRAVITY * np.tan(np.radians(self.max_bank_deg)) / max(speed, 1e-3)
        rate = float(np.clip(self.alpha / e0.duration, -max_rate, max_rate))
        return target_state(self.trim, speed, h + self.alpha, c + self.beta, rate, e0.S,
                            self.settle_s)


def fit_steering_signature(dS: np.ndarray, alpha: np.ndarray, beta: np.ndarray) -> np.ndarray:
    """(8, 2) matrix D with dS ~ D (alpha, beta): the state change that comes with steering
    alpha and elevation beta in a database (least squares through the origin, since the
    reference wingbeat itself is dS = 0 at alpha = beta = 0)."""
    A = np.stack([np.asarray(alpha, float), np.asarray(beta, float)], axis=1)
    D, *_ = np.linalg.lstsq(A, np.asarray(dS, float), rcond=None)
    return D.T


@dataclass
class SignatureTarget:
    """Steer by ``alpha`` and climb by ``beta`` in one wingbeat, asked in the state space the
    controller regresses over: S0 + D (alpha, beta), with D the database's steering
    signature (:func:`fit_steering_signature`). The paper places wingbeats in the alpha-beta
    plane by angles "computed from dS"; this is the inverse of that map."""

    D: np.ndarray
    alpha: float
    beta: float

    def __call__(self, e0: cycle.CycleEnd) -> np.ndarray:
        return e0.S + self.D @ np.array([self.alpha, self.beta])


@dataclass
class PathTurnTarget:
    """Turn the flight path by ``alpha`` (left +) and ``beta`` (up +) within one wingbeat,
    relative to where the reference wingbeat takes it, keeping the reference's attitude
    and rates: S0 with its body-frame velocity rotated by alpha about the body's z axis
    and beta about its y axis. Unlike :class:`SteerTarget` (a coordinated turn, which
    S can only express as bank and yaw rate because it is heading invariant) this asks
    for the change of flight direction itself, in the frame S is measured in."""

    alpha: float
    beta: float

    def __call__(self, e0: cycle.CycleEnd) -> np.ndarray:
        v = e0.S[2:5]
        ca, sa, cb, sb = np.cos(self.alpha), np.sin(self.alpha), np.cos(self.beta), np.sin(self.beta)
        Rz = np.array([[ca, -sa, 0.0], [sa, ca, 0.0], [0.0, 0.0, 1.0]])
        Ry = np.array([[cb, 0.0, -sb], [0.0, 1.0, 0.0], [sb, 0.0, cb]])  # +beta tips +x up
        S = e0.S.copy()
        S[2:5] = Rz @ Ry @ v
        return S
