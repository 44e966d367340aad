"""Polygons on one-sided spring hinges that the force engine integrates: the flight paper's
feather twist (sec. 6, eq. 10-11).

A hinge carries the polygons of one plate (a primary feather) about an axis through a point
of the body they ride on. Its angle is the DOF of its own MuJoCo joint, a hinge of a
weightless body hung from the world: outside the skeleton, as the paper integrates it, so
``qpos``/``qvel`` carry it through snapshots, ``mujoco.rollout`` and repeated ``mj_forward``
calls like any joint, the joint's ``armature`` is the plate's moment of inertia ``H`` about
the axis, and its ``stiffness`` and ``damping`` are the paper's ``k_s`` and ``k_d`` (the
damper implicit, as MuJoCo's integrators treat it). What MuJoCo does not know, the surface
kernel adds to that DOF every step (:func:`hinge_torque`):

* the aerodynamic torque about the axis: the polygons' forces at their twisted centroids,
  which also go to the bone (eq. 9);
* the D'Alembert torque of the bone's motion (eq. 11): the rigid plate following its bone
  needs ``I_o alpha + omega x I_o omega + m c x (a_o - g)`` about the hinge point ``o``;
  minus that, about the axis. The bone's accelerations are those of the last step, finite
  differences of its velocities kept in MuJoCo's ``userdata`` (:func:`hinge_torque`; the
  snapshots must carry ``mjSTATE_USERDATA``): a lag of half a step. The paper's eq. 11 keeps
  the linear and angular acceleration terms; the centripetal and gravity terms are kept here
  too, as the coupled hinge of a multibody simulation has them;
* the one-sided clamp ("the feather twists at upward stroke but does not twist at the
  opposite direction"): the torque that makes the integrator's next angle land exactly on
  the stop, ``(theta_stop - theta)/dt`` as the new rate, when the free step would cross it.
  The DOF is alone in its tree (diagonal mass matrix), so the next rate is known in closed
  form: ``v' = v + dt f / (M + dt k_d)`` with MuJoCo's implicit damper (``implicitfast``,
  ``implicit``, or Euler with its implicit damping); no constraint row, no solver.

Why not a hinge in the skeleton with a joint limit (the model before): each active limit is
a constraint row of the whole tree's problem; the primaries' one-sided stops, active most of
the downstroke, cost ~11 us of a ~50 us dove step. The plate's own mass stays in the bone
(untwisted; its twisted mass distribution differs by the plate's ~1 mm of chordwise offset),
and the hinge does not push back on the bone except through the aerodynamic forces, as in the
paper (eq. 9).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import mujoco
import numpy as np
from numba import njit

from flapsim.core.errors import InputError, ModelError

HI = 4  # ints per hinge: body, qpos address, dof address, its diagonal in data.M
HF = 18  # floats per hinge: axis, origin, mass, com, inertia (6), stop low, stop high
HS = 17  # scratch floats per hinge: rate, world axis, world origin, world frame (9), torque


@dataclass(frozen=True)
class PolygonHinges:
    """Hinges of polygon groups (all in the body frame of the body the polygons ride on).

    ``label[h]``: the polygon label (:attr:`PolygonSet.labels`) whose polygons ride hinge
    ``h``; ``body[h]``: the name of the body the plate rides (its polygons must be on it);
    ``joint[h]``: the name of the hinge's own joint (a hinge of a weightless body hung from the
    world: its angle, rate, inertia ``H`` as armature, spring and damper)."""

    label: tuple[str, ...]
    body: tuple[str, ...]
    joint: tuple[str, ...]
    axis: np.ndarray
    """(h, 3) unit hinge axes, body frame."""
    origin: np.ndarray
    """(h, 3) a point of each axis, body frame, m."""
    mass: np.ndarray
    """(h,) plate masses, kg."""
    com: np.ndarray
    """(h, 3) plate centres of mass at zero angle, body frame, m."""
    inertia: np.ndarray
    """(h, 6) plate inertia about the origin at zero angle (xx, yy, zz, xy, xz, yz), kg m^2."""

    def __post_init__(self) -> None:
        h = len(self.label)
        if len(self.joint) != h or len(self.body) != h:
            raise InputError("PolygonHinges: one body and one joint per label")
        for name, width in (("axis", 3), ("origin", 3), ("com", 3), ("inertia", 6)):
            a = np.ascontiguousarray(np.asarray(getattr(self, name), dtype=float).reshape(h, width))
            if not np.all(np.isfinite(a)):
                raise InputError(f"PolygonHinges.{name} contains NaN or inf")
            object.__setattr__(self, name, a)
        mass = np.ascontiguousarray(np.asarray(self.mass, dtype=float).reshape(h))
        if np.any(~np.isfinite(mass)) or np.any(mass < 0):
            raise InputError("PolygonHinges.mass must be >= 0")
        object.__setattr__(self, "mass", mass)
        if np.any(np.abs(np.linalg.norm(self.axis, axis=1) - 1.0) > 1e-9):
            raise InputError("PolygonHinges.axis must be unit vectors")

    def __len__(self) -> int:
        return len(self.label)

    def tables(self, model: mujoco.MjModel, polygon_labels: Sequence[str], polygon_body: np.ndarray
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The kernel's arrays for ``model``: per polygon its hinge (-1: none), per hinge its
        ints (:data:`HI`) and floats (:data:`HF`). One-line errors for a joint that is not a
        lone hinge of a weightless body hung from the world, or polygons on several bodies."""
        labels = np.asarray(polygon_labels)
        if len(self) and len(labels) != len(polygon_body):
            raise InputError("hinged polygons need labels (PolygonSet.labels)")
        if len(self) and model.nuserdata < userdata_size(len(self)):
            raise ModelError(f"{len(self)} hinges keep their bones' velocities in userdata: the "
                             f'model needs <size nuserdata="{userdata_size(len(self))}"/> or more')
        phinge = np.full(len(polygon_body), -1, dtype=np.int64)
        hint = np.zeros(HI * len(self), dtype=np.int64)
        hflt = np.zeros(HF * len(self))
        for h, (lab, jname) in enumerate(zip(self.label, self.joint, strict=True)):
            j = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, jname)
            if j < 0:
                raise ModelError(f"hinge {lab}: the model has no joint {jname!r}")
            jb = model.jnt_bodyid[j]
            if (model.jnt_type[j] != mujoco.mjtJoint.mjJNT_HINGE or model.body_parentid[jb] != 0
                    or model.body_dofnum[jb] != 1 or model.jnt_limited[j]):
                raise ModelError(f"hinge {lab}: joint {jname!r} must be the only, unlimited hinge "
                                 "of a body hung from the world (the engine clamps it)")
            if model.body_ipos[jb] @ model.body_ipos[jb] > 0 or np.any(model.jnt_pos[j] != 0):
                raise ModelError(f"hinge {lab}: the body of {jname!r} must have its centre of mass "
                                 "on the joint at its origin (no gravity or inertial torque)")
            body = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, self.body[h])
            if body <= 0:
                raise ModelError(f"hinge {lab}: the model has no moving body {self.body[h]!r}")
            on = labels == lab
            if len(labels) and np.any(polygon_body[on] != body):
                raise InputError(f"hinge {lab}: its polygons must all ride body {self.body[h]!r}")
            # no polygon with the label (a plucked feather): the hinge still feels its bone
            phinge[on] = h
            d = model.jnt_dofadr[j]
            # the DOF's diagonal entry of MuJoCo's sparse mass matrix (``data.M``, rows end on it)
            diag = model.M_rowadr[d] + model.M_rownnz[d] - 1
            hint[HI * h:HI * (h + 1)] = (body, model.jnt_qposadr[j], d, diag)
            lo, hi = model.jnt_range[j]
            if not lo < hi:
                raise ModelError(f"hinge {lab}: joint {jname!r} needs its stops as range lo < hi")
            hflt[HF * h:HF * (h + 1)] = (*self.axis[h], *self.origin[h], self.mass[h],
                                         *(self.com[h] - self.origin[h]), *self.inertia[h], lo, hi)
        return phinge, hint, hflt


def userdata_size(n_hinges: int) -> int:
    """``userdata`` entries the hinges use (see :func:`hinge_torque`): two times, then per
    hinge two (velocity, angular velocity) pairs."""
    return 2 + 12 * n_hinges


def integrator_damping(model: mujoco.MjModel) -> float:
    """1 where the integrator treats DOF damping implicitly (the next rate is
    ``v + dt f / (M + dt k_d)``), 0 where it is explicit; an error for RK4, whose four force
    evaluations per step a one-step clamp cannot predict."""
    it = model.opt.integrator
    if it == mujoco.mjtIntegrator.mjINT_RK4:
        raise ModelError("hinged polygons need the Euler, implicit or implicitfast integrator (not RK4)")
    if it == mujoco.mjtIntegrator.mjINT_EULER:
        return 0.0 if model.opt.disableflags & mujoco.mjtDisableBit.mjDSBL_EULERDAMP else 1.0
    return 1.0


def hinge_arrays(model: mujoco.MjModel, data: mujoco.MjData, hint: np.ndarray, hflt: np.ndarray
                 ) -> list[np.ndarray]:
    """What a kernel passes :func:`hinge_frames` and :func:`hinge_torque` for one (model,
    data): the hinges' tables, their scratch (per registration), the MuJoCo data and model
    arrays they read, a ``cacc`` scratch, ``opt`` (the model's own timestep, gravity and
    implicit damping: a coarser copy, say) and ``userdata``."""
    i64 = [np.ascontiguousarray(a, dtype=np.int64)
           for a in (model.body_parentid, model.body_dofadr, model.body_dofnum)]
    opt = np.array([model.opt.timestep, *model.opt.gravity, integrator_damping(model)])
    return [hint, hflt, np.zeros(hint.size // HI * HS), data.qpos, data.qvel,
            data.qacc_warmstart, data.qfrc_passive, data.qfrc_applied, data.M, model.dof_damping,
            *i64, data.cdof.reshape(-1), data.cdof_dot.reshape(-1), np.zeros(6 * model.nbody), opt,
            data.userdata]


@njit(cache=True, inline="always")
def _rot(m, k, x, y, z):
    """``R v`` for the row-major 3x3 ``R`` at ``m[k:k + 9]`` (no slice: no array view)."""
    return (m[k] * x + m[k + 1] * y + m[k + 2] * z, m[k + 3] * x + m[k + 4] * y + m[k + 5] * z,
            m[k + 6] * x + m[k + 7] * y + m[k + 8] * z)


@njit(cache=True, inline="always")
def _rot_t(m, k, x, y, z):
    """``R^T v`` for the row-major 3x3 ``R`` at ``m[k:k + 9]``."""
    return (m[k] * x + m[k + 3] * y + m[k + 6] * z, m[k + 1] * x + m[k + 4] * y + m[k + 7] * z,
            m[k + 2] * x + m[k + 5] * y + m[k + 8] * z)


@njit(cache=True)
def hinge_frames(xpos, xmat, qpos, qvel, hint, hflt, hs):
    """Per hinge: its rate, world axis, world origin and the twisted plate's world frame
    (the body's frame turned by the hinge angle about the axis) into the scratch ``hs``."""
    nh = hint.size // HI
    for h in range(nh):
        b = hint[HI * h]
        th = qpos[hint[HI * h + 1]]
        o = HF * h
        ux, uy, uz = hflt[o], hflt[o + 1], hflt[o + 2]
        c = np.cos(th)
        s = np.sin(th)
        t = 1.0 - c
        # Rodrigues: R = c I + s [u]x + t u u^T (body frame)
        r00 = c + t * ux * ux
        r01 = t * ux * uy - s * uz
        r02 = t * ux * uz + s * uy
        r10 = t * uy * ux + s * uz
        r11 = c + t * uy * uy
        r12 = t * uy * uz - s * ux
        r20 = t * uz * ux - s * uy
        r21 = t * uz * uy + s * ux
        r22 = c + t * uz * uz
        m = 9 * b
        so = HS * h
        hs[so] = qvel[hint[HI * h + 2]]
        for i in range(3):
            a0 = xmat[m + 3 * i]
            a1 = xmat[m + 3 * i + 1]
            a2 = xmat[m + 3 * i + 2]
            hs[so + 1 + i] = a0 * ux + a1 * uy + a2 * uz
            hs[so + 4 + i] = (xpos[3 * b + i] + a0 * hflt[o + 3] + a1 * hflt[o + 4]
                              + a2 * hflt[o + 5])
            hs[so + 7 + 3 * i] = a0 * r00 + a1 * r10 + a2 * r20
            hs[so + 8 + 3 * i] = a0 * r01 + a1 * r11 + a2 * r21
            hs[so + 9 + 3 * i] = a0 * r02 + a1 * r12 + a2 * r22
        hs[so + 16] = 0.0
    return 0


@njit(cache=True, inline="always")
def hinged_point(hflt, hs, h, lx, ly, lz):
    """World position of body-frame point ``l`` on hinge ``h``'s twisted plate."""
    o = HF * h
    so = HS * h
    dx, dy, dz = _rot(hs, so + 7, lx - hflt[o + 3], ly - hflt[o + 4], lz - hflt[o + 5])
    return hs[so + 4] + dx, hs[so + 5] + dy, hs[so + 6] + dz


@njit(cache=True, inline="always")
def hinged_vector(hs, h, lx, ly, lz):
    """World direction of body-frame vector ``l`` on hinge ``h``'s twisted plate."""
    return _rot(hs, HS * h + 7, lx, ly, lz)


@njit(cache=True)
def bone_accelerations(parent, dofadr, dofnum, cdof, cdof_dot, qvel, qacc, cacc):
    """Every body's spatial acceleration (com-based, as MuJoCo's ``cacc`` without gravity)
    from joint accelerations ``qacc``: MuJoCo's rne forward pass."""
    for k in range(6):
        cacc[k] = 0.0
    for b in range(1, parent.size):
        p = parent[b]
        for k in range(6):
            cacc[6 * b + k] = cacc[6 * p + k]
        for j in range(dofadr[b], dofadr[b] + dofnum[b]):
            v = qvel[j]
            a = qacc[j]
            for k in range(6):
                cacc[6 * b + k] += cdof_dot[6 * j + k] * v + cdof[6 * j + k] * a
    return 0


@njit(cache=True, inline="always")
def advance_clock(ud, c, t, dt):
    """The clock of a velocity memory in ``userdata``: ``ud[c]``, ``ud[c + 1]`` = the times of
    the previous and the current call. Returns (stepped: this call is one step after the last,
    so each memory's current values must become its previous ones (:func:`shift_memory`);
    diff: the previous values are one step old, so finite differences of them are the last
    step's accelerations). A call at the same time changes nothing; a jump (a reset, another
    time) leaves no previous values."""
    tol = 0.25 * dt
    stepped = abs(t - ud[c + 1] - dt) < tol
    if stepped:
        ud[c] = ud[c + 1]
    elif abs(t - ud[c + 1]) >= tol:
        ud[c] = np.nan
    ud[c + 1] = t
    return stepped, abs(ud[c] - (t - dt)) < tol


@njit(cache=True, inline="always")
def shift_memory(ud, base, n):
    """Memories ``i < n`` at ``ud[base + 12 i:]`` (previous velocity, angular velocity, then
    the current ones): the current become the previous."""
    for i in range(n):
        for k in range(6):
            ud[base + 12 * i + k] = ud[base + 12 * i + 6 + k]


@njit(cache=True, inline="always")
def memory_acceleration(diff, dt, gx, gy, gz, ud, u, vx, vy, vz, sx, sy, sz, wx, wy, wz, cacc,
                        b, dx, dy, dz):
    """(a - g, alpha) of a frame whose point at ``d`` from its tree's centre of mass moves with
    body ``b`` at velocity ``v`` and which turns at ``s`` (``w`` is the body's own angular
    velocity): finite differences over the last step of the memory at ``ud[u:u + 6]`` when
    ``diff`` (what the integrator really did), else the body's explicit acceleration ``cacc``
    (:func:`bone_accelerations`). Stores ``(v, s)`` as the memory's current values."""
    if diff:
        alx = (sx - ud[u + 3]) / dt
        aly = (sy - ud[u + 4]) / dt
        alz = (sz - ud[u + 5]) / dt
        ax = (vx - ud[u]) / dt - gx
        ay = (vy - ud[u + 1]) / dt - gy
        az = (vz - ud[u + 2]) / dt - gz
    else:
        alx, aly, alz = cacc[6 * b], cacc[6 * b + 1], cacc[6 * b + 2]
        ax = cacc[6 * b + 3] + aly * dz - alz * dy + wy * vz - wz * vy - gx
        ay = cacc[6 * b + 4] + alz * dx - alx * dz + wz * vx - wx * vz - gy
        az = cacc[6 * b + 5] + alx * dy - aly * dx + wx * vy - wy * vx - gz
    ud[u + 6] = vx
    ud[u + 7] = vy
    ud[u + 8] = vz
    ud[u + 9] = sx
    ud[u + 10] = sy
    ud[u + 11] = sz
    return ax, ay, az, alx, aly, alz


@njit(cache=True)
def hinge_torque(hint, hflt, hs, cvel, cacc, scom, rootid, qpos, qvel, qfrc, qfrc_applied, M,
                 damping, opt, t, ud, parent, dofadr, dofnum, cdof, cdof_dot, qacc):
    """Add each hinge's aerodynamic (accumulated in ``hs``), D'Alembert and stop torques to
    its DOF's ``qfrc`` (``opt`` = timestep, gravity (3), implicit damping 1/0).

    The bones' accelerations over the last step are finite differences of their velocities,
    kept in ``ud`` (MuJoCo's ``userdata``: ``t_prev, t_now``, then per hinge the hinge
    point's velocity and the bone's angular velocity at both times): what the implicit
    integrator really did, which the explicit ``qacc`` is not (a servo's damper on a light
    bone: ``dt kv / I`` up to 0.35 in the dove's hand). A call at the same time rewrites the
    current velocities only, so repeated ``mj_forward`` calls change nothing; without the
    previous step (a reset, a jump in time) the explicit ``qacc_warmstart`` stands in, once.
    """
    dt = opt[0]
    gx, gy, gz = opt[1], opt[2], opt[3]
    nh = hint.size // HI
    stepped, diff = advance_clock(ud, 0, t, dt)
    if stepped:
        shift_memory(ud, 2, nh)
    if not diff:
        bone_accelerations(parent, dofadr, dofnum, cdof, cdof_dot, qvel, qacc, cacc)
    for h in range(nh):
        b = hint[HI * h]
        qa = hint[HI * h + 1]
        da = hint[HI * h + 2]
        o = HF * h
        so = HS * h
        tau = hs[so + 16]
        r = rootid[b]
        dx = hs[so + 4] - scom[3 * r]
        dy = hs[so + 5] - scom[3 * r + 1]
        dz = hs[so + 6] - scom[3 * r + 2]
        wx, wy, wz = cvel[6 * b], cvel[6 * b + 1], cvel[6 * b + 2]
        # the hinge point's velocity and (material) acceleration, less gravity
        vx = cvel[6 * b + 3] + wy * dz - wz * dy
        vy = cvel[6 * b + 4] + wz * dx - wx * dz
        vz = cvel[6 * b + 5] + wx * dy - wy * dx
        aox, aoy, aoz, ax, ay, az = memory_acceleration(diff, dt, gx, gy, gz, ud, 2 + 12 * h, vx,
                                                        vy, vz, wx, wy, wz, wx, wy, wz, cacc, b,
                                                        dx, dy, dz)
        # in the twisted plate's frame, where its inertia is constant
        wx, wy, wz = _rot_t(hs, so + 7, wx, wy, wz)
        ax, ay, az = _rot_t(hs, so + 7, ax, ay, az)
        aox, aoy, aoz = _rot_t(hs, so + 7, aox, aoy, aoz)
        m = hflt[o + 6]
        cx, cy, cz = hflt[o + 7], hflt[o + 8], hflt[o + 9]
        ixx, iyy, izz = hflt[o + 10], hflt[o + 11], hflt[o + 12]
        ixy, ixz, iyz = hflt[o + 13], hflt[o + 14], hflt[o + 15]
        # I alpha + w x (I w) + m c x a_o: what the plate needs to follow its bone
        iwx = ixx * wx + ixy * wy + ixz * wz
        iwy = ixy * wx + iyy * wy + iyz * wz
        iwz = ixz * wx + iyz * wy + izz * wz
        nx = ixx * ax + ixy * ay + ixz * az + wy * iwz - wz * iwy + m * (cy * aoz - cz * aoy)
        ny = ixy * ax + iyy * ay + iyz * az + wz * iwx - wx * iwz + m * (cz * aox - cx * aoz)
        nz = ixz * ax + iyz * ay + izz * az + wx * iwy - wy * iwx + m * (cx * aoy - cy * aox)
        tau -= hflt[o] * nx + hflt[o + 1] * ny + hflt[o + 2] * nz
        # the stop: the integrator's next angle, and the torque that puts it on the stop
        th = qpos[qa]
        v = qvel[da]
        f = qfrc[da] + qfrc_applied[da] + tau
        mt = M[hint[HI * h + 3]] + dt * damping[da] * opt[4]
        nxt = th + dt * (v + dt * f / mt)
        lo = hflt[o + 16]
        hi = hflt[o + 17]
        if nxt < lo:
            tau += ((lo - th) / dt - v) * mt / dt - f
        elif nxt > hi:
            tau += ((hi - th) / dt - v) * mt / dt - f
        qfrc[da] += tau
    return 0
