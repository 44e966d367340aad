"""The gaits of the paper's Fig. 3 for the dog and the human, as heuristic recipes.

A gait names, per term, a heuristic category (A-G of section 4.3, or our H, P, J, K for
the gaits the paper composed by hand), an amplitude, a phase (a multiple of 90 degrees
where the paper used heuristics), a frequency and a posture offset beta. The mode for
each term is whatever the heuristics rank first on the analysed model; a mode that tops
several categories is used once (by the first term naming it) and the others are
reported as merged into it. ``bounce`` is the rigid vertical motion the paper's jumps use
(its alpha_4, a rigid mode).

Phase conventions (they follow from the heuristics' signs: left knee bends, left foot
goes forward/up for a positive feature): a swing (B, G) at 0 deg, the same side's knee
bend and foot lift a quarter cycle later (90 deg: they peak mid-swing). A term's
``sign`` = -1 takes the mode with the right side leading instead.

Trot: hind-left with front-right (G, F with sign -1, same phases as B, A). Amble (a
lateral-sequence four-beat gait): each front foot a quarter cycle behind the hind foot of
its side, so G(right) at 90 deg and F(left) at 0 deg. The paper's amplitudes are in its
own unstated normalisation; ours multiply shapes normalised so their largest rotation,
the floating root's included, is 1 rad (:func:`rotation_normalized_shape`), so equal
numbers are not equal motions. The hand-composed gallop and jumping jacks keep the
paper's phases and frequencies; their amplitudes are ours (the paper's a6 = 1 on our
dog's first mode pitches the trunk by 1 rad), and the jumping jack's beta is +0.3 where
the paper's is -0.3: our leg-spread sign is fixed (positive = legs apart), theirs is not
stated, and -0.3 would cross the legs.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass, field, replace
from pathlib import Path

import mujoco
import numpy as np

from flapsim.core.assets import asset_path
from flapsim.core.errors import InputError
from flapsim.core.loading import load_model
from flapsim.modal.analysis import (
    ExtraConstraint,
    ModalAnalysis,
    analyze,
    fix_body_orientation,
    parse_constraint,
)
from flapsim.modal.animate import Component
from flapsim.modal.heuristics import (
    CATEGORY_NAMES,
    HeuristicParams,
    Labels,
    Selection,
    rigid_component,
    score_modes,
)
from flapsim.modal.own import GaitFile

log = logging.getLogger(__name__)

MODELS = {"dog": "dog.xml", "human": "human.xml", "human_cart": "human_cart.xml"}


@dataclass(frozen=True)
class GaitTerm:
    """One mode of a gait, chosen by category."""

    category: str
    """Heuristic category (A-G, H, P, J, K) or 'bounce' (rigid vertical motion)."""
    amplitude: float
    """alpha (shape with largest rotation 1 rad; for 'bounce', units of 0.1 m of root
    vertical motion)."""
    phase_deg: float
    """gamma, degrees."""
    freq_hz: float = 2.0
    """f~, Hz (paper Fig. 3: 2 Hz; the jumping jack's spread modes 1 Hz)."""
    beta: float = 0.0
    """Posture offset along the same shape."""
    sign: float = 1.0
    """+1: the left side leads (the heuristics' sign); -1: the right side."""
    distinct: bool = True
    """False for a companion term (a vertical foot motion C or E, the gallop's H): when
    its top mode is already used by an earlier term, that mode stands for it. A
    distinct term whose top mode an earlier term plays at another phase or sign takes
    the next best mode of its category instead (or the gait is refused): merging it
    would silently turn the gait into another (an amble into a trot)."""


@dataclass(frozen=True)
class Gait:
    """A gait recipe for one bundled creature."""

    name: str
    """Name on the command line."""
    model: str
    """Bundled model: 'dog', 'human' or 'human_cart'."""
    keyframe: str | None
    """Rest pose keyframe (None: the model's zero pose / spring reference)."""
    terms: tuple[GaitTerm, ...]
    """The modes, in priority order (earlier terms win a shared mode)."""
    selection: str
    """How the paper chose the modes: 'heuristics' or 'by hand' (then the terms are our
    recipe with the extra categories H, P, J, K)."""
    paper: str
    """The paper's Fig. 3 parameters, for the report."""
    stiffness: float | None = None
    """Uniform stiffness override, N m/rad (the head-constrained run: 100 uniform)."""
    constraints: tuple[str, ...] = ()
    """Extra constraints: 'orient:BODY' (the model's equalities always apply)."""
    description: str = ""
    """One line for the listing."""
    kind: str = field(default="biped")
    """'biped' or 'quadruped' (which labels the heuristics need)."""


def _t(cat, amp, ph, f=2.0, beta=0.0, sign=1.0, distinct=None) -> GaitTerm:
    return GaitTerm(cat, amp, ph, f, beta, sign,
                    cat not in ("C", "E") if distinct is None else distinct)


WALK = (_t("B", 0.5, 0), _t("A", 0.76, 90), _t("C", 0.5, 90))
RUN = (_t("B", 0.5, 0), _t("A", 0.5, 90), _t("C", 0.75, 90))
JUMP = (_t("bounce", 0.75, 0), _t("D", 0.75, 180), _t("E", 0.75, 180))

GAITS: dict[str, Gait] = {
    g.name: g
    for g in (
        Gait("trot", "dog", None,
             (_t("B", 0.5, 0), _t("G", 0.5, 0, sign=-1), _t("A", 0.5, 90), _t("F", 0.5, 90, sign=-1)),
             "heuristics", "a9=.5 g0, a11=.5 g0, a19=.5 g90, a21=.5 g90, 2 Hz",
             description="diagonal pairs: hind-left with front-right", kind="quadruped"),
        Gait("amble", "dog", None,
             (_t("B", 0.5, 0), _t("G", 0.5, 90, sign=-1), _t("A", 0.3, 90), _t("F", 0.1, 0)),
             "heuristics", "a10=.5 g0, a11=.1 g0, a19=.5 g90, a21=.3 g90, 2 Hz",
             description="lateral four-beat: each front foot a quarter cycle after its hind foot",
             kind="quadruped"),
        Gait("gallop", "dog", None,
             (_t("bounce", 0.2, 0), _t("P", 0.3, 90), _t("H", 0.3, 0, distinct=False), _t("B", 0.2, 90),
              _t("G", 0.2, 90, sign=-1)),
             "by hand", "a4=.2 g0, a6=1 g90, a8=1 g0, a10=.2 g90, a11=.7 g90, a22=1 g90, 2 Hz",
             description="bound (P) and gather/stretch (H) in quadrature, a small left lead",
             kind="quadruped"),
        Gait("walk", "human", "tpose", WALK, "heuristics", "a6=.5 g0, a17=.76 g90, 2 Hz (T-pose)",
             description="T-pose walk"),
        Gait("run", "human", "run", RUN, "heuristics", "a6=.5 g0, a13=.5 g90, a15=.75 g90, 2 Hz",
             description="run from the bent-knee, bent-elbow rest pose"),
        Gait("jump", "human", "run", JUMP, "heuristics",
             "a4=.75 g0, a16=.75 g0, a24=.75 g0, 2 Hz",
             description="bounce (rigid) with synchronous knee bend and foot lift"),
        Gait("jumping_jacks", "human", "tpose",
             (_t("bounce", 0.75, 0), _t("D", 0.3, 180), _t("J", 0.3, 45, 1.0, beta=0.3),
              _t("K", 0.95, 45, 1.0)),
             "by hand", "a4=.75 g0 2Hz, a7=.35 g.79 1Hz b7=-.3, a10=.95 g.79 1Hz, a16, a24=.75 g0 2Hz",
             description="jump plus leg spread (J) and arm raise (K) at half the rate"),
        Gait("run_head", "human", "run", (_t("B", 0.5, 0), _t("A", 0.5, 90), _t("C", 0.5, 90)),
             "heuristics", "44 DOF, 100 uniform, head: a5=.5 g0, a7=.5 g0, a13=.5 g90, a14=.5 g90",
             stiffness=100.0, constraints=("orient:head",),
             description="run with the head orientation held fixed (44 DOF, uniform stiffness)"),
        Gait("push_cart", "human_cart", "push", (_t("B", 0.5, 0), _t("A", 0.5, 90), _t("C", 0.5, 90)),
             "heuristics", "42 DOF, hands: a2=.5 g0, a9=.5 g90, a10=.5 g90",
             description="walk with both hands tied to a cart handle (closed loop, 42 DOF)"),
    )
}


def gait(name: str) -> Gait:
    if name not in GAITS:
        raise InputError(f"unknown gait {name!r}; choose one of {', '.join(GAITS)}")
    return GAITS[name]


def model_file(spec: str) -> Path:
    """The MJCF file of 'dog', 'human', 'human_cart' (bundled) or of a path to one."""
    if spec in MODELS:
        return Path(asset_path("creatures", MODELS[spec]))
    path = Path(spec)
    if not path.exists():
        raise InputError(
            f"--model {spec!r} is neither a bundled creature ({', '.join(MODELS)}) nor an "
            "existing MJCF file"
        )
    return path


def resolve_model(spec: str) -> tuple[mujoco.MjModel, str]:
    """'dog', 'human', 'human_cart' (bundled) or a path to an MJCF file."""
    return load_model(model_file(spec)), (spec if spec in MODELS else Path(spec).stem)


def build_constraints(specs: tuple[str, ...]) -> list[ExtraConstraint]:
    out = []
    for s in specs:
        c = parse_constraint(s)
        out.append(fix_body_orientation(c.names[0]) if c.kind == "orientation" else c)
    return out


@dataclass(frozen=True)
class GaitPlan:
    """A gait resolved on a model: analysis, heuristics and the chosen components."""

    gait: Gait
    analysis: ModalAnalysis
    selection: Selection
    components: tuple[Component, ...]
    chosen: tuple[dict, ...]
    """Per used term: mode, categories, frequency, amplitude, phase, beta, sign."""
    merged: dict[str, int]
    """Category -> mode for terms whose mode an earlier term already used."""
    constraints: tuple[ExtraConstraint, ...]
    substituted: dict[str, dict] = field(default_factory=dict)
    """Category -> {top_mode, mode, relative}: a distinct term whose top mode an earlier
    term already played at another phase or sign, and the next best mode it took."""

    def rejected(self) -> dict[int, str]:
        """Candidate modes this gait does not use -> why the heuristics passed them over."""
        used = {c["mode"] for c in self.chosen}
        return {m: why for m, why in self.selection.rejected.items() if m not in used}


_FEATURE_WHAT = {
    "A": "alternating knee bend", "B": "fore-aft foot motion", "C": "vertical foot motion",
    "D": "knee bend", "E": "vertical foot motion", "F": "front-leg bend",
    "G": "fore-aft front-foot motion", "H": "fore-aft foot motion", "P": "vertical foot motion",
    "J": "sideways foot motion", "K": "vertical hand motion",
}


def _missing_reason(sel: Selection, cat: str, kind: str) -> str:
    """Why no mode serves ``cat``: a label is absent, or no low mode moves the feature."""
    if cat not in sel.functionals:
        parts = {"F": "front-leg elbows", "G": "front feet", "H": "front feet",
                 "P": "front feet", "K": "hands"}.get(cat, "feet and knees")
        return (f"{cat} ({CATEGORY_NAMES[cat]}) needs {parts}, which this {kind}'s labels "
                "do not give: label them (a TOML label file) or pick another gait")
    if cat in ("C", "E", "P"):
        return (f"{cat} ({CATEGORY_NAMES[cat]}): no low mode moves the feet vertically; "
                "straight legs give the feet no first-order vertical motion: flex the knees "
                "in the rest pose (springref, or `flapsim animate MODEL.xml` proposes it)")
    return (f"{cat} ({CATEGORY_NAMES[cat]}): no low mode produces any "
            f"{_FEATURE_WHAT.get(cat, 'motion')} at the rest pose; check the joints' axes "
            "and stiffness (a joint without stiffness has no mode)")


def _same_motion(prev: dict, eff_sign: float, phase_deg: float, freq: float) -> bool:
    """Would a term play the same mode exactly as ``prev`` does (up to a half-cycle flip)?"""
    if not math.isclose(prev["freq_hz"], freq):
        return False
    lag = (phase_deg - prev["phase_deg"]) % 360.0
    if eff_sign == prev["_eff_sign"]:
        return min(lag, 360.0 - lag) < 1e-6
    return abs(lag - 180.0) < 1e-6


def plan_gait(
    model: mujoco.MjModel,
    g: Gait,
    *,
    stiffness_scale: float = 1.0,
    amplitude_scale: float = 1.0,
    freq_hz: float | None = None,
    params: HeuristicParams | None = None,
    labels: Labels | None = None,
    rest_qpos: np.ndarray | None = None,
    joint_stiffness: dict[str, float] | None = None,
) -> GaitPlan:
    """Analyse ``model`` about the gait's rest pose and pick its modes by heuristics.

    ``labels`` replaces the naming convention (a tree-found leg map), ``rest_qpos`` the
    rest pose, ``joint_stiffness`` (joint name -> N m/rad) some joints' stiffness.
    """
    keyframe = g.keyframe
    if keyframe is not None and mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_KEY, keyframe) < 0:
        log.info("model has no keyframe %r: using its spring reference as the rest pose", keyframe)
        keyframe = None
    constraints = build_constraints(g.constraints)
    stiffness: float | dict[str, float] | None = g.stiffness
    if joint_stiffness:
        if g.stiffness is not None:
            raise InputError(f"gait {g.name!r} sets a uniform stiffness; per-joint stiffness "
                             "does not combine with it")
        stiffness = dict(joint_stiffness)
    analysis = analyze(model, keyframe=keyframe, qpos=rest_qpos, constraints=constraints,
                       stiffness=stiffness, stiffness_scale=stiffness_scale)
    wanted = sorted({t.category for t in g.terms if t.category != "bounce"} | {"E"})
    params = params or HeuristicParams()
    sel = score_modes(analysis, model, params, categories=None, labels=labels)
    missing = [c for c in wanted if c not in sel.best]
    if missing:
        raise InputError(f"gait {g.name!r} cannot be built on this {g.kind}: "
                         + "; ".join(_missing_reason(sel, c, g.kind) for c in missing))
    comps: list[Component] = []
    chosen: list[dict] = []
    merged: dict[str, int] = {}
    substituted: dict[str, dict] = {}
    used: dict[int, dict] = {}
    for t in g.terms:
        f = freq_hz if freq_hz is not None and math.isclose(t.freq_hz, 2.0) else t.freq_hz
        phase = math.radians(t.phase_deg)
        if t.category == "bounce":
            shape = rigid_component(analysis, sel.functionals["bounce"], params.rigid_feature_m)
            if shape is None:
                log.warning("gait %s: no rigid vertical motion (constrained model); bounce skipped",
                            g.name)
                continue
            label = "bounce: rigid vertical motion (rigid modes)"
            comps.append(Component(t.sign * shape, amplitude_scale * t.amplitude, phase, f,
                                   amplitude_scale * t.beta, -1, label))
            chosen.append({"mode": "rigid", "categories": ["bounce"], "freq_hz_natural": 0.0,
                           "amplitude": t.amplitude, "phase_deg": t.phase_deg, "freq_hz": f,
                           "beta": t.beta, "sign": t.sign, "mode_sign": t.sign})
            continue
        mode, sign = sel.best[t.category]
        if mode in used:
            prev = used[mode]
            if not t.distinct or _same_motion(prev, sign * t.sign, t.phase_deg, f):
                merged[t.category] = mode
                prev["categories"].append(t.category)
                continue
            alt = [r for r in sel.ranked(t.category) if r[0] not in used]
            if not alt or alt[0][2] < params.min_substitute_relative:
                best_alt = (f"the next best, mode {alt[0][0]}, has {100 * alt[0][2]:.0f}% of its "
                            f"{CATEGORY_NAMES[t.category]}" if alt else "no other mode has any")
                raise InputError(
                    f"gait {g.name!r} needs {t.category} ({CATEGORY_NAMES[t.category]}) at "
                    f"{t.phase_deg:g} deg apart from {'/'.join(prev['categories'])} at "
                    f"{prev['phase_deg']:g} deg, but mode {mode} tops both and {best_alt} "
                    f"(< {100 * params.min_substitute_relative:.0f}%): the gait would collapse "
                    "into another; compose it by hand in a gait file (--save-gait, edit, "
                    "--gait-file) or change the stiffness (--stiffness JOINT=SCALE)")
            substituted[t.category] = {"top_mode": mode, "mode": alt[0][0],
                                       "relative": alt[0][2]}
            log.info("gait %s: mode %d tops %s and %s at different phases; %s takes mode %d "
                     "(%.0f%% of the top)", g.name, mode, prev["categories"][0], t.category,
                     t.category, alt[0][0], 100 * alt[0][2])
            mode, sign = alt[0][0], alt[0][1]
        shape = sign * t.sign * rotation_normalized_shape(analysis, mode)
        label = f"{t.category} {CATEGORY_NAMES[t.category]}"
        comps.append(Component(shape, amplitude_scale * t.amplitude, phase, f,
                               amplitude_scale * t.beta, mode, label))
        entry = {"mode": mode, "categories": [t.category],
                 "freq_hz_natural": float(analysis.freqs_hz[mode]), "amplitude": t.amplitude,
                 "phase_deg": t.phase_deg, "freq_hz": f, "beta": t.beta, "sign": t.sign,
                 "mode_sign": sign * t.sign, "_eff_sign": sign * t.sign}
        used[mode] = entry
        chosen.append(entry)
    for e in chosen:
        e.pop("_eff_sign", None)
    return GaitPlan(g, analysis, sel, tuple(comps), tuple(chosen), merged, tuple(constraints),
                    substituted)


def plan_from_file(
    model: mujoco.MjModel,
    g: Gait,
    gf: GaitFile,
    stiffness_scale: float,
    labels: Labels | None = None,
    amplitude_scale: float = 1.0,
) -> GaitPlan:
    """A gait file played on ``model``: the same analysis as :func:`plan_gait` (``g``
    gives the rest keyframe and constraints), the modes and sliders from the file."""
    keyframe = g.keyframe
    if keyframe is not None and mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_KEY, keyframe) < 0:
        keyframe = None
    constraints = build_constraints(g.constraints)
    analysis = analyze(model, keyframe=keyframe, constraints=constraints, stiffness=g.stiffness,
                       stiffness_scale=stiffness_scale)
    sel = score_modes(analysis, model, HeuristicParams(), labels=labels)
    file_gait = replace(g, name=gf.name, selection="gait file", terms=())
    comps = gf.components(analysis, lambda m: rotation_normalized_shape(analysis, m))
    if amplitude_scale != 1.0:
        comps = [replace(c, amplitude=c.amplitude * amplitude_scale, beta=c.beta * amplitude_scale)
                 for c in comps]
    chosen = tuple({"mode": c.mode, "categories": list(c.label.split("+")),
                    "freq_hz_natural": float(analysis.freqs_hz[c.mode]), "amplitude": c.amplitude,
                    "phase_deg": math.degrees(c.phase_rad), "freq_hz": c.freq_hz, "beta": c.beta,
                    "sign": 1.0, "mode_sign": float(np.sign(np.dot(c.shape, analysis.shapes[:, c.mode])))}
                   for c in comps)
    return GaitPlan(file_gait, analysis, sel, tuple(comps), chosen, {}, tuple(constraints))


def gait_file_of(plan: GaitPlan, amplitude_scale: float = 1.0, *, knee_flex_deg: float = 0.0,
                 stiffness_scale: float = 1.0, stiffness: dict[str, float] | None = None) -> GaitFile:
    """What the heuristics chose, as a gait file (the rigid bounce of the jumps is not a
    mode and is left out, with a warning)."""
    modes = []
    for c in plan.chosen:
        if c["mode"] == "rigid":
            log.warning("gait %s: its rigid bounce is not a mode; the gait file leaves it out",
                        plan.gait.name)
            continue
        modes.append({"mode": int(c["mode"]), "categories": list(c["categories"]),
                      "sign": float(c["mode_sign"]), "amplitude": c["amplitude"] * amplitude_scale,
                      "phase_deg": float(c["phase_deg"]), "freq_hz": float(c["freq_hz"]),
                      "beta": c["beta"] * amplitude_scale})
    if not modes:
        raise InputError(f"gait {plan.gait.name!r} uses no vibration mode: nothing to save")
    sel = plan.selection
    sway = sel.ranked("sway") if "sway" in sel.functionals else []
    posture = sel.ranked("D") if "D" in sel.functionals else []
    return GaitFile(
        name=plan.gait.name, modes=modes,
        sway_mode=sway[0][0] if sway else None, sway_sign=sway[0][1] if sway else 1.0,
        posture_mode=posture[0][0] if posture else None,
        posture_sign=posture[0][1] if posture else 1.0,
        knee_flex_deg=knee_flex_deg, stiffness_scale=stiffness_scale,
        stiffness=dict(stiffness or {}))


def rotation_normalized_shape(analysis: ModalAnalysis, mode: int) -> np.ndarray:
    """Mode shape scaled so its largest rotation, the floating root's included, is 1 rad.

    ``ModalAnalysis.shape(i, 'max')`` normalises on the internal joints only; the lowest
    modes of a free creature can tilt the whole body more than they bend any joint (the
    dog's first mode pitches the trunk 1.3 rad per rad of hip), so amplitude 1 would
    turn the body over. Counting the root's rotation keeps amplitude 1 = 1 rad anywhere.
    """
    phi = np.asarray(analysis.shapes[:, mode], dtype=np.float64)
    rot = np.array([not lab.endswith((":tx", ":ty", ":tz")) for lab in analysis.dof_labels])
    scale = float(np.max(np.abs(phi[rot]))) if rot.any() else float(np.max(np.abs(phi)))
    if scale <= 0:
        raise InputError(f"mode {mode} has no rotation to normalise")
    return phi / scale


def cycle_seconds(plan: GaitPlan) -> float:
    """Length of one full cycle: 1 / (gcd of the component frequencies), s."""
    freqs = [c.freq_hz for c in plan.components if c.amplitude != 0]
    if not freqs:
        return 1.0
    base = min(freqs)
    for f in freqs:
        ratio = f / base
        if abs(ratio - round(ratio)) > 1e-9:
            return 1.0 / base * 4  # incommensurate: show a few periods of the slowest
    return 1.0 / base


def head_orientation_error(model: mujoco.MjModel, qpos: np.ndarray, rest: np.ndarray,
                           body: str = "head") -> float:
    """Largest rotation angle of ``body`` away from its rest orientation over frames, rad."""
    d = mujoco.MjData(model)
    d.qpos[:] = rest
    mujoco.mj_forward(model, d)
    b = model.body(body).id
    q0 = d.xquat[b].copy()
    worst = 0.0
    err = np.zeros(3)
    for q in np.atleast_2d(qpos):
        d.qpos[:] = q
        mujoco.mj_kinematics(model, d)
        mujoco.mju_subQuat(err, d.xquat[b], q0)
        worst = max(worst, float(np.linalg.norm(err)))
    return worst
