"""A surface (duck) dive to a target below the water, and the way back up.

Real swimmers reach a point a few metres down from the surface by a surface dive:
they breathe out, pike at the hips with the head and arms down, then lift the legs
above the water, whose weight (no longer carried by the water) drives the body down;
under water they swim on towards the point. :class:`SurfaceDive` does that as a hook
of :func:`flapsim.swim.simulate.swim` (``control_hook``), above the stroke's layers:

1. **Swim** with the stroke until the point below is within ``trigger_m``
   horizontally (at the start of a stroke cycle).
2. **Breathe out** to ``exhaled_l`` litres of lung air (1.33 L: body density 1028
   kg/m^3, REFERENCE_DATA's "after exhalation"; the swimmer is then ~2.6 N heavier
   than the sea water it displaces instead of 14 N lighter), and swim the dive
   (``flapsim/swim/data/manoeuvres/surface_dive.toml``, one cycle) with the basic layer
   only.
3. **Swim on** under water with the stroke and its layers, or with ``under_stroke``
   (a stroke that can swim down, steered by its own per-cycle layer towards the point).
   The front crawl cannot: its pitch-down sequence turns it 2-3 deg a cycle, and its
   arms recover through the air, which they cannot do under water; crawl swimmers go
   down and come back up with the breaststroke's underwater pull and kick, as in a
   breaststroke pullout, then crawl on at the surface.
4. **Breathe in** (back to the start volume, as a swimmer surfacing takes a breath)
   once the head or the pelvis is within the target's radius of the point, or after
   ``breath_hold_s``: buoyancy and the stroke bring the swimmer up; with an
   ``under_stroke``, the stroke takes over again once the head is out of the water.

Only the swimmer acts: the lung volume changes the thorax's buoyant volume (the
breathing action) and the dive is joint targets for the PD muscles; every force is
still hydrodynamics, buoyancy, gravity and joint torques. The thorax's hydrodynamic box
keeps its size when breathing (a chest 2 L smaller is ~1 cm thinner).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import mujoco
import numpy as np

from flapsim.core.errors import InputError
from flapsim.swim.layers import BasicStrokeLayer
from flapsim.swim.model import SEGMENTS, Swimmer
from flapsim.swim.per_cycle import CycleLayer, load_table
from flapsim.swim.strokes import load_stroke, stroke_tables

DIVE_FILE = Path(__file__).resolve().parent / "data" / "manoeuvres" / "surface_dive.toml"
#: the stroke each stroke swims under water when it cannot itself (the crawl's arms
#: recover through the air): see the module docstring
UNDER_WATER_STROKE = {"crawl": "breaststroke"}
#: lung air after breathing out [L]: the swimmer's mass M at 1044 kg/m^3 plus V L of
#: air has density 1028 kg/m^3 (REFERENCE_DATA) when V = M (1/1028 - 1/1044) = 1.33 L
EXHALED_L = 1.33


@dataclass
class SurfaceDive:
    """Control hook: ``swim(..., target=waypoints, control_hook=SurfaceDive(waypoints))``.

    ``target`` needs ``points`` (n, 3) [m] and ``radius`` [m] (a
    :class:`flapsim.swim.goals.Waypoints`); its first point below the surface is the
    one dived for."""

    target: object
    lungs_l: float = 3.0
    exhaled_l: float = EXHALED_L
    trigger_m: float = 2.5
    breath_hold_s: float = 25.0
    #: what happened when [s]: "dive", "under", "reached", "inhale" (None: not yet)
    events: dict = field(default_factory=dict)
    #: closest the head or the pelvis came to the point below [m]
    closest_m: float = math.inf
    #: the stroke swum under water (a name or file, e.g. "breaststroke"; its per-cycle
    #: table steers it), None: the swim's own stroke
    under_stroke: str | None = None
    #: with an ``under_stroke``: it takes over this much further out than ``trigger_m``
    #: [m] (about two breaststroke cycles)
    switch_ahead_m: float = 2.5

    def __post_init__(self) -> None:
        pts = np.asarray(self.target.points, dtype=float)
        below = np.flatnonzero(pts[:, 2] < 0.0)
        if not len(below):
            raise InputError("a surface dive needs a target point below the surface")
        self.point = pts[below[0]]
        self._index = int(below[0])
        if not (0.0 < self.exhaled_l <= self.lungs_l):
            raise InputError(f"exhaled lung air must be in (0, {self.lungs_l}] L")
        self.dive = load_stroke(str(DIVE_FILE))
        self.state = "swim"
        self.events = {k: None for k in ("dive", "under", "reached", "inhale", "stroke_again")}
        self._under: tuple | None = None
        self._thorax = SEGMENTS.index("thorax")
        self._vol0: float | None = None
        self._saved: tuple | None = None

    def _breathe(self, sw: Swimmer, litres: float) -> None:
        """Set the lung air to ``litres``: the thorax's buoyant volume changes by the
        difference (the breathing action)."""
        vol = sw.buoyancy.volumes[self._thorax]
        if self._vol0 is None:
            self._vol0 = float(vol)
        sw.buoyancy.set_volume_scale(self._thorax, self._vol0 - (self.lungs_l - litres) * 1e-3)

    def __call__(self, sw: Swimmer, layer: BasicStrokeLayer) -> bool:
        d = sw.data
        t = float(d.time)
        head = d.geom_xpos[mujoco.mj_name2id(sw.model, mujoco.mjtObj.mjOBJ_GEOM, "head")]
        near = min(float(np.linalg.norm(head - self.point)),
                   float(np.linalg.norm(d.xpos[sw.body["pelvis"]] - self.point)))
        self.closest_m = min(self.closest_m, near)
        radius = float(self.target.radius)
        if self.state == "swim":
            horiz = float(np.hypot(*(self.point[:2] - sw.com()[:2])))
            if (self.under_stroke is not None and self._under is None
                    and horiz < self.trigger_m + self.switch_ahead_m):
                # the under-water stroke from a little before the dive: the dive starts
                # from its glide, level and not rolled
                self._leave_stroke(layer, t)
                self._start_under_stroke(sw, layer)
            elif horiz < self.trigger_m and layer.phase < 0.05:  # at a cycle start
                self._breathe(sw, self.exhaled_l)
                if self._saved is None:
                    self._leave_stroke(layer, t)
                layer.set_tables(stroke_tables(self.dive, sw.joints, layer.tables.q.shape[0]))
                layer.rate_hz, layer.phase = 1.0 / self.dive.period_s, 0.0
                self.state, self.events["dive"] = "dive", t
        elif self.state == "dive":
            if t - self.events["dive"] >= self.dive.period_s:  # one dive cycle: swim on
                if self._under is not None:
                    layer.phase = 0.0
                    self._under[1].reset()
                else:
                    self._stroke_again(layer, t)
                self.state, self.events["under"] = "under", t
        if self.state in ("dive", "under"):
            if near <= radius and self.events["reached"] is None:
                self.events["reached"] = t
                # the target goes on with the dive: its own rule (the centre of mass)
                # could miss the point the head reached and turn the swimmer back to it
                if hasattr(self.target, "reached_by"):
                    self.target.reached_by(self._index, t)
            if self.events["reached"] is not None or t - self.events["dive"] >= self.breath_hold_s:
                self._breathe(sw, self.lungs_l)  # breathe in: up to the surface
                self.state, self.events["inhale"] = "up", t
        if self._under is not None and self.state != "dive":
            if self.state == "up" and head[2] > sw.params.water_level:
                self._under = None  # the head is out: the stroke again
                self._stroke_again(layer, t)
            else:
                self._swim_under(layer, d)
        return True

    def _leave_stroke(self, layer: BasicStrokeLayer, t: float) -> None:
        """Keep the swim's stroke rate and layers for later; its layers rest (the dive
        is swum as keyed, the under-water stroke steers itself)."""
        self._saved = layer.rest_layers(t)

    def _stroke_again(self, layer: BasicStrokeLayer, t: float) -> None:
        """Back to the swim's own stroke and layers."""
        layer.resume(self._saved, t)
        self.events["stroke_again"] = t

    def _start_under_stroke(self, sw: Swimmer, layer: BasicStrokeLayer) -> None:
        """The under-water stroke, steered by its own per-cycle layer, drives the swim's
        basic layer (whose clock and PD muscles run it) from now on."""
        st = load_stroke(self.under_stroke)
        basic = BasicStrokeLayer(sw, st, nsamp=layer.tables.q.shape[0])
        table = load_table(st, layers="cycle", body_shape=sw.params.body_shape)
        cycle = CycleLayer(basic, table, target=self.target)
        layer.rate_hz, layer.phase = basic.rate_hz, 0.0
        self._under = (basic, cycle)

    def _swim_under(self, layer: BasicStrokeLayer, data: mujoco.MjData) -> None:
        basic, cycle = self._under
        basic.phase, basic.cycles = layer.phase, layer.cycles
        cycle.update(data)
        layer.set_tables(basic.tables)
        layer.rate_hz = basic.rate_hz
