"""Arriving at a target: slow down, stop and tread water there; keep pace with a moving
one.

A swimmer heading for a point does not swim at full speed into it: it eases off as
the point comes near, stops there and treads water. One chasing a moving target
swims at the target's speed plus a little to close the gap. :class:`Approach` does both
on top of the layers (:func:`flapsim.swim.simulate.swim`, ``approach=``):

* **The speed asked** of each stroke cycle (the per-cycle layer holds it by the stroke
  rate, :class:`flapsim.swim.per_cycle.CycleLayer`): ``v = |v_target| + k d``
  (``d``: the horizontal distance to the target), between ``floor_m_s`` and the
  cruise speed. For a fixed target ``v = k d``: the swimmer slows as it closes in.
* **Treading water at a fixed target**: once the target is within ``tread_within_m``
  the stroke's layers rest and the swimmer stands up (``data/manoeuvres/stand_up.toml``:
  legs down, head up, arms press down) until its trunk is upright, then treads water
  (the bundled ``treading`` stroke, its balance rules holding it upright and over the
  target: their drift reference is the target, at ``station_gain_per_m``, their frame
  the way the treader faces now); beyond ``swim_beyond_m`` (hysteresis: a treader's
  sway does not restart the swim) the stroke takes over again.

Only the swimmer acts: the speed is the stroke rate, treading is joint targets for the
PD muscles, every force is still hydrodynamics, buoyancy, gravity and joint torques.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from flapsim.core.errors import InputError
from flapsim.swim.layers import BasicStrokeLayer, FeedbackLayer
from flapsim.swim.model import Swimmer
from flapsim.swim.strokes import Stroke, load_stroke, stroke_tables

#: the stroke swum while waiting at a fixed target
TREADING = "treading"
#: the manoeuvre from a prone stroke to treading water
STAND_UP = Path(__file__).resolve().parent / "data" / "manoeuvres" / "stand_up.toml"
#: treading takes over at this phase of the stand-up (its keys reach treading's pose)
STAND_UP_END = 0.95
#: treading takes over from the stand-up as soon as the legs are down (this phase) and
#: the trunk leans less than STAND_UP_LEAN_DEG from upright: treading's balance rules
#: saturate at ~10 deg of lean and cannot lift a trunk leaning much more
STAND_UP_LEGS_DOWN = 0.3
STAND_UP_LEAN_DEG = 25.0
#: ... or this long [s] after the stand-up's keys reached treading's pose
STAND_UP_HOLD_S = 6.0


@dataclass(frozen=True)
class ApproachParams:
    """How a swimmer closes in on a target."""

    #: closing gain k [1/s]: the speed asked above the target's is k times the distance
    #: (0.15: from ~7 m out the crawl's full ~1 m/s, at 2 m 0.3 m/s)
    gain_per_s: float = 0.15
    #: the slowest speed asked [m/s] (the crawl at 0.35 of its stroke rate, the per-cycle
    #: layer's lowest, swims 0.28 m/s: `flapsim swim --stroke crawl --rate 0.28`)
    floor_m_s: float = 0.3
    #: a fixed target: tread water once it is this close (horizontally) [m]
    tread_within_m: float = 1.0
    #: ... and swim again once it is this far [m] (hysteresis)
    swim_beyond_m: float = 2.5
    #: treading at the target: weight of its balance rules' lean and sway per metre of
    #: drift from the target (the treading stroke's own, 1 per m, lets a treader wander
    #: about half a metre from where it started)
    station_gain_per_m: float = 3.0

    def __post_init__(self) -> None:
        if not (self.gain_per_s > 0 and self.floor_m_s > 0):
            raise InputError("the approach's closing gain and slowest speed must be > 0")
        if not (0 < self.tread_within_m < self.swim_beyond_m):
            raise InputError("the approach treads within tread_within_m > 0 and swims again "
                             "beyond a larger swim_beyond_m")


@dataclass
class Approach:
    """Speed plan (``asked_speed``, read by the per-cycle layer once per cycle) and
    control hook (``__call__``, every control step) for ``target``: anything with
    ``at(t) -> (x, y)`` and, if it moves, ``velocity(t) -> (vx, vy)``
    (:mod:`flapsim.swim.goals`)."""

    target: object
    params: ApproachParams = field(default_factory=ApproachParams)
    #: "swim", "stand" (coming upright) or "tread"
    state: str = field(default="swim", init=False)
    #: (time [s], "tread" | "swim") at each switch
    switches: list = field(default_factory=list, init=False)

    def __post_init__(self) -> None:
        if not hasattr(self.target, "at"):
            raise InputError("an approach needs a target with a position (a point, a circling "
                             "or trajectory target), not a heading or a path")
        self._tread: BasicStrokeLayer | None = None
        self._fb: FeedbackLayer | None = None
        self._saved: tuple[float, str] | None = None

    def _velocity(self, t: float) -> np.ndarray:
        v = getattr(self.target, "velocity", None)
        return np.zeros(2) if v is None else np.asarray(v(t), dtype=float)[:2]

    def distance(self, com_xy: np.ndarray, t: float) -> float:
        """Horizontal distance [m] from ``com_xy`` to the target at time ``t``."""
        return float(np.linalg.norm(np.asarray(self.target.at(t))[:2] - np.asarray(com_xy)[:2]))

    def asked_speed(self, com_xy: np.ndarray, t: float, cruise: float) -> float:
        """The speed to ask of the next cycle [m/s]: the target's speed plus the closing
        term, within [floor, ``cruise``]."""
        p = self.params
        v = float(np.linalg.norm(self._velocity(t))) + p.gain_per_s * self.distance(com_xy, t)
        return float(min(max(v, p.floor_m_s), max(cruise, p.floor_m_s)))

    def __call__(self, sw: Swimmer, layer: BasicStrokeLayer) -> bool:
        d = sw.data
        t = float(d.time)
        if np.any(self._velocity(t)):  # a moving target is chased, never waited at
            return True
        dist = self.distance(sw.com()[:2], t)
        p = self.params
        if self.state == "swim" and dist <= p.tread_within_m:
            self._stand_up(sw, layer, t)
        elif self.state == "stand":
            if self._stood(sw, t):
                self._start_treading(sw, layer, t)
            elif (t - self._since) / self._stand.period_s >= STAND_UP_END:
                # in treading's pose but not yet upright: hold it (the clock stopped)
                # while the hanging legs pull the trunk up
                layer.rate_hz, layer.phase = 0.0, STAND_UP_END
        elif self.state in ("stand", "tread") and dist >= p.swim_beyond_m:
            self._stop_treading(layer, t)
        if self.state == "tread":
            # lean and drift are measured in the treader's own frame: it turns as it
            # treads, and its sweeps push along its own front
            self._fb.frame_yaw = self._facing(sw)
            self._fb.update(d)
            layer.set_tables(self._tread.tables)
        return True

    def _stand_up(self, sw: Swimmer, layer: BasicStrokeLayer, t: float) -> None:
        """Leave the stroke: its layers rest, the stand-up manoeuvre is swum once."""
        n = layer.tables.q.shape[0]
        if self._tread is None:
            self._stand = load_stroke(str(STAND_UP))
            self._stand_tables = stroke_tables(self._stand, sw.joints, n)
            self._tread = BasicStrokeLayer(sw, self._station_keeping(load_stroke(TREADING)),
                                           nsamp=n)
            self._fb = FeedbackLayer(self._tread)
        self._saved = layer.rest_layers(t)
        layer.set_tables(self._stand_tables)
        layer.rate_hz, layer.phase = 1.0 / self._stand.period_s, 0.0
        self._since = t
        self.state = "stand"
        self.switches.append((t, "stand"))

    def _stood(self, sw: Swimmer, t: float) -> bool:
        """Whether the stand-up is done: the trunk upright (within STAND_UP_LEAN_DEG)
        once the legs are down, or STAND_UP_HOLD_S after the manoeuvre's end."""
        phase = (t - self._since) / self._stand.period_s
        up = float(sw.data.xmat[sw.body["thorax"]][8])
        held = t - self._since - STAND_UP_END * self._stand.period_s
        return held >= STAND_UP_HOLD_S or (
            phase >= STAND_UP_LEGS_DOWN and up >= math.cos(math.radians(STAND_UP_LEAN_DEG)))

    @staticmethod
    def _facing(sw: Swimmer) -> float:
        """The horizontal direction the trunk faces [rad]: square to its left (local y)
        axis, which stays level whether the trunk is prone, upright or leans either way."""
        left = sw.data.xmat[sw.body["thorax"]].reshape(3, 3)[:, 1]
        return math.atan2(-left[0], left[1])

    def _station_keeping(self, stroke: Stroke) -> Stroke:
        """``stroke`` with its drift gains (``offset_x``, ``offset_y``) at the station gain,
        their signs kept."""
        g = self.params.station_gain_per_m
        perts = {}
        for name, p in stroke.perturbations.items():
            gains = {k: (math.copysign(g, v) if k in ("offset_x", "offset_y") else v)
                     for k, v in p.gains.items()}
            perts[name] = replace(p, gains=gains)
        return replace(stroke, perturbations=perts)

    def _start_treading(self, sw: Swimmer, layer: BasicStrokeLayer, t: float) -> None:
        self._fb.reset(reference=np.asarray(self.target.at(t))[:2])
        layer.rate_hz, layer.phase = self._tread.rate_hz, 0.0
        self.state = "tread"
        self.switches.append((t, "tread"))

    def _stop_treading(self, layer: BasicStrokeLayer, t: float) -> None:
        layer.resume(self._saved, t)
        self.state = "swim"
        self.switches.append((t, "swim"))

    def summary(self) -> dict:
        return {"state": self.state, "switches": [{"t": a, "to": b} for a, b in self.switches],
                "params": {k: getattr(self.params, k) for k in self.params.__dataclass_fields__}}
