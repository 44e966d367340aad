"""Where the muscles' power goes in the water: the surface engine's work per segment, split
into the part that moves the body and the part that only stirs the water.

The water's force ``F`` on a polygon whose centre moves at ``v`` takes ``-F . v`` from the
swimmer. Written with the whole body's centre-of-mass velocity ``V`` as
``-F . v = -F . V - F . (v - V)``, the first term is what the force does against the body's
progress (negative where it pushes the body forwards: thrust) and the second is what the
segment pays for moving *relative to* the body: the slip of a paddle through the water, a
kick's up-and-down, the arm swept forwards in a recovery. For the arms (hands and
forearms) this is the Froude efficiency that Toussaint et al. (1988) measured on swimmers
(the useful part of the arms' power, 0.44-0.61 in the crawl): thrust power over the power
the arms put into the water. A body gliding without moving its limbs has no slip at all
(``tests/swim/test_budget.py``).

Only the surface engine's drag, lift and friction are counted (the wave-making part, under
1 N in the crawl, and buoyancy are not), sampled at the swim's recording rate.
"""

from __future__ import annotations

import math

import mujoco
import numpy as np

from flapsim.swim.model import SEGMENTS, Swimmer
from flapsim.swim.muscles import kind_of

#: the segments folded left/right into the groups reported, head to foot
GROUPS: tuple[str, ...] = ("head", "thorax", "abdomen", "pelvis", "upper_arm", "forearm",
                           "hand", "thigh", "shank", "foot")
#: the groups whose Froude efficiency is the arms' (the paddles of the crawl and the pull)
ARMS: tuple[str, ...] = ("forearm", "hand")
#: ... and the legs' (the breaststroke's kick, the crawl's flutter kick)
LEGS: tuple[str, ...] = ("shank", "foot")


def group_of(segment: str) -> str:
    """The reported group of a segment name (``hand_l`` -> ``hand``)."""
    return segment[:-2] if segment.endswith(("_l", "_r")) else segment


def water_work_rates(sw: Swimmer, d: mujoco.MjData | None = None,
                     scratch: mujoco.MjData | None = None, per_segment: bool = False
                     ) -> np.ndarray:
    """(len(GROUPS), 2) the power [W] each group gives the water at this instant: the total
    ``-sum F . v`` over its polygons and its part ``-sum F . V`` against the body's
    centre-of-mass velocity ``V`` (the slip is their difference); both velocities through
    the water's uniform flow. ``per_segment``: (len(SEGMENTS), 2) per segment instead, left
    and right apart (:func:`fold_segments` groups them).

    The kinematics are computed afresh from ``d``'s positions and velocities in
    ``scratch`` (an ``MjData`` of the same model; a new one if None), so that ``d`` itself,
    which the control layers read between steps, is not touched."""
    d = sw.data if d is None else d
    m = sw.model
    s = mujoco.MjData(m) if scratch is None else scratch
    s.time = d.time
    s.qpos[:] = d.qpos
    s.qvel[:] = d.qvel
    mujoco.mj_kinematics(m, s)
    mujoco.mj_comPos(m, s)
    mujoco.mj_comVel(m, s)
    d = s
    rep = sw.hydro.evaluate(d)
    pb = sw.polygons.body
    root = m.body_rootid[pb]
    # each polygon centre's velocity: cvel is (angular, linear) at the root's subtree com
    v = d.cvel[pb, 3:] + np.cross(d.cvel[pb, :3], rep.points - d.subtree_com[root])
    mujoco.mj_subtreeVel(m, d)
    # through the water: a uniform current (and the swimmer-induced flow) carries the body
    # without work; sources and vortices are not subtracted
    u = sw.flow.params[1:4]
    V = d.subtree_linvel[m.body_rootid[sw.body["pelvis"]]] - u
    F = rep.force
    total = -np.einsum("ij,ij->i", F, v - u)
    against = -(F @ V)
    if per_segment:
        out = np.zeros((len(SEGMENTS), 2))
        si = np.zeros(m.nbody, dtype=int)
        for i, name in enumerate(SEGMENTS):
            si[sw.body[name]] = i
        np.add.at(out[:, 0], si[pb], total)
        np.add.at(out[:, 1], si[pb], against)
        return out
    out = np.zeros((len(GROUPS), 2))
    gi = _group_index(sw)
    np.add.at(out[:, 0], gi[pb], total)
    np.add.at(out[:, 1], gi[pb], against)
    return out


def fold_segments(rates: np.ndarray) -> np.ndarray:
    """(..., len(GROUPS), 2) from per-segment (..., len(SEGMENTS), 2) rates: left and right
    added into their group."""
    r = np.asarray(rates, dtype=float)
    out = np.zeros(r.shape[:-2] + (len(GROUPS), r.shape[-1]))
    for i, name in enumerate(SEGMENTS):
        out[..., GROUPS.index(group_of(name)), :] += r[..., i, :]
    return out


def _group_index(sw: Swimmer) -> np.ndarray:
    """(nbody,) each body's row in :data:`GROUPS` (bodies that are no segment: row 0, and
    they carry no polygons)."""
    gi = np.zeros(sw.model.nbody, dtype=int)
    for name in SEGMENTS:
        gi[sw.body[name]] = GROUPS.index(group_of(name))
    return gi


def summarize(rates: np.ndarray) -> dict:
    """The budget's JSON from (n, len(GROUPS), 2) sampled :func:`water_work_rates`: per group
    the mean power into the water, its part against the progress and the slip [W]; the
    whole body's; and the arms' and the legs' Froude efficiency (None where they make no
    thrust)."""
    r = np.asarray(rates, dtype=float)
    if r.ndim != 3 or r.shape[1:] != (len(GROUPS), 2) or not len(r):
        raise ValueError(f"expected (n, {len(GROUPS)}, 2) sampled rates, got {r.shape}")
    mean = r.mean(axis=0)
    groups = {g: {"water_w": float(mean[i, 0]), "against_progress_w": float(mean[i, 1]),
                  "slip_w": float(mean[i, 0] - mean[i, 1])} for i, g in enumerate(GROUPS)}
    out = {"segments": groups, "water_w": float(mean[:, 0].sum()),
           "slip_w": float((mean[:, 0] - mean[:, 1]).sum())}
    for name, members in (("arms", ARMS), ("legs", LEGS)):
        rows = [GROUPS.index(g) for g in members]
        total = float(mean[rows, 0].sum())
        # the thrust power is minus the work against the progress
        thrust = -float(mean[rows, 1].sum())
        out[f"{name}_thrust_power_w"] = thrust
        out[f"{name}_water_w"] = total
        out[f"{name}_froude_efficiency"] = thrust / total if thrust > 0 and total > 0 else None
    out["samples"] = int(len(r))
    return out


def ideal_paddle(speed: float, drag: float, rate_hz: float, area: float, path: float,
                 cd: float = 1.2, density: float = 1025.0) -> dict:
    """The least power two drag-based paddles need to hold ``drag`` [N] at ``speed`` [m/s]:
    each arm pulls once a cycle (``rate_hz``), its paddle (``area`` [m^2] at drag
    coefficient ``cd``) moving straight backwards ``path`` [m] relative to the body at a
    constant slip ``u`` through the water [m/s], all its force along the swim (no sideways or
    vertical sweep, no recovery, quasi-steady). Its pull lasts ``path / (speed + u)``; the
    impulse of the two pulls, ``density cd area u^2 path / (speed + u)``, balances ``drag /
    rate_hz`` a cycle, which fixes ``u``; the arms then put ``drag (speed + u)`` into the
    water, a Froude efficiency of ``speed / (speed + u)``.

    Returns ``slip_m_s``, ``power_w``, ``froude_efficiency``, ``pull_s`` (each arm's) and
    ``pull_fraction`` (of the cycle)."""
    if not all(x > 0 and math.isfinite(x) for x in (speed, drag, rate_hz, area, path, cd,
                                                    density)):
        raise ValueError("ideal_paddle takes positive, finite numbers")
    k = drag / (rate_hz * density * cd * area * path)
    # u^2 = k (speed + u): the positive root
    u = 0.5 * (k + math.sqrt(k * k + 4.0 * k * speed))
    pull = path / (speed + u)
    return {"slip_m_s": u, "power_w": drag * (speed + u),
            "froude_efficiency": speed / (speed + u), "pull_s": pull,
            "pull_fraction": pull * rate_hz}


#: joint groups of the muscles' budget, each the muscle kinds
#: (:func:`flapsim.swim.muscles.kind_of`) in it
JOINT_GROUPS: dict[str, tuple[str, ...]] = {
    "shoulders": ("shoulder",), "elbows": ("elbow", "pronation"), "wrists": ("wrist",),
    "trunk_neck": ("lumbar", "thoracic", "neck"), "hips": ("hip",), "knees": ("knee",),
    "ankles": ("ankle", "inversion"),
}


def dof_groups(model: mujoco.MjModel) -> np.ndarray:
    """(nv - 6,) each joint dof's row in :data:`JOINT_GROUPS` (the free root's six dofs left
    out, as the power records do)."""
    names = list(JOINT_GROUPS)
    out = np.zeros(model.nv - 6, dtype=int)
    for k in range(6, model.nv):
        kind = kind_of(mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_JOINT,
                                         int(model.dof_jntid[k])))
        out[k - 6] = next(i for i, g in enumerate(names) if kind in JOINT_GROUPS[g])
    return out


def summarize_joints(joint_power: np.ndarray, groups: np.ndarray) -> dict:
    """Per joint group the mean net, positive and absorbed (negative) muscle power, the
    joint damping's share of the net and the joint limits' power [W], from (n, dofs, 4)
    samples (:func:`flapsim.swim.simulate.step_joint_powers`); and the totals."""
    jp = np.asarray(joint_power, dtype=float)
    if jp.ndim != 3 or jp.shape[2] != 4 or jp.shape[1] != len(groups) or not len(jp):
        raise ValueError(f"expected (n, {len(groups)}, 4) joint powers, got {jp.shape}")
    mean = jp.mean(axis=0)
    out: dict = {}
    for i, g in enumerate(JOINT_GROUPS):
        r = mean[groups == i].sum(axis=0)
        out[g] = {"net_w": float(r[0]), "positive_w": float(r[1]),
                  "negative_w": float(r[1] - r[0]), "damping_w": float(r[2]),
                  "limits_w": float(r[3])}
    tot = mean.sum(axis=0)
    return {"groups": out, "net_w": float(tot[0]), "positive_w": float(tot[1]),
            "negative_w": float(tot[1] - tot[0]), "limits_w": float(tot[3])}
