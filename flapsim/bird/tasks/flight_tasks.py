"""Flight tasks: a path flown by the learned controller under disturbances, judged.

:func:`fly_task` is the one runner behind every flight scenario (``flapsim eval``): the
dove starts on the path's first point, the path controller (:mod:`flapsim.bird.tasks.path_control`)
drives the wingbeat controller until the path's end, and the flight is judged by the
paper's Ep, Er, Eo, Ef (eq. 12-15) and by whether it got *lost*: left a tube around the
path (``tube_m``), fell below it, or hit an obstacle. Disturbances are the paper's:

* pushes (:class:`PushSpec`): a force for 0.1 s at the trunk's centre of mass, in the
  bird's heading frame (front, back, left, right, up, down); the controller's P0
  prediction does not see it coming;
* plucked feathers (names such as ``l_p9``: left primary 9, p10 outermost): their
  triangles carry no force;
* wind: a steady wind plus any flow primitives (gusts, breezes) of :mod:`flapsim.fluid.flow`;
* obstacles (:class:`Forest`): vertical trunks with round crowns; a collision is the bird
  (a sphere of half its span around the trunk) touching one.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import mujoco
import numpy as np
from tqdm import tqdm

from flapsim.bird.control.controller import (
    database_dove,
    database_pitch,
    database_table,
    load_controller,
)
from flapsim.bird.control.targets import trim_of_base_flight
from flapsim.bird.flight import cycle
from flapsim.bird.flight.dove_flight import DoveFlight, FlightConfig
from flapsim.bird.tasks.path_control import FlightPath, PathTarget, path_metrics, start_on_path
from flapsim.core.errors import InputError, SimulationError

#: The path target's default extra angle of attack per g of a turn's load factor, deg, per
#: dove (:attr:`~flapsim.bird.tasks.path_control.PathTarget.aoa_per_g_deg`): 40 for the rigid
#: dove completes more of the ten user paths and the level and 15 deg climbing circles over
#: starts under 1 mm/s apart than 30, 20 or 50 (docs/design/flight.md, "More angle of attack
#: in turns: 40 deg per g"). Modal feathers keep 0 with their carry of 0.
DEFAULT_AOA_PER_G_DEG = {"rigid": 40.0, "modal": 0.0}

#: How far ahead the path target asks the bank, s, per dove
#: (:attr:`~flapsim.bird.tasks.path_control.PathTarget.bank_lead_s`; docs/design/flight.md,
#: "Asking the bank ahead"): measured for the rigid dove over starts under 1 mm/s apart (the
#: ten user paths and the level and 15 deg climbing circles, 10 starts each); modal feathers
#: keep the 0.3 s they were measured with.
DEFAULT_BANK_LEAD_S = {"rigid": 0.2, "modal": 0.3}

#: The path target's default climb given up per m/s of missing airspeed, rad s/m, per dove
#: (:attr:`~flapsim.bird.tasks.path_control.PathTarget.climb_per_speed_deficit`;
#: docs/design/flight.md, "Speed first: off"): 0 for both; 0.1 and 0.05 do no better over the
#: five rigid databases.
DEFAULT_CLIMB_PER_SPEED_DEFICIT = {"rigid": 0.0, "modal": 0.0}

#: The largest bank the path target asks, deg, per dove
#: (:attr:`~flapsim.bird.tasks.path_control.PathTarget.max_bank_deg`; docs/design/flight.md,
#: "A 60 deg bank by default"): 60 for the rigid dove steers the sharp sinusoid wider than the
#: capture on both sides in 15 of 20 starts (45 deg: 1 of 10) with the rest of the suite
#: unchanged. Modal feathers keep the 45 deg they were measured with.
DEFAULT_MAX_BANK_DEG = {"rigid": 60.0, "modal": 45.0}

#: The reference wingbeat's period, s (the capture's mean cycle, 0.1076 s): the unit of the
#: flight time a task allows beyond its path's own.
REFERENCE_PERIOD_S = 0.1075

#: The most lift the rigid dove's wing holds at constant speed at 7-8 m/s, in g (docs/design/flight.md,
#: "Where the tight turns and steep climbs fail": ``studies/dove_turn_limit.py``,
#: :mod:`flapsim.bird.flight.limits`). The time a task allows counts a turn tighter than that allows
#: at the speed asked at the speed where it does (a 3.6 m circle: 5.0 m/s, not 7): a bird
#: that slows for such a turn, as it must, is not lost by the clock. The paper's lost is a
#: tube left, a fall or a collision; the clock only catches a bird that stops making way.
WING_LOAD_FACTOR = 1.23

#: The most lift the rigid dove's wing holds at constant speed, in g, by speed in m/s (the same
#: study's table: 96 wingbeats around P0 within the joint ranges in free flight, flown in the
#: fixed-trunk tunnel at trunk pitches of 0-20 deg). Slower flight frees lift: a faster beat.
WING_LOAD_FACTOR_BY_SPEED = {5.0: 1.35, 6.0: 1.39, 7.0: 1.23, 8.0: 1.23}


def wing_load_factor(speed: float) -> float | None:
    """The most lift the rigid dove's wing holds at constant ``speed`` (m/s), in g: the
    :data:`WING_LOAD_FACTOR_BY_SPEED` table interpolated linearly; None outside the 5-8 m/s
    it was measured over."""
    v = np.array(sorted(WING_LOAD_FACTOR_BY_SPEED))
    if not (np.isfinite(speed) and v[0] <= speed <= v[-1]):
        return None
    return float(np.interp(speed, v, [WING_LOAD_FACTOR_BY_SPEED[s] for s in v]))

#: The slowest average way (m/s along the path) the clock accepts: a task allows at least its
#: path's length at this speed. Climbing pigeons fly 2.9-4.9 m/s (Berg & Biewener 2008, J Exp
#: Biol 211:1120), and the dove, short of power on a climb, slows as they do: on 80 m at 7 deg
#: it stays within 1.44 m of the path at 3.7 m/s on average (bundled database),
#: and 1.5x the flight time at 7 m/s (17.7 s) called that lost at 70 of 80 m. A bird slower than
#: this on average is not making way.
MIN_WAY_SPEED = 3.0

#: Unit push directions in the bird's heading frame: (forward, left, up) components.
PUSH_DIRECTIONS: dict[str, tuple[float, float, float]] = {
    "front": (1.0, 0.0, 0.0), "back": (-1.0, 0.0, 0.0), "left": (0.0, 1.0, 0.0),
    "right": (0.0, -1.0, 0.0), "up": (0.0, 0.0, 1.0), "down": (0.0, 0.0, -1.0),
}


@dataclass(frozen=True)
class PushSpec:
    """A push: ``newtons`` along ``direction`` (a key of :data:`PUSH_DIRECTIONS`) for
    ``duration_s`` from the first wingbeat that starts at or after ``at_s``."""

    at_s: float
    newtons: float
    direction: str
    duration_s: float = 0.1

    def __post_init__(self) -> None:
        if self.direction not in PUSH_DIRECTIONS:
            raise InputError(f"push direction must be one of {', '.join(PUSH_DIRECTIONS)}, "
                             f"got {self.direction!r}")
        if not (np.isfinite(self.newtons) and 0 <= self.newtons <= 100):
            raise InputError(f"push force must be 0..100 N, got {self.newtons}")

    def world_force(self, heading: float) -> np.ndarray:
        f, lft, u = PUSH_DIRECTIONS[self.direction]
        c, s = np.cos(heading), np.sin(heading)
        return self.newtons * np.array([f * c - lft * s, f * s + lft * c, u])


@dataclass(frozen=True)
class Tree:
    """A vertical trunk (cylinder from the ground) with a spherical crown on top, m."""

    x: float
    y: float
    height: float
    trunk_radius: float
    crown_radius: float

    def distance(self, p: np.ndarray) -> np.ndarray:
        """Distance from points (n, 3) to the tree's surface (negative inside)."""
        p = np.atleast_2d(p)
        r = np.hypot(p[:, 0] - self.x, p[:, 1] - self.y)
        z = p[:, 2]
        # trunk: a capped cylinder 0..height
        dz = np.maximum(np.maximum(-z, z - self.height), 0.0)
        d_trunk = np.where(dz > 0, np.hypot(np.maximum(r - self.trunk_radius, 0.0), dz),
                           r - self.trunk_radius)
        c = np.array([self.x, self.y, self.height])
        d_crown = np.linalg.norm(p - c, axis=1) - self.crown_radius
        return np.minimum(d_trunk, d_crown)


@dataclass(frozen=True)
class Forest:
    """Trees (see :class:`Tree`); the bird is a sphere of radius ``bird_radius_m``."""

    trees: tuple[Tree, ...]
    bird_radius_m: float = 0.26
    """Half the dove's span (0.51 m): a wing tip may touch anywhere around the trunk."""

    def clearance(self, p: np.ndarray) -> np.ndarray:
        """Distance from each point (n, 3) to the nearest tree, less the bird's radius."""
        p = np.atleast_2d(p)
        if not self.trees:
            return np.full(len(p), np.inf)
        return np.min([t.distance(p) for t in self.trees], axis=0) - self.bird_radius_m


@dataclass
class Task:
    """What to fly and under what."""

    path: FlightPath
    speed: float = 7.0
    """Flight speed asked, m/s."""
    pushes: tuple[PushSpec, ...] = ()
    plucked: tuple[str, ...] = ()
    wind: tuple[float, float, float] = (0.0, 0.0, 0.0)
    flow: tuple = ()
    """More flow primitives (gusts, breezes) on the simulation clock."""
    forest: Forest | None = None
    tube_m: float = 3.0
    """Lost when farther than this from the path at a wingbeat's end, m."""
    feathers: str = "rigid"
    """``rigid`` or ``modal`` feathers (the database must be of the same dove)."""
    max_wingbeats: int | None = None
    """Wingbeats allowed (None, the default: as many as fit in 1.5x the path's flight time at
    ``speed`` (turns tighter than :data:`WING_LOAD_FACTOR` allows counted at the speed where it
    does), or in the path's length at :data:`MIN_WAY_SPEED` if that is longer, plus five
    reference wingbeats, whatever their length)."""
    stop_when_lost_m: float = 15.0
    """Give up when this far from the path (nothing more to learn), m."""
    bank_lead_s: float | None = None
    """The path target asks the bank its recovery curve has this long after the wingbeat's
    end, s (None: the dove's default, :data:`DEFAULT_BANK_LEAD_S`; 0: at the end, the
    paper's)."""
    aoa_per_g_deg: float | None = None
    """The path target asks this much more angle of attack per g of a turn's load factor,
    deg (None: the dove's default, :data:`DEFAULT_AOA_PER_G_DEG`; 0: the paper's)."""
    max_bank_deg: float | None = None
    """The largest bank the path target asks, deg (None: the dove's default,
    :data:`DEFAULT_MAX_BANK_DEG`)."""
    climb_per_speed_deficit: float | None = None
    """The climb asked drops this much per m/s of airspeed below the speed asked, rad s/m
    (None: the dove's default, :data:`DEFAULT_CLIMB_PER_SPEED_DEFICIT`; 0: independent speed
    and height loops, the paper's)."""
    max_climb_deg: float | None = None
    """The steepest climb or descent the path target asks, deg (None: the path target's, 15)."""
    turn_load_factor: float = 0.0
    """The speed asked drops ahead of turns that would need more than this load factor at
    ``speed`` (0: no slowing, the paper's;
    :attr:`~flapsim.bird.tasks.path_control.PathTarget.turn_load_factor`)."""
    turn_speed_floor: float | None = None
    """The lowest speed asked for a turn, m/s (None: the path target's, 6.5 m/s, or ``speed``
    when that is lower)."""
    start_speed_change: float = 0.0
    """Added to the start's ground speed along its velocity, m/s (0, the default). Near its
    limits a controlled flight is chaotic and one start's verdict says little: verdict-spread
    studies fly a path from starts under 1 mm/s apart (``studies/dove_verdict_spread.py``)."""

    def __post_init__(self) -> None:
        dv = self.start_speed_change
        if isinstance(dv, bool) or not isinstance(dv, (int, float)) or not abs(dv) <= 1.0:
            raise InputError(f"the start's speed change must be a number within +-1 m/s (a "
                             f"perturbation, not another speed: see speed), got {dv!r}")


def _per_dove(table: dict, feathers: str, asked: float | None) -> float:
    return float(table.get(feathers, 0.0) if asked is None else asked)


def default_climb_per_speed_deficit(feathers: str, asked: float | None = None) -> float:
    """``asked``, or the dove's default climb given up per m/s of missing airspeed."""
    return _per_dove(DEFAULT_CLIMB_PER_SPEED_DEFICIT, feathers, asked)


def default_bank_lead(feathers: str, asked: float | None = None) -> float:
    """``asked``, or the dove's default bank lead (s)."""
    return _per_dove(DEFAULT_BANK_LEAD_S, feathers, asked)


def default_max_bank(feathers: str, asked: float | None = None) -> float:
    """``asked``, or the dove's default largest bank asked (deg)."""
    return _per_dove(DEFAULT_MAX_BANK_DEG, feathers, asked)


def default_aoa_per_g(feathers: str, asked: float | None = None) -> float:
    """``asked``, or the dove's default extra angle of attack per g (deg)."""
    return _per_dove(DEFAULT_AOA_PER_G_DEG, feathers, asked)


@dataclass
class TaskResult:
    """A flown task: the per-wingbeat record and the verdict."""

    status: str
    """``completed`` (reached the path's end, never lost), ``lost`` or ``diverged``."""
    reason: str
    metrics: dict
    positions: np.ndarray
    """(n + 1, 3) trunk position at the start and each wingbeat's end, m."""
    quats: np.ndarray
    """(n, 4) trunk orientation at each wingbeat's end."""
    desired: list
    steering_deg: np.ndarray
    """(n,) heading change over each wingbeat, deg (+ left)."""
    elevation_deg: np.ndarray
    """(n,) climb-angle change over each wingbeat, deg (+ up)."""
    qpos: np.ndarray | None
    """(steps, nq) every simulation step's positions, when recorded."""
    times: np.ndarray
    """(n + 1,) simulation time at the start and each wingbeat's end, s."""
    wall_s: float
    collisions: int = 0
    push_log: list = field(default_factory=list)
    model_hash: str = ""
    k: int | None = None
    """Neighbours of the controller's regression."""
    database_samples: int | None = None
    refine: int | None = None
    """The controller's simulated corrections per wingbeat."""
    refine_goal: str | None = None
    """What those corrections aim at (``reachable`` or ``full``)."""
    lookahead: tuple[int, int] | None = None
    """With the controller's look-ahead (:mod:`flapsim.bird.control.lookahead`): the wingbeats whose
    reference it had simulated ahead, and those simulated on the spot; None without one."""
    path_target: dict | None = None
    """The path target's settings as flown (:data:`PATH_TARGET_SETTINGS`: the dove's defaults
    resolved), so a result says what it was asked under."""

    @property
    def ok(self) -> bool:
        return self.status == "completed"


#: The :class:`~flapsim.bird.tasks.path_control.PathTarget` settings a :class:`TaskResult` records.
PATH_TARGET_SETTINGS = ("speed", "max_bank_deg", "bank_lead_s", "aoa_per_g_deg",
                        "climb_per_speed_deficit", "turn_load_factor", "turn_speed_floor",
                        "lookahead_s", "max_climb_deg")


def build_flight(task: Task, db=None, method: str = "lwlr", k: int | None = None, mirror: bool = True,
                 **options):
    """The :class:`~flapsim.bird.flight.dove_flight.DoveFlight` (with the feather table the database was
    sampled with) and learned controller for ``task`` (``mirror``: the regression also
    searches the samples' mirror images, the default; ``options``:
    :func:`~flapsim.bird.control.controller.load_controller`'s others, such as ``clip_request``,
    ``state_weight`` or ``predict``)."""

    fl = DoveFlight(database_dove(db, task.feathers), table=database_table(db, task.feathers),
                    wind=tuple(task.wind), flow=tuple(task.flow), plucked=tuple(task.plucked))
    try:
        ctl = load_controller(fl, db, method=method, k=k, mirror=mirror, **options)
    except BaseException:
        fl.close()
        raise
    return fl, ctl


def fly_task(task: Task, db=None, method: str = "lwlr", k: int | None = None,
             record: bool = False, progress: bool = False, controller=None,
             mirror: bool = True, **options) -> TaskResult:
    """Fly ``task`` with the learned controller over database ``db`` (default: bundled);
    ``controller``: an already built one (its flight's disturbances must match the task)."""

    own = controller is None
    if own:
        fl, ctl = build_flight(task, db, method, k, mirror, **options)
    else:
        ctl = controller
        fl = ctl.flight
    try:
        # the trim is measured from the attitude the database's pre-states were centred at:
        # a level start leaves a pitched dove's base flight settling over the trim's wingbeats
        pitch = database_pitch(db, task.feathers)
        cfg = FlightConfig(speed=task.speed, pitch_deg=pitch)
        trim = trim_of_base_flight(fl, ctl.P0, cfg)
        lead = {"bank_lead_s": default_bank_lead(task.feathers, task.bank_lead_s)}
        lead["aoa_per_g_deg"] = default_aoa_per_g(task.feathers, task.aoa_per_g_deg)
        lead["climb_per_speed_deficit"] = default_climb_per_speed_deficit(
            task.feathers, task.climb_per_speed_deficit)
        lead["turn_load_factor"] = float(task.turn_load_factor)
        lead["max_bank_deg"] = default_max_bank(task.feathers, task.max_bank_deg)
        if task.max_climb_deg is not None:
            lead["max_climb_deg"] = float(task.max_climb_deg)
        lead["turn_speed_floor"] = float(min(task.speed, PathTarget.turn_speed_floor)
                                         if task.turn_speed_floor is None else task.turn_speed_floor)
        target = PathTarget(trim, task.path, speed=task.speed, **lead)
        if any(task.wind) or task.flow:
            # the bird feels the air it flies through (and flies its path relative to it)
            target.wind = lambda p, t: fl.flow.velocity(np.asarray(p, float)[None], t)[0]
        # the bird starts at the speed asked where it starts (slower at a tight turn there)
        v_start = target.speed_for(0.0, 2.0 * target.lookahead_s * task.speed)
        start_on_path(fl, ctl.P0, task.path, v_start,
                      wind=None if target.wind is None else target.wind(task.path.point(0.0), 0.0),
                      pitch_deg=pitch)
        if task.start_speed_change:
            v = fl.data.qvel[0:3]  # along the velocity: the speed changes, not the direction
            v += task.start_speed_change * v / max(float(np.linalg.norm(v)), 1e-9)
            mujoco.mj_forward(fl.model, fl.data)
        if hasattr(ctl, "reset"):
            ctl.reset()  # a new flight: nothing carried from an earlier one
        la = getattr(ctl, "lookahead", None)
        before = (0, 0) if la is None else (la.hits, la.misses)
        r = _fly(fl, ctl, target, task, record, progress)
        r.model_hash, r.k, r.database_samples = fl.dove.hash(), ctl.regressor.k, ctl.regressor.n
        r.refine = getattr(ctl, "refine", None)
        r.refine_goal = getattr(ctl, "refine_goal", None)
        r.lookahead = None if la is None else (la.hits - before[0], la.misses - before[1])
        r.path_target = {k: float(getattr(target, k)) for k in PATH_TARGET_SETTINGS}
        return r
    finally:
        if own:
            fl.close()


def _fly(fl, ctl, target: PathTarget, task: Task, record: bool, progress: bool) -> TaskResult:
    m, d = fl.model, fl.data
    dt = float(m.opt.timestep)
    # the time allowed (unless a wingbeat count is given): 1.5x the path's flight time at the
    # speeds asked (slower ahead of tight turns with turn_load_factor), in turns tighter than
    # the wing holds at that speed at the speed where it holds them (WING_LOAD_FACTOR), and
    # never less than the path at MIN_WAY_SPEED (a bird that slows on a climb, as it must
    # short of power, is not lost by the clock either), plus five reference wingbeats. A
    # budget in wingbeats of the reference's period would give a controller with shorter
    # wingbeats less time (0.095 s wingbeats: 11.9 s for a 60 m path where the bundled
    # database's have 12.5 s)
    t_budget = (max(1.5 * target.flight_time(wing_load_factor=WING_LOAD_FACTOR),
                    task.path.length / MIN_WAY_SPEED) + 5 * REFERENCE_PERIOD_S)
    n_max = task.max_wingbeats or int(np.ceil(3.0 * t_budget / REFERENCE_PERIOD_S))
    pushes = sorted(task.pushes, key=lambda p: p.at_s)
    positions = [d.qpos[0:3].copy()]
    times = [float(d.time)]
    quats, steer, elev, qpos, push_log = [], [], [], [], []
    progress_s = [float(target.s)]  # the closest path point as each wingbeat began
    v_prev = fl.com_velocity()
    status, reason = "lost", (f"the path's end not reached in {n_max} wingbeats" if task.max_wingbeats
                              else f"the path's end not reached in {t_budget:.1f} s")
    lost_at = None
    bar = None
    if progress:
        bar = tqdm(total=round(task.path.length, 1), desc="path", unit="m")
    t0 = time.perf_counter()
    try:
        for _ in range(n_max):
            push = None
            if pushes and d.time + 1e-9 >= pushes[0].at_s:
                ps = pushes.pop(0)
                heading = float(np.arctan2(v_prev[1], v_prev[0]))
                force = ps.world_force(heading)
                push = cycle.Push(fl.dove.trunk, force, int(round(ps.duration_s / dt)))
                push_log.append({"t": float(d.time), "newtons": ps.newtons,
                                 "direction": ps.direction, "force": force.tolist()})
            target.begin(d.qpos[0:3], v_prev)
            try:
                step = ctl.choose(target, record=record, push=push)
            except SimulationError as exc:
                status, reason = "diverged", str(exc)
                break
            e = step.end
            target.end(e.duration)
            positions.append(e.trunk_pos)
            times.append(float(d.time))
            quats.append(e.trunk_quat)
            h0, c0 = cycle.heading_and_climb(v_prev)
            h1, c1 = cycle.heading_and_climb(e.com_vel)
            steer.append(np.degrees(cycle.wrap(h1 - h0)))
            elev.append(np.degrees(c1 - c0))
            progress_s.append(float(target.s))
            v_prev = e.com_vel
            if record:
                qpos.append(e.qpos)
            if bar is not None:
                bar.update(round(target.s, 1) - bar.n)
            off = task.path.distance(e.trunk_pos)
            if lost_at is None and off > task.tube_m:
                lost_at = (len(quats), float(d.time), off)
            if off > task.stop_when_lost_m:
                break
            if target.done:
                status, reason = "completed", ""
                break
            if not task.max_wingbeats and d.time - times[0] >= t_budget - 1e-9:
                break
    finally:
        if bar is not None:
            bar.close()
    wall = time.perf_counter() - t0
    positions_a = np.array(positions)
    quats_a = np.array(quats).reshape(-1, 4)
    desired = target.desired[:len(quats)]
    metrics = path_metrics(task.path, positions_a[1:], quats_a, desired) if len(quats) else {}
    collisions = 0
    qpos_a = np.concatenate(qpos) if record and qpos else None
    if task.forest is not None:
        # every simulated step when recorded, else the wingbeat ends
        pts = qpos_a[:, 0:3] if qpos_a is not None else positions_a
        hits = task.forest.clearance(pts) < 0.0
        collisions = int(np.count_nonzero(np.diff(np.concatenate([[0], hits.astype(int)])) == 1))
        metrics["min_tree_clearance"] = float(np.min(task.forest.clearance(pts)))
    if lost_at is not None and status != "diverged":
        status = "lost"
        reason = (f"left the {task.tube_m:g} m tube at wingbeat {lost_at[0]} "
                  f"(t = {lost_at[1]:.1f} s, {lost_at[2]:.1f} m off)")
    if collisions and status == "completed":
        status, reason = "lost", f"hit a tree {collisions} time(s)"
    sim_s = times[-1] - times[0]
    metrics.update({
        "wingbeats": len(quats), "simulated_s": sim_s, "progress_m": float(target.s),
        "path_length_m": task.path.length, "collisions": collisions,
        "steering_range_deg": _range(steer),
        # what it steered while following the path: the wingbeats that ended within the tube
        # (a bird lost and stalling swings its velocity's heading by tens of degrees)
        "steering_range_in_tube_deg": _range(steer[:len(steer) if lost_at is None else lost_at[0] - 1]),
        "elevation_range_deg": _range(elev),
        "path_steering_range_deg": _path_steering(task.path, progress_s, positions_a),
        "real_time_factor": sim_s / wall if wall > 0 else None,
        "way_speed_m_s": float(target.s) / sim_s if sim_s > 0 else None,
    })
    return TaskResult(status, reason, metrics, positions_a, quats_a, desired, np.array(steer),
                      np.array(elev), qpos_a, np.array(times), wall, collisions, push_log)


def _range(values: list[float]) -> list[float] | None:
    """[smallest, largest] of ``values``, or None for none."""
    return [float(np.min(values)), float(np.max(values))] if len(values) else None


def _path_steering(path, progress_s: list[float], positions: np.ndarray) -> list[float] | None:
    """Smallest and largest turn of the path's own heading over each wingbeat's flown
    distance, deg, from the path point the bird was closest to as that wingbeat began: what
    the path asked where it was flown, at the bird's pace (its ``steering_range_deg`` is what
    it did). ``progress_s[k + 1]``: the closest point as wingbeat k began."""
    if len(progress_s) < 2 or len(positions) < 2:
        return None
    n = min(len(progress_s) - 1, len(positions) - 1)
    s0 = np.asarray(progress_s[1:n + 1])
    flown = np.linalg.norm(np.diff(positions[:n + 1], axis=0), axis=1)
    t0, t1 = path.tangent(s0), path.tangent(s0 + flown)
    turn = np.degrees(cycle.wrap(np.arctan2(t1[:, 1], t1[:, 0]) - np.arctan2(t0[:, 1], t0[:, 0])))
    return [float(np.min(turn)), float(np.max(turn))]
