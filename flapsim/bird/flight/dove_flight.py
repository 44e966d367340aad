"""Flying the dove: feather aerodynamics, one wingbeat at a time, the reduced state.

Every step MuJoCo runs the 14 PD servos (affine actuators, see :mod:`flapsim.core.pd`)
toward the wingbeat's targets and the surface-force engine adds drag and lift on every
feather triangle (the flight paper's eq. 7-9) and bluff-body drag on the trunk
(:func:`body_polygons`) through the passive dispatcher. Nothing else acts on the bird
but gravity.

Per wingbeat, the per-step controls are precomputed (:func:`~flapsim.bird.flight.wingbeat.
control_table`) and the cycle is stepped either in a Python loop or, by default, inside
``mujoco.rollout`` (C++), which with the compiled force provider runs no Python per step.
"""

from __future__ import annotations

import copy
import logging
import time as _time
from dataclasses import dataclass, field

import mujoco
import numpy as np
from mujoco import rollout
from tqdm import tqdm

from flapsim.bird.body.feather_dynamics import ModalFeathers, dove_feather_modes
from flapsim.bird.body.model import WING_GROUPS, Dove, build_xml, wing_group, wingspan
from flapsim.bird.body.params import (
    DOF_NAMES,
    DoveParams,
    fan_ratio,
    rectrix_joints,
    rectrix_spread_gains,
)
from flapsim.bird.flight.capture import segment_cycles
from flapsim.bird.flight.wingbeat import (
    ReferenceWingbeat,
    control_table,
    p0,
    reference_wingbeat,
    with_tail_bias,
)
from flapsim.core.callbacks import DISPATCHER
from flapsim.core.errors import InputError, SimulationError
from flapsim.core.loading import load_model
from flapsim.core.pd import affine_gains
from flapsim.fluid.coefficients import bluff_body, get_table
from flapsim.fluid.flow import FlowField, Uniform
from flapsim.fluid.induced import InducedFlow
from flapsim.fluid.surfaces import FluidParams, PolygonSet, SurfaceForces

log = logging.getLogger(__name__)

AIR_DENSITY = 1.225  # kg/m^3, the flight paper (sec. 6)


@dataclass(frozen=True)
class FlightConfig:
    """Settings of the base controller and its standard cruise start."""

    table: str = "dickinson1999_profile"
    """Feather CL/CD table: Dickinson et al. 1999 quasi-steady flapping-wing fit with its
    viscous (low-angle) drag scaled to a bird wing's profile drag CD0 = 0.05 (Withers 1981:
    0.03-0.13) and the fit unchanged at high angle of attack
    (:func:`~flapsim.fluid.coefficients.dickinson1999_profile`)."""
    tail_bias_deg: float = 17.0
    """Tail bend added to the reference wingbeat (paper sec. 7: +17 deg, tail up)."""
    speed: float = 7.0
    """Initial forward speed, m/s (the paper's biased bird flew ~7 m/s)."""
    pitch_deg: float = 0.0
    """Initial trunk pitch, deg (nose up +)."""
    climb_rate: float = 0.0
    """Initial vertical velocity, m/s."""
    height: float = 10.0
    """Initial trunk height, m."""


#: The cruise dove (``--cruise``): a bird wing's section, its induced flow
#: (``Dove.load(induced=True)``) and the cruise capture's reference wingbeat
#: (``reference_wingbeat("cruise")``), trimmed by a +26 deg tail bias at an 8.5 m/s start
#: (``studies/dove_cruise_kinematics.py --trim-capture``).
CRUISE = FlightConfig(table="bird_wing", tail_bias_deg=26.0, speed=8.5)


def feather_polygons(dove: Dove) -> PolygonSet:
    """Every feather triangle as a force polygon (body frame; forward = toward the leading
    edge; coefficient table 0, the feather table)."""
    bodies, tris, fwd, names = dove.feather_triangles()
    return PolygonSet.from_triangles(bodies, tris, forward=fwd, table=0, labels=names)


def _without(polys: PolygonSet, names: tuple[str, ...]) -> PolygonSet:
    """``polys`` less every polygon labelled with one of ``names`` (one-line error for a
    name that is no feather)."""
    labels = np.asarray(polys.labels)
    unknown = sorted(set(names) - set(labels.tolist()))
    if unknown:
        raise InputError(f"no feather named {', '.join(unknown)} (primaries are l_p1..l_p10 and "
                         "r_p1..r_p10, p10 outermost)")
    keep = ~np.isin(labels, list(names))
    return polys.subset(keep)


#: Index of the bluff-body table in :class:`DoveFlight`'s table list (feathers: 0).
BODY_TABLE = 1


def body_polygons(dove: Dove) -> PolygonSet:
    """The trunk with head as a bluff body: its three orthogonal cross-sections through the
    trunk centre, each a rectangle with the area of the trunk ellipsoid's section
    (``pi b c`` frontal, ``pi a c`` side, ``pi a b`` plan), on the bluff-body table
    (:func:`~flapsim.fluid.coefficients.bluff_body`, ``params.body_drag_cd``): drag
    ``1/2 rho V^2 CD A_frontal`` head-on, no lift, no moment about the trunk centre. The
    frontal section is the reference area of the bird-body drag coefficients; the head
    lies mostly within it seen from ahead (Pennycuick's allometric body frontal area for
    0.17 kg, 0.00813 m^0.666 = 2.5e-3 m^2, against this trunk's 3.0e-3 m^2)."""
    a, b, c = dove.params.trunk_semi_axes
    h = np.sqrt(np.pi) / 2  # a rectangle of half-sides h*u, h*v has area pi u v
    quads = []
    for axis, (u, v) in ((0, (b, c)), (1, (a, c)), (2, (a, b))):
        i, j = [k for k in range(3) if k != axis]
        corners = []
        for su, sv in ((-1, -1), (1, -1), (1, 1), (-1, 1)):
            p = np.zeros(3)
            p[i], p[j] = su * h * u, sv * h * v
            corners.append(p)
        quads.append(corners)
    return PolygonSet.from_polygons(dove.trunk, np.array(quads), table=BODY_TABLE,
                                    labels=("body_frontal", "body_side", "body_plan"))


@dataclass
class CycleRecord:
    """What one simulated wingbeat recorded per step."""

    time: np.ndarray
    """(n,) time at the end of each step, s."""
    trunk_pos: np.ndarray
    """(n, 3) trunk position, m."""
    trunk_quat: np.ndarray
    """(n, 4) trunk orientation."""
    qpos14: np.ndarray
    """(n, 14) actuated joint angles (tail spread: the tendon), rad."""
    qpos: np.ndarray | None = None
    """(n, nq) full positions (for videos), when recorded; with engine-integrated modal
    feathers the frames of :meth:`DoveFlight.frame` (``qpos``, then the modal coordinates)."""


@dataclass
class DoveFlight:
    """A dove in air with feather forces registered on its own ``MjData``."""

    dove: Dove
    ref: ReferenceWingbeat = field(default_factory=reference_wingbeat)
    table: str = FlightConfig.table
    wind: tuple[float, float, float] = (0.0, 0.0, 0.0)
    use_rollout: bool = True
    flow: tuple = ()
    """More flow primitives (:mod:`flapsim.fluid.flow`: gusts, breezes, ...) added to the
    steady ``wind``; time-dependent ones run on the simulation clock."""
    plucked: tuple[str, ...] = ()
    """Feathers (names such as ``l_p9``) whose triangles carry no force: plucked. Their
    mass stays (a primary is ~0.3 % of the bird's)."""

    def __post_init__(self) -> None:
        m = self.dove.model
        self.model = m
        self.data = mujoco.MjData(m)
        self.flow = FlowField([Uniform(self.wind), *self.flow])
        self.modal = None
        """The modal feathers' provider (:class:`~flapsim.bird.body.feather_dynamics.ModalFeathers`)
        of a modal dove (``Dove.load(feathers="modal")``); None for rigid feathers."""
        if self.dove.modal is None:
            feathers = feather_polygons(self.dove)
            if self.plucked:
                feathers = _without(feathers, self.plucked)
            self.polygons = PolygonSet.concat([feathers, body_polygons(self.dove)])
        else:
            # the deformable feathers are the modal provider's; the trunk stays a polygon set
            self.polygons = body_polygons(self.dove)
            # engine-integrated modes: the primaries' twist hinges are integrated with them
            self.modal = ModalFeathers(m, dove_feather_modes(self.dove.params, self.dove.modal),
                                       get_table(self.table), AIR_DENSITY, self.flow,
                                       plucked=self.plucked, hinges=self.dove.twist_hinges(),
                                       params=self.dove.modal)
        self.aero = SurfaceForces(m, self.polygons,
                                  [get_table(self.table), bluff_body(self.dove.params.body_drag_cd)],
                                  FluidParams(AIR_DENSITY), self.flow, name="dove feathers and body",
                                  hinges=self.dove.twist_hinges() if self.modal is None else None,
                                  induced=self._induced_flow())
        self.registration = self.aero.register(self.data)
        self._modal_registration = self.modal.register(self.data) if self.modal else None
        self.kp, self.kv = affine_gains(m)
        self._free = m.jnt_type[0] == mujoco.mjtJoint.mjJNT_FREE
        self._tendon = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_TENDON, "tail_spread")
        # the tail fan: each rectrix hinge's qpos/qvel address, its share g of the spread and
        # its weight c in the tail_spread tendon (s = c . q)
        jids = [mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, n)
                for n in rectrix_joints(self.dove.params)]
        self._tail_q = m.jnt_qposadr[jids]
        self._tail_v = m.jnt_dofadr[jids]
        self._tail_g, self._tail_c = rectrix_spread_gains(self.dove.params)
        self._fan = []
        for s in "lr":
            wrist = DOF_NAMES.index(f"{s}_wrist_flex")
            for k in range(len(self.dove.params.primary_angle_deg)):
                j = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, f"{s}_p{k + 1}_fan")
                self._fan.append((m.jnt_qposadr[j], m.jnt_dofadr[j], wrist,
                                  fan_ratio(self.dove.params, k)))
        self._rollout_data = None
        self._twins: list[DoveFlight] = []
        self._on_close: list = []

    def _induced_flow(self) -> InducedFlow | None:
        """Each side's feathers (the wing and its half of the tail) push and see their own
        downwash, on half the span's disk (``pi b^2 / 8`` each), with the trunk's velocity as
        the free stream; None for a dove built without the downwash state (the default)."""
        if not self.dove.induced:
            return None
        if self.modal is not None:
            raise InputError("the induced flow needs rigid feathers")
        groups = np.array([wing_group(lb) for lb in self.polygons.labels])
        area = float(np.pi * wingspan(self.dove.params) ** 2 / 8.0)
        return InducedFlow(WING_GROUPS, groups, (area, area), "trunk")

    def close(self) -> None:
        for fn in self._on_close:
            fn()  # helpers stepping a copy of this flight stop first (the look-ahead)
        self._on_close.clear()
        self.registration.remove()
        if self._modal_registration is not None:
            self._modal_registration.remove()
        for tw in self._twins:
            tw.close()
        self._twins.clear()

    def twin(self, rate_hz: float | None) -> DoveFlight:
        """This flight's dove stepped at ``rate_hz`` (None: this flight's own step, to the
        bit) on its own ``MjData``: the same forces, flows and plucked feathers (shared, not
        copied), so any snapshot of this flight restores into it. The learned controller's
        ``predict="coarse"`` flies the reference wingbeat there, and its look-ahead
        (:mod:`flapsim.bird.control.lookahead`) the next one. Closed with this flight."""
        if rate_hz is not None:
            rate_hz = float(rate_hz)
            if not np.isfinite(rate_hz) or not 100.0 <= rate_hz <= 1.0e5:
                raise InputError(f"a step rate must be 100-100000 Hz, got {rate_hz}")
        if self.modal is not None and not self.modal.engine:
            # the mode joints' gains (their unresolved modes' k dt damping) are compiled in
            raise InputError("a coarser-stepped copy of a modal dove needs its modes integrated "
                             "by the engine (ModalParams(integration='engine'), the default)")
        tw = copy.copy(self)
        tw.model = copy.copy(self.model)  # mj_copyModel: the option struct is its own
        if rate_hz is not None:
            tw.model.opt.timestep = 1.0 / rate_hz
        tw.data = mujoco.MjData(tw.model)
        tw.registration = self.aero.register(tw.data, model=tw.model)
        tw._modal_registration = None
        if self.modal is not None:
            # its own provider: the modes' exact step (and the unresolved ones' k dt damping)
            # is built for the copy's timestep; geometry, flow and plucked feathers are the same
            tw.modal = self.modal.for_model(tw.model)
            tw._modal_registration = tw.modal.register(tw.data)
        tw._rollout_data, tw._twins, tw._on_close = None, [], []
        self._twins.append(tw)
        return tw

    def aero_forces(self, d: mujoco.MjData | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Every aerodynamic polygon's (force (n, 3), world point (n, 3), is-feather (n,)) for
        the current state: the feathers (deformed, for a modal dove) and the trunk."""
        d = self.data if d is None else d
        rep = self.aero.evaluate(d)
        is_feather = self.polygons.table != BODY_TABLE
        if self.modal is None:
            return rep.force, rep.points, is_feather
        mr = self.modal.evaluate(d)
        return (np.vstack([mr.force, rep.force]), np.vstack([mr.points, rep.points]),
                np.concatenate([np.ones(len(mr.force), bool), is_feather]))

    # -- state -----------------------------------------------------------------------------
    def set_pose(self, q: np.ndarray, qd: np.ndarray) -> None:
        """Set the 14 DOF (and the feathers that follow them) to angles and rates."""
        d, dv = self.data, self.dove
        for i in range(len(DOF_NAMES)):
            if dv.qadr[i] >= 0:
                d.qpos[dv.qadr[i]] = q[i]
                d.qvel[dv.dadr[i]] = qd[i]
        ts = DOF_NAMES.index("tail_spread")
        d.qpos[self._tail_q] = self._tail_g * q[ts]  # every rectrix at its share of the spread
        d.qvel[self._tail_v] = self._tail_g * qd[ts]
        for qa, da, wrist, c in self._fan:
            d.qpos[qa], d.qvel[da] = c * q[wrist], c * qd[wrist]

    def reset(self, cfg: FlightConfig | None = None, p: np.ndarray | None = None) -> None:
        """The standard cruise start: level trunk at ``cfg.height`` flying +x at
        ``cfg.speed``, joints on wingbeat ``p``'s targets at phase 0 (top of the stroke)."""
        cfg = cfg or FlightConfig()
        p = with_tail_bias(p0(), cfg.tail_bias_deg) if p is None else p
        m, d = self.model, self.data
        mujoco.mj_resetData(m, d)
        if self._free:
            th = np.radians(cfg.pitch_deg)
            d.qpos[0:3] = (0.0, 0.0, cfg.height)
            d.qpos[3:7] = (np.cos(th / 2), 0.0, -np.sin(th / 2), 0.0)
            d.qvel[0:3] = (cfg.speed, 0.0, cfg.climb_rate)
        q, qd = self.ref.evaluate(p, np.zeros(1))
        self.set_pose(q[0], qd[0])
        mujoco.mj_forward(m, d)

    def reduced_state(self) -> np.ndarray:
        """S = (pitch, roll, body-frame linear velocity xyz, body-frame angular velocity xyz):
        8 numbers invariant to position and heading (the flight paper's eq. 1)."""
        return reduced_state(self.data)

    # -- frames (what videos and the viewer draw) ------------------------------------------
    @property
    def modes_in_userdata(self) -> bool:
        """True for engine-integrated modal feathers: their state is not in ``qpos``, so
        :meth:`frame` appends it, and recorded wingbeats are stepped one by one (a
        ``mujoco.rollout`` returns no ``userdata``)."""
        return self.modal is not None and self.modal.engine

    def frame(self, d: mujoco.MjData | None = None) -> np.ndarray:
        """What a video frame or the viewer shows of the state: ``qpos``, then the modal
        coordinates of engine-integrated feathers (:class:`~flapsim.bird.body.feather_dynamics.
        FeatherDrawing` takes it apart)."""
        d = self.data if d is None else d
        if not self.modes_in_userdata:
            return d.qpos.copy()
        return np.concatenate([d.qpos, self.modal.coordinates(d).ravel()])

    # -- stepping --------------------------------------------------------------------------
    def run_cycle(self, p: np.ndarray, record: bool = True, frames: bool = True) -> CycleRecord | None:
        """Fly one wingbeat of parameters ``p`` from the current state. ``frames=False``: the
        record's ``qpos`` is only the last step's frame, so that engine-integrated modal
        feathers need not be stepped one by one (see :attr:`modes_in_userdata`)."""
        m, d = self.model, self.data
        ctrl, q_t, _ = control_table(self.ref, p, m.opt.timestep, self.kp, self.kv)
        n = len(ctrl)
        if self.use_rollout and not (record and frames and self.modes_in_userdata):
            pos, quat, q14, t, qpos = self._rollout(ctrl)
            if not frames:
                qpos = self.frame()[None]
            return CycleRecord(t, pos, quat, q14, qpos) if record else None
        else:
            pos, quat, q14, t = (np.empty((n, 3)), np.empty((n, 4)), np.empty((n, 14)),
                                 np.empty(n))
            qpos = np.empty((n, len(self.frame()) if record else m.nq))
            for k in range(n):
                d.ctrl[:] = ctrl[k]
                mujoco.mj_step(m, d)
                if record:
                    pos[k], quat[k], t[k] = d.qpos[0:3], d.qpos[3:7], d.time
                    q14[k] = self._q14()
                    qpos[k] = self.frame()
        DISPATCHER.check(d)
        self._check_warnings()
        if not np.all(np.isfinite(d.qpos)) or not np.all(np.isfinite(d.qvel)):
            raise SimulationError(f"dove state is not finite at t={d.time:.4f} s (diverged)")
        return CycleRecord(t, pos, quat, q14, qpos) if record else None

    def _check_warnings(self) -> None:
        """MuJoCo resets a diverged simulation and only warns: turn that into an error."""
        w = self.data.warning[mujoco.mjtWarning.mjWARN_BADQACC]
        if w.number > 0:
            raise SimulationError("dove simulation diverged (bad accelerations before t="
                                  f"{self.data.time:.4f} s; MuJoCo reset the state): lower the "
                                  "timestep or check the wingbeat")

    def _q14(self) -> np.ndarray:
        dv = self.dove
        out = np.where(dv.qadr >= 0, self.data.qpos[np.maximum(dv.qadr, 0)], 0.0)
        out[DOF_NAMES.index("tail_spread")] = self.data.ten_length[self._tendon]
        return out

    def _rollout(self, ctrl: np.ndarray):
        m, d = self.model, self.data
        spec = mujoco.mjtState.mjSTATE_FULLPHYSICS
        size = mujoco.mj_stateSize(m, spec)
        state0 = np.empty(size)
        mujoco.mj_getState(m, d, state0, spec)
        # the warm start too: the feathers' twist hinges read the last step's accelerations
        states, _ = rollout.rollout(m, d, state0[None], ctrl[None], skip_checks=False,
                                    initial_warmstart=d.qacc_warmstart[None].copy())
        states = states[0]
        mujoco.mj_setState(m, d, states[-1], spec)
        mujoco.mj_forward(m, d)
        # FULLPHYSICS = time, qpos, qvel, act, ...
        t = states[:, 0]
        qpos = states[:, 1:1 + m.nq]
        dv = self.dove
        q14 = np.where(dv.qadr >= 0, qpos[:, np.maximum(dv.qadr, 0)], 0.0)
        q14[:, DOF_NAMES.index("tail_spread")] = qpos[:, self._tail_q] @ self._tail_c
        self._check_warnings()
        if not (np.all(np.isfinite(states[-1]))):
            raise SimulationError(f"dove state is not finite at t={d.time:.4f} s (diverged)")
        DISPATCHER.check(d)
        if self._free:
            return qpos[:, 0:3].copy(), qpos[:, 3:7].copy(), q14, t, qpos
        return np.zeros((len(t), 3)), np.tile([1.0, 0, 0, 0], (len(t), 1)), q14, t, qpos

    def com_velocity(self) -> np.ndarray:
        """Velocity of the whole bird's centre of mass, m/s (world frame)."""
        mujoco.mj_subtreeVel(self.model, self.data)
        return self.data.subtree_linvel[self.dove.trunk].copy()


def reduced_state(d: mujoco.MjData) -> np.ndarray:
    """The 8-number state of a free-flying trunk (body 1, free joint at qpos[0:7])."""
    q = d.qpos[3:7]
    R = np.zeros(9)
    mujoco.mju_quat2Mat(R, q)
    R = R.reshape(3, 3)
    pitch, roll = pitch_roll(R)
    v_body = R.T @ d.qvel[0:3]
    w_body = d.qvel[3:6]  # MuJoCo's free-joint angular velocity is in the body frame
    return np.array([pitch, roll, *v_body, *w_body])


def pitch_roll(R: np.ndarray) -> tuple[float, float]:
    """Nose-up pitch and right-wing-down roll of a body frame (x forward, y left, z up), rad.

    ``R``'s columns are the body axes in world coordinates. Pitch is the forward axis's
    elevation above the horizontal (+ nose up). Roll is the left axis's elevation (+ left
    wing up = right wing down): a right-handed rotation by +r about the body's forward x
    axis from level gives roll +r (``tests/bird/flight/test_dove_flight.py`` checks the sign).
    """
    fwd, left = R[:, 0], R[:, 1]
    pitch = float(np.arcsin(np.clip(fwd[2], -1, 1)))
    roll = float(np.arcsin(np.clip(left[2], -1, 1)))
    return pitch, roll


# -- wind tunnel -------------------------------------------------------------------------------


@dataclass
class TunnelResult:
    """Cycle-averaged aerodynamic force on a welded dove in a headwind."""

    speed: float
    pitch_deg: float
    lift_per_weight: float
    """Mean vertical force / body weight."""
    thrust_per_weight: float
    """Mean forward (+x) force / body weight: > 0 means thrust exceeds drag."""
    pitch_moment: float
    """Mean nose-up moment about the trunk centre, N m."""
    upstroke_area_ratio: float
    """Mean projected (xy) feather area in the upstroke / in the downstroke."""
    roll_moment: float = 0.0
    """Mean moment about the forward axis, N m: > 0 lifts the left wing (rolls right)."""
    yaw_moment: float = 0.0
    """Mean moment about the vertical, N m: > 0 turns the nose left."""


def wind_tunnel(params: DoveParams, p: np.ndarray, speed: float, pitch_deg: float = 0.0,
                cycles: int = 3, table: str = FlightConfig.table,
                ref: ReferenceWingbeat | None = None, modal: object | None = None,
                plucked: tuple[str, ...] = ()) -> TunnelResult:
    """Weld the trunk, blow ``speed`` m/s from ahead, flap wingbeat ``p`` and average the
    aerodynamic force over the last cycle (the first ones settle the feathers). ``modal``:
    a :class:`~flapsim.bird.body.feather_modes.ModalParams` for modal (deformable) feathers;
    ``plucked``: feathers without force polygons (:class:`DoveFlight`'s)."""
    if cycles < 2:
        raise InputError("wind_tunnel needs >= 2 cycles (the first settles the transients)")
    model = load_model(build_xml(params, fixed_trunk_pitch_deg=pitch_deg, modal=modal),
                       is_xml=True)
    dove = Dove.from_model(model, params, modal)
    fl = DoveFlight(dove, ref or reference_wingbeat(), table, (-speed, 0.0, 0.0),
                    use_rollout=False, plucked=tuple(plucked))
    try:
        fl.reset(FlightConfig(speed=0.0), p)
        m, d = fl.model, fl.data
        weight = float(params.total_mass * 9.81)
        ctrl, _, _ = control_table(fl.ref, p, m.opt.timestep, fl.kp, fl.kv)
        for _ in range(cycles - 1):
            for k in range(len(ctrl)):
                d.ctrl[:] = ctrl[k]
                mujoco.mj_step(m, d)
        F = np.zeros(3)
        M = np.zeros(3)
        trunk = d.xpos[dove.trunk].copy()
        down_area, up_area = [], []
        feathers = fl.polygons.table != BODY_TABLE
        areas = fl.polygons.area[feathers]
        ds = fl.ref.period * split_w(p) * 0.55
        for k in range(len(ctrl)):
            d.ctrl[:] = ctrl[k]
            mujoco.mj_step(m, d)
            f, points, _ = fl.aero_forces(d)
            F += f.sum(axis=0)
            M += np.cross(points - trunk, f).sum(axis=0)
            if fl.modal is None:
                proj = float(np.sum(areas * np.abs(fl.aero.world_normals(d)[feathers, 2])))
            else:  # the deformed triangles
                mr = fl.modal.evaluate(d)
                proj = float(np.sum(mr.area * np.abs(mr.normal[:, 2])))
            (down_area if k * m.opt.timestep < ds else up_area).append(proj)
        DISPATCHER.check(d)
        n = len(ctrl)
        # nose-up is about -y (x forward, z up)
        return TunnelResult(speed, pitch_deg, F[2] / n / weight, F[0] / n / weight, -M[1] / n,
                            float(np.mean(up_area) / np.mean(down_area)), M[0] / n, M[2] / n)
    finally:
        fl.close()


def split_w(p: np.ndarray) -> float:
    return float(np.asarray(p)[-1])


# -- a straight flight and its metrics ----------------------------------------------------------


@dataclass
class Flight:
    """A simulated flight of repeated wingbeats and its per-step record."""

    time: np.ndarray
    """(n,) s."""
    trunk_pos: np.ndarray
    """(n, 3) m."""
    trunk_quat: np.ndarray
    """(n, 4)."""
    qpos14: np.ndarray
    """(n, 14) rad."""
    qpos: np.ndarray
    """(n, nq) full positions."""
    states: np.ndarray
    """(wingbeats + 1, 8) reduced state at the start of each wingbeat and at the end."""
    com_vel_start: np.ndarray
    """Whole-bird centre-of-mass velocity at the start, m/s."""
    com_vel_end: np.ndarray
    """... and at the end."""
    start_pos: np.ndarray
    """Trunk position at the start, m."""
    start_vel: np.ndarray
    """Trunk velocity at the start (defines the initial straight line), m/s."""
    wall_time: float
    """Wall-clock seconds spent stepping (model set-up excluded)."""
    mass: float
    """Bird mass, kg."""


def fly(dove: Dove, wingbeats: int, cfg: FlightConfig | None = None, p: np.ndarray | None = None,
        use_rollout: bool = True, ref: ReferenceWingbeat | None = None,
        progress: bool = False, keep_qpos: bool = True) -> Flight:
    """The base controller: repeat wingbeat ``p`` (default: P0 with the tail bias) from the
    standard cruise state for ``wingbeats`` cycles. ``keep_qpos=False`` keeps the full
    positions only at wingbeat ends (a long flight without a video then needs ~45 kB per
    wingbeat instead of ~0.2-0.6 MB)."""

    if wingbeats < 1:
        raise InputError(f"--wingbeats must be >= 1, got {wingbeats}")
    cfg = cfg or FlightConfig()
    p = with_tail_bias(p0(), cfg.tail_bias_deg) if p is None else p
    fl = DoveFlight(dove, ref or reference_wingbeat(), cfg.table, use_rollout=use_rollout)
    try:
        fl.reset(cfg, p)
        d = fl.data
        start_pos, start_vel = d.qpos[0:3].copy(), d.qvel[0:3].copy()
        v0 = fl.com_velocity()
        states = [fl.reduced_state()]
        recs = []
        it = range(wingbeats)
        if progress:
            it = tqdm(it, desc="wingbeats", unit="wb")
        t0 = _time.perf_counter()
        for _ in it:
            rec = fl.run_cycle(p, frames=keep_qpos)
            if not keep_qpos and rec.qpos is not None:
                rec.qpos = rec.qpos[-1:].copy()
            recs.append(rec)
            states.append(fl.reduced_state())
        wall = _time.perf_counter() - t0
        v1 = fl.com_velocity()
    finally:
        fl.close()
    cat = lambda name: np.concatenate([getattr(r, name) for r in recs])  # noqa: E731
    return Flight(cat("time"), cat("trunk_pos"), cat("trunk_quat"), cat("qpos14"), cat("qpos"),
                  np.array(states), v0, v1, start_pos, start_vel, wall, dove.mass)


def flight_metrics(f: Flight, gravity: float = 9.81) -> dict:
    """The numbers ``flapsim fly`` reports (SI; angles in degrees with ``_deg``).

    * deviations from the initial straight line (through the start position along the
      start velocity): lateral = horizontal distance across it, vertical = height
      above/below it;
    * wingbeat frequency from the simulated shoulder elevation (tops found as in capture
      data), not from the commanded wingbeat;
    * mean vertical aerodynamic force / weight from the whole bird's momentum: gravity
      and feather forces are the only external forces, so their mean over the flight is
      ``m (v_end - v_start) / T`` and the aerodynamic part is that plus ``m g``.
    """

    T = float(f.time[-1] - (f.time[0] - (f.time[1] - f.time[0])))
    rel = f.trunk_pos - f.start_pos
    u = f.start_vel / max(np.linalg.norm(f.start_vel), 1e-12)
    along = rel @ u
    off = rel - np.outer(along, u)
    zhat = np.array([0.0, 0.0, 1.0])
    # vertical direction orthogonal to the line (the line is horizontal in the standard start)
    nvert = zhat - (zhat @ u) * u
    nvert /= np.linalg.norm(nvert)
    vertical = off @ nvert
    lateral = np.linalg.norm(off - np.outer(vertical, nvert), axis=1)
    steps = np.linalg.norm(np.diff(np.vstack([f.start_pos, f.trunk_pos]), axis=0), axis=1)
    pr = np.array([_pitch_roll_quat(q) for q in f.trunk_quat])
    rate = 1.0 / float(np.median(np.diff(f.time)))
    s, e = segment_cycles(f.qpos14, rate)
    freq = float(1.0 / np.mean((e - s) / rate)) if len(s) else float("nan")
    lift = 1.0 + float(f.com_vel_end[2] - f.com_vel_start[2]) / (gravity * T)
    thrust = float(f.com_vel_end @ u - f.com_vel_start @ u) / (gravity * T)
    return {
        "simulated_s": T,
        "mean_speed": float(steps.sum() / T),
        "wingbeat_hz": freq,
        "max_lateral_deviation": float(np.abs(lateral).max()),
        "max_vertical_deviation": float(np.abs(vertical).max()),
        "final_vertical_offset": float(vertical[-1]),
        "pitch_range_deg": [float(np.degrees(pr[:, 0].min())), float(np.degrees(pr[:, 0].max()))],
        "roll_range_deg": [float(np.degrees(pr[:, 1].min())), float(np.degrees(pr[:, 1].max()))],
        "mean_lift_per_weight": lift,
        "mean_net_forward_force_per_weight": thrust,
        "finite": bool(np.all(np.isfinite(f.qpos))),
        "real_time_factor": T / f.wall_time if f.wall_time > 0 else float("nan"),
    }


def _pitch_roll_quat(q: np.ndarray) -> tuple[float, float]:
    R = np.zeros(9)
    mujoco.mju_quat2Mat(R, q)
    return pitch_roll(R.reshape(3, 3))


def pose_quat(pitch: float, roll: float, heading: float = 0.0) -> np.ndarray:
    """Trunk quaternion with nose-up ``pitch``, ``roll`` and ``heading`` (about +z), all rad,
    such that :func:`flapsim.bird.flight.dove_flight.pitch_roll` gives back (pitch, roll) (for
    |sin roll| <= cos pitch)."""

    # pitch_roll's roll is the wing axis' elevation, asin(y_z) = asin(sin(roll_euler) cos(pitch))
    # for a heading-pitch-roll rotation: invert that, so pitch_roll returns ``roll`` exactly
    roll = float(np.arcsin(np.clip(np.sin(roll) / max(np.cos(pitch), 1e-12), -1.0, 1.0)))
    qz = np.array([np.cos(heading / 2), 0.0, 0.0, np.sin(heading / 2)])
    qy = np.array([np.cos(-pitch / 2), 0.0, np.sin(-pitch / 2), 0.0])  # +y is left: nose up is -y
    qx = np.array([np.cos(roll / 2), np.sin(roll / 2), 0.0, 0.0])
    q = np.empty(4)
    t = np.empty(4)
    mujoco.mju_mulQuat(t, qz, qy)
    mujoco.mju_mulQuat(q, t, qx)
    # follow pitch_roll's roll sign, whatever it is (one convention everywhere)
    R = np.zeros(9)
    mujoco.mju_quat2Mat(R, q)
    _, r = pitch_roll(R.reshape(3, 3))
    if abs(roll) > 1e-9 and np.sign(r) != np.sign(roll):
        qx[1] = -qx[1]
        mujoco.mju_mulQuat(q, t, qx)
    return q
