"""The learned wingbeat controller (the flight paper, sec. 4.2).

Each wingbeat, from the current full state the bird first flies the reference wingbeat
P0 in a throw-away simulation (-> S0, the "instantaneous reference"); the target state
S_target for the end of the wingbeat gives dS = S_target - S0; a regression over the
database's (dS_i, dP_i) pairs gives dP, and the bird flies P0 + dP for real.

The regression is :mod:`flapsim.bird.control.regression`, the targets :mod:`flapsim.bird.control.targets`,
the cheaper predictions of S0 :mod:`flapsim.bird.control.prediction`; this module holds the
controller that uses them, a controlled flight and the loading of a database.
"""

from __future__ import annotations

import dataclasses
import logging
import time
from dataclasses import dataclass, field
from pathlib import Path

import mujoco
import numpy as np
from tqdm import tqdm

from flapsim.bird.body.model import Dove
from flapsim.bird.control import longitudinal as longi
from flapsim.bird.control.config import LOOKAHEAD_MODES, MAX_REFINE, REFINE_GOALS, ControllerConfig
from flapsim.bird.control.database import load_database, read_header
from flapsim.bird.control.lateral import (
    N_STATE,
    TRUNK,
    BankedRegulator,
    LateralRegulator,
    build_banked_regulator,
    build_regulator,
    lateral_state,
    turn_trims_for,
)
from flapsim.bird.control.lookahead import ReferenceLookahead
from flapsim.bird.control.prediction import COARSE_RATE_HZ, PREDICT_MODES, CoarsePredictor, S0Predictor
from flapsim.bird.control.regression import (
    MIRROR_STATE,
    PAPER_WEIGHTS,
    Regressor,
    default_k,
    mirror_samples,
    resolve_k,
)
from flapsim.bird.control.targets import CruiseTarget
from flapsim.bird.flight import cycle
from flapsim.bird.flight.dove_flight import DoveFlight, FlightConfig, pose_quat
from flapsim.bird.flight.wingbeat import (
    N_PARAMS,
    ReferenceWingbeat,
    mirror_params,
    p0,
    project_to_ranges,
    with_tail_bias,
)
from flapsim.core.errors import InputError, SimulationError
from flapsim.core.parallel import usable_cores
from flapsim.fluid.coefficients import get_table

log = logging.getLogger(__name__)

#: The reduced-state components by which :attr:`WingbeatController.refine` ranks the
#: wingbeats it simulates and raises its request: pitch, roll and the body-frame velocity,
#: weighted as the regression weighs them (the paper's eq. 3 weights over each component's
#: spread in the database), and not the angular velocity. At a wingbeat's end the trunk's
#: angular velocity is dominated by its counter-rotation against the wings (measured in an
#: 8 m turn: the roll rate swings from +10 to -20 rad/s within 5 ms of the upstroke, and
#: wingbeats end at +-8-11 rad/s while the roll angle moves 2 deg), and the path target asks
#: for none of it (whatever P0 gives). The forward speed is judged against the speed asked
#: without the target's integral surplus (``speed_surplus``; see
#: :meth:`WingbeatController.choose`).
REFINE_COMPONENTS = np.array([True, True, True, True, True, False, False, False])


def correction_goal(S_t: np.ndarray, S_ref: np.ndarray, speed_surplus: float = 0.0,
                    reach: tuple[np.ndarray | None, np.ndarray | None] | None = None) -> np.ndarray:
    """The state :attr:`WingbeatController.refine` aims at: the target ``S_t`` less the path
    target's integral ``speed_surplus`` on the forward speed, and with ``reach`` = (lo, hi)
    each component's change from the reference wingbeat's end ``S_ref`` clipped to [lo, hi]
    (the request's clip: :attr:`WingbeatController.refine_goal` ``reachable``)."""
    goal = np.array(S_t, dtype=float)
    goal[2] -= float(speed_surplus)
    if reach is not None and reach[0] is not None:
        ref = np.asarray(S_ref, float)
        goal = ref + np.clip(goal - ref, reach[0], reach[1])
    return goal


def refine_error(S: np.ndarray, S_target: np.ndarray, weights: np.ndarray) -> float:
    """sqrt((S - S_t) W (S - S_t)^T) over :data:`REFINE_COMPONENTS`, diag W = ``weights``."""
    w = np.where(REFINE_COMPONENTS, np.asarray(weights, float), 0.0)
    d = np.asarray(S, float) - np.asarray(S_target, float)
    return float(np.sqrt(d @ (w * d)))




@dataclass
class ControlStep:
    """What the controller did in one wingbeat."""

    P: np.ndarray
    """The wingbeat flown."""
    dS_target: np.ndarray
    """S_target - S0."""
    S_target: np.ndarray
    reference: cycle.CycleEnd
    """Where P0 would have ended."""
    end: cycle.CycleEnd
    """Where P ended."""
    projected: bool
    """True when P0 + dP left a joint range and was pulled back in."""
    simulated: int = 1
    """Wingbeats simulated to choose it (1 + :attr:`WingbeatController.refine`; 1 when the
    answer is flown as it is); P0's simulation for S0 not counted."""


@dataclass
class WingbeatController:
    """P = P0 + regression(S_target - S0), one wingbeat at a time."""

    flight: DoveFlight
    regressor: Regressor
    P0: np.ndarray = field(default_factory=lambda: with_tail_bias(p0(), FlightConfig.tail_bias_deg))
    lo: np.ndarray | None = None
    hi: np.ndarray | None = None
    predictor: S0Predictor | CoarsePredictor | None = None
    """None (default here): S0 from a simulation of P0 on the flight every wingbeat (the
    paper); else simulated on a copy at a coarser step (:class:`CoarsePredictor`: the rigid
    dove's default through :attr:`ControllerConfig.reference_hz`, and ``predict="coarse"``)
    or predicted (:class:`S0Predictor`)."""
    carry: float = 0.0
    """Share c of the last wingbeat's change from P0 that the next wingbeat starts from:
    its reference is P0 + c (P_last - P0), simulated for S0 as P0 is, and the regression's
    dP is added to it (0, the default: P0 every wingbeat, the paper's). In a sustained turn
    or after a push the answer to a request falls short of it (the regression delivers part
    of a requested change); carrying the last answer keeps what was reached and asks only
    the rest (integral action in wingbeat space). The sum stays within the database's dP."""
    refine: int = 0
    """Simulated corrections per wingbeat (0, the default: the regression's answer is flown
    as it is, the paper's). With N > 0 the answer P1 is simulated from the wingbeat's start
    before it is flown; where it would end short of the target, the request is raised by the
    shortfall in pitch, roll and velocity (:data:`REFINE_COMPONENTS`) and answered again, N
    times, and of the N + 1 wingbeats simulated the one that ends nearest the target, in the
    regression's own metric, is flown. Its simulation is the flight itself: the chosen end is
    restored, not flown again, unless a push or a record asks for it. The regression's local
    model holds near the samples' calm, near-level start states; in a steep bank the same dP
    rolls the bird differently (measured: asked -8.7 deg of roll, flown -45.6), and the
    simulation sees it. Each correction costs one wingbeat's simulation."""
    lookahead: ReferenceLookahead | None = None
    """None (default): each wingbeat's reference is simulated when it is needed. A
    :class:`~flapsim.bird.control.lookahead.ReferenceLookahead` (:func:`enable_lookahead`): with
    ``refine`` > 0 and S0 simulated, the next wingbeat's reference is simulated from each
    best-so-far candidate's end in a second thread while the next correction runs; the flight
    is the same to the bit, the wall time shorter on two free cores."""
    refine_goal: str = "full"
    """What the corrections aim at and rank by (:data:`REFINE_GOALS`): ``full``, the target
    (the default here; :func:`load_controller` uses its configuration's), or
    ``reachable``, the target with each component's change from P0's end clipped as the
    request is (needs the regression's ``clip_request``). Far from what any wingbeat can do
    in one beat (the forward speed a slowing dove is asked, 2-4 m/s short), the unreachable
    part of the shortfall outweighs the rest in the ranking, and the wingbeat that keeps a
    little more speed is flown over the one that holds the bank or the pitch asked."""
    refine_stop: float = 0.0
    """The corrections stop at the first candidate that ends within this of the target, in
    :func:`refine_error`'s metric (0, the default here: all :attr:`refine` corrections are
    simulated; :func:`load_controller` uses its configuration's). In steady flight the first
    answer usually lands that close, and a correction costs a whole wingbeat's simulation."""
    config: ControllerConfig | None = None
    """The configuration :func:`load_controller` built it from (provenance), None otherwise."""
    lateral: LateralRegulator | BankedRegulator | None = None
    """None (default, the paper's): the reference wingbeat is flown as it is. A
    :class:`~flapsim.bird.control.lateral.LateralRegulator`: its once-a-beat change for the
    lateral state at the wingbeat's start, against the last wingbeat's target, is added to the
    reference before S0 is simulated, and the regression's answer is added to that. A
    :class:`~flapsim.bird.control.lateral.BankedRegulator` likewise, and then the regression's
    answer is made left-right symmetric (the regulator flies the bank)."""
    longitudinal: longi.LongitudinalRegulator | None = None
    """None (default, the paper's), or a
    :class:`~flapsim.bird.control.longitudinal.LongitudinalRegulator` whose change is added to
    the reference as the lateral regulator's is."""
    _lateral_dP: np.ndarray | None = field(default=None, repr=False)
    _lateral_target: np.ndarray | None = field(default=None, repr=False)
    _long_dP: np.ndarray | None = field(default=None, repr=False)
    _long_target: np.ndarray | None = field(default=None, repr=False)
    _last: np.ndarray | None = field(default=None, repr=False)
    _predict: str = field(default="simulate", repr=False)

    def __post_init__(self) -> None:
        if self.refine_goal not in REFINE_GOALS:
            raise InputError(f"refine_goal must be one of {', '.join(REFINE_GOALS)}, got "
                             f"{self.refine_goal!r}")
        if (isinstance(self.refine, bool) or not isinstance(self.refine, (int, np.integer))
                or not 0 <= int(self.refine) <= MAX_REFINE):
            raise InputError(f"refine (simulated corrections per wingbeat) must be 0..{MAX_REFINE}, "
                             f"got {self.refine!r}")
        if not (np.isfinite(self.refine_stop) and self.refine_stop >= 0.0):
            raise InputError(f"refine_stop (the error that ends the corrections) must be >= 0, "
                             f"got {self.refine_stop!r}")
        if self.regressor.dP.shape[1] != N_PARAMS:
            raise InputError(f"database dP has {self.regressor.dP.shape[1]} columns, expected {N_PARAMS}")
        if not (np.isfinite(self.carry) and 0.0 <= self.carry <= 1.0):
            raise InputError(f"the wingbeat carry must be a share 0..1, got {self.carry}")
        if self.lo is None or self.hi is None:
            self.lo, self.hi = cycle.model_dof_ranges(self.flight)
        if self.lateral is not None and self.lookahead is not None:
            raise InputError("the lateral regulator needs each wingbeat's start state: fly it "
                             "without the look-ahead (lookahead = \"off\")")
        if self.longitudinal is not None and self.lookahead is not None:
            raise InputError("the longitudinal regulator needs each wingbeat's start state: fly "
                             "it without the look-ahead (lookahead = \"off\")")

    def reset(self) -> None:
        """Forget the last wingbeat (a new flight)."""
        self._last = None
        self._lateral_dP = self._lateral_target = None
        self._long_dP = self._long_target = None
        if isinstance(self.lateral, BankedRegulator):
            self.lateral.reset()
        if self.predictor is not None:
            self.predictor.reset()
        if self.lookahead is not None:
            self.lookahead.drop()

    def reference_params(self) -> np.ndarray:
        """The wingbeat simulated for S0 and added to: P0 + carry (P_last - P0)."""
        return self._reference_after(self._last)

    def _reference_after(self, last: np.ndarray | None) -> np.ndarray:
        if self.carry == 0.0 or last is None:
            base = self.P0
        else:
            base = self.P0 + self.carry * (last - self.P0)
        if self._lateral_dP is not None:
            base = base + self._lateral_dP
        if self._long_dP is not None:
            base = base + self._long_dP
        return base

    @property
    def ref(self) -> ReferenceWingbeat:
        return self.flight.ref

    def choose(self, target, snap: cycle.Snapshot | None = None, record: bool = False,
               push: cycle.Push | None = None) -> ControlStep:
        """Decide and fly one wingbeat toward ``target`` (a callable: P0's end -> S_target).
        ``push`` acts on the wingbeat flown only: the controller's prediction cannot see it
        coming."""
        fl = self.flight
        S_now = None
        if self.regressor.conditioned:
            if snap is not None:
                cycle.restore(fl, snap)
            S_now = fl.reduced_state()  # the wingbeat's start state, as the samples' S
        if self.lateral is not None:
            if snap is not None:
                cycle.restore(fl, snap)
            xt = self._lateral_target
            self._lateral_dP = self.lateral.offset(lateral_state(fl),
                                                   np.zeros(N_STATE) if xt is None else xt)
        if self.longitudinal is not None:
            if snap is not None:
                cycle.restore(fl, snap)
            self._long_dP = self.longitudinal.offset(longi.longitudinal_state(fl),
                                                     self.longitudinal.target(self._long_target))
        snap = snap or cycle.snapshot(fl)
        base = self.reference_params()
        if self.predictor is None:
            e0 = self.lookahead.take(snap, base) if self.lookahead is not None else None
            if e0 is None:
                e0 = cycle.fly_cycle(fl, snap, base, self.ref)
        else:
            e0 = self.predictor.reference(self, snap)
        S_t = np.asarray(target(e0), float)
        dS = S_t - e0.S
        Pp, projected = self._answer(dS, S_now, base)
        end, tried = None, 1
        if self.refine:
            # the forward speed is judged against the speed asked, less what the target's
            # integral asks on top: with it, a bird short of speed for long (a tight turn
            # winds the integral up to 2 m/s) is asked a speed no wingbeat reaches, and the
            # ranking turned into "lose the least speed" (pushed 6 N sideways, the dove drifted
            # 11 m from the path before turning back: 2.2 m without the corrections)
            reg = self.regressor
            reach = (reg.dS_lo, reg.dS_hi) if self.refine_goal == "reachable" else None
            goal = correction_goal(S_t, e0.S, float(getattr(target, "speed_surplus", 0.0)), reach)
            Pp, projected, end, tried = self._refined(snap, Pp, projected, dS, goal, S_now, base)
        if end is None or push is not None or record:
            end = cycle.fly_cycle(fl, snap, Pp, self.ref, record=record, push=push)
        else:
            cycle.restore(fl, end.snapshot)  # the chosen wingbeat's simulation was the flight
        # what the next wingbeat carries is the controller's choice, not the regulator's
        # change, which it makes afresh from the next start state
        self._last = Pp if self._lateral_dP is None else Pp - self._lateral_dP
        if self._long_dP is not None:
            self._last = self._last - self._long_dP
        if self.longitudinal is not None:
            self._long_target = S_t[list(longi.TRUNK)].copy()
        if self.lateral is not None:
            # the next wingbeat regulates toward this one's target (its bank, sideslip and
            # rates); its own target needs S0, which needs the regulated reference
            xt = np.zeros(N_STATE)
            xt[:len(TRUNK)] = S_t[list(TRUNK)]
            self._lateral_target = xt
        if self.predictor is not None:
            self.predictor.flown(end)
        return ControlStep(Pp, dS, S_t, e0, end, projected, tried)

    def _answer(self, dS: np.ndarray, S_now, base: np.ndarray) -> tuple[np.ndarray, bool]:
        """The wingbeat for request ``dS`` (within the joint ranges) and whether it was pulled
        back into them."""
        dP = self.regressor.predict(dS, S_now)
        if isinstance(self.lateral, BankedRegulator):
            # the regulator flies the bank: the regression's answer keeps its symmetric part
            # (what it asks of both wings alike: lift, thrust, pitch)
            dP = 0.5 * (dP + (mirror_params(self.P0 + dP) - self.P0))
            if base is not self.P0:
                # what is carried and the regulator's change plus the answer, unclipped: the
                # regulator's integral and the banked gains ask more than the database spans
                # (clipped to it, the steady crosswinds and the sinusoid were lost sooner)
                dP = base - self.P0 + dP
        elif base is not self.P0:
            # what is carried plus the answer, within the database's own wingbeats
            dP = np.clip(base - self.P0 + dP, self.regressor.dP_lo, self.regressor.dP_hi)
        P = self.P0 + dP
        Pp = project_to_ranges(self.ref, P, self.lo, self.hi)
        return Pp, bool(np.max(np.abs(Pp - P)) > 1e-12)

    def _refined(self, snap, P, projected, dS, S_t, S_now, base):
        """:attr:`refine`: (wingbeat, projected, its simulated end or None, wingbeats
        simulated)."""
        best, request, n = None, dS.copy(), int(self.refine)
        for i in range(n + 1):
            try:
                e = cycle.fly_cycle(self.flight, snap, P, self.ref)
            except SimulationError:
                break  # this answer diverges from here: not a candidate, and nothing to correct
            err = refine_error(e.S, S_t, self.regressor.w)
            if best is None or err < best[0]:
                best = (err, P, projected, e)
                if err < self.refine_stop:
                    break  # near enough: the next correction would cost a wingbeat for little
                if self.lookahead is not None and self.predictor is None and i < n:
                    # the next wingbeat's reference if this one is flown, on the other core
                    # while the next correction is simulated here (after the last correction
                    # nothing runs here meanwhile: the next wingbeat simulates it itself)
                    self.lookahead.submit(e.snapshot, self._reference_after(P), self.ref)
            if i == n:
                break
            request = request + np.where(REFINE_COMPONENTS, S_t - e.S, 0.0)
            P, projected = self._answer(request, S_now, base)
        if best is None:
            return P, projected, None, i + 1  # flown as it is: its divergence is reported there
        return best[1], best[2], best[3], i + 1

    @property
    def predict(self) -> str:
        """How S0 is found, as :func:`load_controller`'s ``predict``: ``simulate`` (on the
        flight, or on a copy at :attr:`ControllerConfig.reference_hz`), ``coarse``
        (:class:`CoarsePredictor` at :data:`COARSE_RATE_HZ`) or ``regression``
        (:class:`S0Predictor`)."""
        if self.predictor is None:
            return "simulate"
        if isinstance(self.predictor, CoarsePredictor):
            return "simulate" if self._predict == "simulate" else "coarse"
        return "regression"


@dataclass
class BaseController:
    """The base controller in the learned one's interface: always P0 (for comparisons)."""

    flight: DoveFlight
    P0: np.ndarray

    def choose(self, target, snap: cycle.Snapshot | None = None, record: bool = False,
               push: cycle.Push | None = None) -> ControlStep:
        fl = self.flight
        end = cycle.fly_cycle(fl, snap, self.P0, fl.ref, record=record, push=push)
        S_t = np.asarray(target(end), float)
        return ControlStep(self.P0.copy(), S_t - end.S, S_t, end, end, False)


# -- a controlled flight ----------------------------------------------------------------------


@dataclass
class ControlledFlight:
    """Per-wingbeat record of a flight under the learned controller."""

    steps: list[ControlStep]
    start_pos: np.ndarray
    """Trunk position at the start, m."""
    wall_time: float
    """Wall-clock seconds (the P0 predictions included)."""

    @property
    def positions(self) -> np.ndarray:
        """(n + 1, 3) trunk position at the start and at each wingbeat's end."""
        return np.vstack([self.start_pos, [s.end.trunk_pos for s in self.steps]])

    @property
    def velocities(self) -> np.ndarray:
        """(n, 3) centre-of-mass velocity at each wingbeat's end."""
        return np.array([s.end.com_vel for s in self.steps])

    @property
    def params(self) -> np.ndarray:
        """(n, 29) wingbeats flown."""
        return np.array([s.P for s in self.steps])

    @property
    def states(self) -> np.ndarray:
        """(n, 8) reduced state at each wingbeat's end."""
        return np.array([s.end.S for s in self.steps])

    @property
    def simulated_s(self) -> float:
        return float(sum(s.end.duration for s in self.steps))


def fly_controlled(controller, target, wingbeats: int, progress: bool = False,
                   record: bool = False) -> ControlledFlight:
    """Fly ``wingbeats`` wingbeats under ``controller`` toward ``target`` from the flight's
    current state."""

    fl = controller.flight
    start = fl.data.qpos[0:3].copy()
    it = range(wingbeats)
    if progress:
        it = tqdm(it, desc="wingbeats", unit="wb")
    steps = []
    t0 = time.perf_counter()
    for _ in it:
        steps.append(controller.choose(target, record=record))
    return ControlledFlight(steps, start, time.perf_counter() - t0)


def start_cruise(fl: DoveFlight, P0: np.ndarray, cfg: FlightConfig | None = None,
                 roll_deg: float = 0.0) -> None:
    """The standard cruise start (:meth:`DoveFlight.reset`), rolled by ``roll_deg`` (in
    :func:`~flapsim.bird.flight.dove_flight.pitch_roll`'s convention) about the trunk's forward axis."""

    cfg = cfg or FlightConfig()
    fl.reset(cfg, P0)
    if roll_deg:
        d = fl.data
        q = pose_quat(np.radians(cfg.pitch_deg), np.radians(roll_deg))
        d.qpos[3:7] = q
        mujoco.mj_forward(fl.model, d)


def cruise_metrics(f: ControlledFlight, target: CruiseTarget) -> dict:
    """Largest deviations from the cruise target over the flight (at wingbeat ends)."""
    pos = f.positions[1:]
    vel = f.velocities
    speed = np.linalg.norm(vel, axis=1)
    heading = np.arctan2(vel[:, 1], vel[:, 0])
    S = f.states
    return {
        "wingbeats": len(f.steps),
        "simulated_s": f.simulated_s,
        "max_altitude_deviation": float(np.max(np.abs(pos[:, 2] - target.altitude))),
        "final_altitude_deviation": float(pos[-1, 2] - target.altitude),
        "max_speed_deviation": float(np.max(np.abs(speed - target.speed))),
        "mean_speed": float(speed.mean()),
        "max_heading_deviation_deg": float(np.degrees(np.max(np.abs(cycle.wrap(heading - target.heading))))),
        "max_abs_roll_deg": float(np.degrees(np.max(np.abs(S[:, 1])))),
        "pitch_range_deg": [float(np.degrees(S[:, 0].min())), float(np.degrees(S[:, 0].max()))],
        "distance": float(np.linalg.norm(pos[-1, :2] - f.start_pos[:2])),
        "projected_wingbeats": int(sum(s.projected for s in f.steps)),
        "max_range_excess_deg": float(np.degrees(max(s.end.range_excess for s in f.steps))),
        "real_time_factor": f.simulated_s / f.wall_time if f.wall_time > 0 else float("nan"),
    }


# -- loading --------------------------------------------------------------------------------

#: The bundled controller database, made by ``flapsim train --samples 10000 --pre-pitch-deg 10
#: --pre-roll-deg 10 --seed 1 --float32 --out dove_controller.db`` (phase 1; 236-277 s on two
#: idle cores; 2.3 MB: float32, exactly the float64 run's samples rounded). Regenerate it after
#: any change to the dove model: a database of another model is refused by its model hash.
BUNDLED_DB = "dove_controller.db"


BUNDLED_MODAL_DB = "dove_controller_modal.db"
"""The modal-feather dove's database: the rigid one's command with ``--feathers modal``
(phase 1, 10,000 samples, pre-states within 10 deg, seed 2, float32)."""


BUNDLED_CRUISE_DB = "dove_controller_cruise.db"
"""The cruise dove's database (bird-wing section, induced flow, the cruise capture):
``flapsim train --cruise --samples 10000 --pre-pitch-deg 10 --pre-roll-deg 10 --seed 2
--float32``; flown with ``--db`` and this file's path (``bundled_database_path("cruise")``)."""


def bundled_database_path(feathers: str = "rigid"):
    """The bundled controller database of the rigid (default) or the modal-feather dove
    (``Dove.load(feathers="modal")`` with the default :class:`~flapsim.bird.body.feather_modes.
    ModalParams`), or ``"cruise"``: the cruise dove's (rigid feathers)."""

    names = {"rigid": BUNDLED_DB, "modal": BUNDLED_MODAL_DB, "cruise": BUNDLED_CRUISE_DB}
    if feathers not in names:
        raise InputError(f"feathers must be 'rigid' or 'modal' (or 'cruise'), got {feathers!r}")
    return Path(__file__).resolve().parent / "data" / names[feathers]


def database_config(db_path=None, feathers: str = "rigid") -> dict:
    """The sampling configuration in a controller database's header (default: the bundled one
    of the ``feathers`` dove); empty where it has none (a merged database, say)."""
    return read_header(db_path or bundled_database_path(feathers)).get("config") or {}


def database_table(db_path=None, feathers: str = "rigid") -> str:
    """The feather coefficient table a controller database (default: the bundled one of the
    ``feathers`` dove) was sampled with: its sampling configuration's, or the default table
    where it names none (a merged database, say). A learned controller flies with that table
    only."""

    cfg = database_config(db_path, feathers)
    return str(cfg.get("table") or FlightConfig.table)


def database_speed(db_path=None, feathers: str = "rigid") -> float:
    """The cruise speed a controller database's pre-states were drawn around, m/s (default:
    the bundled one of the ``feathers`` dove): the speed its flights are asked to hold unless
    told otherwise (its samples describe the bird there)."""

    cfg = database_config(db_path, feathers)
    return float(cfg.get("cruise_speed") or FlightConfig.speed)


def database_pitch(db_path=None, feathers: str = "rigid") -> float:
    """The trunk pitch a controller database's pre-states were centred at, deg (default: the
    bundled one of ``feathers``): its flights start there, level (0 for the paper's
    databases)."""

    cfg = database_config(db_path, feathers)
    return float(cfg.get("pitch_centre_deg") or 0.0)


def database_dove(db_path=None, feathers: str = "rigid") -> Dove:
    """The dove a controller database (default: the bundled one of ``feathers``) was sampled
    with: with its wings' induced flow where its sampling configuration says so."""

    cfg = database_config(db_path, feathers)
    return Dove.load(feathers=feathers, induced=bool(cfg.get("induced", False)))


def database_reference(header: dict) -> ReferenceWingbeat | None:
    """The reference wingbeat a controller database was sampled around (its provenance's
    Fourier coefficients and period), None where the header names none (a merged one)."""
    prov = header.get("provenance") or {}
    coef, period = prov.get("reference_coef"), prov.get("reference_period")
    if coef is None or period is None:
        return None
    coef = np.asarray(coef, dtype=float)
    if coef.ndim != 2 or not np.all(np.isfinite(coef)) or not float(period) > 0:
        raise InputError("the database's reference wingbeat is malformed (its provenance's "
                         "reference_coef / reference_period): retrain it")
    return ReferenceWingbeat(coef, float(period), int(prov.get("reference_cycles", 0)))


def make_lookahead(flight: DoveFlight, mode: str, refine: int, predict: str
                   ) -> ReferenceLookahead | None:
    """The :class:`~flapsim.bird.control.lookahead.ReferenceLookahead` ``mode`` asks for
    (:func:`load_controller`'s ``lookahead``), or None."""
    if mode not in LOOKAHEAD_MODES:
        raise InputError(f"lookahead must be one of {', '.join(LOOKAHEAD_MODES)}, got {mode!r}")
    if mode == "off":
        return None
    why = None
    if not refine:
        why = "it runs beside the simulated corrections: set refine = 1 or more"
    elif predict != "simulate":
        why = ("it simulates S0 ahead at the flight's own rate: use --predict simulate with "
               f"reference_hz = 0, not S0 {'on a coarser copy' if predict == 'coarse' else 'regressed'}")
    elif flight.aero.flow.has_python:
        why = "a Python flow field runs under the GIL every step: nothing to run beside it"
    elif flight.modal is not None and not flight.modal.engine:
        why = ("a copy of a modal dove needs its modes integrated by the engine "
               "(ModalParams(integration='engine'), the default)")
    elif mode == "auto" and usable_cores() < 2:
        why = "one CPU core"
    if why is None:
        return ReferenceLookahead(flight)
    if mode == "on":
        raise InputError(f"lookahead on: {why}")
    return None


def load_controller(flight: DoveFlight, db_path=None, method: str = "lwlr", k: int | None = None,
                    weights: tuple[float, float, float] = PAPER_WEIGHTS,
                    predict: str = "simulate", predict_every: int = 4,
                    mirror: bool = True, config: ControllerConfig | None = None,
                    **overrides) -> WingbeatController:
    """A controller over a database (default: the bundled one of ``flight``'s dove, rigid or
    modal feathers) built for ``flight``'s model;
    a database of another model, or a foreign/corrupt file, is a one-line error.

    ``mirror`` (default): the regression searches the samples and their mirror images
    (:func:`mirror_samples`); ``k`` (default :data:`DEFAULT_K_SHARE`: 2 % for LWLR, 0.5 %
    for k-NN) counts among both.

    ``config`` (:class:`~flapsim.bird.control.config.ControllerConfig`; None: the defaults of
    ``flight``'s dove, :meth:`ControllerConfig.for_dove`, without the look-ahead thread)
    tunes the rest: the carry (:attr:`WingbeatController.carry`), the simulated corrections
    and their goal (:attr:`WingbeatController.refine`, :attr:`WingbeatController.refine_goal`),
    the early stop of the corrections (:attr:`WingbeatController.refine_stop`), the
    reference's step rate (``reference_hz``), the look-ahead, and the regression's dense
    neighbourhood (LWLR only: ``k_dense_share`` of the samples searched, at most ``k``;
    :class:`Regressor`'s ``k_dense``), request clip and start-state weight
    (:class:`Regressor`'s ``clip_request``, ``context_weight``).
    ``overrides``: fields of the config replaced (``carry=0.3``, as
    :func:`dataclasses.replace`).

    ``predict``: ``simulate`` (default; the paper) flies P0 every wingbeat for S0, on the
    flight or, where the config's ``reference_hz`` asks (the rigid dove's default), on a copy
    at that step rate (:class:`CoarsePredictor`);
    ``coarse`` flies it every wingbeat at :data:`COARSE_RATE_HZ` (:class:`CoarsePredictor`);
    ``regression`` predicts it from the database's (S, S0) pairs and simulates P0 only
    every ``predict_every``-th wingbeat (:class:`S0Predictor`); it predicts P0's end only,
    so its defaults carry nothing and a carry is an error.

    The config's ``lookahead`` (:data:`LOOKAHEAD_MODES`): ``on`` simulates the next
    wingbeat's reference in a second thread while the corrections run
    (:attr:`WingbeatController.lookahead`: the same flight, less wall time on two free
    cores), and is a one-line error where it cannot (no corrections, S0 not simulated on the
    flight at its own rate, a Python flow field); ``auto`` turns it on where it can and two
    CPU cores are free to this process; ``off`` never."""
    if predict not in PREDICT_MODES:
        raise InputError(f"S0 prediction must be one of {', '.join(PREDICT_MODES)}, got {predict!r}")
    if config is None:
        # a library call runs no second thread unless asked (the command line's default is auto)
        config = dataclasses.replace(ControllerConfig.for_dove(flight.dove.feathers, predict),
                                     lookahead="off")
    config = dataclasses.replace(config, **overrides)
    if config.carry and predict == "regression":
        raise InputError("carry needs S0 simulated (--predict simulate or coarse): --predict "
                         "regression predicts the reference wingbeat P0's end only")
    rate = reference_rate(flight, predict, config)
    if rate and flight.modal is not None and not flight.modal.engine:
        raise InputError("S0 simulated on a coarser copy (--predict coarse, reference_hz) needs "
                         "rigid feathers or modal ones integrated by the engine "
                         "(ModalParams(integration='engine'), the default)")
    path = db_path or bundled_database_path(flight.dove.feathers)
    db = load_database(path, model_hash=flight.dove.hash(), require_finalized=True)
    for name in ("dS", "dP"):
        if name not in db.arrays:
            raise InputError(f"{path} has no {name!r} field: not a wingbeat controller database")
    sampled = (db.header.get("config") or {}).get("table")
    flown = get_table(flight.table).name
    if sampled and sampled != flown:
        raise InputError(f"{path} was sampled with the {sampled} feather table but this flight uses "
                         f"{flown}: fly it with --table {sampled} (its wingbeats are right only for "
                         "the forces they were sampled with)")
    prov = db.header.get("provenance", {})
    ref = database_reference(db.header)
    if ref is not None and not np.array_equal(ref.coef, flight.ref.coef):
        # a database's wingbeats are offsets from the reference it was sampled around: the
        # flight flies that one (a database made before the bundled capture changed, say)
        flight.ref = ref
    P0 = np.asarray(prov.get("P0", with_tail_bias(p0(), FlightConfig.tail_bias_deg)), float)
    dS, dP = db.arrays["dS"], db.arrays["dP"]
    S = None
    if config.state_weight:
        if "S" not in db.arrays:
            raise InputError(f"{path} has no 'S' field: a state weight needs the samples' start states")
        S = db.arrays["S"]
    if mirror:
        dS, dP = mirror_samples(dS, dP, P0)
        S = None if S is None else np.vstack([S, S * MIRROR_STATE])
    share = config.k_dense_share if method == "lwlr" else 0.0
    # never more than k (a user's smaller --k)
    k_dense = min(default_k(len(dS), share), resolve_k(len(dS), k, method)) if share > 0 else 0
    reg = Regressor(dS, dP, k=k, weights=weights, method=method, context=S,
                    context_weight=config.state_weight, clip_request=config.clip_request,
                    k_dense=int(k_dense))
    refine_goal = config.refine_goal
    if refine_goal == "reachable" and reg.dS_lo is None:
        refine_goal = "full"  # no clip, nothing to clip the goal to: the same thing
    ctl = WingbeatController(flight, reg, P0, carry=float(config.carry), refine=config.refine,
                             refine_goal=refine_goal, refine_stop=float(config.refine_stop),
                             config=config, _predict=predict)
    on = [name for name, wanted in (("lateral", lateral_on(config, db.header)),
                                    ("longitudinal", longitudinal_on(config, db.header))) if wanted]
    if on:
        if config.lookahead == "on":
            raise InputError(f"the {on[0]} regulator needs each wingbeat's start state: set "
                             f"lookahead = \"off\" or \"auto\", or {on[0]} = \"off\"")
        # both maps are measured from the start the database's samples were drawn around
        cfg = FlightConfig(table=flight.table, speed=database_speed(path, flight.dove.feathers),
                           pitch_deg=database_pitch(path, flight.dove.feathers))
        if "lateral" in on and config.lateral == "banked":
            trims = turn_trims_for(P0)
            if trims is None:
                raise InputError("lateral = \"banked\" needs turn trims searched around this "
                                 "database's reference wingbeat (bundled for the cruise dove's: "
                                 "train --cruise); make them with python studies/dove_turn_trim.py")
            ctl.lateral = build_banked_regulator(flight, P0, cfg, float(config.lateral_r), trims,
                                                 float(np.radians(config.lateral_integral_deg)))
        elif "lateral" in on:
            ctl.lateral = build_regulator(flight, P0, cfg, float(config.lateral_r))
        if "longitudinal" in on:
            ctl.longitudinal = longi.build_regulator(flight, P0, cfg, float(config.longitudinal_r))
    else:
        ctl.lookahead = make_lookahead(flight, config.lookahead, config.refine,
                                       "coarse" if rate else predict)
    if predict == "regression":
        ctl.predictor = _predictor(db, path, predict_every)
    elif rate:
        ctl.predictor = CoarsePredictor(rate)
    return ctl


def _cruise_database(header: dict) -> bool:
    return (header.get("config") or {}).get("capture_preset") == "cruise"


def longitudinal_on(config: ControllerConfig, header: dict) -> bool:
    """Whether a controller under ``config`` for the database with ``header`` flies the
    longitudinal regulator: ``longitudinal`` "on", or "auto" and the database sampled around
    the cruise capture."""
    if config.longitudinal != "auto":
        return config.longitudinal == "on"
    return _cruise_database(header)


def lateral_on(config: ControllerConfig, header: dict) -> bool:
    """Whether a controller under ``config`` for the database with ``header`` flies the lateral
    regulator: ``lateral`` "on", or "auto" and the database sampled around the cruise capture
    (its dove's spiral mode grows 1.34x a wingbeat and the database's wingbeats do not hold it;
    the paper's and the robofly dove's fly as the paper's, without one)."""
    if config.lateral != "auto":
        return config.lateral in ("on", "banked")
    return _cruise_database(header)


def reference_rate(flight: DoveFlight, predict: str, config: ControllerConfig) -> float:
    """The step rate, Hz, of the copy of ``flight`` that simulates the reference wingbeat for
    S0 (:class:`CoarsePredictor`), or 0 where it is simulated on the flight itself (at its own
    rate) or not at all (``predict="regression"``)."""
    if predict == "coarse":
        return COARSE_RATE_HZ
    own = 1.0 / float(flight.model.opt.timestep)
    if predict != "simulate" or not config.reference_hz or config.reference_hz >= own * (1 - 1e-9):
        return 0.0
    return float(config.reference_hz)


def _predictor(db, path, every: int) -> S0Predictor:
    for name in ("S", "S0"):
        if name not in db.arrays:
            raise InputError(f"{path} has no {name!r} field: --predict regression needs the "
                             "database's (S, S0) pairs")
    return S0Predictor.from_arrays(db.arrays["S"], db.arrays["S0"], every=every)


def attach_predictor(ctl: WingbeatController, db_path=None, every: int = 4) -> WingbeatController:
    """Switch ``ctl`` (made by :func:`load_controller` over ``db_path``) to
    ``predict="regression"`` (and to carry 0: the prediction is of P0's end)."""

    ctl.carry = 0.0  # the regression predicts P0's end only: nothing is carried
    ctl.reset()
    path = db_path or bundled_database_path(ctl.flight.dove.feathers)
    db = load_database(path, model_hash=ctl.flight.dove.hash(), require_finalized=True)
    ctl.predictor = _predictor(db, path, every)
    return ctl
