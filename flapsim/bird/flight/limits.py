"""What the dove's wing can sustain: the tightest level turn and the steepest climb that any
wingbeat it can fly holds at constant speed.

A path asks for a load factor (a level turn of radius r at speed v: n = sqrt(1 + (v^2 / (g
r))^2)) or a climb (angle gamma: lift cos(gamma), thrust - drag sin(gamma) of the weight).
Whether the learned controller follows it is a matter of the database; whether any wingbeat
could is a matter of the wing. :func:`search` answers the second: it flies candidate
wingbeats in the fixed-trunk tunnel (:func:`~flapsim.bird.flight.dove_flight.wind_tunnel`) at a grid of
trunk pitches and speeds, and keeps only wingbeats the dove can fly in free flight (its joints
stay within :data:`~flapsim.bird.flight.wingbeat.RANGE_TOLERANCE` of their ranges, the database's own
acceptance rule; torque limits and PD servos as always). The tunnel's cycle-mean forces are
quasi-steady in the trunk's pose: they neglect the trunk's own heave and pitch over a
wingbeat.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np

from flapsim.bird.body.model import Dove
from flapsim.bird.body.params import DoveParams
from flapsim.bird.flight import cycle
from flapsim.bird.flight.dove_flight import DoveFlight, FlightConfig, wind_tunnel
from flapsim.bird.flight.wingbeat import (
    RANGE_TOLERANCE,
    p0,
    reference_wingbeat,
    with_flap_and_beat,
    with_tail_bias,
    with_twist_bias,
)
from flapsim.core.errors import InputError

GRAVITY = 9.81


def turn_radius(load_factor: float, speed: float) -> float:
    """Radius of a level coordinated turn at ``speed`` (m/s) with lift ``load_factor`` times
    the weight, m (inf when the lift does not exceed the weight): r = v^2 / (g sqrt(n^2 - 1))."""
    if not (np.isfinite(load_factor) and np.isfinite(speed) and speed > 0):
        raise InputError(f"need a finite load factor and a positive speed, got {load_factor}, {speed}")
    if load_factor <= 1.0:
        return float("inf")
    return float(speed ** 2 / (GRAVITY * np.sqrt(load_factor ** 2 - 1.0)))


def load_factor_for_radius(radius: float, speed: float) -> float:
    """Lift / weight a level turn of ``radius`` (m) at ``speed`` (m/s) needs."""
    if not (radius > 0 and speed > 0):
        raise InputError(f"need a positive radius and speed, got {radius}, {speed}")
    return float(np.hypot(1.0, speed ** 2 / (GRAVITY * radius)))


def climb_angle_deg(lift_per_weight: float, thrust_per_weight: float) -> float | None:
    """The steady straight climb angle a wingbeat holds, deg, or None when it holds none.

    In a steady climb at gamma the flow meets the bird from along its path: lift (normal to
    the flow) must carry cos(gamma) of the weight and thrust less drag (along the flow)
    sin(gamma). A wingbeat with T/W = t >= 0 and L/W >= sqrt(1 - t^2) holds gamma = asin(t)
    (surplus lift is shed by pitching down a little); a wingbeat with t < 0 holds only a
    glide, reported as a negative angle when its lift suffices."""
    t = float(np.clip(thrust_per_weight, -1.0, 1.0))
    if lift_per_weight < np.sqrt(1.0 - t * t) - 1e-12:
        return None
    return float(np.degrees(np.arcsin(t)))


@dataclass(frozen=True)
class Candidate:
    """A wingbeat of the search: P0 with both shoulder flaps scaled, the cycle's duration
    stretched and both shoulder twists translated."""

    flap_scale: float
    """Scale of both shoulder-flap strokes about their mean (P0: 1)."""
    timewarp: float
    """Cycle duration over P0's (< 1: a faster beat)."""
    twist_deg: float
    """Both shoulder twists translated, deg (- supinates: more angle of attack)."""

    def params(self, P0: np.ndarray) -> np.ndarray:
        return with_twist_bias(with_flap_and_beat(P0, self.flap_scale, self.timewarp), self.twist_deg)


@dataclass
class TunnelPoint:
    speed: float
    pitch_deg: float
    flap_scale: float
    timewarp: float
    twist_deg: float
    lift_per_weight: float
    thrust_per_weight: float
    range_excess_deg: float
    """The wingbeat's largest excursion past a joint range in free flight at this speed."""
    pitch_moment: float = float("nan")
    """Cycle-mean nose-up moment about the trunk centre, N m: a held turn needs it trimmed
    as well (by the tail or the stroke), which the search does not ask."""


def free_flight_range_excess(fl, P: np.ndarray, speed: float) -> float:
    """Largest excursion of any DOF past its range (rad) flying ``P`` for one wingbeat in free
    flight after one reference wingbeat from the level cruise start at ``speed``: how the
    database judges a sample's wingbeat."""

    P0 = with_tail_bias(p0(), FlightConfig.tail_bias_deg)
    fl.reset(FlightConfig(speed=speed), P0)
    start = cycle.fly_cycle(fl, cycle.snapshot(fl), P0, fl.ref).snapshot
    return float(cycle.fly_cycle(fl, start, P, fl.ref).range_excess)


def search(candidates: list[Candidate], speeds: list[float], pitches_deg: list[float]
           ) -> list[TunnelPoint]:
    """Every candidate at every speed: its free-flight range excess, and (when within the
    database's tolerance) its tunnel forces at every pitch."""

    params = DoveParams.load()
    ref = reference_wingbeat()
    P0 = with_tail_bias(p0(), FlightConfig.tail_bias_deg)
    fl = DoveFlight(Dove.load(), ref)
    out: list[TunnelPoint] = []
    try:
        for v in speeds:
            for c in candidates:
                P = c.params(P0)
                excess = free_flight_range_excess(fl, P, v)
                for pitch in pitches_deg:
                    if excess > RANGE_TOLERANCE:
                        lift = thrust = moment = float("nan")
                    else:
                        r = wind_tunnel(params, P, v, pitch, ref=ref)
                        lift, thrust = float(r.lift_per_weight), float(r.thrust_per_weight)
                        moment = float(r.pitch_moment)
                    out.append(TunnelPoint(v, pitch, c.flap_scale, c.timewarp, c.twist_deg, lift,
                                           thrust, float(np.degrees(excess)), moment))
    finally:
        fl.close()
    return out


def best_sustained(points: list[TunnelPoint], thrust_floor: float = 0.0) -> dict:
    """Per speed: the largest load factor held with thrust - drag >= ``thrust_floor`` of the
    weight (0: at constant speed; the reference wingbeat's own cruise runs at -0.025..-0.05,
    slowing a little) and its tightest level turn, and the steepest climb; over all speeds,
    the tightest turn."""
    rows = []
    for v in sorted({p.speed for p in points}):
        ok = [p for p in points if p.speed == v and np.isfinite(p.lift_per_weight)]
        level = [p for p in ok if p.thrust_per_weight >= thrust_floor]
        turn = max(level, key=lambda p: p.lift_per_weight, default=None)
        climbs = [(climb_angle_deg(p.lift_per_weight, p.thrust_per_weight), p) for p in ok]
        climbs = [(g, p) for g, p in climbs if g is not None]
        climb = max(climbs, key=lambda gp: gp[0], default=None)
        rows.append({
            "speed": v,
            "wingbeats_in_range": len({(p.flap_scale, p.timewarp, p.twist_deg) for p in ok}),
            "max_load_factor": turn.lift_per_weight if turn else None,
            # None where no held wingbeat lifts more than the weight (JSON has no inf)
            "tightest_turn_m": (turn_radius(turn.lift_per_weight, v)
                                if turn and turn.lift_per_weight > 1.0 else None),
            "turn_wingbeat": asdict(turn) if turn else None,
            "steepest_climb_deg": climb[0] if climb else None,
            "climb_wingbeat": asdict(climb[1]) if climb else None,
        })
    finite = [r for r in rows if r["tightest_turn_m"] is not None]
    tight = min(finite, key=lambda r: r["tightest_turn_m"], default=None)
    return {"thrust_floor": thrust_floor, "per_speed": rows,
            "tightest_turn_m": tight["tightest_turn_m"] if tight else None,
            "tightest_turn_speed": tight["speed"] if tight else None}
