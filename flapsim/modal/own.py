"""Your own creature, from load to gait (Kry et al. 2009, sec. 5.1's "typical session"):
legs found from the tree (:mod:`flapsim.modal.legs`), joint stiffness edits (sec. 5.2's
morphology and injury styles), a flexed-knee rest pose when straight legs give the feet
no vertical motion, the uniform stiffness scale that carries the creature's weight, a
gait file (the paper's sliders), each foot's phase, and optional root travel from the
stance feet.

Gait file (TOML), written by ``animate --save-gait`` and read by ``--gait-file``::

    [gait]
    name = "amble"
    stride = 1.0       # multiplies the amplitude of the swing modes (categories B, G)
    hip_sway = 0.0     # amplitude of the sideways sway mode, a quarter cycle after the swing
    posture = 0.0      # offset along the synchronous knee-bend mode (> 0 crouches)
    sway_mode = 12     # the modes hip_sway and posture move (and their signs)
    sway_sign = 1.0
    posture_mode = 9
    posture_sign = -1.0
    [rest]
    knee_flex_deg = 30.0   # 0: the model's own rest pose
    stiffness_scale = 1.4  # uniform scale of every joint's stiffness
    [stiffness]            # per-joint scales applied first (--stiffness JOINT=SCALE)
    [[modes]]              # equation 4: alpha sin(2 pi f t + gamma) + beta, per mode
    mode = 10
    categories = ["B"]
    sign = -1.0            # multiplies the mode's shape (largest rotation 1 rad)
    amplitude = 0.5
    phase_deg = 0.0
    freq_hz = 2.0
    beta = 0.0

Root travel (ours; the paper plays gaits in place): every frame the root rises or sinks
so the lowest foot stands on the ground (its height at rest), and between frames it moves
horizontally by minus the mean horizontal motion of the stance feet, those within
:data:`CONTACT_M` of the lowest at both ends of the frame. A foot in stance alone then
does not slip at all; feet in stance together slip by how much their motions differ.
"""

from __future__ import annotations

import math
import tomllib
from dataclasses import dataclass, field
from pathlib import Path

import mujoco
import numpy as np

from flapsim.core.errors import InputError, SimulationError
from flapsim.core.io import atomic_path
from flapsim.core.validate import require_finite
from flapsim.modal.analysis import rest_pose, tangent_difference
from flapsim.modal.animate import Component
from flapsim.modal.heuristics import Labels, Point, point_world
from flapsim.modal.legs import (
    STRAIGHT_RATIO,
    LegMap,
    find_legs,
    flexed_rest_pose,
    labels_from_legs,
    leg_straightness,
    read_label_file,
)
from flapsim.modal.stiffness import tune_stiffness

#: Knee flexion of the proposed rest pose, deg (ours: bends each shank ~15 deg from the
#: vertical, enough for the knee to lift the foot by a quarter of its swing; the paper's
#: run pose bends knees and elbows without a number).
PROPOSED_KNEE_FLEX_DEG = 30.0


@dataclass
class OwnCreature:
    """A user's model prepared for the heuristics."""

    legs: LegMap
    labels: Labels
    rest_qpos: np.ndarray
    """The rest pose the modes are computed about (also written to ``qpos_spring``)."""
    straightness: float
    """tan of the most-leaning shank at the model's own rest pose (0: straight legs)."""
    knee_flex_deg: float
    """Knee flexion applied to the rest pose (0: none)."""
    flex_reason: str
    stiffness_scale: float
    """Uniform stiffness scale (tuned: the smallest that carries the weight)."""
    tuning: dict | None
    stiffness_edits: dict[str, float] = field(default_factory=dict)

    def report(self, model: mujoco.MjModel) -> dict:
        return {"legs": self.legs.to_dict(model), "straightness_tan": self.straightness,
                "knee_flex_deg": self.knee_flex_deg, "rest_pose": self.flex_reason,
                "stiffness_scale": self.stiffness_scale, "stiffness_tuning": self.tuning,
                "stiffness_edits": dict(self.stiffness_edits)}


def parse_stiffness_edits(specs: list[str] | None) -> dict[str, float]:
    """``JOINT=SCALE`` strings -> {joint: scale}."""
    out: dict[str, float] = {}
    for s in specs or []:
        name, eq, val = s.partition("=")
        try:
            scale = float(val)
        except ValueError:
            scale = float("nan")
        if not eq or not name or not (math.isfinite(scale) and scale > 0):
            raise InputError(f"--stiffness {s!r}: write JOINT=SCALE with a positive scale, "
                             "e.g. --stiffness knee_l=0.5")
        out[name] = scale
    return out


def apply_stiffness_edits(model: mujoco.MjModel, edits: dict[str, float]) -> None:
    """Multiply the named joints' stiffness (and damping) in place."""
    for name, scale in edits.items():
        j = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, name)
        if j < 0:
            names = [model.joint(k).name for k in range(model.njnt)]
            raise InputError(f"--stiffness: no joint {name!r} in the model; joints: "
                             f"{', '.join(names[:24])}")
        if model.jnt_stiffness[j] == 0:
            raise InputError(f"--stiffness: joint {name!r} has no stiffness to scale; give it "
                             "stiffness= in the MJCF")
        model.jnt_stiffness[j] *= scale
        n = {0: 6, 1: 3, 2: 1, 3: 1}[int(model.jnt_type[j])]
        a = int(model.jnt_dofadr[j])
        model.dof_damping[a : a + n] *= scale


def prepare(
    model: mujoco.MjModel,
    *,
    label_file: str | Path | None = None,
    knee_flex_deg: float | None = None,
    tune: bool = True,
    stiffness_edits: dict[str, float] | None = None,
) -> OwnCreature:
    """The paper's setup step on ``model`` (edited in place: stiffness, ``qpos_spring``).

    ``knee_flex_deg``: None proposes :data:`PROPOSED_KNEE_FLEX_DEG` when the legs are
    straight, 0 keeps the model's pose, a number flexes by it.
    """
    edits = dict(stiffness_edits or {})
    apply_stiffness_edits(model, edits)
    q0 = rest_pose(model)
    legs = find_legs(model, q0, read_label_file(label_file) if label_file else None)
    labels = labels_from_legs(model, legs)
    straight = leg_straightness(model, q0, legs)
    if knee_flex_deg is None:
        if straight < STRAIGHT_RATIO:
            flex = PROPOSED_KNEE_FLEX_DEG
            reason = (f"straight legs (shanks within {math.degrees(math.atan(straight)):.1f} deg "
                      "of vertical) give the feet no first-order vertical motion: proposed "
                      f"knees flexed {flex:g} deg, hips turned back over the feet")
        else:
            flex, reason = 0.0, "the model's own rest pose (knees already bent)"
    else:
        flex = float(knee_flex_deg)
        reason = (f"knees flexed {flex:g} deg as asked" if flex > 0
                  else "the model's own rest pose, as asked")
        if flex == 0 and straight < STRAIGHT_RATIO:
            reason += " (straight legs: the feet have no vertical motion, gaits may be refused)"
    rest = flexed_rest_pose(model, q0, legs, flex) if flex > 0 else q0
    model.qpos_spring[:] = rest
    scale, tuning = 1.0, None
    if tune:
        try:
            res = tune_stiffness(model, qpos=rest)
            scale = res.scale
            tuning = {"scale": res.scale, "failing_scale": res.failing_scale, "holds": True,
                      "trials": len(res.trials)}
        except SimulationError as e:
            tuning = {"scale": 1.0, "holds": False, "why": str(e)}
    return OwnCreature(legs, labels, rest, straight, flex, reason, scale, tuning, edits)


# -- foot phases -------------------------------------------------------------------------
def foot_tracks(model: mujoco.MjModel, qpos: np.ndarray, feet: tuple[Point, ...],
                root: int) -> tuple[np.ndarray, np.ndarray]:
    """World positions of the feet (T, n, 3) and of the root body (T, 3) over frames."""
    d = mujoco.MjData(model)
    out = np.empty((len(qpos), len(feet), 3))
    roots = np.empty((len(qpos), 3))
    for k, q in enumerate(qpos):
        d.qpos[:] = q
        mujoco.mj_kinematics(model, d)
        roots[k] = d.xpos[root]
        for i, p in enumerate(feet):
            out[k, i] = point_world(d, p)
    return out, roots


def foot_phases_deg(times: np.ndarray, fwd_pos: np.ndarray, freq_hz: float) -> np.ndarray:
    """Each foot's phase: when in the cycle its fore-aft position (relative to the body)
    peaks, from a least-squares fit of ``c + a sin(w t) + b cos(w t)`` at the gait's
    fundamental ``freq_hz``; degrees in [0, 360), a later foot has a larger phase."""
    w = 2 * math.pi * freq_hz
    A = np.column_stack([np.ones_like(times), np.sin(w * times), np.cos(w * times)])
    coef = np.linalg.lstsq(A, fwd_pos, rcond=None)[0]  # (3, n)
    # a sin + b cos = R sin(w t + phi), peak at w t = 90 deg - phi
    phi = np.degrees(np.arctan2(coef[2], coef[1]))
    return (90.0 - phi) % 360.0


def feet_of(labels: Labels) -> tuple[Point, ...]:
    return labels.feet + (labels.front_feet or ())


# -- root travel -------------------------------------------------------------------------
#: A foot counts as on the ground within this height of the lowest foot, m (ours: half a
#: centimetre, below the 2-3 cm the gaits' swinging feet rise).
CONTACT_M = 0.005
#: Least-squares steps per frame that bring a stance foot back to its touchdown point.
IK_STEPS = 4


@dataclass(frozen=True)
class Travel:
    qpos: np.ndarray
    """Poses with the travelling root (T, nq)."""
    distance_m: float
    """Root travel along forward, m."""
    max_slip_m: float
    """Largest horizontal slip of a foot over one stance, m."""
    slip_per_foot_m: tuple[float, ...]
    stance_fraction: tuple[float, ...]
    max_leg_correction_rad: float = 0.0
    """Largest change of a leg joint made to plant a stance foot, rad (or m)."""


def travel_root(model: mujoco.MjModel, qpos: np.ndarray, labels: Labels,
                rest_qpos: np.ndarray | None = None,
                contact_m: float = CONTACT_M) -> Travel:
    """Move the root so the feet on the ground stay planted (see the module docstring)."""
    root_jnt = [j for j in range(model.body_jntadr[labels.root_body],
                                 model.body_jntadr[labels.root_body]
                                 + model.body_jntnum[labels.root_body])
                if int(model.jnt_type[j]) == mujoco.mjtJoint.mjJNT_FREE]
    if not root_jnt:
        raise InputError("root travel needs a floating root (a free joint on the root body)")
    if not (math.isfinite(contact_m) and contact_m >= 0):
        raise InputError("the contact band must be a non-negative length, m")
    adr = int(model.jnt_qposadr[root_jnt[0]])
    feet = feet_of(labels)
    pos, _ = foot_tracks(model, qpos, feet, labels.root_body)
    if rest_qpos is not None:
        ground = float(foot_tracks(model, np.asarray(rest_qpos)[None], feet,
                                   labels.root_body)[0][0, :, 2].min())
    else:
        ground = float(pos[:, :, 2].min())
    lift = ground - pos[:, :, 2].min(axis=1)  # root height change putting a foot on the ground
    on_ground = pos[:, :, 2] - pos[:, :, 2].min(axis=1, keepdims=True) <= contact_m
    fwd = labels.forward
    vel = np.diff(pos[:, :, :2], axis=0)  # (T-1, n, 2): foot motion in place
    stance = on_ground[1:] & on_ground[:-1]  # on the ground at both ends of a frame
    step = np.zeros((len(qpos) - 1, 2))
    for k in range(len(step)):
        if stance[k].any():
            step[k] = -vel[k, stance[k]].mean(axis=0)
    offset = np.vstack([np.zeros((1, 2)), np.cumsum(step, axis=0)])
    out = np.array(qpos, dtype=np.float64, copy=True)
    out[:, adr : adr + 2] += offset
    out[:, adr + 2] += lift
    # Feet in stance together move differently (a kinematic gait knows no ground), so the
    # root alone cannot plant them all: each stance foot's own leg takes up what is left
    # (a few least-squares steps on the leg's joints towards where the foot touched down).
    legs = leg_dofs(model, labels)
    d = mujoco.MjData(model)
    touch: dict[int, np.ndarray] = {}
    for k in range(len(out)):
        d.qpos[:] = out[k]
        mujoco.mj_kinematics(model, d)
        for i, p in enumerate(feet):
            if not on_ground[k, i]:
                touch.pop(i, None)
                continue
            if i not in touch:
                touch[i] = point_world(d, p).copy()
                continue
            for _ in range(IK_STEPS):
                mujoco.mj_kinematics(model, d)
                mujoco.mj_comPos(model, d)
                now = point_world(d, p)
                # keep the height the gait gives (which feet touch the ground stays)
                err = np.array([touch[i][0] - now[0], touch[i][1] - now[1],
                                pos[k, i, 2] + lift[k] - now[2]])
                if np.linalg.norm(err) < 1e-6:
                    break
                jp = np.zeros((3, model.nv))
                mujoco.mj_jac(model, d, jp, None, now, p[0])
                dq = np.zeros(model.nv)
                dq[legs[i]] = np.linalg.lstsq(jp[:, legs[i]], err, rcond=1e-8)[0]
                mujoco.mj_integratePos(model, out[k], dq, 1.0)
                d.qpos[:] = out[k]
    base = np.array(qpos, dtype=np.float64, copy=True)
    base[:, adr : adr + 2] += offset
    base[:, adr + 2] += lift
    correction = max((float(np.max(np.abs(tangent_difference(model, out[k], base[k]))))
                      for k in range(len(out))), default=0.0)
    final, _ = foot_tracks(model, out, feet, labels.root_body)
    slips, frac = [], []
    for i in range(len(feet)):
        worst, start = 0.0, None
        for k in range(len(out)):
            if on_ground[k, i]:
                start = final[k, i, :2] if start is None else start
                worst = max(worst, float(np.linalg.norm(final[k, i, :2] - start)))
            else:
                start = None
        slips.append(worst)
        frac.append(float(on_ground[:, i].mean()))
    return Travel(out, float(offset[-1] @ fwd[:2]), max(slips), tuple(slips), tuple(frac),
                  correction)


def leg_dofs(model: mujoco.MjModel, labels: Labels) -> list[np.ndarray]:
    """Per foot, the dofs of its own leg: the joints between the foot's body and the first
    body shared with another foot's chain."""
    feet = feet_of(labels)
    chains = []
    for _, p in enumerate(feet):
        b, ch = p[0], []
        while b not in (0, labels.root_body):
            ch.append(b)
            b = int(model.body_parentid[b])
        chains.append(ch)
    out = []
    for i, ch in enumerate(chains):
        others = {b for j, c in enumerate(chains) if j != i for b in c}
        dofs = [dof for b in ch if b not in others
                for dof in range(model.body_dofadr[b], model.body_dofadr[b] + model.body_dofnum[b])
                if model.body_dofnum[b] > 0]
        out.append(np.array(dofs, dtype=np.int64))
    return out


# -- gait files --------------------------------------------------------------------------
def _v(x: object) -> str:
    if isinstance(x, bool):
        return "true" if x else "false"
    if isinstance(x, int | np.integer):
        return str(int(x))
    if isinstance(x, float | np.floating):
        return repr(float(x))
    if isinstance(x, str):
        return '"' + x.replace("\\", "\\\\").replace('"', '\\"') + '"'
    if isinstance(x, list | tuple):
        return "[" + ", ".join(_v(y) for y in x) + "]"
    raise TypeError(f"cannot write {x!r} to TOML")


@dataclass
class GaitFile:
    """A gait as the paper's sliders: modes with amplitude, phase, offset, plus stride,
    hip sway and posture (see the module docstring)."""

    name: str
    modes: list[dict]
    stride: float = 1.0
    hip_sway: float = 0.0
    posture: float = 0.0
    sway_mode: int | None = None
    sway_sign: float = 1.0
    posture_mode: int | None = None
    posture_sign: float = 1.0
    knee_flex_deg: float = 0.0
    stiffness_scale: float = 1.0
    stiffness: dict[str, float] = field(default_factory=dict)

    def write(self, path: str | Path) -> None:
        lines = ["# flapsim gait file: play with `flapsim animate MODEL --gait-file FILE`",
                 "[gait]", f"name = {_v(self.name)}",
                 f"stride = {_v(float(self.stride))}", f"hip_sway = {_v(float(self.hip_sway))}",
                 f"posture = {_v(float(self.posture))}"]
        if self.sway_mode is not None:
            lines += [f"sway_mode = {_v(self.sway_mode)}", f"sway_sign = {_v(self.sway_sign)}"]
        if self.posture_mode is not None:
            lines += [f"posture_mode = {_v(self.posture_mode)}",
                      f"posture_sign = {_v(self.posture_sign)}"]
        lines += ["", "[rest]", f"knee_flex_deg = {_v(float(self.knee_flex_deg))}",
                  f"stiffness_scale = {_v(float(self.stiffness_scale))}", "", "[stiffness]"]
        lines += [f"{_v(k)} = {_v(float(v))}" for k, v in self.stiffness.items()]
        for m in self.modes:
            lines += ["", "[[modes]]"] + [f"{k} = {_v(m[k])}" for k in MODE_KEYS]
        with atomic_path(path) as tmp:
            Path(tmp).write_text("\n".join(lines) + "\n")

    @classmethod
    def read(cls, path: str | Path) -> GaitFile:
        p = Path(path)
        if not p.exists():
            raise InputError(f"gait file {str(p)!r} does not exist (write one with --save-gait)")
        try:
            with p.open("rb") as f:
                t = tomllib.load(f)
        except tomllib.TOMLDecodeError as e:
            raise InputError(f"gait file {str(p)!r} is not valid TOML: {e}") from None
        require_finite(t, f"gait file {str(p)!r}", fix="correct that entry (or write the file "
                       "again with --save-gait)")
        g, rest = t.get("gait", {}), t.get("rest", {})
        modes = t.get("modes", [])
        if not modes:
            raise InputError(f"gait file {str(p)!r} has no [[modes]]")
        out = []
        for i, m in enumerate(modes):
            missing = [k for k in MODE_KEYS if k not in m]
            if missing:
                raise InputError(f"gait file {str(p)!r}: mode entry {i + 1} lacks "
                                 f"{', '.join(missing)}")
            entry = {k: m[k] for k in MODE_KEYS}
            for k in ("sign", "amplitude", "phase_deg", "freq_hz", "beta"):
                if not isinstance(entry[k], int | float) or not math.isfinite(entry[k]):
                    raise InputError(f"gait file {str(p)!r}: mode entry {i + 1}: {k} must be "
                                     "a finite number")
            if not isinstance(entry["mode"], int) or entry["mode"] < 0:
                raise InputError(f"gait file {str(p)!r}: mode entry {i + 1}: mode must be a "
                                 "mode index (an integer >= 0)")
            if entry["freq_hz"] <= 0:
                raise InputError(f"gait file {str(p)!r}: mode entry {i + 1}: freq_hz must be > 0")
            out.append(entry)
        try:
            return cls(name=str(g.get("name", p.stem)), modes=out,
                       stride=float(g.get("stride", 1.0)), hip_sway=float(g.get("hip_sway", 0.0)),
                       posture=float(g.get("posture", 0.0)), sway_mode=g.get("sway_mode"),
                       sway_sign=float(g.get("sway_sign", 1.0)),
                       posture_mode=g.get("posture_mode"),
                       posture_sign=float(g.get("posture_sign", 1.0)),
                       knee_flex_deg=float(rest.get("knee_flex_deg", 0.0)),
                       stiffness_scale=float(rest.get("stiffness_scale", 1.0)),
                       stiffness={str(k): float(v) for k, v in t.get("stiffness", {}).items()})
        except (TypeError, ValueError) as e:
            raise InputError(f"gait file {str(p)!r}: {e}") from None

    def components(self, analysis, shape_of) -> list[Component]:
        """Equation 4's components; ``shape_of(mode)`` gives a mode's normalised shape."""
        comps = []
        swing = {c["mode"] for c in self.modes if {"B", "G"} & set(c["categories"])}
        ref = next((c for c in self.modes if c["mode"] in swing), self.modes[0])
        for c in self.modes:
            if c["mode"] >= analysis.n_modes or c["mode"] < analysis.n_rigid:
                raise InputError(f"gait file: mode {c['mode']} is not an elastic mode of this "
                                 f"model (elastic modes {analysis.n_rigid}.."
                                 f"{analysis.n_modes - 1})")
            amp = c["amplitude"] * (self.stride if c["mode"] in swing else 1.0)
            beta = c["beta"]
            if self.posture and c["mode"] == self.posture_mode:
                beta += self.posture * self.posture_sign * c["sign"]
            comps.append(Component(c["sign"] * shape_of(c["mode"]), amp,
                                   math.radians(c["phase_deg"]), c["freq_hz"], beta, c["mode"],
                                   "+".join(c["categories"])))
        used = {c["mode"] for c in self.modes}
        if self.posture and self.posture_mode is not None and self.posture_mode not in used:
            comps.append(Component(self.posture_sign * shape_of(self.posture_mode), 0.0, 0.0,
                                   ref["freq_hz"], self.posture, self.posture_mode, "posture"))
        if self.hip_sway and self.sway_mode is not None:
            comps.append(Component(self.sway_sign * shape_of(self.sway_mode), self.hip_sway,
                                   math.radians(ref["phase_deg"] + 90.0), ref["freq_hz"], 0.0,
                                   self.sway_mode, "hip sway"))
        if (self.hip_sway and self.sway_mode is None) or (self.posture
                                                          and self.posture_mode is None):
            raise InputError("gait file: hip_sway or posture is set but its mode "
                             "(sway_mode / posture_mode) is not")
        return comps


MODE_KEYS = ("mode", "categories", "sign", "amplitude", "phase_deg", "freq_hz", "beta")
