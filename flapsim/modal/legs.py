"""Legs found from the kinematic tree, for creatures that do not follow the naming
convention of :mod:`flapsim.modal.heuristics` (the paper's "typical session", sec. 5.1,
has the user label hands, feet, knees and elbows; here the tree says most of it).

* Feet: the leaf bodies of the root's subtree whose lowest geometry lies near the ground
  (within a quarter of the root's height above the lowest one); 2 make a biped, 4 a
  quadruped. The foot point is the lowest point of the leaf's geometry at rest.
* Sides: left is +y of the forward frame (forward = the root's x axis, up = world z);
  for a quadruped the two feet farther forward are the front ones.
* A leg: the bodies between the foot and the first body shared with another foot's
  chain. Its hip: the joints of its topmost jointed body. Its knee (elbow for a front
  leg): the hinge below the hip whose axis is most sideways (at least cos 45 deg), the
  one nearest the hip if several.
* Flexion sign (what the heuristics' knee features mean): positive moves a hind foot
  (a biped's foot) backwards and a front foot forwards, the convention of our dog and
  human (a dog's elbow points back, its stifle forward).

A TOML label file overrides any of it::

    [feet]        # body or site names
    left = "shin_a"            # biped: left/right; quadruped: hind_left, hind_right,
    right = "shin_b"           #   front_left, front_right
    [knees]       # hinge joint names ("-name": positive rotation is extension)
    left = "kn_a"
    [hands]
    left = "palm_a"
    right = "palm_b"
    head = "skull"             # body name
    forward = [1.0, 0.0, 0.0]  # world direction of travel (default the root's x axis)

Straight legs (:func:`leg_straightness`): a hinge or ball joint on the line from it to
the foot moves the foot only perpendicular to that line, so a vertical straight leg's
foot has no first-order vertical motion and the heuristics' C and E find nothing.
:func:`flexed_rest_pose` proposes the fix: each knee flexed by an angle, the hip turned
back about the sideways axis so the foot returns under it, the root lowered so the
lowest foot keeps its height.
"""

from __future__ import annotations

import math
import tomllib
from dataclasses import dataclass
from pathlib import Path

import mujoco
import numpy as np

from flapsim.core.errors import InputError, ModelError
from flapsim.core.validate import require_finite
from flapsim.modal.heuristics import Labels, Point, point_jacobian, point_world

UP = np.array([0.0, 0.0, 1.0])
FOOT_ROLES = {2: ("left", "right"), 4: ("hind_left", "hind_right", "front_left", "front_right")}
#: Feet are leaves within this fraction of the root's height above the lowest leaf.
FOOT_BAND = 0.25
#: A knee's axis must be at least this sideways (cos 45 deg).
KNEE_AXIS_MIN = math.cos(math.radians(45.0))
#: Legs count as straight when every shank leans less than 5 deg from the vertical
#: (tan 5 deg): the knee then moves the foot vertically by under 9 % of its fore-aft
#: motion; our dog's shanks lean 22 deg (front) and 32 deg (hind).
STRAIGHT_RATIO = math.tan(math.radians(5.0))


@dataclass(frozen=True)
class Leg:
    """One leg, found or labelled."""

    role: str
    """left/right (biped) or hind_left, hind_right, front_left, front_right."""
    foot_name: str
    """The body (or site) carrying the foot point."""
    foot: Point
    """The foot point."""
    knee: str | None
    """Knee (elbow) hinge joint name; None when the leg has none."""
    knee_sign: float
    """+1 when the hinge's positive rotation is flexion."""
    hip: tuple[str, ...]
    """Joints of the leg's topmost jointed body."""
    joints: tuple[str, ...]
    """Every joint of the leg, hip first."""


@dataclass(frozen=True)
class LegMap:
    """A creature's legs and the parts the heuristics read."""

    legs: tuple[Leg, ...]
    """Two (left, right) or four (hind left, hind right, front left, front right)."""
    root_body: int
    """The floating root's body id."""
    forward: np.ndarray
    """Unit forward direction, world."""
    hands: tuple[Point, Point] | None
    head_body: int | None
    source: dict[str, str]
    """Part -> 'tree' or 'label file'."""

    @property
    def quadruped(self) -> bool:
        return len(self.legs) == 4

    def to_dict(self, model: mujoco.MjModel) -> dict:
        return {
            "kind": "quadruped" if self.quadruped else "biped",
            "root": model.body(self.root_body).name,
            "forward": [float(v) for v in self.forward],
            "legs": {g.role: {"foot": g.foot_name, "knee": g.knee, "knee_sign": g.knee_sign,
                              "hip": list(g.hip), "joints": list(g.joints)} for g in self.legs},
            "source": dict(self.source),
        }


def _body_name(model: mujoco.MjModel, b: int) -> str:
    return model.body(b).name or f"body#{b}"


def find_root(model: mujoco.MjModel) -> int:
    """The floating root: a top-level body with a free joint, the heaviest if several."""
    tops = [b for b in range(1, model.nbody) if model.body_parentid[b] == 0]
    free = [b for b in tops if any(int(model.jnt_type[j]) == mujoco.mjtJoint.mjJNT_FREE
                                   for j in range(model.body_jntadr[b],
                                                  model.body_jntadr[b] + model.body_jntnum[b]))]
    pool = free or tops
    if not pool:
        raise ModelError("the model has no bodies: nothing walks")
    return max(pool, key=lambda b: float(model.body_subtreemass[b]))


def _lowest_point(model: mujoco.MjModel, data: mujoco.MjData, b: int) -> np.ndarray | None:
    """The lowest point (world) of a body's geometry at the current pose."""
    best: np.ndarray | None = None
    for g in range(model.ngeom):
        if model.geom_bodyid[g] != b:
            continue
        c = data.geom_xpos[g].copy()
        R = data.geom_xmat[g].reshape(3, 3)
        size = model.geom_size[g]
        kind = int(model.geom_type[g])
        if kind == mujoco.mjtGeom.mjGEOM_SPHERE:
            p = c - UP * size[0]
        elif kind in (mujoco.mjtGeom.mjGEOM_CAPSULE, mujoco.mjtGeom.mjGEOM_CYLINDER):
            ends = [c + R[:, 2] * size[1], c - R[:, 2] * size[1]]
            low = min(ends, key=lambda e: e[2])
            r = size[0] if kind == mujoco.mjtGeom.mjGEOM_CAPSULE else 0.0
            p = low - UP * r
        elif kind == mujoco.mjtGeom.mjGEOM_BOX:
            p = c - UP * float(np.abs(R[2, :]) @ size)
        else:
            p = c - UP * float(model.geom_rbound[g])
        if best is None or p[2] < best[2]:
            best = p
    return best


def _ancestors(model: mujoco.MjModel, b: int, root: int) -> list[int]:
    """Bodies from ``b`` up to (excluding) ``root``; empty if ``b`` is not below it."""
    out = []
    while b != root:
        if b == 0:
            return []
        out.append(b)
        b = int(model.body_parentid[b])
    return out


def _joints_of(model: mujoco.MjModel, b: int) -> list[int]:
    return list(range(model.body_jntadr[b], model.body_jntadr[b] + model.body_jntnum[b]))


def _forward(model: mujoco.MjModel, data: mujoco.MjData, root: int) -> np.ndarray:
    fwd = data.xmat[root].reshape(3, 3)[:, 0].copy()
    fwd[2] = 0.0
    if np.linalg.norm(fwd) < 1e-6:
        raise ModelError("the root body's x axis points straight up, so forward is unknown: "
                         "give forward = [x, y, z] in a label file (--labels FILE)")
    return fwd / np.linalg.norm(fwd)


def _resolve_point(model: mujoco.MjModel, data: mujoco.MjData, name: str,
                   what: str) -> tuple[int, Point]:
    s = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, name)
    if s >= 0:
        return int(model.site_bodyid[s]), (int(model.site_bodyid[s]),
                                           tuple(float(v) for v in model.site_pos[s]))
    b = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, name)
    if b < 0:
        raise InputError(f"label file: {what} {name!r} is neither a site nor a body of the model")
    low = _lowest_point(model, data, b)
    world = data.xpos[b].copy() if low is None else low
    local = data.xmat[b].reshape(3, 3).T @ (world - data.xpos[b])
    return int(b), (int(b), tuple(float(v) for v in local))


def read_label_file(path: str | Path) -> dict:
    """The TOML label file as a dict (see the module docstring)."""
    p = Path(path)
    if not p.exists():
        raise InputError(f"label file {str(p)!r} does not exist")
    try:
        with p.open("rb") as f:
            data = tomllib.load(f)
    except tomllib.TOMLDecodeError as e:
        raise InputError(f"label file {str(p)!r} is not valid TOML: {e}") from None
    require_finite(data, f"label file {str(p)!r}")
    known = {"feet", "knees", "hands", "head", "forward"}
    unknown = set(data) - known
    if unknown:
        raise InputError(f"label file {str(p)!r}: unknown keys {sorted(unknown)}; "
                         f"known: {sorted(known)}")
    return data


def find_legs(model: mujoco.MjModel, qpos: np.ndarray, overrides: dict | None = None) -> LegMap:
    """Legs, knees, hips, hands and head of ``model`` at pose ``qpos`` (see the module
    docstring); ``overrides`` is a label file's content."""
    ov = overrides or {}
    data = mujoco.MjData(model)
    data.qpos[:] = qpos
    mujoco.mj_forward(model, data)
    root = find_root(model)
    source: dict[str, str] = {}
    if "forward" in ov:
        f = np.asarray(ov["forward"], dtype=np.float64)
        if f.shape != (3,) or not np.all(np.isfinite(f)) or np.linalg.norm(f[:2]) < 1e-9:
            raise InputError("label file: forward must be three numbers, not vertical")
        fwd = np.array([f[0], f[1], 0.0]) / np.linalg.norm(f[:2])
        source["forward"] = "label file"
    else:
        fwd = _forward(model, data, root)
        source["forward"] = "tree"
    lat = np.cross(UP, fwd)

    # -- feet ------------------------------------------------------------------------
    feet_ov = ov.get("feet", {})
    if feet_ov:
        if len(feet_ov) not in FOOT_ROLES or set(feet_ov) != set(FOOT_ROLES[len(feet_ov)]):
            raise InputError("label file: [feet] must name left, right (a biped) or "
                             "hind_left, hind_right, front_left, front_right (a quadruped)")
        feet = {role: _resolve_point(model, data, name, f"foot {role}")
                for role, name in feet_ov.items()}
        names = dict(feet_ov)
        source["feet"] = "label file"
    else:
        leaves = [b for b in range(1, model.nbody)
                  if _ancestors(model, b, root) or b == root]
        leaves = [b for b in leaves if not any(model.body_parentid[c] == b
                                               for c in range(1, model.nbody))]
        lows = {b: _lowest_point(model, data, b) for b in leaves}
        lows = {b: p for b, p in lows.items() if p is not None}
        if not lows:
            raise ModelError("the model's leaf bodies have no geometry: no feet to find; "
                             "label them in a TOML file (--labels FILE)")
        ground = min(p[2] for p in lows.values())
        height = float(data.xpos[root][2]) - ground
        if height <= 0:
            raise ModelError("the root is not above the lowest leaf, so feet cannot be told "
                             "from the rest: label them in a TOML file (--labels FILE)")
        cand = sorted(b for b, p in lows.items() if p[2] <= ground + FOOT_BAND * height)
        if len(cand) not in FOOT_ROLES:
            raise ModelError(
                f"found {len(cand)} end effectors near the ground "
                f"({', '.join(_body_name(model, b) for b in cand)}); a biped needs 2 and a "
                "quadruped 4: label the feet in a TOML file (--labels FILE, [feet])")
        rel = {b: lows[b] - data.xpos[root] for b in cand}
        if len(cand) == 2:
            left, right = sorted(cand, key=lambda b: -float(rel[b] @ lat))
            order = {"left": left, "right": right}
        else:
            by_fwd = sorted(cand, key=lambda b: float(rel[b] @ fwd))
            hind, front = by_fwd[:2], by_fwd[2:]
            hl, hr = sorted(hind, key=lambda b: -float(rel[b] @ lat))
            fl, fr = sorted(front, key=lambda b: -float(rel[b] @ lat))
            order = {"hind_left": hl, "hind_right": hr, "front_left": fl, "front_right": fr}
        for b in order.values():
            if abs(float(rel[b] @ lat)) < 1e-3 * height:
                raise ModelError(
                    f"foot {_body_name(model, b)} lies on the midline, so left and right "
                    "cannot be told apart: label the feet in a TOML file (--labels FILE)")
        feet = {}
        for role, b in order.items():
            local = data.xmat[b].reshape(3, 3).T @ (lows[b] - data.xpos[b])
            feet[role] = (b, (b, tuple(float(v) for v in local)))
        names = {role: _body_name(model, b) for role, b in order.items()}
        source["feet"] = "tree"
    roles = FOOT_ROLES[len(feet)]

    # -- legs: the bodies from each foot up to the first one shared with another foot ----
    chains = {role: _ancestors(model, feet[role][0], root) for role in roles}
    for role, ch in chains.items():
        if not ch:
            raise ModelError(f"foot {names[role]} is not below the root body "
                             f"{_body_name(model, root)}: label the feet (--labels FILE)")
    knees_ov = ov.get("knees", {})
    unknown = set(knees_ov) - set(roles)
    if unknown:
        raise InputError(f"label file: [knees] has {sorted(unknown)}; use {', '.join(roles)}")
    legs = []
    for role in roles:
        others = {b for r, ch in chains.items() if r != role for b in ch}
        leg = [b for b in chains[role] if b not in others]  # foot first
        jointed = [b for b in leg if model.body_jntnum[b] > 0]
        if not jointed:
            raise ModelError(f"the {role.replace('_', ' ')} leg (foot {names[role]}) has no "
                             "joint of its own: a leg needs a hip and a knee")
        hip_body = jointed[-1]
        hip = tuple(model.joint(j).name for j in _joints_of(model, hip_body))
        joints = tuple(model.joint(j).name for b in reversed(jointed) for j in _joints_of(model, b))
        front = role.startswith("front")
        if role in knees_ov:
            name = str(knees_ov[role])
            sign = -1.0 if name.startswith("-") else 1.0
            name = name.lstrip("-")
            j = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, name)
            if j < 0 or int(model.jnt_type[j]) != mujoco.mjtJoint.mjJNT_HINGE:
                raise InputError(f"label file: knee {role} {name!r} is not a hinge joint")
            knee: str | None = name
            source[f"knee {role}"] = "label file"
        else:
            knee, sign = None, 1.0
            best = 0.0
            for b in reversed(jointed[:-1]):  # nearest the hip first
                for j in _joints_of(model, b):
                    if int(model.jnt_type[j]) != mujoco.mjtJoint.mjJNT_HINGE:
                        continue
                    side = abs(float(data.xaxis[j] @ lat))
                    if side >= KNEE_AXIS_MIN and side > best + 1e-9:
                        knee, best = model.joint(j).name, side
                if knee is not None:
                    break
            if knee is not None:
                sign = _flexion_sign(model, data, knee, feet[role][1], root, fwd, front)
            source[f"knee {role}"] = "tree"
        legs.append(Leg(role, names[role], feet[role][1], knee, sign, hip, joints))

    hands: tuple[Point, Point] | None = None
    if "hands" in ov:
        h = ov["hands"]
        if set(h) != {"left", "right"}:
            raise InputError("label file: [hands] must name left and right")
        hands = (_resolve_point(model, data, h["left"], "hand left")[1],
                 _resolve_point(model, data, h["right"], "hand right")[1])
        source["hands"] = "label file"
    head = None
    if "head" in ov:
        head = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, str(ov["head"]))
        if head < 0:
            raise InputError(f"label file: head {ov['head']!r} is not a body of the model")
        source["head"] = "label file"
    return LegMap(tuple(legs), root, fwd, hands, head, source)


def _flexion_sign(model, data, knee: str, foot: Point, root: int, fwd: np.ndarray,
                  front: bool) -> float:
    dof = int(model.jnt_dofadr[model.joint(knee).id])
    J = point_jacobian(model, data, foot, root)
    along = float(fwd @ J[:, dof])
    sign = -1.0 if along > 0 else 1.0  # a hind foot goes back when the knee flexes
    return -sign if front else sign


def labels_from_legs(model: mujoco.MjModel, legs: LegMap) -> Labels:
    """The heuristics' labels from a leg map; refuses a leg without a knee."""
    no_knee = [g.role.replace("_", " ") for g in legs.legs if g.knee is None]
    if no_knee:
        raise ModelError(
            f"no knee found on the {', '.join(no_knee)} leg(s): the heuristics need a hinge "
            "below each hip whose axis is sideways; name it in a TOML label file "
            "([knees] ..., --labels FILE)")

    def dof(name: str) -> int:
        return int(model.jnt_dofadr[model.joint(name).id])

    g = legs.legs
    quad = legs.quadruped
    return Labels(
        quadruped=quad,
        feet=(g[0].foot, g[1].foot),
        knees=(dof(g[0].knee), dof(g[1].knee)),
        front_feet=(g[2].foot, g[3].foot) if quad else None,
        elbows=(dof(g[2].knee), dof(g[3].knee)) if quad else None,
        hands=legs.hands,
        head_body=legs.head_body,
        root_body=legs.root_body,
        forward=legs.forward,
        knee_signs=(g[0].knee_sign, g[1].knee_sign),
        elbow_signs=(g[2].knee_sign, g[3].knee_sign) if quad else (1.0, 1.0),
        foot_names=tuple(x.role for x in g),
    )


def leg_straightness(model: mujoco.MjModel, qpos: np.ndarray, legs: LegMap) -> float:
    """Largest ratio, over the legs, of vertical to fore-aft motion of the point below
    the knee (the next joint down the leg, else the foot) per unit knee rotation:
    ``tan`` of the shank's lean from the vertical, 0 for a straight vertical leg."""
    data = mujoco.MjData(model)
    data.qpos[:] = qpos
    mujoco.mj_forward(model, data)
    worst = 0.0
    for g in legs.legs:
        if g.knee is None:
            continue
        kj = model.joint(g.knee).id
        kbody = int(model.jnt_bodyid[kj])
        below = [b for b in _ancestors(model, g.foot[0], kbody) if model.body_jntnum[b] > 0]
        point: Point = (below[-1], (0.0, 0.0, 0.0)) if below else g.foot
        J = point_jacobian(model, data, point, legs.root_body)[:, int(model.jnt_dofadr[kj])]
        worst = max(worst, abs(float(J[2])) / max(abs(float(legs.forward @ J)), 1e-12))
    return worst


def _leg_dofs(model: mujoco.MjModel, leg: Leg) -> list[int]:
    out = []
    for name in leg.joints:
        j = model.joint(name).id
        n = {0: 6, 1: 3, 2: 1, 3: 1}[int(model.jnt_type[j])]
        out += list(range(int(model.jnt_dofadr[j]), int(model.jnt_dofadr[j]) + n))
    return out


def flexed_rest_pose(model: mujoco.MjModel, qpos: np.ndarray, legs: LegMap,
                     knee_deg: float) -> np.ndarray:
    """``qpos`` with every knee flexed by ``knee_deg``, each hip turned so its foot comes
    back under it (fore-aft), and the root lowered so the lowest foot keeps its height."""
    if not (math.isfinite(knee_deg) and 0 < knee_deg < 90):
        raise InputError(f"knee flexion must be between 0 and 90 deg, got {knee_deg}")
    data = mujoco.MjData(model)
    q = np.array(qpos, dtype=np.float64)
    data.qpos[:] = q
    mujoco.mj_forward(model, data)
    ground = min(point_world(data, g.foot)[2] for g in legs.legs)
    start = {g.role: point_world(data, g.foot) - data.xpos[legs.root_body] for g in legs.legs}
    dq = np.zeros(model.nv)
    for g in legs.legs:
        if g.knee is None:
            continue
        dq[int(model.jnt_dofadr[model.joint(g.knee).id])] = g.knee_sign * math.radians(knee_deg)
    mujoco.mj_integratePos(model, q, dq, 1.0)
    # The hips bring the feet back under them (fore-aft only): a few Gauss-Newton steps.
    for _ in range(6):
        data.qpos[:] = q
        mujoco.mj_forward(model, data)
        step = np.zeros(model.nv)
        for g in legs.legs:
            hip_dofs = _leg_dofs(model, Leg(g.role, g.foot_name, g.foot, None, 1.0, g.hip, g.hip))
            if not hip_dofs:
                continue
            now = point_world(data, g.foot) - data.xpos[legs.root_body]
            err = float(legs.forward @ (now - start[g.role]))
            J = (legs.forward @ point_jacobian(model, data, g.foot, legs.root_body))[hip_dofs]
            if float(J @ J) < 1e-12:
                continue
            step[hip_dofs] = -err * J / float(J @ J)
        if np.max(np.abs(step)) < 1e-10:
            break
        mujoco.mj_integratePos(model, q, step, 1.0)
    data.qpos[:] = q
    mujoco.mj_forward(model, data)
    drop = min(point_world(data, g.foot)[2] for g in legs.legs) - ground
    root_jnt = [j for j in _joints_of(model, legs.root_body)
                if int(model.jnt_type[j]) == mujoco.mjtJoint.mjJNT_FREE]
    if root_jnt:
        q[int(model.jnt_qposadr[root_jnt[0]]) + 2] -= drop
    return q
