"""One wingbeat from any full simulation state: the unit of sampling and of control.

A :class:`Snapshot` is everything MuJoCo needs to repeat a step bit for bit: the
``mjSTATE_FULLPHYSICS`` vector (time, joint positions and velocities of the trunk, the
14 DOF and every feather hinge, ...) and the constraint solver's warm start (joint limits
make the solver's answer depend on where it starts). :func:`fly_cycle` restores a
snapshot, flies one wingbeat of parameters ``P`` inside ``mujoco.rollout`` and returns
the end snapshot, the 8-number reduced state ``S`` (position and heading invariant) and
the world quantities that steering is measured in.
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np
from mujoco import rollout

from flapsim.bird.body.params import DOF_NAMES
from flapsim.bird.flight.dove_flight import DoveFlight, reduced_state
from flapsim.bird.flight.wingbeat import ReferenceWingbeat, control_table, split
from flapsim.core.callbacks import DISPATCHER
from flapsim.core.errors import SimulationError

STATE_SPEC = mujoco.mjtState.mjSTATE_FULLPHYSICS


@dataclass(frozen=True)
class Snapshot:
    """A full simulation state of one dove model."""

    physics: np.ndarray
    """``mj_getState(..., mjSTATE_FULLPHYSICS)``."""
    warmstart: np.ndarray
    """(nv,) ``qacc_warmstart``: the constraint solver's starting point."""
    userdata: np.ndarray | None = None
    """``userdata``: the twist hinges' memory of the bones' last velocities
    (:mod:`flapsim.fluid.hinges`); None: left as it is on restore."""


@dataclass(frozen=True)
class CycleEnd:
    """Where one wingbeat ended."""

    snapshot: Snapshot
    S: np.ndarray
    """(8,) reduced state (pitch, roll, body-frame velocity, body-frame angular velocity)."""
    trunk_pos: np.ndarray
    """(3,) trunk position, m (world)."""
    trunk_quat: np.ndarray
    """(4,) trunk orientation (w, x, y, z)."""
    com_vel: np.ndarray
    """(3,) whole-bird centre-of-mass velocity, m/s (world)."""
    duration: float
    """Simulated wingbeat duration, s."""
    range_excess: float
    """Largest excursion of any of the 14 DOF beyond its joint range over the cycle, rad
    (0 inside; MuJoCo's soft limits allow a little)."""
    qpos: np.ndarray | None = None
    """(n, nq) positions at every step, when recorded."""
    predicted: bool = False
    """True when this end was not simulated but predicted (the learned controller's
    ``predict="regression"``): then ``snapshot`` is the start state with the end's time and
    not a state to restore, and ``range_excess`` is 0."""


def snapshot(fl: DoveFlight) -> Snapshot:
    """The flight's current full state."""
    m, d = fl.model, fl.data
    s = np.empty(mujoco.mj_stateSize(m, STATE_SPEC))
    mujoco.mj_getState(m, d, s, STATE_SPEC)
    return Snapshot(s, d.qacc_warmstart.copy(), d.userdata.copy())


def restore(fl: DoveFlight, snap: Snapshot, forward: bool = True) -> None:
    """Put the flight back into ``snap`` (bit-identical continuation). ``forward=False``
    skips the ``mj_forward`` that makes the data's derived quantities (positions of bodies,
    forces) current: for a caller that only steps on from here."""
    m, d = fl.model, fl.data
    mujoco.mj_setState(m, d, snap.physics, STATE_SPEC)
    d.qacc_warmstart[:] = snap.warmstart
    if snap.userdata is not None:
        d.userdata[:] = snap.userdata
    d.ctrl[:] = 0.0
    if forward:
        mujoco.mj_forward(m, d)


def heading_and_climb(v: np.ndarray) -> tuple[float, float]:
    """Heading (rad, + toward +y = left) and climb angle (rad, + up) of a world velocity."""
    v = np.asarray(v, float)
    return float(np.arctan2(v[1], v[0])), float(np.arctan2(v[2], np.hypot(v[0], v[1])))


def wrap(a: float | np.ndarray) -> float | np.ndarray:
    """Angle(s) wrapped to (-pi, pi]."""
    return -((-np.asarray(a) + np.pi) % (2 * np.pi) - np.pi)


def dof_angles(fl: DoveFlight, qpos: np.ndarray) -> np.ndarray:
    """(n, 14) angles of the 14 DOF from (n, nq) positions (a tendon DOF: its length, the
    coefficient-weighted sum of its joints)."""
    m, dv = fl.model, fl.dove
    qpos = np.atleast_2d(qpos)
    out = np.where(dv.qadr >= 0, qpos[:, np.maximum(dv.qadr, 0)], 0.0)
    for i in np.flatnonzero(dv.qadr < 0):
        t = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_TENDON, DOF_NAMES[i])
        a, k = m.tendon_adr[t], m.tendon_num[t]
        objs = m.wrap_objid[a:a + k]
        out[:, i] = qpos[:, m.jnt_qposadr[objs]] @ m.wrap_prm[a:a + k]
    return out


def model_dof_ranges(fl: DoveFlight) -> tuple[np.ndarray, np.ndarray]:
    """(lo, hi) of the 14 DOF from the compiled model (joint ranges; the tail spread's
    tendon range); +-inf where a DOF is unlimited."""
    m = fl.model
    # read twice a wingbeat by the controller: cached, keyed on the ranges themselves so that
    # a model edited in place is read afresh
    key = (m.jnt_range.tobytes(), m.jnt_limited.tobytes(), m.tendon_range.tobytes(),
           m.tendon_limited.tobytes())
    cached = getattr(fl, "_dof_ranges_cache", None)
    if cached is None or cached[0] != key:
        cached = (key, _dof_ranges(fl))
        fl._dof_ranges_cache = cached
    lo, hi = cached[1]
    return lo.copy(), hi.copy()


def _dof_ranges(fl: DoveFlight) -> tuple[np.ndarray, np.ndarray]:
    m, dv = fl.model, fl.dove
    lo, hi = np.full(len(dv.qadr), -np.inf), np.full(len(dv.qadr), np.inf)
    for i in range(len(dv.qadr)):
        if dv.qadr[i] >= 0:
            j = int(np.flatnonzero(m.jnt_qposadr == dv.qadr[i])[0])
            if m.jnt_limited[j]:
                lo[i], hi[i] = m.jnt_range[j]
        else:
            t = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_TENDON, DOF_NAMES[i])
            if t >= 0 and m.tendon_limited[t]:
                lo[i], hi[i] = m.tendon_range[t]
    return lo, hi


@dataclass(frozen=True)
class Push:
    """An external force on one body for the first ``steps`` steps of a wingbeat (the
    flight paper's random pushes: 3-12 N for 0.1 s at the trunk's centre of mass)."""

    body: int
    """Body id (MuJoCo applies ``xfrc_applied`` at the body's centre of mass)."""
    force: np.ndarray
    """(3,) world force, N."""
    steps: int
    """Steps it lasts (from the wingbeat's start)."""


def _push_controls(m: mujoco.MjModel, ctrl: np.ndarray, push: Push) -> tuple[np.ndarray, int]:
    """Per-step control vectors carrying ``ctrl`` and the push's ``xfrc_applied`` (in
    ``mj_getState``'s own layout for CTRL | XFRC_APPLIED), and that spec."""
    spec = mujoco.mjtState.mjSTATE_CTRL | mujoco.mjtState.mjSTATE_XFRC_APPLIED
    scratch = mujoco.MjData(m)
    out = np.empty((len(ctrl), mujoco.mj_stateSize(m, spec)))
    for k in range(len(ctrl)):
        scratch.ctrl[:] = ctrl[k]
        scratch.xfrc_applied[:] = 0.0
        if k < push.steps:
            scratch.xfrc_applied[push.body, 0:3] = push.force
        mujoco.mj_getState(m, scratch, out[k], spec)
    return out, int(spec)


def _stepped(fl: DoveFlight, ctrl: np.ndarray, push: Push | None, size: int
             ) -> tuple[np.ndarray, np.ndarray]:
    """The wingbeat stepped one ``mj_step`` at a time: (the states a rollout would return,
    the frames :meth:`DoveFlight.frame`). Diverging here raises as the rollout's check does."""
    m, d = fl.model, fl.data
    states = np.empty((len(ctrl), size))
    frames = None
    try:
        for k in range(len(ctrl)):
            d.ctrl[:] = ctrl[k]
            if push is not None:
                d.xfrc_applied[push.body, 0:3] = push.force if k < push.steps else 0.0
            mujoco.mj_step(m, d)
            mujoco.mj_getState(m, d, states[k], STATE_SPEC)
            row = fl.frame()
            if frames is None:
                frames = np.empty((len(ctrl), len(row)))
            frames[k] = row
    finally:
        if push is not None:
            d.xfrc_applied[:] = 0.0
    return states, frames


def _controls(fl: DoveFlight, ref: ReferenceWingbeat, p: np.ndarray) -> np.ndarray:
    """The control table of wingbeat ``p``; the last few are kept, since the learned
    controller flies the same reference wingbeat P0 every wingbeat."""
    m = fl.model
    key = (id(ref), ref.coef.tobytes(), float(ref.period), np.asarray(p, float).tobytes(),
           float(m.opt.timestep), fl.kp.tobytes(), fl.kv.tobytes())
    cache = fl.__dict__.setdefault("_control_cache", {})
    ctrl = cache.pop(key, None)
    if ctrl is None:
        ctrl, _, _ = control_table(ref, p, m.opt.timestep, fl.kp, fl.kv)
        ctrl.setflags(write=False)
        if len(cache) >= 4:
            cache.pop(next(iter(cache)))  # the least recently used
    cache[key] = ctrl
    return ctrl


def fly_cycle(fl: DoveFlight, snap: Snapshot | None, p: np.ndarray,
              ref: ReferenceWingbeat | None = None, record: bool = False,
              push: Push | None = None) -> CycleEnd:
    """Fly one wingbeat of parameters ``p`` from ``snap`` (``None``: from the flight's
    current state) and leave the flight at its end; ``push``: an external force during
    its first steps.

    Raises :class:`~flapsim.core.errors.SimulationError` (one line) when the simulation
    diverges; the flight is then in an undefined state (restore a snapshot).
    """

    split(p)  # shape / finiteness check with a one-line error
    m, d = fl.model, fl.data
    if not DISPATCHER.providers(d):
        # a bird with no feather forces falls like a stone and every number looks plausible
        raise SimulationError("the dove's feather forces are not registered (the passive "
                              "dispatcher was cleared): build a new DoveFlight")
    if snap is not None:
        restore(fl, snap, forward=False)  # rollout steps from the state alone
    ref = ref or fl.ref
    ctrl = _controls(fl, ref, p)
    s0 = np.empty(mujoco.mj_stateSize(m, STATE_SPEC))
    mujoco.mj_getState(m, d, s0, STATE_SPEC)
    warm = d.qacc_warmstart.copy()
    n = len(ctrl)
    frames = None
    if record and fl.modes_in_userdata:  # the frames need the modes' state: step one by one
        states, frames = _stepped(fl, ctrl, push, s0.size)
    elif push is None:
        states, _ = rollout.rollout(m, d, s0[None], ctrl[None], initial_warmstart=warm[None],
                                    skip_checks=False)
    else:
        controls, spec = _push_controls(m, ctrl, push)
        states, _ = rollout.rollout(m, d, s0[None], controls[None], control_spec=spec,
                                    initial_warmstart=warm[None], skip_checks=False)
        d.xfrc_applied[:] = 0.0
    if frames is None:
        states = states[0]
    if not np.all(np.isfinite(states[-1])):
        raise SimulationError(f"dove simulation diverged within a wingbeat at t={states[-1, 0]:.4f} s "
                              "(non-finite state): the wingbeat or start state is out of reach")
    if d.warning[mujoco.mjtWarning.mjWARN_BADQACC].number > 0:
        d.warning[mujoco.mjtWarning.mjWARN_BADQACC].number = 0
        raise SimulationError("dove simulation diverged within a wingbeat (bad accelerations; "
                              "MuJoCo reset the state): the wingbeat or start state is out of reach")
    mujoco.mj_setState(m, d, states[-1], STATE_SPEC)
    mujoco.mj_forward(m, d)
    DISPATCHER.check(d)
    lo, hi = model_dof_ranges(fl)
    q = dof_angles(fl, states[:, 1:1 + m.nq])
    excess = float(max(0.0, np.max(lo - q), np.max(q - hi)))
    mujoco.mj_subtreeVel(m, d)
    com_vel = d.subtree_linvel[fl.dove.trunk].copy()
    qpos = (states[:, 1:1 + m.nq].copy() if frames is None else frames) if record else None
    return CycleEnd(Snapshot(states[-1].copy(), d.qacc_warmstart.copy(), d.userdata.copy()),
                    reduced_state(d),
                    d.qpos[0:3].copy(), d.qpos[3:7].copy(), com_vel, n * float(m.opt.timestep),
                    excess, qpos)


