"""Generate creatures/dog.xml, creatures/human.xml and creatures/human_cart.xml: the dog
(80 DOF) and human (47 DOF) of Kry et al. 2009 (Fig. 1, Fig. 3) and the cart scene.

    python -m flapsim.modal.build.dog_human [--out DIR] [--print NAME]

writes the three files into the bundled ``creatures/`` folder (or ``--out``; ``--print NAME``
shows one file instead) and prints each model's size and mass. The bundled files are this
module's output, byte for byte (``tests/modal/test_build.py``): change the design here, then
regenerate them.

Design (SI units; x forward, y left, z up; zero joint angles = the standing rest pose):

* Masses and inertias come from the geometry: every geom is a capsule, ellipsoid, sphere
  or box of tissue density 1000 kg/m^3 (MuJoCo's ``inertiafromgeom``). The dog weighs
  ~27 kg (a medium dog, shoulder height ~0.55 m), the human ~71 kg at 1.78 m.
* Every joint but the free root is a hinge; a 3-axis joint is three hinges in one body
  (flexion, abduction/lateral bend, rotation), which at the rest pose spans the same
  velocity space as a ball joint with stiffness k I3, and maps one-to-one onto BVH
  Euler channels. Axes are mirrored on the right side, so a positive angle means the
  same anatomical motion on both sides; ``knee_*`` and ``elbow_*`` are positive in
  flexion (the heuristics read that).
* Stiffness as in the paper's Fig. 3: dog 20 N m/rad, spine and neck x5 (100); human
  100 N m/rad, spine and neck x10 (1000). Damping 0.05 s x stiffness (Rayleigh-like),
  armature 0.5 g m^2 (dog) / 1 g m^2 (human) so the light distal links stay stable at
  the 1 ms time step of the stiffness-tuning simulation.
* DOF: dog = 6 (root) + 15 spine (5 x 3) + 6 neck + 3 head + 1 jaw + 15 tail (5 x 3)
  + 2 x 8 hind legs (hip 3, stifle 1, hock 3, paw 1) + 2 x 9 front legs (scapula 3,
  shoulder 3, elbow 1, carpus 1, paw 1) = 80. Human = 6 + 15 spine/neck/head (5 x 3)
  + 2 x 7 legs (hip 3, knee 1, ankle 2, toe 1) + 2 x 6 arms (shoulder 3, elbow 1,
  wrist 2) = 47.
* Labels read by :mod:`flapsim.modal.heuristics`: sites ``foot_l/_r`` and ``hand_l/_r``
  (human), ``paw_hl/_hr/_fl/_fr`` (dog), ``head`` (both); joints ``knee_l/_r``,
  ``elbow_l/_r`` (human), ``knee_hl/_hr``, ``elbow_fl/_fr`` (dog).
* Human keyframes: ``tpose`` (zeros; the walk's rest pose), ``run`` (bent knees and
  elbows, arms down: the run and jump rest pose), ``push`` (arms forward to a handle).
* Cart scene: the human in the ``push`` pose plus a 15 kg cart on a slider along x;
  each hand is tied to the handle by a ``connect`` equality (a closed loop), so the
  analysis has 47 + 1 - 6 = 42 dofs (the paper's count) and 2 rigid modes (rolling the
  cart with the walker, and turning about the line through the hands).
"""

from __future__ import annotations

import argparse
from dataclasses import dataclass, field
from pathlib import Path

import mujoco
import numpy as np

from flapsim.core.assets import asset_dir
from flapsim.core.errors import ModelError
from flapsim.core.io import atomic_path

DENSITY = 1000.0
DOG_K = 20.0
DOG_SPINE_MULT = 5.0
HUMAN_K = 100.0
HUMAN_SPINE_MULT = 10.0
DAMPING_S = 0.05
DOG_ARMATURE = 0.0005
HUMAN_ARMATURE = 0.001


@dataclass
class J:
    name: str
    axis: tuple[float, float, float]
    lo: float
    hi: float
    k: float


@dataclass
class Body:
    name: str
    pos: tuple[float, float, float]
    joints: list[J] = field(default_factory=list)
    geoms: list[str] = field(default_factory=list)
    sites: list[str] = field(default_factory=list)
    children: list[Body] = field(default_factory=list)
    free: bool = False


def _f(v) -> str:
    return " ".join(f"{x:.10g}" for x in v)


def cap(a, b, r, rgba="0.8 0.6 0.4 1", name="") -> str:
    nm = f'name="{name}" ' if name else ""
    return f'<geom {nm}type="capsule" fromto="{_f(a)} {_f(b)}" size="{r:.6g}" rgba="{rgba}"/>'


def ell(c, s, rgba="0.8 0.6 0.4 1") -> str:
    return f'<geom type="ellipsoid" pos="{_f(c)}" size="{_f(s)}" rgba="{rgba}"/>'


def box(c, s, rgba="0.8 0.6 0.4 1", name="") -> str:
    nm = f'name="{name}" ' if name else ""
    return f'<geom {nm}type="box" pos="{_f(c)}" size="{_f(s)}" rgba="{rgba}"/>'


def sph(c, r, rgba="0.8 0.6 0.4 1") -> str:
    return f'<geom type="sphere" pos="{_f(c)}" size="{r:.6g}" rgba="{rgba}"/>'


def site(name, p) -> str:
    return f'<site name="{name}" pos="{_f(p)}" size="0.015" rgba="1 0.2 0.2 1"/>'


def mirror_axis(a, side: str):
    # Mirroring y -> -y maps an axial vector (ax, ay, az) to (-ax, ay, -az).
    return a if side == "l" else (-a[0], a[1], -a[2])


def my(p, side: str):
    return p if side == "l" else (p[0], -p[1], p[2])


def tri(prefix: str, k: float, flex=(-0.5, 0.5), abd=(-0.4, 0.4), rot=(-0.4, 0.4),
        side: str = "", flex_axis=(0, 1, 0)) -> list[J]:
    """Three hinges (flex about y, abduction/lateral bend about x, rotation about z)."""
    ax = [flex_axis, (1, 0, 0), (0, 0, 1)]
    if side:
        ax = [mirror_axis(a, side) for a in ax]
    return [J(f"{prefix}_flex", ax[0], *flex, k), J(f"{prefix}_abd", ax[1], *abd, k),
            J(f"{prefix}_rot", ax[2], *rot, k)]


def write_body(b: Body, indent: str, armature: float) -> str:
    s = f'{indent}<body name="{b.name}" pos="{_f(b.pos)}">\n'
    ind = indent + "  "
    if b.free:
        s += f'{ind}<freejoint name="root"/>\n'
    for j in b.joints:
        s += (f'{ind}<joint name="{j.name}" axis="{_f(j.axis)}" range="{j.lo:.4g} {j.hi:.4g}" '
              f'stiffness="{j.k:.6g}" damping="{DAMPING_S * j.k:.6g}" armature="{armature:g}"/>\n')
    for g in b.geoms:
        s += f"{ind}{g}\n"
    for t in b.sites:
        s += f"{ind}{t}\n"
    for c in b.children:
        s += write_body(c, ind, armature)
    return s + f"{indent}</body>\n"


def header(model: str, comment: str) -> str:
    return f"""<!-- {comment}
     Generated by flapsim/modal/build/dog_human.py; see that module for the design. -->
<mujoco model="{model}">
  <compiler angle="radian" autolimits="true" inertiafromgeom="true"/>
  <option timestep="0.001" integrator="implicitfast"/>
  <size memory="20M"/>
  <visual>
    <global offwidth="960" offheight="720"/>
    <quality shadowsize="2048"/>
  </visual>
  <default>
    <geom density="{DENSITY:g}" friction="1.0 0.005 0.0001" contype="1" conaffinity="0"
          condim="3" solref="0.005 1"/>
  </default>
  <asset>
    <texture name="grid" type="2d" builtin="checker" rgb1="0.25 0.3 0.35"
             rgb2="0.3 0.35 0.4" width="512" height="512"/>
    <material name="grid" texture="grid" texrepeat="10 10" reflectance="0.05"/>
  </asset>
  <worldbody>
    <light pos="0 -2 4" dir="0 0.4 -1" directional="true"/>
    <geom name="ground" type="plane" size="30 30 0.1" material="grid" contype="0"
          conaffinity="1"/>
"""


# ---------------------------------------------------------------------------------------
# Dog
# ---------------------------------------------------------------------------------------
FUR = "0.72 0.52 0.32 1"
DARK = "0.45 0.3 0.2 1"


def dog_tree() -> Body:
    ks, kl = DOG_K * DOG_SPINE_MULT, DOG_K
    pelvis = Body("pelvis", (-0.3, 0, 0.535), free=True,
                  geoms=[cap((-0.08, 0, 0), (0.06, 0, 0), 0.06, FUR)],
                  sites=[site("pelvis", (0, 0, 0))])
    # Spine: five segments from the pelvis to the chest.
    radii = [0.058, 0.061, 0.064, 0.067]
    names = ["lumbar1", "lumbar2", "lumbar3", "thorax1"]
    parent, pos = pelvis, (0.06, 0, 0)
    for nm, r in zip(names, radii, strict=True):
        b = Body(nm, pos, tri(nm, ks, flex=(-0.35, 0.35), abd=(-0.3, 0.3), rot=(-0.25, 0.25)),
                 [cap((0, 0, 0), (0.1, 0, 0), r, FUR)])
        parent.children.append(b)
        parent, pos = b, (0.1, 0, 0)
    chest = Body("thorax2", (0.1, 0, 0),
                 tri("thorax2", ks, flex=(-0.35, 0.35), abd=(-0.3, 0.3), rot=(-0.25, 0.25)),
                 [cap((0, 0, 0), (0.12, 0, 0), 0.07, FUR), ell((0.06, 0, -0.04), (0.09, 0.075, 0.075), FUR)])
    parent.children.append(chest)
    neck1 = Body("neck1", (0.12, 0, 0.04), tri("neck1", ks, flex=(-0.6, 0.6), abd=(-0.5, 0.5),
                                               rot=(-0.5, 0.5)),
                 [cap((0, 0, 0), (0.07, 0, 0.07), 0.05, FUR)])
    neck2 = Body("neck2", (0.07, 0, 0.07), tri("neck2", ks, flex=(-0.6, 0.6), abd=(-0.5, 0.5),
                                               rot=(-0.5, 0.5)),
                 [cap((0, 0, 0), (0.06, 0, 0.06), 0.045, FUR)])
    head = Body("head", (0.06, 0, 0.06), tri("head", ks, flex=(-0.7, 0.7), abd=(-0.5, 0.5),
                                             rot=(-0.6, 0.6)),
                [ell((0.05, 0, 0), (0.08, 0.055, 0.055), FUR),
                 cap((0.08, 0, -0.01), (0.17, 0, -0.03), 0.028, DARK),
                 ell((0.02, 0.04, 0.05), (0.015, 0.01, 0.035), DARK),
                 ell((0.02, -0.04, 0.05), (0.015, 0.01, 0.035), DARK)],
                [site("head", (0.05, 0, 0))])
    jaw = Body("jaw", (0.07, 0, -0.035), [J("jaw", (0, -1, 0), -0.1, 0.6, kl)],
               [cap((0, 0, 0), (0.09, 0, -0.015), 0.02, DARK)])
    head.children.append(jaw)
    neck2.children.append(head)
    neck1.children.append(neck2)
    chest.children.append(neck1)
    # Tail: five segments up and back from the pelvis.
    parent, pos = pelvis, (-0.09, 0, 0.04)
    for i in range(5):
        r = 0.025 - 0.0025 * i
        b = Body(f"tail{i + 1}", pos, tri(f"tail{i + 1}", kl, flex=(-0.6, 0.6), abd=(-0.7, 0.7),
                                          rot=(-0.3, 0.3)),
                 [cap((0, 0, 0), (-0.06, 0, 0.03), r, FUR)])
        parent.children.append(b)
        parent, pos = b, (-0.06, 0, 0.03)
    for side in ("l", "r"):
        sgn = 1 if side == "l" else -1
        hs = "h" + side
        paw = Body(f"paw_{hs}b", (0.02, 0, -0.14), [J(f"toe_{hs}", (0, 1, 0), -0.6, 0.6, kl)],
                   [box((0.025, 0, -0.005), (0.045, 0.03, 0.015), DARK)],
                   [site(f"paw_{hs}", (0.025, 0, -0.02))])
        meta = Body(f"meta_{hs}", (-0.1, 0, -0.16),
                    tri(f"hock_{hs}", kl, flex=(-0.6, 1.0), abd=(-0.2, 0.2), rot=(-0.2, 0.2),
                        side=side, flex_axis=(0, -1, 0)),
                    [cap((0, 0, 0), (0.02, 0, -0.14), 0.02, FUR)], children=[paw])
        shank = Body(f"shank_{hs}", (0.08, 0, -0.18), [J(f"knee_{hs}", (0, 1, 0), -0.3, 1.6, kl)],
                     [cap((0, 0, 0), (-0.1, 0, -0.16), 0.03, FUR)], children=[meta])
        thigh = Body(f"thigh_{hs}", (-0.02, sgn * 0.07, -0.03),
                     tri(f"hip_{hs}", kl, flex=(-0.9, 1.2), abd=(-0.4, 0.5), rot=(-0.4, 0.4),
                         side=side, flex_axis=(0, -1, 0)),
                     [cap((0, 0, 0), (0.08, 0, -0.18), 0.045, FUR)], children=[shank])
        pelvis.children.append(thigh)
        fs = "f" + side
        fpaw = Body(f"paw_{fs}b", (0.02, 0, -0.06), [J(f"toe_{fs}", (0, 1, 0), -0.6, 0.6, kl)],
                    [box((0.025, 0, -0.005), (0.045, 0.03, 0.015), DARK)],
                    [site(f"paw_{fs}", (0.025, 0, -0.02))])
        carpus = Body(f"meta_{fs}", (0, 0, -0.2), [J(f"carpus_{fs}", (0, 1, 0), -0.3, 1.6, kl)],
                      [cap((0, 0, 0), (0.02, 0, -0.06), 0.018, FUR)], children=[fpaw])
        forearm = Body(f"forearm_{fs}", (-0.06, 0, -0.15),
                       [J(f"elbow_{fs}", (0, -1, 0), -0.3, 1.8, kl)],
                       [cap((0, 0, 0), (0, 0, -0.2), 0.025, FUR)], children=[carpus])
        upper = Body(f"upperarm_{fs}", (0.05, 0, -0.13),
                     tri(f"shoulder_{fs}", kl, flex=(-1.0, 1.0), abd=(-0.4, 0.4), rot=(-0.4, 0.4),
                         side=side, flex_axis=(0, -1, 0)),
                     [cap((0, 0, 0), (-0.06, 0, -0.15), 0.035, FUR)], children=[forearm])
        scap = Body(f"scapula_{fs}", (0.06, sgn * 0.085, 0.03),
                    tri(f"scapula_{fs}", kl, flex=(-0.5, 0.5), abd=(-0.2, 0.2), rot=(-0.2, 0.2),
                        side=side, flex_axis=(0, -1, 0)),
                    [cap((0, 0, 0), (0.05, 0, -0.13), 0.03, FUR)], children=[upper])
        chest.children.append(scap)
    return pelvis


def make_dog() -> str:
    xml = header("dog", "Dog: 80 DOF (free root + 74 hinges), Kry et al. 2009 Fig. 1 / Fig. 3.")
    xml += '    <camera name="side" pos="0 -2.6 0.7" xyaxes="1 0 0 0 0.2 1" mode="trackcom"/>\n'
    xml += write_body(dog_tree(), "    ", DOG_ARMATURE)
    xml += "  </worldbody>\n</mujoco>\n"
    return xml


# ---------------------------------------------------------------------------------------
# Human
# ---------------------------------------------------------------------------------------
SKIN = "0.85 0.68 0.55 1"
CLOTH = "0.3 0.4 0.6 1"
PANTS = "0.25 0.25 0.3 1"


def human_tree() -> Body:
    ks, kl = HUMAN_K * HUMAN_SPINE_MULT, HUMAN_K
    pelvis = Body("pelvis", (0, 0, 0.96), free=True,
                  geoms=[cap((0, -0.08, 0), (0, 0.08, 0), 0.095, PANTS)],
                  sites=[site("pelvis", (0, 0, 0))])
    lumbar = Body("lumbar", (0, 0, 0.1), tri("lumbar", ks, flex=(-0.4, 0.8), abd=(-0.4, 0.4),
                                             rot=(-0.4, 0.4)),
                  [cap((0, -0.07, 0.06), (0, 0.07, 0.06), 0.09, CLOTH)])
    thorax = Body("thorax", (0, 0, 0.14), tri("thorax", ks, flex=(-0.3, 0.6), abd=(-0.3, 0.3),
                                              rot=(-0.4, 0.4)),
                  [cap((0, -0.08, 0.05), (0, 0.08, 0.05), 0.105, CLOTH)])
    chest = Body("chest", (0, 0, 0.12), tri("chest", ks, flex=(-0.3, 0.5), abd=(-0.3, 0.3),
                                            rot=(-0.4, 0.4)),
                 [cap((0, -0.1, 0.07), (0, 0.1, 0.07), 0.09, CLOTH)])
    neck = Body("neck", (0, 0, 0.17), tri("neck", ks, flex=(-0.6, 0.7), abd=(-0.5, 0.5),
                                          rot=(-0.8, 0.8)),
                [cap((0, 0, 0), (0, 0, 0.08), 0.045, SKIN)])
    head = Body("head", (0, 0, 0.09), tri("head", ks, flex=(-0.5, 0.5), abd=(-0.4, 0.4),
                                          rot=(-0.6, 0.6)),
                [sph((0.01, 0, 0.1), 0.1, SKIN), ell((0.09, 0, 0.08), (0.02, 0.02, 0.025), SKIN)],
                [site("head", (0.01, 0, 0.1))])
    neck.children.append(head)
    chest.children.append(neck)
    thorax.children.append(chest)
    lumbar.children.append(thorax)
    pelvis.children.append(lumbar)
    for side in ("l", "r"):
        sgn = 1 if side == "l" else -1
        toe = Body(f"toes_{side}", (0.13, 0, -0.05), [J(f"toe_{side}", (0, -1, 0), -0.5, 0.8, kl)],
                   [box((0.03, 0, -0.005), (0.03, 0.045, 0.015), PANTS)])
        foot = Body(f"foot_{side}b", (0, 0, -0.41),
                    [J(f"ankle_{side}_flex", (0, -1, 0), -0.8, 0.6, kl),
                     J(f"ankle_{side}_inv", mirror_axis((1, 0, 0), side), -0.4, 0.4, kl)],
                    [box((0.04, 0, -0.045), (0.09, 0.045, 0.025), PANTS)],
                    [site(f"foot_{side}", (0.04, 0, -0.07))], children=[toe])
        shank = Body(f"shank_{side}", (0, 0, -0.42), [J(f"knee_{side}", (0, 1, 0), -0.05, 2.4, kl)],
                     [cap((0, 0, -0.02), (0, 0, -0.37), 0.048, PANTS)], children=[foot])
        thigh = Body(f"thigh_{side}", (0, sgn * 0.09, -0.05),
                     tri(f"hip_{side}", kl, flex=(-0.5, 2.0), abd=(-0.5, 0.8), rot=(-0.6, 0.6),
                         side=side, flex_axis=(0, -1, 0)),
                     [cap((0, 0, -0.02), (0, 0, -0.38), 0.07, PANTS)], children=[shank])
        pelvis.children.append(thigh)
        hand = Body(f"hand_{side}b", my((0, 0.26, 0), side),
                    [J(f"wrist_{side}_flex", mirror_axis((1, 0, 0), side), -0.8, 0.8, kl),
                     J(f"wrist_{side}_dev", mirror_axis((0, 0, -1), side), -0.4, 0.4, kl)],
                    [box(my((0, 0.08, 0), side), (0.045, 0.08, 0.015), SKIN)],
                    [site(f"hand_{side}", my((0, 0.08, 0), side))])
        fore = Body(f"forearm_{side}", my((0, 0.3, 0), side),
                    [J(f"elbow_{side}", mirror_axis((0, 0, -1), side), 0.0, 2.5, kl)],
                    [cap(my((0, 0.02, 0), side), my((0, 0.24, 0), side), 0.035, SKIN)],
                    children=[hand])
        upper = Body(f"upperarm_{side}", my((0, 0.19, 0.1), side),
                     [J(f"shoulder_{side}_elev", mirror_axis((1, 0, 0), side), -1.6, 1.4, kl),
                      J(f"shoulder_{side}_fwd", mirror_axis((0, 0, -1), side), -1.0, 1.8, kl),
                      J(f"shoulder_{side}_twist", mirror_axis((0, 1, 0), side), -1.2, 1.2, kl)],
                     [cap(my((0, 0.03, 0), side), my((0, 0.27, 0), side), 0.045, CLOTH)],
                     children=[fore])
        chest.children.append(upper)
    return pelvis


HUMAN_POSES = {
    # Bent knees and elbows, arms down by the sides, a slight forward lean: run / jump.
    "run": {"hip_l_flex": 0.35, "hip_r_flex": 0.35, "knee_l": 0.7, "knee_r": 0.7,
            "ankle_l_flex": 0.3, "ankle_r_flex": 0.3, "lumbar_flex": 0.1,
            "shoulder_l_elev": -1.3, "shoulder_r_elev": -1.3, "elbow_l": 1.5, "elbow_r": 1.5},
    # Arms forward and down to a handle at waist height.
    "push": {"lumbar_flex": 0.12, "shoulder_l_elev": -0.45, "shoulder_r_elev": -0.45,
             "shoulder_l_fwd": 1.25, "shoulder_r_fwd": 1.25, "elbow_l": 0.45, "elbow_r": 0.45,
             "hip_l_flex": 0.05, "hip_r_flex": 0.05, "knee_l": 0.1, "knee_r": 0.1,
             "ankle_l_flex": 0.05, "ankle_r_flex": 0.05},
}


def _keyframes(xml_body: str, poses: dict[str, dict[str, float]], feet: list[str]) -> tuple[str, dict]:
    """Keyframes with the root lowered so the lowest foot geom touches the ground."""
    model = mujoco.MjModel.from_xml_string(xml_body)
    data = mujoco.MjData(model)
    out, qposes = "  <keyframe>\n", {}
    for name, pose in poses.items():
        q = model.qpos0.copy()
        for jn, v in pose.items():
            q[model.jnt_qposadr[model.joint(jn).id]] = v
        data.qpos[:] = q
        mujoco.mj_forward(model, data)
        lowest = min(_geom_bottom(model, data, g) for g in range(model.ngeom)
                     if model.body(model.geom_bodyid[g]).name in feet)
        q[2] -= lowest
        qposes[name] = q
        out += f'    <key name="{name}" qpos="{_f(q)}"/>\n'
    return out + "  </keyframe>\n", qposes


def _geom_bottom(model, data, g) -> float:
    size = model.geom_size[g]
    R = data.geom_xmat[g].reshape(3, 3)
    c = data.geom_xpos[g]
    t = model.geom_type[g]
    if t == mujoco.mjtGeom.mjGEOM_BOX:
        corners = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)])
        return float(np.min(c[2] + (corners * size) @ R.T[:, 2]))
    return float(c[2] - size[0])


def make_human(poses: bool = True) -> tuple[str, dict]:
    tree = human_tree()
    body = write_body(tree, "    ", HUMAN_ARMATURE)
    xml = header("human", "Human: 47 DOF (free root + 41 hinges), Kry et al. 2009 Fig. 3.")
    xml += '    <camera name="side" pos="0.4 -3.6 1.1" xyaxes="1 0 0 0 0.15 1" mode="trackcom"/>\n'
    xml += body + "  </worldbody>\n"
    feet = ["foot_lb", "foot_rb", "toes_l", "toes_r"]
    keys = "  <keyframe>\n" + f'    <key name="tpose" qpos="{_f(_zero_qpos(xml))}"/>\n  </keyframe>\n'
    qposes = {}
    if poses:
        extra, qposes = _keyframes(xml + "</mujoco>\n", HUMAN_POSES, feet)
        keys = keys.replace("  </keyframe>\n", "") + extra.replace("  <keyframe>\n", "")
    return xml + keys + "</mujoco>\n", qposes


def _zero_qpos(xml: str) -> np.ndarray:
    return mujoco.MjModel.from_xml_string(xml + "</mujoco>\n").qpos0.copy()


CART_MASS = 15.0


def make_human_cart() -> str:
    human_xml, qposes = make_human()
    model = mujoco.MjModel.from_xml_string(human_xml)
    data = mujoco.MjData(model)
    data.qpos[:] = qposes["push"]
    mujoco.mj_forward(model, data)
    hl = data.site("hand_l").xpos.copy()
    hr = data.site("hand_r").xpos.copy()
    if abs(hl[0] - hr[0]) > 1e-9 or abs(hl[2] - hr[2]) > 1e-9:
        raise ModelError("push pose is not symmetric: the handle would not be straight")
    hx, hz = hl[0], hl[2]
    # The cart: a basket ahead of the handle, its frame at the handle's centre.
    basket_c = (0.45, 0.0, -0.35)
    basket_s = (0.3, 0.25, 0.2)
    vol = 8 * basket_s[0] * basket_s[1] * basket_s[2]
    density = CART_MASS / vol
    cart = f"""    <body name="cart" pos="{hx:.10g} 0 {hz:.10g}">
      <joint name="cart_slide" type="slide" axis="1 0 0" damping="1" armature="0.01"/>
      <geom name="handle" type="capsule" fromto="0 {hl[1] + 0.05:.6g} 0 0 {hr[1] - 0.05:.6g} 0"
            size="0.015" density="500" rgba="0.2 0.2 0.2 1" contype="0" conaffinity="0"/>
      <geom name="basket" type="box" pos="{_f(basket_c)}" size="{_f(basket_s)}"
            density="{density:.6g}" rgba="0.6 0.65 0.7 0.6" contype="0" conaffinity="0"/>
      <geom type="capsule" fromto="0 0.2 0 0.15 0.2 -0.15" size="0.012" density="200"
            rgba="0.2 0.2 0.2 1" contype="0" conaffinity="0"/>
      <geom type="capsule" fromto="0 -0.2 0 0.15 -0.2 -0.15" size="0.012" density="200"
            rgba="0.2 0.2 0.2 1" contype="0" conaffinity="0"/>
"""
    for wx in (0.2, 0.7):
        for wy in (-0.22, 0.22):
            cart += (f'      <geom type="cylinder" pos="{wx} {wy} {-hz + 0.06:.6g}" '
                     f'size="0.06 0.015" euler="1.5708 0 0" density="300" rgba="0.1 0.1 0.1 1" '
                     'contype="0" conaffinity="0"/>\n')
    cart += (f'      <site name="handle_l" pos="0 {hl[1]:.10g} 0" size="0.015"/>\n'
             f'      <site name="handle_r" pos="0 {hr[1]:.6g} 0" size="0.015"/>\n'
             "    </body>\n")
    xml = human_xml.replace("Human: 47 DOF", "Human pushing a cart: 47 + 1 DOF, hands tied to the handle")
    xml = xml.replace('<mujoco model="human">', '<mujoco model="human_cart">')
    xml = xml.replace("  </worldbody>\n", cart + "  </worldbody>\n")
    eq = """  <equality>
    <!-- The closed loop: each hand is tied to its spot on the handle (3 rows each). -->
    <connect name="grip_l" site1="hand_l" site2="handle_l" solref="0.004 1"/>
    <connect name="grip_r" site1="hand_r" site2="handle_r" solref="0.004 1"/>
  </equality>
"""
    xml = xml.replace("  <keyframe>\n", eq + "  <keyframe>\n")
    # Keyframes need the extra cart coordinate (0 = the handle in the push pose).
    lines = []
    for line in xml.splitlines(keepends=True):
        if line.strip().startswith("<key "):
            line = line.replace('"/>', ' 0"/>')
        lines.append(line)
    xml = "".join(lines)
    m2 = mujoco.MjModel.from_xml_string(xml)
    d2 = mujoco.MjData(m2)
    mujoco.mj_resetDataKeyframe(m2, d2, m2.key("push").id)
    mujoco.mj_forward(m2, d2)
    gap = max(np.linalg.norm(d2.site(f"hand_{s}").xpos - d2.site(f"handle_{s}").xpos) for s in "lr")
    if gap > 1e-6:
        raise ModelError(f"hands miss the handle by {gap} m in the push pose")
    return xml


def build_all() -> dict[str, str]:
    """Each file name and its XML text."""
    return {"dog.xml": make_dog(), "human.xml": make_human()[0], "human_cart.xml": make_human_cart()}


def write(out: str | Path) -> list[Path]:
    """Write every file into the folder ``out``; returns the paths written."""
    paths = []
    for name, text in build_all().items():
        path = Path(out, name)
        with atomic_path(path) as tmp:
            tmp.write_text(text)
        paths.append(path)
    return paths


def main(argv: list[str] | None = None) -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--print", choices=("dog", "human", "human_cart"), help="print one file")
    p.add_argument("--out", default=None,
                   help="output folder (default: the bundled creatures/ folder the package loads)")
    args = p.parse_args(argv)
    if args.print:
        print(build_all()[f"{args.print}.xml"])
        return
    for path in write(args.out or asset_dir("creatures")):
        m = mujoco.MjModel.from_xml_path(str(path))
        mass = float(np.sum(m.body_mass))
        print(f"wrote {path}: nv={m.nv} nq={m.nq} bodies={m.nbody - 1} mass={mass:.2f} kg")


if __name__ == "__main__":
    main()
