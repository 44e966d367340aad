"""Kinematic modal animation (Kry et al. 2009, section 4.2, equation 4).

    theta(t) = theta_0 (+) [ sum_i alpha_i R N u_i sin(2 pi f_i t + gamma_i) + sum_i beta_i R N u_i ]

``(+)`` applies the joint-space displacement with ``mj_integratePos`` (hinges add, the
floating root's quaternion stays unit). Each component's shape ``R N u_i`` comes from
:class:`flapsim.modal.analysis.ModalAnalysis`, normalised and signed by the caller (the
gaits: largest rotation 1 rad, sign fixed by the heuristics).

Soft joint limits (the paper's): a joint that passes its limit by ``d`` is pulled back
by ``d^2 / (d + dtheta_soft)``, so it ends at ``limit + d dtheta_soft / (d + dtheta_soft)``:
never beyond ``limit + dtheta_soft``, and C1-continuous at the limit (slope 1 there).
Hinge and slide limits act on the coordinate; a ball joint's limit acts on its rotation
angle.

Constraints held at finite amplitude: the modes respect the analysis constraints to first
order only, so :class:`ConstraintProjector` can pull each frame back onto them (closed
loops from the model's equalities, a fixed head orientation, pinned sites) with a few
minimum-norm Gauss-Newton steps. That is ours, not the paper's; it is off unless asked.

Outputs: the joint trajectory as ``.npz`` (:func:`save_trajectory`), a video
(:func:`flapsim.modal.video.render_poses`) and BVH (:mod:`flapsim.modal.bvh`).
"""

from __future__ import annotations

import logging
import math
from collections.abc import Sequence
from dataclasses import dataclass

import mujoco
import numpy as np
from tqdm import tqdm

from flapsim.core.errors import InputError
from flapsim.core.io import save_npz
from flapsim.modal.analysis import ExtraConstraint

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class Component:
    """One mode in equation 4."""

    shape: np.ndarray
    """Joint-space shape R N u_i (nv,), signed and normalised (rad for hinges, m for the
    root translation)."""
    amplitude: float
    """alpha_i: amplitude of the sinusoid (dimensionless multiplier of ``shape``)."""
    phase_rad: float = 0.0
    """gamma_i: phase, rad (the heuristics use multiples of pi/2)."""
    freq_hz: float = 2.0
    """f~_i: animation frequency, Hz (the paper's Fig. 3 uses 2 Hz, some 1 Hz)."""
    beta: float = 0.0
    """beta_i: constant postural offset along the same shape (section 4.3)."""
    mode: int = -1
    """Mode index in the analysis (-1: a rigid-body combination)."""
    label: str = ""
    """What it is for (e.g. 'B alternating forward foot motion')."""


@dataclass(frozen=True)
class SoftLimits:
    """The paper's soft joint limits."""

    soft_rad: float = 0.1
    """dtheta_soft: the most a joint may pass its limit, rad (m for slides); ours, the
    paper does not give its value. 0 clamps hard."""
    enabled: bool = True
    """False leaves the joints free (for checking the raw modal motion)."""


def soft_limit(x: np.ndarray, lo: float, hi: float, soft: float) -> np.ndarray:
    """Map values past [lo, hi] by ``d -> d - d^2 / (d + soft)`` (the paper's rule)."""
    x = np.asarray(x, dtype=np.float64)
    if soft < 0:
        raise InputError("dtheta_soft must be >= 0")
    out = x.copy()
    over = x > hi
    under = x < lo
    if soft == 0:
        return np.clip(out, lo, hi)
    d = x[over] - hi
    out[over] = hi + d * soft / (d + soft)
    d = lo - x[under]
    out[under] = lo - d * soft / (d + soft)
    return out


def apply_soft_limits(model: mujoco.MjModel, qpos: np.ndarray, limits: SoftLimits) -> np.ndarray:
    """Soft limits on every limited hinge, slide and ball joint of ``qpos`` (..., nq)."""
    q = np.array(qpos, dtype=np.float64, copy=True)
    if not limits.enabled:
        return q
    for j in range(model.njnt):
        if not model.jnt_limited[j]:
            continue
        adr = int(model.jnt_qposadr[j])
        lo, hi = (float(v) for v in model.jnt_range[j])
        kind = int(model.jnt_type[j])
        if kind in (mujoco.mjtJoint.mjJNT_HINGE, mujoco.mjtJoint.mjJNT_SLIDE):
            q[..., adr] = soft_limit(q[..., adr], lo, hi, limits.soft_rad)
        elif kind == mujoco.mjtJoint.mjJNT_BALL:
            quat = q[..., adr : adr + 4]
            w = np.clip(np.abs(quat[..., 0]), 0.0, 1.0)
            angle = 2.0 * np.arccos(w)
            new = soft_limit(angle, -np.inf, hi, limits.soft_rad)
            ratio = np.ones_like(angle)
            moving = angle > 1e-12
            # Rescale the rotation angle about the same axis.
            s_old = np.sin(angle[moving] / 2)
            ratio[moving] = np.sin(new[moving] / 2) / s_old
            sign = np.where(quat[..., 0] < 0, -1.0, 1.0)
            q[..., adr] = sign * np.cos(new / 2)
            q[..., adr + 1 : adr + 4] = quat[..., 1:] * ratio[..., None]
    return q


class ConstraintProjector:
    """Pull poses back onto constraints that the modes keep only to first order.

    Residuals: the model's equality constraints (``efc_pos``), the world orientation of
    bodies named by ``orientation`` constraints and the world position of sites named by
    ``pin`` constraints (both relative to the rest pose). A few minimum-norm Gauss-Newton
    steps ``dq = -pinv(J) r`` per frame.
    """

    def __init__(
        self,
        model: mujoco.MjModel,
        rest_qpos: np.ndarray,
        constraints: Sequence[ExtraConstraint] = (),
        iterations: int = 4,
    ) -> None:
        self.model = model
        self.data = mujoco.MjData(model)
        self.iterations = int(iterations)
        self.orient: list[tuple[int, np.ndarray]] = []
        self.pins: list[tuple[int, np.ndarray]] = []
        self.data.qpos[:] = rest_qpos
        mujoco.mj_forward(model, self.data)
        for c in constraints:
            for name in c.names:
                if c.kind == "orientation":
                    b = model.body(name).id
                    self.orient.append((b, self.data.xquat[b].copy()))
                elif c.kind == "pin":
                    s = model.site(name).id
                    self.pins.append((s, self.data.site_xpos[s].copy()))
                else:
                    log.info("constraint %s is not projected (first-order only)", c.label)
        self.active = bool(self.orient or self.pins or model.neq)

    def _residual(self) -> tuple[np.ndarray, np.ndarray]:
        m, d = self.model, self.data
        rows, res = [], []
        nefc = int(d.nefc)
        if nefc:
            sel = np.asarray(d.efc_type[:nefc]) == mujoco.mjtConstraint.mjCNSTR_EQUALITY
            if sel.any():
                if mujoco.mj_isSparse(m):
                    J = np.zeros((nefc, m.nv))
                    for r in range(nefc):
                        a, n = int(d.efc_J_rowadr[r]), int(d.efc_J_rownnz[r])
                        J[r, d.efc_J_colind[a : a + n]] = d.efc_J[a : a + n]
                else:
                    J = np.array(d.efc_J[: nefc * m.nv]).reshape(nefc, m.nv)
                rows.append(J[sel])
                res.append(np.asarray(d.efc_pos[:nefc])[sel])
        for b, q0 in self.orient:
            jr = np.zeros((3, m.nv))
            mujoco.mj_jacBody(m, d, None, jr, b)
            err = np.zeros(3)
            # Rotation vector taking the rest orientation to the current one (world frame).
            mujoco.mju_subQuat(err, d.xquat[b], q0)  # q0 * exp(err) = q: err in q0's frame
            R = np.zeros(9)
            mujoco.mju_quat2Mat(R, q0)
            R = R.reshape(3, 3)
            rows.append(jr)
            res.append(R @ err)
        for s, p0 in self.pins:
            jp = np.zeros((3, m.nv))
            mujoco.mj_jacSite(m, d, jp, None, s)
            rows.append(jp)
            res.append(d.site_xpos[s] - p0)
        if not rows:
            return np.zeros((0, m.nv)), np.zeros(0)
        return np.vstack(rows), np.concatenate(res)

    def project(self, qpos: np.ndarray) -> tuple[np.ndarray, float]:
        """The projected pose and its remaining residual norm (m or rad)."""
        m, d = self.model, self.data
        q = np.array(qpos, dtype=np.float64, copy=True)
        d.qpos[:] = q
        mujoco.mj_forward(m, d)
        J, r = self._residual()
        for _ in range(self.iterations):
            if r.size == 0 or np.max(np.abs(r)) < 1e-10:
                break
            dq = -np.linalg.lstsq(J, r, rcond=1e-10)[0]
            mujoco.mj_integratePos(m, q, dq, 1.0)
            d.qpos[:] = q
            mujoco.mj_forward(m, d)
            J, r = self._residual()
        return q, float(np.max(np.abs(r))) if r.size else 0.0


@dataclass(frozen=True)
class Animation:
    """A joint trajectory."""

    times: np.ndarray
    """Frame times (T,), s."""
    qpos: np.ndarray
    """Poses (T, nq), MuJoCo generalized positions."""
    raw_displacement: np.ndarray
    """Equation 4's displacement before soft limits (T, nv)."""
    max_limit_overshoot_rad: float
    """Largest distance past a joint limit after the soft limits (rad or m)."""
    constraint_residual: float
    """Largest residual left after projection (0 when nothing was projected)."""


def displacement(components: Sequence[Component], times: np.ndarray, nv: int) -> np.ndarray:
    """sum_i alpha_i shape_i sin(2 pi f_i t + gamma_i) + beta_i shape_i  ->  (T, nv)."""
    t = np.asarray(times, dtype=np.float64)
    out = np.zeros((t.size, nv))
    for c in components:
        shape = np.asarray(c.shape, dtype=np.float64)
        if shape.shape != (nv,):
            raise InputError(f"component {c.label or c.mode} has shape {shape.shape}, need ({nv},)")
        for name in ("amplitude", "phase_rad", "freq_hz", "beta"):
            if not math.isfinite(getattr(c, name)):
                raise InputError(f"component {c.label or c.mode}: {name} must be finite")
        wave = c.amplitude * np.sin(2 * np.pi * c.freq_hz * t + c.phase_rad) + c.beta
        out += wave[:, None] * shape[None, :]
    return out


def animate(
    model: mujoco.MjModel,
    rest_qpos: np.ndarray,
    components: Sequence[Component],
    times: np.ndarray,
    limits: SoftLimits = SoftLimits(),
    projector: ConstraintProjector | None = None,
) -> Animation:
    """Equation 4 at ``times`` with soft limits (and constraint projection if given)."""
    times = np.asarray(times, dtype=np.float64)
    if times.ndim != 1 or not np.all(np.isfinite(times)):
        raise InputError("times must be a finite 1-D array")
    rest = np.asarray(rest_qpos, dtype=np.float64)
    dq = displacement(components, times, model.nv)
    qpos = np.empty((times.size, model.nq))
    for k in range(times.size):
        q = rest.copy()
        mujoco.mj_integratePos(model, q, dq[k], 1.0)
        qpos[k] = q
    qpos = apply_soft_limits(model, qpos, limits)
    residual = 0.0
    if projector is not None and projector.active:
        # a few Gauss-Newton steps per frame: show progress on long animations
        for k in tqdm(range(times.size), desc="projecting onto the constraints", unit="frame",
                      leave=False, disable=times.size < 1000):
            qpos[k], r = projector.project(qpos[k])
            residual = max(residual, r)
    return Animation(times, qpos, dq, limit_overshoot(model, qpos), residual)


def limit_overshoot(model: mujoco.MjModel, qpos: np.ndarray) -> float:
    """Largest distance past a hinge/slide limit in ``qpos`` (..., nq)."""
    worst = 0.0
    for j in range(model.njnt):
        if model.jnt_limited[j] and int(model.jnt_type[j]) in (
            mujoco.mjtJoint.mjJNT_HINGE, mujoco.mjtJoint.mjJNT_SLIDE
        ):
            x = np.asarray(qpos)[..., model.jnt_qposadr[j]]
            lo, hi = model.jnt_range[j]
            worst = max(worst, float(np.max(x - hi)), float(np.max(lo - x)))
    return max(worst, 0.0)


def save_trajectory(path: str, model: mujoco.MjModel, anim: Animation, **meta: np.ndarray) -> None:
    """The joint trajectory as ``.npz``: times, qpos, joint names and qpos addresses."""
    names = np.array([model.joint(j).name for j in range(model.njnt)])
    save_npz(
        path,
        schema=np.array("flapsim.modal.trajectory/1"),
        times=anim.times,
        qpos=anim.qpos,
        joint_names=names,
        joint_qposadr=np.array(model.jnt_qposadr, dtype=np.int64),
        **meta,
    )
