"""Automatic mode selection (Kry et al. 2009, section 4.3): heuristics A-G.

Every low-frequency vibration mode is scored by how much it moves the labelled parts of
the body in a locomotion-like way, using the labelled sites' Jacobians at the rest pose
(all features are linear in the mode shape ``phi = R N u``):

(``J`` below is a site's velocity Jacobian relative to the root body, the pelvis: the
velocity of the site minus that of a point riding on the pelvis at the same place, so a
feature measures leg motion and not whole-body rocking.)

* A alternating knee bend        ``(q_kneeL - q_kneeR) / 2``
* B alternating forward foot      ``x_fwd . (J_footL - J_footR) phi / 2``
* C alternating vertical foot     ``z . (J_footL - J_footR) phi / 2``
* D synchronous knee bend         ``(q_kneeL + q_kneeR) / 2``
* E synchronous vertical foot     ``z . (J_footL + J_footR) phi / 2``
* F front-leg bend (quadrupeds)   ``(q_elbowL - q_elbowR) / 2``
* G front-leg swing (quadrupeds)  ``x_fwd . (J_pawFL - J_pawFR) phi / 2``

For a quadruped the "feet" and "knees" of A-E are the hind legs. Three more features
(ours, used only by the gaits the paper composed by hand and to name rejected modes):

* H gather/stretch (quadrupeds)   hind feet forward while the front feet go back
* P bound (quadrupeds)            front feet up while the hind feet go down
* J leg spread (jumping jack)     ``y . (J_footL - J_footR) phi / 2``
* K arm raise (jumping jack)      ``z . (J_handL + J_handR) phi / 2``

Score: the feature of the mode shape scaled to unit strain energy
(``phi / sqrt(phi^T K phi)``), i.e. the displacement the mode gives per unit of energy:
the paper's reason to prefer low modes ("at a given energy level they involve larger
displacements"). Only the ``n_candidates`` lowest elastic modes compete. The sign of a
selected mode is flipped so that its feature is positive (left knee bends, left foot
goes forward/up), which fixes what the gait phases mean.

Labels (a naming convention; :func:`find_labels` reports what is missing):
sites ``foot_l``/``foot_r`` (biped) or ``paw_hl``/``paw_hr`` and ``paw_fl``/``paw_fr``
(quadruped), ``hand_l``/``hand_r``, ``head``; hinge joints ``knee_l``/``knee_r`` or
``knee_hl``/``knee_hr``, and ``elbow_l``/``elbow_r`` or ``elbow_fl``/``elbow_fr``,
positive in flexion. Forward is the root body's x axis at rest, up is world z.

Rejected modes: every candidate not selected is reported with the feature it is best at
relative to the other candidates; when that is a twist (spine roll/yaw between pelvis
and head), a jumping jack (J or K) or a sideways sway, it is named so.
"""

from __future__ import annotations

import logging
from collections.abc import Sequence
from dataclasses import dataclass

import mujoco
import numpy as np

from flapsim.core.errors import InputError, ModelError
from flapsim.modal.analysis import ModalAnalysis

log = logging.getLogger(__name__)

CATEGORY_NAMES: dict[str, str] = {
    "A": "alternating knee bend",
    "B": "alternating forward foot motion",
    "C": "alternating vertical foot motion",
    "D": "synchronous knee bend",
    "E": "synchronous vertical foot motion",
    "F": "front-leg bend",
    "G": "front-leg swing",
    "H": "gather/stretch (hind feet forward, front feet back)",
    "P": "bound (front feet up, hind feet down)",
    "J": "leg spread (jumping jack)",
    "K": "arm raise (jumping jack)",
}
PAPER_CATEGORIES = ("A", "B", "C", "D", "E", "F", "G")
_REJECT_FEATURES = {"twist": "twist of the spine", "sway": "sideways sway",
                    "J": "jumping jack (legs)", "K": "jumping jack (arms)"}


@dataclass(frozen=True)
class HeuristicParams:
    """Which modes compete."""

    n_candidates: int = 24
    """How many of the lowest elastic modes are scored; the paper's Fig. 3 picks modes up
    to index 24 (human) and 22 (dog), so ~24 low modes is the palette it drew from."""
    rigid_feature_m: float = 0.1
    """Size of a rigid-body component (the jump's bounce) at amplitude 1, m of its
    feature (ours: the paper does not state its normalisation)."""
    min_substitute_relative: float = 0.25
    """When a gait needs two categories in different phases and one mode tops both, the
    next best mode of the later category replaces it only if its feature is at least
    this fraction of the top mode's (ours: below a quarter, the gait would be the other
    gait with a faint trace of this one, so it is refused instead)."""


Point = tuple[int, tuple[float, float, float]]
"""A point riding on a body: (body id, position in the body's frame, m)."""


@dataclass(frozen=True)
class Labels:
    """The labelled parts of a creature, resolved to ids."""

    quadruped: bool
    """True when front feet are labelled."""
    feet: tuple[Point, Point]
    """The left and right (hind) feet."""
    knees: tuple[int, int]
    """Dof addresses of the left and right (hind) knee hinges."""
    front_feet: tuple[Point, Point] | None
    """The front feet (quadrupeds)."""
    elbows: tuple[int, int] | None
    """Dof addresses of the left/right elbows (front legs of a quadruped)."""
    hands: tuple[Point, Point] | None
    """The hands (bipeds)."""
    head_body: int | None
    """Body id of the head."""
    root_body: int
    """Body id of the floating root (the pelvis)."""
    forward: np.ndarray
    """Unit forward direction (world), from the root's x axis at rest."""
    knee_signs: tuple[float, float] = (1.0, 1.0)
    """+1 where the knee hinge's positive rotation is flexion, else -1."""
    elbow_signs: tuple[float, float] = (1.0, 1.0)
    """The same for the elbows."""
    foot_names: tuple[str, ...] = ()
    """Display names of the feet: left, right (hind), then front left, front right."""


def _site(model: mujoco.MjModel, name: str) -> int | None:
    i = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, name)
    return None if i < 0 else int(i)


def site_point(model: mujoco.MjModel, site: int) -> Point:
    """The site as a point riding on its body."""
    return int(model.site_bodyid[site]), tuple(float(v) for v in model.site_pos[site])


def point_world(data: mujoco.MjData, p: Point) -> np.ndarray:
    """World position of a body point."""
    b, local = p
    return data.xpos[b] + data.xmat[b].reshape(3, 3) @ np.asarray(local)


def _hinge_dof(model: mujoco.MjModel, name: str) -> int | None:
    j = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, name)
    if j < 0:
        return None
    if model.jnt_type[j] != mujoco.mjtJoint.mjJNT_HINGE:
        raise ModelError(f"joint {name!r} must be a hinge (flexion positive) for the heuristics")
    return int(model.jnt_dofadr[j])


def has_convention_labels(model: mujoco.MjModel) -> bool:
    """True when the model names its feet by the convention (foot_l/r or paw_hl/hr)."""
    return (_site(model, "foot_l") is not None and _site(model, "foot_r") is not None) or (
        _site(model, "paw_hl") is not None and _site(model, "paw_hr") is not None)


def find_labels(model: mujoco.MjModel, data: mujoco.MjData) -> Labels:
    """Resolve the naming convention (see the module docstring) on ``model``; ``data``
    holds the rest pose (after ``mj_forward``)."""
    quad = _site(model, "paw_fl") is not None and _site(model, "paw_fr") is not None
    if quad:
        feet = (_site(model, "paw_hl"), _site(model, "paw_hr"))
        knees = (_hinge_dof(model, "knee_hl"), _hinge_dof(model, "knee_hr"))
        elbows = (_hinge_dof(model, "elbow_fl"), _hinge_dof(model, "elbow_fr"))
        need = {"site paw_hl": feet[0], "site paw_hr": feet[1], "joint knee_hl": knees[0],
                "joint knee_hr": knees[1], "joint elbow_fl": elbows[0], "joint elbow_fr": elbows[1]}
    else:
        feet = (_site(model, "foot_l"), _site(model, "foot_r"))
        knees = (_hinge_dof(model, "knee_l"), _hinge_dof(model, "knee_r"))
        elbows = (_hinge_dof(model, "elbow_l"), _hinge_dof(model, "elbow_r"))
        need = {"site foot_l": feet[0], "site foot_r": feet[1], "joint knee_l": knees[0],
                "joint knee_r": knees[1]}
    missing = [k for k, v in need.items() if v is None]
    if missing:
        raise ModelError(
            f"the model lacks the labels the gait heuristics read: {', '.join(missing)}; "
            "name the feet sites foot_l/foot_r (or paw_hl/paw_hr/paw_fl/paw_fr for a "
            "quadruped) and the knee/elbow hinges knee_l/knee_r, elbow_l/elbow_r "
            "(or knee_hl/knee_hr, elbow_fl/elbow_fr), or let `flapsim animate MODEL.xml` "
            "find them from the kinematic tree"
        )
    hands = (_site(model, "hand_l"), _site(model, "hand_r"))
    head = _site(model, "head")
    # The root: the top body of the tree that carries the feet.
    root = int(model.site_bodyid[feet[0]])
    while model.body_parentid[root] != 0:
        root = int(model.body_parentid[root])
    fwd = np.array(data.xmat[root]).reshape(3, 3)[:, 0].copy()
    fwd[2] = 0.0
    if np.linalg.norm(fwd) < 1e-6:
        raise ModelError("the root body's x axis points straight up: cannot tell forward")
    front = (_site(model, "paw_fl"), _site(model, "paw_fr")) if quad else None
    return Labels(
        quadruped=quad,
        feet=(site_point(model, feet[0]), site_point(model, feet[1])),
        knees=(int(knees[0]), int(knees[1])),
        front_feet=(site_point(model, front[0]), site_point(model, front[1])) if quad else None,
        elbows=(int(elbows[0]), int(elbows[1])) if None not in elbows else None,
        hands=(site_point(model, hands[0]), site_point(model, hands[1]))
        if None not in hands else None,
        head_body=int(model.site_bodyid[head]) if head is not None else None,
        root_body=root,
        forward=fwd / np.linalg.norm(fwd),
        foot_names=("paw_hl", "paw_hr", "paw_fl", "paw_fr") if quad else ("foot_l", "foot_r"),
    )


def point_jacobian(model: mujoco.MjModel, data: mujoco.MjData, p: Point, root: int) -> np.ndarray:
    """Velocity Jacobian (3, nv) of a body point relative to a point riding rigidly on the
    root body: leg motion, not whole-body rocking (a free creature's low modes rock the
    whole body to keep its momentum zero, and with the head fixed the body swings about
    the head)."""
    nv = model.nv
    x = point_world(data, p)
    jp = np.zeros((3, nv))
    mujoco.mj_jac(model, data, jp, None, x, p[0])
    jroot = np.zeros((3, nv))
    mujoco.mj_jac(model, data, jroot, None, x, root)
    return jp - jroot


def feature_functionals(
    model: mujoco.MjModel, rest_qpos: np.ndarray, labels: Labels | None = None
) -> tuple[dict[str, np.ndarray], Labels]:
    """The linear functionals g (nv,) of every feature at the rest pose: feature = g . phi."""
    data = mujoco.MjData(model)
    data.qpos[:] = rest_qpos
    mujoco.mj_forward(model, data)
    lab = labels or find_labels(model, data)
    nv = model.nv
    up = np.array([0.0, 0.0, 1.0])
    fwd = lab.forward
    lat = np.cross(up, fwd)

    def jsite(p: Point) -> np.ndarray:
        return point_jacobian(model, data, p, lab.root_body)

    def unit(d: int, sign: float = 1.0) -> np.ndarray:
        e = np.zeros(nv)
        e[d] = sign
        return e

    jl, jr = jsite(lab.feet[0]), jsite(lab.feet[1])
    kl, kr = unit(lab.knees[0], lab.knee_signs[0]), unit(lab.knees[1], lab.knee_signs[1])
    g: dict[str, np.ndarray] = {
        "A": (kl - kr) / 2,
        "B": fwd @ (jl - jr) / 2,
        "C": up @ (jl - jr) / 2,
        "D": (kl + kr) / 2,
        "E": up @ (jl + jr) / 2,
        "J": lat @ (jl - jr) / 2,
        "sway": lat @ (jl + jr) / 2,
    }
    # World vertical motion of the root: what a rigid bounce (the paper's jumps) produces.
    jroot = np.zeros((3, nv))
    mujoco.mj_jacBody(model, data, jroot, None, lab.root_body)
    g["bounce"] = up @ jroot
    if lab.quadruped:
        fl, fr = jsite(lab.front_feet[0]), jsite(lab.front_feet[1])
        g["F"] = (unit(lab.elbows[0], lab.elbow_signs[0])
                  - unit(lab.elbows[1], lab.elbow_signs[1])) / 2
        g["G"] = fwd @ (fl - fr) / 2
        g["H"] = fwd @ ((jl + jr) - (fl + fr)) / 4
        g["P"] = up @ ((fl + fr) - (jl + jr)) / 4
        # A quadruped's jumping jack and sway involve all four legs.
        g["J"] = lat @ ((jl - jr) + (fl - fr)) / 4
        g["sway"] = lat @ (jl + jr + fl + fr) / 4
    if lab.hands is not None:
        hl, hr = jsite(lab.hands[0]), jsite(lab.hands[1])
        g["K"] = up @ (hl + hr) / 2
    if lab.head_body is not None:
        jh, jp = np.zeros((3, nv)), np.zeros((3, nv))
        mujoco.mj_jacBody(model, data, None, jh, lab.head_body)
        mujoco.mj_jacBody(model, data, None, jp, lab.root_body)
        # Twist: roll about the body axis and yaw of the head relative to the pelvis.
        rel = jh - jp
        g["twist"] = np.vstack([fwd @ rel, up @ rel])  # 2 rows: scored by their norm
    return g, lab


@dataclass(frozen=True)
class ModeScore:
    """One candidate mode and its features."""

    mode: int
    """Mode index (0-based, rigid modes first: the paper's numbering)."""
    freq_hz: float
    """Natural frequency, Hz."""
    features: dict[str, float]
    """Signed feature of the unit-energy shape, per category (m or rad per sqrt(J))."""
    relative: dict[str, float]
    """|feature| / (largest |feature| among the candidates), per category, in [0, 1]."""


@dataclass(frozen=True)
class Selection:
    """The heuristics' answer for one analysis."""

    scores: tuple[ModeScore, ...]
    """Every candidate, lowest frequency first."""
    best: dict[str, tuple[int, float]]
    """Per category: (mode index, sign) of the top-ranked mode; sign makes the feature > 0."""
    rejected: dict[int, str]
    """Candidates no category picked -> why (twist, jumping jack, sway, or weak)."""
    labels: Labels
    """The resolved labels."""
    functionals: dict[str, np.ndarray]
    """Feature functionals g (nv,) at the rest pose (twist: 2 x nv)."""

    def category_of(self, mode: int) -> list[str]:
        return [c for c, (m, _) in self.best.items() if m == mode]

    def ranked(self, category: str) -> list[tuple[int, float, float]]:
        """Candidates for ``category``, best first: (mode, sign, relative feature)."""
        out = [(s.mode, 1.0 if s.features[category] > 0 else -1.0, s.relative[category])
               for s in self.scores if category in s.features and s.features[category] != 0]
        return sorted(out, key=lambda x: -x[2])


def score_modes(
    analysis: ModalAnalysis,
    model: mujoco.MjModel,
    params: HeuristicParams = HeuristicParams(),
    categories: Sequence[str] | None = None,
    labels: Labels | None = None,
) -> Selection:
    """Score the lowest ``params.n_candidates`` elastic modes and pick the top mode of
    each category (``categories``: default all the model's labels support; ``labels``:
    default the naming convention)."""
    if params.n_candidates < 1:
        raise InputError("n_candidates must be >= 1")
    g, lab = feature_functionals(model, analysis.rest_qpos, labels)
    first = analysis.n_rigid
    cand = list(range(first, min(analysis.n_modes, first + params.n_candidates)))
    if not cand:
        raise ModelError("the analysis has no elastic modes to choose from")
    lam = np.asarray(analysis.eigenvalues)
    phis = np.asarray(analysis.shapes)[:, cand] / np.sqrt(lam[cand])  # unit strain energy
    feats: dict[str, np.ndarray] = {}
    for name, vec in g.items():
        val = vec @ phis
        feats[name] = np.linalg.norm(val, axis=0) if val.ndim == 2 else val
    rel = {}
    for name, val in feats.items():
        top = float(np.max(np.abs(val)))
        rel[name] = np.abs(val) / top if top > 0 else np.zeros_like(val)
    scores = tuple(
        ModeScore(
            mode=m,
            freq_hz=float(analysis.freqs_hz[m]),
            features={n: float(feats[n][k]) for n in feats},
            relative={n: float(rel[n][k]) for n in rel},
        )
        for k, m in enumerate(cand)
    )
    wanted = [c for c in (categories or CATEGORY_NAMES) if c in feats]
    best: dict[str, tuple[int, float]] = {}
    for c in wanted:
        k = int(np.argmax(np.abs(feats[c])))
        if abs(feats[c][k]) <= 0:
            continue
        best[c] = (cand[k], 1.0 if feats[c][k] > 0 else -1.0)
    # Only the locomotion categories (A-G) claim a mode here: the top jumping-jack or
    # gather modes are reported as rejected for locomotion (a gait that uses them, such
    # as the jumping jacks, drops them from its own rejected list: GaitPlan.rejected).
    used = {m for c, (m, _) in best.items() if c in PAPER_CATEGORIES}
    rejected: dict[int, str] = {}
    loco = [c for c in PAPER_CATEGORIES if c in rel]
    for k, m in enumerate(cand):
        if m in used:
            continue
        rivals = {c: rel[c][k] for c in loco}
        rivals.update({c: rel[c][k] for c in _REJECT_FEATURES if c in rel})
        top = max(rivals, key=rivals.get)
        if rivals[top] < 0.05:
            rejected[m] = "moves no labelled part much (below 5% of every leader)"
        elif top in _REJECT_FEATURES:
            rejected[m] = f"{_REJECT_FEATURES[top]} ({100 * rivals[top]:.0f}% of the strongest)"
        else:
            leader = best.get(top, (None,))[0]
            rejected[m] = (f"weaker {CATEGORY_NAMES[top]} ({100 * rivals[top]:.0f}% of mode "
                           f"{leader})")
    return Selection(scores, best, rejected, lab, g)


def rigid_component(
    analysis: ModalAnalysis, functional: np.ndarray, feature_m: float = 0.1
) -> np.ndarray | None:
    """The rigid-body motion (a combination of the rigid modes) that best produces a
    feature per unit kinetic energy, scaled so the feature equals ``feature_m``.

    Maximises ``(g . v)^2 / (v^T M v)`` over ``v`` in the rigid span: ``c ~ (R^T M R)^-1 R^T g``.
    Returns None when no rigid motion produces the feature (a pinned creature).
    """
    nr = analysis.n_rigid
    if nr == 0:
        return None
    R = np.asarray(analysis.shapes)[:, :nr]
    Mr = R.T @ np.asarray(analysis.mass_matrix) @ R
    c = np.linalg.solve(Mr, R.T @ functional)
    v = R @ c
    val = float(functional @ v)
    if val <= 1e-12 * max(np.linalg.norm(functional) * np.linalg.norm(v), 1e-300):
        return None
    return v * (feature_m / val)
