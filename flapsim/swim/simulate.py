"""Swim a stroke for a while and measure it: speed, stroke rate, distance per stroke,
floating height, drift.
"""

from __future__ import annotations

import logging
import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field

import mujoco
import numpy as np
from tqdm import tqdm

from flapsim.core.errors import InputError
from flapsim.fluid.flow import FlowField
from flapsim.render.scene import Marker, add_items
from flapsim.render.video import Camera, CameraRig, new_renderer
from flapsim.swim.budget import dof_groups, fold_segments, summarize_joints, water_work_rates
from flapsim.swim.budget import summarize as summarize_budget
from flapsim.swim.continuous import RULES, HandRules
from flapsim.swim.goals import Circle, Heading, Path, Point, Trajectory, Waypoints
from flapsim.swim.layers import BasicStrokeLayer, FeedbackLayer
from flapsim.swim.model import Swimmer, SwimmerParams, check_diverged
from flapsim.swim.per_cycle import CycleLayer, load_table
from flapsim.swim.strokes import Stroke, load_stroke

log = logging.getLogger(__name__)

SAMPLE_HZ = 50.0  # recorded states per simulated second
SETTLE_CYCLES = 2  # cycles left out of the steady-state averages (start from rest)
#: the control layers a swim can run (the paper's Fig. 2): the basic stroke alone; with
#: the per-cycle layer; with the per-cycle and the continuous layers
LAYERS = ("basic", "cycle", "all")
LAYER_NAMES = {"basic": ["basic stroke"], "cycle": ["basic stroke", "per-cycle"],
               "all": ["basic stroke", "per-cycle", "continuous"]}


class LayerStack:
    """The layers above the basic stroke, switchable while swimming (:meth:`set_mode`,
    e.g. from the viewer). ``update`` runs them at the control rate: the per-cycle layer
    (once per cycle), then the continuous layer (the stroke's feedback rules and the
    hand rules)."""

    def __init__(self, basic: BasicStrokeLayer, mode: str, cycle=None, feedback=None,
                 hands=None) -> None:
        self.basic = basic
        self.cycle = cycle
        self.feedback = feedback
        self.hands = hands
        self.mode = "basic"
        self.switches: list[dict] = []
        self.set_mode(mode)

    def set_mode(self, mode: str, t: float | None = None) -> None:
        """Switch to ``mode`` (one of :data:`LAYERS`); the stroke's own tables come back
        and the new layers take over at their next update."""
        if mode not in LAYERS:
            raise InputError(f"layers must be one of {', '.join(LAYERS)}, got {mode!r}")
        if mode == self.mode and self.switches:
            return
        self.mode = mode
        base = self.basic.base_tables
        self.basic.set_tables(base)
        self.basic.extra[:] = 0.0
        self.basic.extra_on = mode == "all" and self.hands is not None
        if self.cycle is not None:
            self.cycle.reset()
        if self.feedback is not None:
            self.feedback.rebase(base)
        if self.hands is not None:
            for h in self.hands.hands:
                h["off"][:] = 0.0
        self.switches.append({"t": t, "layers": mode})

    def update(self, data: mujoco.MjData) -> None:
        if self.mode in ("cycle", "all") and self.cycle is not None:
            self.cycle.update(data)
        if self.mode == "all":
            if self.feedback is not None:
                self.feedback.update(data)
            if self.hands is not None:
                self.hands.update(data)


@dataclass
class SwimResult:
    """What one swim measured (SI units; world frame, +x = the initial heading)."""

    stroke: str
    seconds: float
    rate_hz: float
    cycles: int
    times: np.ndarray = field(repr=False)
    com: np.ndarray = field(repr=False)  # (n, 3)
    head: np.ndarray = field(repr=False)  # (n, 3) head box centre
    wall_s: float = 0.0
    water_level: float = 0.0
    #: muscle power at each sample [W]: (motor torque - joint damping qdot) . qdot summed
    #: over the joints (the damping is the PD's velocity term, see flapsim.swim.muscles),
    #: the mean over the physics steps since the previous sample (:func:`step_muscle_power`):
    #: net, a joint braking (negative work) pays back what another one delivers
    power: np.ndarray = field(default=None, repr=False)
    #: the same with each joint dof's negative work counted as nothing (a muscle braking
    #: is not paid back), the upper of the two counts [W]
    power_positive: np.ndarray | None = field(default=None, repr=False)
    #: the feedback layer's weights (see FeedbackLayer.summary); None = basic layer only
    feedback: dict | None = None
    #: what the swimmer steered for (flapsim.swim.goals), if anything
    target: object | None = None
    frames: list = field(default_factory=list, repr=False)
    #: the layers swum (one of LAYERS; the last one when switched while swimming)
    layers: str = "all"
    #: the per-cycle layer's weights (CycleLayer.summary) and the hand rules' offsets
    cycle: dict | None = None
    hands: dict | None = None
    #: at each sample: where the target was (n, 3) [m] (NaN where it has no position),
    #: the heading it asked for and the body line's heading [rad]
    target_xyz: np.ndarray | None = field(default=None, repr=False)
    aim_heading: np.ndarray | None = field(default=None, repr=False)
    body_yaw: np.ndarray | None = field(default=None, repr=False)
    #: at each sample: the roll of the thorax (shoulders) and of the pelvis (hips) about
    #: the body's long axis (the left side's rise above the horizontal) and the trunk's
    #: incline (the pelvis-to-neck line above the horizontal) [rad]
    carriage: np.ndarray | None = field(default=None, repr=False)
    #: at each sample: the heights of the centres of the hands (left, right) and the feet
    #: (left, right) [m, world z]
    limbs: np.ndarray | None = field(default=None, repr=False)
    #: at each sample, with ``swim(budget=True)``: (n, groups, 2) the power each segment
    #: group gives the water and its part against the body's progress [W]
    #: (:func:`flapsim.swim.budget.water_work_rates`)
    water_rates: np.ndarray | None = field(default=None, repr=False)
    #: at each sample, with ``swim(budget=True)``: (n, segments, 2) the same per segment,
    #: left and right apart (:data:`flapsim.swim.model.SEGMENTS` order)
    water_rates_segments: np.ndarray | None = field(default=None, repr=False)
    #: at each sample, with ``swim(budget=True)``: (n, joint dofs, 4) each joint dof's mean
    #: power over the steps since the previous sample [W]: the muscle's net (as ``power``),
    #: its positive part (per step), the part the joint damping (the PD's velocity term)
    #: gives (<= 0 where it brakes) and the joint limits' (and contacts') constraint force's
    #: (:func:`step_joint_powers`); dofs in ``model.jnt_dofadr`` order from dof 6
    joint_power: np.ndarray | None = field(default=None, repr=False)
    #: each joint dof's row in :data:`flapsim.swim.budget.JOINT_GROUPS` (with ``joint_power``)
    joint_groups: np.ndarray | None = field(default=None, repr=False)
    #: at each sample, with ``swim(budget=True)``: the stroke phase (0..1) of the basic layer
    phase: np.ndarray | None = field(default=None, repr=False)
    #: at each sample, with ``swim(budget=True)``: the whole body's kinetic energy [J] and
    #: the part of it in the motion relative to the centre of mass [J]
    kinetic: np.ndarray | None = field(default=None, repr=False)
    #: the approach's switches between swimming and treading water
    #: (:meth:`flapsim.swim.arrival.Approach.summary`), if one ran
    approach: dict | None = None

    def _steady(self) -> np.ndarray:
        t0 = SETTLE_CYCLES / self.rate_hz if self.seconds > 3 * SETTLE_CYCLES / self.rate_hz else 0
        return self.times >= t0

    @property
    def distance_m(self) -> float:
        """Forward (+x) displacement of the centre of mass over the whole run [m]."""
        return float(self.com[-1, 0] - self.com[0, 0])

    @property
    def speed(self) -> float:
        """Mean forward speed of the centre of mass after the first cycles [m/s]
        (whole cycles only, so the intra-cycle surge averages out)."""
        sel = self._steady()
        t = self.times[sel]
        x = self.com[sel, 0]
        ncyc = math.floor((t[-1] - t[0]) * self.rate_hz)
        if ncyc < 1:
            return float((x[-1] - x[0]) / max(t[-1] - t[0], 1e-9))
        t_end = t[0] + ncyc / self.rate_hz
        k = int(np.searchsorted(t, t_end - 1e-9))
        k = min(k, len(t) - 1)
        return float((x[k] - x[0]) / (t[k] - t[0]))

    def _cycle_peaks(self) -> np.ndarray:
        """Highest head-centre height above the water in each whole cycle after the
        first ones [m]."""
        sel = self._steady()
        t, z = self.times[sel], self.head[sel, 2] - self.water_level
        if len(t) < 2:
            return np.zeros(0)
        cycle = np.floor((t - t[0]) * self.rate_hz + 1e-9).astype(int)
        n = math.floor((t[-1] - t[0]) * self.rate_hz + 1e-9)
        if n < 1:
            return np.array([z.max()])
        return np.array([z[cycle == c].max() for c in range(n)])

    @property
    def breathing_cycles(self) -> float:
        """Fraction of the whole cycles after the first ones in which the head's centre
        (about eye level) rises above the water at least once."""
        peaks = self._cycle_peaks()
        return float(np.mean(peaks > 0)) if len(peaks) else 0.0

    def _target_summary(self) -> dict:
        t = self.target
        if t is None:
            return {}
        out: dict = {"target": t.describe()}
        xy = self.com[:, :2]
        if isinstance(t, (Point, Circle)):
            d = t.distance(xy, self.times)
            hit = np.flatnonzero(d <= t.radius)
            out["target_distance_end_m"] = float(d[-1])
            out["target_distance_min_m"] = float(d.min())
            out["target_reached_s"] = float(self.times[hit[0]]) if len(hit) else None
            sel = self._steady()
            out["target_distance_mean_m"] = float(d[sel].mean())
            # how well it was held once caught (a moving target) or stayed at (a fixed one)
            out["target_distance_after_reached_mean_m"] = float(d[hit[0]:].mean()) \
                if len(hit) else None
        elif isinstance(t, Path):
            # distance to the path and progress along it, in order (as the steering saw
            # it), until the end of the path comes within the look-ahead
            prog_a, err_a = t.track(xy)
            done = np.flatnonzero(prog_a >= t.length - t.lookahead)
            sel = self._steady() & (np.arange(len(prog_a)) < (done[0] if len(done) else len(prog_a)))
            if not np.any(sel):
                sel = np.ones(len(prog_a), dtype=bool)
            out["path_error_mean_m"] = float(err_a[sel].mean())
            out["path_error_max_m"] = float(err_a[sel].max())
            out["path_progress_m"] = float(prog_a[-1])
            out["path_completed_fraction"] = float(min(1.0, prog_a[-1] / t.length))
            out["path_completed_s"] = float(self.times[done[0]]) if len(done) else None
        return out

    def tracking(self) -> dict:
        """Distance to the target (3D for targets with a depth) and heading error, after
        the first cycles; distance swum along the track; when the target was first
        within its radius. Empty without a target that has a position."""
        out: dict = {}
        if self.aim_heading is not None and len(self.aim_heading):
            sel = self._steady()
            err = np.abs((self.aim_heading - self.body_yaw + np.pi) % (2 * np.pi) - np.pi)
            out["heading_error_mean_deg"] = float(np.degrees(err[sel].mean()))
        xy = self.com[:, :2]
        out["distance_swum_m"] = float(np.linalg.norm(np.diff(xy, axis=0), axis=1).sum())
        if self.target_xyz is None or not np.all(np.isfinite(self.target_xyz)):
            return out
        t = self.target
        full = bool(getattr(t, "is_3d", False))
        diff = self.target_xyz - self.com
        dist = np.linalg.norm(diff if full else diff[:, :2], axis=1)
        sel = self._steady()
        out["target_distance_3d"] = full
        out["distance_to_target_mean_m"] = float(dist[sel].mean())
        out["distance_to_target_max_m"] = float(dist[sel].max())
        out["distance_to_target_end_m"] = float(dist[-1])
        r = float(getattr(t, "radius", 0.5))
        hit = np.flatnonzero(dist <= r)
        out["time_to_reach_s"] = float(self.times[hit[0]]) if len(hit) else None
        return out

    @property
    def track_speed(self) -> float:
        """Mean horizontal speed along the centre of mass's track after the first cycles,
        whatever its direction [m/s] (sampled once per cycle, so the intra-cycle sway
        does not count): the speed of a swimmer that turns."""
        sel = self._steady()
        t, xy = self.times[sel], self.com[sel, :2]
        if len(t) < 2:
            return 0.0
        k = np.searchsorted(t, np.arange(t[0], t[-1] + 1e-9, 1.0 / self.rate_hz))
        k = np.unique(np.minimum(k, len(t) - 1))
        if len(k) < 2:
            return float(np.linalg.norm(xy[-1] - xy[0]) / max(t[-1] - t[0], 1e-9))
        return float(np.linalg.norm(np.diff(xy[k], axis=0), axis=1).sum() / (t[k[-1]] - t[k[0]]))

    @property
    def distance_per_stroke(self) -> float:
        """Forward distance per cycle [m]."""
        return self.speed / self.rate_hz

    def _carriage_summary(self, sel: np.ndarray) -> dict:
        """Roll to each side (half the range of the settled swim) of the shoulders and
        hips, and the trunk's mean incline [deg] (Psycharakis & Sanders 2008; Zamparo et
        al. 2009 measure these on swimmers)."""
        if self.carriage is None or not len(self.carriage) or not sel.any():
            return {}
        c = np.degrees(self.carriage[sel])
        return {"roll_shoulders_deg": float(0.5 * np.ptp(c[:, 0])),
                "roll_hips_deg": float(0.5 * np.ptp(c[:, 1])),
                "trunk_incline_deg": float(c[:, 2].mean())}

    def _limbs_summary(self, sel: np.ndarray) -> dict:
        """The highest the centre of a hand and of a foot came relative to the surface in
        the settled swim [m] (a breaststroker's recovery stays under water; a crawler's
        hands come out)."""
        if self.limbs is None or not len(self.limbs) or not sel.any():
            return {}
        z = self.limbs[sel] - self.water_level
        return {"hands_height_max_m": float(z[:, :2].max()),
                "feet_height_max_m": float(z[:, 2:].max())}

    def summary(self) -> dict:
        head_z = self.head[:, 2] - self.water_level
        com_z = self.com[:, 2] - self.water_level
        sel = self._steady()
        drift = np.linalg.norm(self.head[:, :2] - self.head[0, :2], axis=1)
        return {
            "stroke": self.stroke,
            "seconds": self.seconds,
            "stroke_rate_hz": self.rate_hz,
            "cycles": self.cycles,
            "speed_m_s": self.speed,
            "mean_speed_whole_run_m_s": self.distance_m / self.seconds,
            "track_speed_m_s": self.track_speed,
            "distance_m": self.distance_m,
            "distance_per_stroke_m": self.distance_per_stroke,
            "head_height_mean_m": float(head_z[sel].mean()),
            "head_height_min_m": float(head_z[sel].min()),
            "head_height_max_m": float(head_z[sel].max()),
            "head_above_water_fraction": float((head_z[sel] > 0).mean()),
            "breathing_cycles_fraction": self.breathing_cycles,
            "head_height_cycle_peak_mean_m": float(np.mean(self._cycle_peaks()))
            if len(self._cycle_peaks()) else None,
            "com_height_mean_m": float(com_z[sel].mean()),
            "com_height_end_m": float(com_z[-1]),
            "lateral_drift_m": float(self.com[-1, 1] - self.com[0, 1]),
            "muscle_power_mean_w": float(self.power[sel].mean()) if self.power is not None
            else None,
            "muscle_power_positive_mean_w": float(self.power_positive[sel].mean())
            if self.power_positive is not None else None,
            "layers": LAYER_NAMES[self.layers],
            "layers_mode": self.layers,
            "feedback_weights": self.feedback,
            "cycle_weights": self.cycle,
            "hand_rules": self.hands,
            "approach": self.approach,
            **self.tracking(),
            **self._target_summary(),
            **self._carriage_summary(sel),
            **self._limbs_summary(sel),
            **({"water_budget": summarize_budget(self.water_rates[sel])}
               if self.water_rates is not None and sel.any() else {}),
            **({"joint_budget": summarize_joints(self.joint_power[sel], self.joint_groups)}
               if self.joint_power is not None and self.joint_groups is not None and sel.any()
               else {}),
            "head_horizontal_drift_max_m": float(drift.max()),
            "wall_s": self.wall_s,
            "realtime_factor": self.seconds / self.wall_s if self.wall_s > 0 else None,
        }


def step_muscle_power(d: mujoco.MjData, damping: np.ndarray, qvel_before: np.ndarray
                      ) -> np.ndarray:
    """Each joint dof's muscle power [W] over the physics step just taken (call after
    ``mj_step``; ``qvel_before``: the velocities before it; ``damping``: the joint dofs'
    ``dof_damping``): the motor torque of the step's start, less the damping that the
    implicit integrator applied at the step's end velocity, times the step's mean
    velocity. This is the work the integrator did (the energy balance closes to ~1 %);
    torque x velocity sampled at one instant undercounts it by ~6 % at a 4 ms step (the
    implicit damping), converging only as the step shrinks."""
    v1 = d.qvel[6:]
    return (d.qfrc_actuator[6:] - damping * v1) * (0.5 * (qvel_before[6:] + v1))


def step_joint_powers(d: mujoco.MjData, damping: np.ndarray, qvel_before: np.ndarray
                      ) -> np.ndarray:
    """(joint dofs, 4) each joint dof's power over the physics step just taken [W]: the
    muscle's net (:func:`step_muscle_power`), its positive part, the damping's share of
    the net (``-damping v1 v_mean``, the PD's velocity term, negative where it brakes) and
    the constraint force's (joint limits, contacts: ``qfrc_constraint v_mean``). Call after
    ``mj_step``."""
    v1 = d.qvel[6:]
    vm = 0.5 * (qvel_before[6:] + v1)
    net = (d.qfrc_actuator[6:] - damping * v1) * vm
    return np.stack([net, np.maximum(net, 0.0), -damping * v1 * vm,
                     d.qfrc_constraint[6:] * vm], axis=1)


def kinetic_energies(m: mujoco.MjModel, d: mujoco.MjData, scratch: mujoco.MjData,
                     root: int) -> tuple[float, float]:
    """The whole body's kinetic energy and its part relative to the centre of mass [J]
    (König: total less 1/2 M V^2), from ``d``'s state computed afresh in ``scratch``."""
    scratch.qpos[:] = d.qpos
    scratch.qvel[:] = d.qvel
    mujoco.mj_fwdPosition(m, scratch)
    mv = np.zeros(m.nv)
    mujoco.mj_mulM(m, scratch, mv, scratch.qvel)
    total = 0.5 * float(scratch.qvel @ mv)
    mujoco.mj_comVel(m, scratch)
    mujoco.mj_subtreeVel(m, scratch)
    v = scratch.subtree_linvel[root]
    return total, total - 0.5 * float(m.body_subtreemass[root]) * float(v @ v)


def _roll(d: mujoco.MjData, body: int) -> float:
    """The angle of ``body``'s left axis (local y) above the horizontal [rad]."""
    return math.asin(max(-1.0, min(1.0, float(d.xmat[body][7]))))


def swim(
    stroke: str | Stroke,
    seconds: float = 20.0,
    params: SwimmerParams | None = None,
    rate_hz: float | None = None,
    flow: FlowField | None = None,
    current: tuple[float, float, float] = (0.0, 0.0, 0.0),
    video_fps: float = 0.0,
    video_size: tuple[int, int] = (480, 640),
    progress: bool = False,
    swimmer: Swimmer | None = None,
    feedback: bool = True,
    target: Heading | Point | Circle | Path | Waypoints | Trajectory | None = None,
    control_hook: Callable[[Swimmer, BasicStrokeLayer], bool] | None = None,
    on_frame: Callable[[np.ndarray], None] | None = None,
    layers: str | None = None,
    rules: tuple[str, ...] | None = None,
    cycle_table: object | None = None,
    hand_params: object | None = None,
    speed: float | None = None,
    approach: object | None = None,
    budget: bool = False,
) -> SwimResult:
    """Simulate ``stroke`` for ``seconds`` from rest and return what it measured.

    ``video_fps`` > 0 also renders frames (offscreen) into ``result.frames``, or hands
    each to ``on_frame(rgb)`` (e.g. a video writer) so that memory stays bounded.
    ``layers`` (:data:`LAYERS`): "basic" = the stroke alone; "cycle" = with the
    per-cycle layer (steering for ``target``, or holding the start heading, through
    the stroke's ``[cycle.*]`` sequences and its calibration table); "all" (default) =
    also the continuous layer: the hand rules ``rules`` (default both, see
    :mod:`flapsim.swim.continuous`) and the stroke's feedback rules (its
    ``[perturb.*]`` sections: treading water's balance) at 50 Hz. ``feedback=False``
    (older API) means "basic". ``speed`` [m/s]: the per-cycle layer sets each cycle's stroke
    rate to hold it (:class:`flapsim.swim.per_cycle.CycleLayer`). ``cycle_table``: a
    :class:`flapsim.swim.per_cycle.CycleTable`
    instead of the stroke's own. ``hand_params``: a
    :class:`flapsim.swim.continuous.HandRuleParams` instead of the defaults.
    ``target``: a heading, a point (with a depth: 3D), waypoints, a timed trajectory or
    a path (flapsim.swim.goals).
    ``approach``: a :class:`flapsim.swim.arrival.Approach` for ``target``: the per-cycle
    layer asks the speed it plans of each cycle (``speed``, if given, is the cruise),
    and at a fixed target the swimmer treads water (``result.approach``: its switches).
    ``budget``: also sample where the water takes the power (:mod:`flapsim.swim.budget`) at
    every recorded state (``result.water_rates``; the swim itself is unchanged).
    ``control_hook(swimmer, layer)`` runs at every control step (50 Hz) after the
    layers; returning False ends the swim early (the viewer uses it; ``layer.stack``
    is the :class:`LayerStack`, whose mode it may switch).
    """

    if layers is None:
        layers = "all" if feedback else "basic"
    if layers not in LAYERS:
        raise InputError(f"layers must be one of {', '.join(LAYERS)}, got {layers!r}")
    st = stroke if isinstance(stroke, Stroke) else load_stroke(stroke)
    sw = swimmer or Swimmer(params, flow)
    layer = BasicStrokeLayer(sw, st, rate_hz)
    sw.reset(st.posture, qpos_joints=layer.start_pose(0.0))
    sw.set_current(np.asarray(current, dtype=float))
    if target is not None and hasattr(target, "reset"):
        target.reset()
    steering = [k for k in st.cycle if k.startswith("yaw")]
    if target is not None and layers != "basic" and not steering:
        raise InputError(f"stroke {st.name!r} cannot steer: it has no [cycle.yaw_*] sequences "
                         "(crawl, breaststroke and treading have)")
    if speed is not None and layers == "basic":
        raise InputError("a speed asked is held by the per-cycle layer: use layers 'cycle' or "
                         "'all', not 'basic'")
    fb = FeedbackLayer(layer, target=target) if st.perturbations else None
    cyc = None
    if st.cycle:
        try:
            table = cycle_table if cycle_table is not None else \
                load_table(st, layers="all" if layers == "all" else "cycle",
                           body_shape=sw.params.body_shape)
            cyc = CycleLayer(layer, table, target=target, feedback=fb, speed=speed)
        except InputError:
            if (target is not None or speed is not None) and layers != "basic":
                raise
            log.warning("stroke %s has no per-cycle calibration table: the per-cycle layer is "
                        "off", st.name)
    hook = control_hook
    if approach is not None:
        if cyc is None or layers == "basic":
            raise InputError("an approach asks its speeds of the per-cycle layer: swim a prone "
                             "stroke (crawl, breaststroke) with layers 'cycle' or 'all'")
        cyc.plan = approach

        def hook(sw: Swimmer, layer: BasicStrokeLayer) -> bool:
            approach(sw, layer)
            return control_hook is None or control_hook(sw, layer)
    hands = HandRules(layer, target, RULES if rules is None else tuple(rules), hand_params) \
        if (rules is None or len(rules)) else None
    if hands is not None:
        hands.cycle = cyc
    stack = LayerStack(layer, layers, cyc, fb, hands)
    layer.stack = stack
    aim: list[float] = []
    yaw: list[float] = []
    txyz: list = []
    head_body = sw.body["head"]
    m, d = sw.model, sw.data
    dt = m.opt.timestep
    nsteps = int(round(seconds / dt))
    every = max(1, int(round(1.0 / (SAMPLE_HZ * dt))))
    control_every = max(1, int(round(0.02 / dt)))  # swimmer-induced flow at 50 Hz
    times, com, head, power, power_pos = [], [], [], [], []
    work = work_pos = 0.0  # muscle work [J] since the last sample, over `steps` steps
    steps = 0
    v_before = np.zeros(m.nv)
    carriage: list[tuple[float, float, float]] = []  # roll of thorax, pelvis; incline [rad]
    thorax = sw.body["thorax"]
    damp = m.dof_damping[6:].copy()
    head_gid = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, "head")
    limb_gids = [mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, n)
                 for n in ("hand_l", "hand_r", "foot_l", "foot_r")]
    limbs: list[np.ndarray] = []
    water: list[np.ndarray] = []
    joints: list[np.ndarray] = []  # per dof: mean net, positive, damping, constraint [W]
    phases: list[float] = []
    kinetic: list[tuple[float, float]] = []
    jwork = np.zeros((m.nv - 6, 4))  # per dof work [J] since the last sample
    scratch = mujoco.MjData(m) if budget else None
    pelvis = sw.body["pelvis"]
    renderer = None
    frames: list[np.ndarray] = []
    frame_every = 0
    if video_fps > 0:
        renderer = new_renderer(m, *video_size)
        frame_every = max(1, int(round(1.0 / (video_fps * dt))))
        cam = mujoco.MjvCamera()
        # the shared chase camera: behind the swimmer along its heading, the target ahead
        rig = CameraRig(m, Camera(mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_BODY, pelvis), "chase",
                                  distance=3.2, elevation_deg=-18.0, lead_m=0.8, tau_s=0.6))
    bar = None
    if progress:
        bar = tqdm(total=nsteps, unit=" sim s", unit_scale=dt, desc=st.name, leave=False)
    t_wall = time.perf_counter()
    try:
        with sw:
            t_wall = time.perf_counter()  # after attaching (which may compile the callback)
            for i in range(nsteps + 1):
                if i % every == 0:
                    times.append(d.time)
                    com.append(d.subtree_com[pelvis].copy())
                    head.append(d.geom_xpos[head_gid].copy())
                    limbs.append(d.geom_xpos[limb_gids, 2].copy())
                    if budget:
                        water.append(water_work_rates(sw, d, scratch, per_segment=True))
                        phases.append(layer.phase)
                        kinetic.append(kinetic_energies(m, d, scratch, pelvis))
                        joints.append(jwork / (steps * dt) if steps else np.zeros_like(jwork))
                        jwork = np.zeros_like(jwork)
                    if steps:  # the mean over the steps since the last sample
                        power.append(work / (steps * dt))
                        power_pos.append(work_pos / (steps * dt))
                    else:  # at the start: the torque x speed of this instant
                        qd = d.qvel[6:]
                        p_dof = (d.qfrc_actuator[6:] - damp * qd) * qd
                        power.append(float(p_dof.sum()))
                        power_pos.append(float(p_dof[p_dof > 0.0].sum()))
                    work = work_pos = 0.0
                    steps = 0
                    line = d.xpos[head_body] - d.xpos[pelvis]
                    yaw.append(math.atan2(line[1], line[0]))
                    carriage.append((_roll(d, thorax), _roll(d, pelvis),
                                     math.atan2(line[2], math.hypot(line[0], line[1]))))
                    if target is not None:
                        aim.append(target.heading(com[-1][:2].copy(), np.zeros(2), float(d.time)))
                        pos = getattr(target, "position", None)
                        txyz.append(pos(float(d.time)) if pos is not None else np.full(3, np.nan))
                if renderer is not None and i % frame_every == 0:
                    rig.update(cam, d, frame_every * dt if i else 0.0)
                    renderer.update_scene(d, camera=cam)
                    if txyz and np.all(np.isfinite(txyz[-1])):  # the target, in view ahead
                        add_items(renderer.scene, [Marker(txyz[-1])])
                    if on_frame is not None:
                        on_frame(renderer.render())
                    else:
                        frames.append(renderer.render())
                if i == nsteps:
                    break
                if i % control_every == 0:
                    sw.update_flow()
                    stack.update(d)
                    if bar is not None and i:
                        bar.update(control_every)
                    if hook is not None and not hook(sw, layer):
                        nsteps = i  # stopped early: what was swum so far is the result
                        if times[-1] != d.time:
                            times.append(d.time)
                            com.append(d.subtree_com[pelvis].copy())
                            head.append(d.geom_xpos[head_gid].copy())
                            limbs.append(limbs[-1])
                            if budget:
                                water.append(water[-1])
                                phases.append(phases[-1])
                                kinetic.append(kinetic[-1])
                                joints.append(joints[-1])
                            power.append(power[-1])
                            power_pos.append(power_pos[-1])
                            yaw.append(yaw[-1])
                            carriage.append(carriage[-1])
                            if target is not None:
                                aim.append(aim[-1])
                                txyz.append(txyz[-1])
                        break
                layer.apply(d, dt)
                v_before[:] = d.qvel
                mujoco.mj_step(m, d)
                p_dof = step_muscle_power(d, damp, v_before)
                if budget:
                    jwork += step_joint_powers(d, damp, v_before) * dt
                work += float(p_dof.sum()) * dt
                work_pos += float(p_dof[p_dof > 0.0].sum()) * dt
                steps += 1
                if i % 500 == 0:
                    check_diverged(m, d)
            check_diverged(m, d)
    finally:
        if renderer is not None:
            renderer.close()
        if bar is not None:
            bar.close()
    wall = time.perf_counter() - t_wall
    if approach is not None and approach.state != "swim":
        # the layers rest while treading water at the target, not switched off
        stack.mode = layers
    return SwimResult(st.name, nsteps * dt, layer.rate_hz, layer.cycles, np.asarray(times),
                      np.asarray(com), np.asarray(head), wall, sw.params.water_level,
                      power=np.asarray(power), power_positive=np.asarray(power_pos),
                      frames=frames,
                      feedback=fb.summary() if (fb is not None and stack.mode == "all") else None,
                      target=target, layers=stack.mode,
                      cycle=cyc.summary() if (cyc is not None and stack.mode != "basic") else None,
                      hands=hands.summary() if (hands is not None and stack.mode == "all") else None,
                      target_xyz=np.asarray(txyz) if target is not None else None,
                      aim_heading=np.asarray(aim) if target is not None else None,
                      body_yaw=np.asarray(yaw), carriage=np.asarray(carriage),
                      limbs=np.asarray(limbs),
                      water_rates=fold_segments(np.asarray(water)) if budget else None,
                      water_rates_segments=np.asarray(water) if budget else None,
                      joint_power=np.asarray(joints) if budget else None,
                      joint_groups=dof_groups(m) if budget else None,
                      phase=np.asarray(phases) if budget else None,
                      kinetic=np.asarray(kinetic) if budget else None,
                      approach=approach.summary() if approach is not None else None)


