"""Stiffness tuning (Kry et al. 2009, sections 3 and 5.1): the smallest uniform scale of
the joint stiffness that lets the creature hold its rest pose under gravity.

The paper's "typical session": load the creature, "run a simulation to adjust the
stiffness of joints (typically a uniform scaling) such that the creature is sufficiently
stiff to support its own weight under gravity". Here: the creature starts at rest in its
rest pose, standing on the ground (MuJoCo contact), with joint springs about that pose
(``qpos_spring`` = the rest pose) and nothing else holding it: no actuators, no invisible
forces. A scale *holds* when, over ``seconds`` of simulation, no internal joint strays
more than ``tolerance_rad`` from its rest angle. Joint damping is scaled with the
stiffness (the models' damping is a fixed multiple of stiffness: Rayleigh-like). The
smallest holding scale is found by bisection on log(scale) between a failing and a
holding bracket (sagging decreases monotonically with stiffness for these creatures; a
non-monotonic case would only make the answer conservative, never wrong: the returned
scale was simulated and holds).
"""

from __future__ import annotations

import copy
import logging
import math
from dataclasses import dataclass

import mujoco
import numpy as np

from flapsim.core.errors import InputError, SimulationError
from flapsim.modal.analysis import rest_pose

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class TuningParams:
    """How the tuning simulation judges a stiffness scale."""

    seconds: float = 1.0
    """Simulated time per trial, s (the sag settles within a few of the lowest periods,
    ~1 Hz modes: 1 s catches the first sag and its overshoot)."""
    tolerance_rad: float = math.radians(10.0)
    """Largest allowed deviation of any internal joint from its rest angle, rad (ours:
    10 deg is a visibly held pose; the paper gives no number)."""
    lo: float = 1.0 / 64
    """Lower end of the search bracket (scale)."""
    hi: float = 64.0
    """Upper end of the search bracket (scale)."""
    rel_tol: float = 0.05
    """Bisection stops when hi/lo < 1 + rel_tol."""


@dataclass(frozen=True)
class Trial:
    """One simulated scale."""

    scale: float
    """Stiffness (and damping) multiplier."""
    max_dev_rad: float
    """Largest internal-joint deviation from rest over the trial, rad."""
    worst_joint: str
    """The joint that strayed most."""
    holds: bool
    """max_dev_rad <= tolerance."""


def sag(
    model: mujoco.MjModel,
    scale: float,
    *,
    keyframe: str | None = None,
    seconds: float = 1.0,
    qpos: np.ndarray | None = None,
) -> tuple[float, str]:
    """Simulate ``seconds`` from rest at stiffness ``scale``; return the largest internal
    joint deviation from the rest pose (rad) and that joint's name."""
    if not (scale > 0 and math.isfinite(scale)):
        raise InputError("stiffness scale must be a positive number")
    m = _copy(model)
    q0 = rest_pose(m, keyframe, qpos)
    m.qpos_spring[:] = q0
    m.jnt_stiffness[:] = model.jnt_stiffness * scale
    m.dof_damping[:] = model.dof_damping * scale
    d = mujoco.MjData(m)
    d.qpos[:] = q0
    mujoco.mj_forward(m, d)
    hinges = [j for j in range(m.njnt) if int(m.jnt_type[j]) in (
        mujoco.mjtJoint.mjJNT_HINGE, mujoco.mjtJoint.mjJNT_SLIDE)]
    adr = np.array([m.jnt_qposadr[j] for j in hinges], dtype=np.int64)
    worst = np.zeros(adr.size)
    steps = max(int(round(seconds / m.opt.timestep)), 1)
    for k in range(steps):
        mujoco.mj_step(m, d)
        if k % 10 == 0 or k == steps - 1:
            if not np.all(np.isfinite(d.qpos)):
                raise SimulationError(f"tuning simulation diverged at scale {scale:g}")
            np.maximum(worst, np.abs(d.qpos[adr] - q0[adr]), out=worst)
    i = int(np.argmax(worst)) if worst.size else 0
    name = m.joint(hinges[i]).name if hinges else ""
    return (float(worst[i]) if worst.size else 0.0), name


def _copy(model: mujoco.MjModel) -> mujoco.MjModel:
    return copy.deepcopy(model)


@dataclass(frozen=True)
class TuningResult:
    """The answer of :func:`tune_stiffness`."""

    scale: float
    """Smallest simulated scale that holds the pose."""
    failing_scale: float
    """Largest simulated scale that does not (the bracket's other end)."""
    trials: tuple[Trial, ...]
    """Every simulated scale, in order."""


def tune_stiffness(
    model: mujoco.MjModel, *, keyframe: str | None = None, params: TuningParams = TuningParams(),
    qpos: np.ndarray | None = None,
) -> TuningResult:
    """Bisect for the smallest uniform stiffness scale that holds the rest pose."""
    if not (0 < params.lo < params.hi):
        raise InputError("tuning bracket must satisfy 0 < lo < hi")
    trials: list[Trial] = []

    def trial(s: float) -> bool:
        dev, name = sag(model, s, keyframe=keyframe, seconds=params.seconds, qpos=qpos)
        ok = dev <= params.tolerance_rad
        trials.append(Trial(s, dev, name, ok))
        log.info("stiffness x%.4g: max deviation %.1f deg (%s) -> %s", s, math.degrees(dev),
                 name, "holds" if ok else "sags")
        return ok

    lo, hi = params.lo, params.hi
    if not trial(hi):
        raise SimulationError(
            f"even {hi:g} x the stiffness does not hold the rest pose within "
            f"{math.degrees(params.tolerance_rad):.0f} deg (the creature falls over or its "
            "pose is unbalanced); check the rest pose and the feet"
        )
    if trial(lo):
        return TuningResult(lo, float("nan"), tuple(trials))
    while hi / lo > 1 + params.rel_tol:
        mid = math.sqrt(lo * hi)
        if trial(mid):
            hi = mid
        else:
            lo = mid
    return TuningResult(hi, lo, tuple(trials))
