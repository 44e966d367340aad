"""The dove: parameters (from ``flapsim/bird/body/data/dove.toml``), MJCF generation, and the
feather polygons the force engine acts on.

Skeleton (the flight paper, sec. 3.1): trunk on a free joint (unactuated), per side an
upper arm (shoulder: flap, sweep, twist), forearm (elbow: flex, twist) and hand (wrist:
flex), and a tail (bend, spread): 14 actuated DOF. Joint conventions are mirror
symmetric: the same angle on the left and right DOF gives mirror-image poses, so a
symmetric wingbeat has equal left/right angles and mirroring swaps them.

* ``*_shoulder_flap``  + raises the wing (elevation), about the trunk's x axis.
* ``*_shoulder_sweep`` + sweeps the wing back (retraction), about z.
* ``*_shoulder_twist`` + pronates (leading edge down), about the upper arm.
* ``*_elbow_flex``     + folds the forearm forward; ``*_elbow_twist`` + pronates.
* ``*_wrist_flex``     + folds the hand back; the primaries fan in with it.
* ``tail_bend``        + tilts the tail up; ``tail_spread`` + opens the fan (the outermost
  rectrices turn outward by this angle, the others in proportion: see below).

Every actuated DOF has an anatomical range (MJCF joint ``range``; the tail spread's on its
tendon) and a torque limit (actuator ``forcerange``), both from ``data/dove.toml`` with
their sources: :func:`dof_ranges` and :func:`torque_limits` return them in
:data:`DOF_NAMES` order, for controllers to refuse wingbeats that leave them.

Feathers: 10 primaries per hand, each a body on two hinges: a *fan* hinge tied to the
wrist angle by a stiff tendon spring (the postpatagial ligament that spreads the
primaries as the wrist extends) and a *twist* hinge about the shaft with the paper's
spring (0.6e-4 N m/rad) and damper (0.6e-5 N m s/rad), range one-sided (0 .. trailing
edge down): the vanes are held closed against the neighbouring feather at the
downstroke and twist open at the upstroke. 9 secondaries per forearm and 3 tertials per
upper arm are fixed to their bone. The tail is one fan of 12 rectrices, each a body on
its own hinge at the tail root (``l_r1_fan`` central .. ``l_r6_fan`` outer, the same on
the right; + turns a rectrix outward on either side). The actuated ``tail_spread`` DOF is
a fixed tendon reading the fan's spread, and a stiff tendon spring per rectrix (the
primaries' mechanism) holds every rectrix at its share of it, so the fan opens with
uniform spacing and no gap (:func:`rectrix_spread_gains`).

No part of the bird collides with itself (feathers have contype = conaffinity = 0,
bones collide only with the world): self-contacts cost ~15x in step time.
"""

from __future__ import annotations

import hashlib
import tomllib
from dataclasses import dataclass, field
from pathlib import Path

import mujoco
import numpy as np

from flapsim.bird.body import feather_geometry as fz
from flapsim.core.assets import asset_path
from flapsim.core.errors import DataFileError, ModelError
from flapsim.fluid.hinges import userdata_size

PARAM_FILE = Path(__file__).resolve().parent / "data" / "dove.toml"
#: Name suffix of the visual-only underside twin of each feather mesh (not a force polygon).
UNDERSIDE = "_under"

SIDE_DOFS = ("shoulder_flap", "shoulder_sweep", "shoulder_twist", "elbow_flex", "elbow_twist",
             "wrist_flex")
#: The 14 actuated DOF, in wingbeat parameter order (shoulder 3, elbow 2, wrist 1 per side; tail 2).
DOF_NAMES: tuple[str, ...] = (
    *(f"l_{n}" for n in SIDE_DOFS), *(f"r_{n}" for n in SIDE_DOFS), "tail_bend", "tail_spread"
)
N_DOF = len(DOF_NAMES)
#: Index permutation that mirrors a 14-vector of joint angles (swap left and right).
MIRROR_PERM = np.array([*range(6, 12), *range(0, 6), 12, 13])


@dataclass(frozen=True)
class DoveParams:
    """All numbers that define the dove model (values and sources: ``data/dove.toml``)."""

    total_mass: float
    """Whole-bird mass, kg (flight paper ~0.170; Dunning 1993)."""
    upper_arm_mass: float
    """Upper-arm mass incl. tertials, kg (Harvard pigeon data scaled by mass)."""
    forearm_mass: float
    """Forearm mass incl. secondaries, kg (same source)."""
    hand_mass: float
    """Hand mass incl. primaries, kg (same source)."""
    tail_mass: float
    """Tail mass incl. rectrices, kg (same source)."""
    trunk_semi_axes: tuple[float, float, float]
    """Trunk ellipsoid semi-axes (x, y, z), m."""
    head_offset: tuple[float, float, float]
    """Head centre from the trunk centre, m."""
    head_radius: float
    """Head sphere radius, m."""
    head_mass_fraction: float
    """Share of the trunk+head mass in the head (inertia only)."""
    body_drag_cd: float
    """Bluff-body drag coefficient of trunk and head on the trunk's frontal section
    (Pennycuick et al. 1988: bird bodies 0.2-0.4)."""
    shoulder_pos: tuple[float, float, float]
    """Left shoulder joint from the trunk centre, m (right: mirrored)."""
    shoulder_pitch_deg: float
    """Fixed nose-up angle between trunk and wing at the neutral pose, deg (tuned, as in the paper)."""
    upper_arm_length: float
    """Humerus length, m."""
    forearm_length: float
    """Ulna length, m."""
    hand_length: float
    """Carpometacarpus + digits length, m."""
    leading_edge_offset: float
    """Coverts/patagium ahead of the bones, m."""
    primary_mass: float
    """Mass of one primary, kg."""
    secondary_mass: float
    """Mass of one secondary, kg."""
    tertial_mass: float
    """Mass of one tertial, kg."""
    primary_angle_deg: tuple[float, ...]
    """P1..P10 shaft angle back from the hand axis at the extended wrist, deg."""
    primary_length: tuple[float, ...]
    """P1..P10 lengths, m."""
    primary_root_width: float
    """Exposed primary vane width at the root, m."""
    primary_tip_width: float
    """Exposed primary vane width near the tip, m."""
    primary_lead_fraction: float
    """Share of the primary's width ahead of its shaft (narrow outer vane)."""
    twist_stiffness: float
    """Primary twist spring, N m/rad (paper: 0.6e-4)."""
    twist_damping: float
    """Primary twist damper, N m s/rad (paper: 0.6e-5)."""
    twist_max_deg: float
    """Largest primary twist (trailing edge down), deg; the other direction is blocked at 0."""
    fan_fold_wrist_deg: float
    """Wrist flexion at which the primaries lie along the hand, deg."""
    fan_stiffness: float
    """Tendon spring tying each primary's fan angle to the wrist, N m/rad."""
    fan_damping: float
    """Damper of that tendon, N m s/rad."""
    primary_segments: int
    """Quads along a primary's shaft."""
    secondary_length: tuple[float, ...]
    """Secondary lengths from the innermost (S9) to the outermost (S1), m."""
    secondary_outward_deg: tuple[float, ...]
    """Secondary splay toward the tip, inner -> outer, deg."""
    secondary_segments: int
    """Quads along a secondary."""
    tertial_length: tuple[float, ...]
    """Tertial lengths, inner -> outer, m."""
    tertial_inward_deg: tuple[float, ...]
    """Tertial splay toward the body, inner -> outer, deg."""
    tertial_segments: int
    """Quads along a tertial."""
    tail_root_pos: tuple[float, float, float]
    """Tail root (bend hinge) from the trunk centre, m."""
    rectrices_per_side: int
    """Rectrices on each side of the fan's centre line."""
    rectrix_length: float
    """Rectrix length, m."""
    rectrix_width: float
    """Exposed rectrix width, m."""
    tail_spacing_deg: float
    """Angle between neighbouring rectrices of the closed fan, deg (uniform)."""
    tail_fan_stiffness: float
    """Tendon spring holding each rectrix on the fan's shape, N m/rad."""
    tail_fan_damping: float
    """Its damper, N m s/rad."""
    rectrix_segments: int
    """Quads along a rectrix."""
    joint_damping: float
    """Passive damping on the 14 actuated DOF, N m s/rad."""
    joint_armature: float
    """Armature on the 14 actuated DOF, kg m^2."""
    pd_kp: float
    """PD stiffness of the wing/tail servos, N m/rad (paper: 10)."""
    pd_kv: float
    """PD damping of the servos, N m s/rad (paper: 0.002)."""
    timestep: float
    """Integration step, s (paper: 1/2400)."""
    dof_range_deg: tuple[tuple[float, float], ...] = ()
    """(lo, hi) joint range of each of the 14 DOF in :data:`DOF_NAMES` order, deg, in the
    model's sign conventions (left and right equal: mirror-symmetric joints). Anatomical
    ranges of pigeons/doves; sources in ``data/dove.toml`` [limits]."""
    limit_solref: tuple[float, float] = (0.004, 1.0)
    """MuJoCo solref (time constant s, damping ratio) of the joint-range constraints."""
    dof_torque_limit: tuple[tuple[float, float], ...] = ()
    """(lo, hi) actuator torque limit of each of the 14 DOF, N m (tail spread: N m per rad
    of its tendon); sources in ``data/dove.toml`` [torque]."""
    source: str = field(default="", compare=False)
    """Path of the parameter file these values came from."""

    @classmethod
    def load(cls, path: str | Path = PARAM_FILE) -> DoveParams:
        """Read a dove parameter file (TOML), with a one-line error on a bad file."""
        path = Path(path)
        try:
            raw = tomllib.loads(path.read_text())
        except FileNotFoundError:
            raise DataFileError(f"dove parameter file {path} does not exist") from None
        except tomllib.TOMLDecodeError as exc:
            raise DataFileError(f"dove parameter file {path} is not valid TOML: {exc}") from None
        try:
            b, w, p, s, tl, t, j, pd = (raw[k] for k in ("body", "wing", "primaries", "secondaries",
                                                        "tertials", "tail", "joints", "control"))
            g = 1e-3
            params = cls(
                total_mass=b["total_mass"], upper_arm_mass=b["upper_arm_mass_g"] * g,
                forearm_mass=b["forearm_mass_g"] * g, hand_mass=b["hand_mass_g"] * g,
                tail_mass=b["tail_mass_g"] * g, trunk_semi_axes=tuple(b["trunk_semi_axes"]),
                head_offset=tuple(b["head_offset"]), head_radius=b["head_radius"],
                head_mass_fraction=b["head_mass_fraction"], body_drag_cd=b["drag_cd"],
                shoulder_pos=tuple(w["shoulder_pos"]), shoulder_pitch_deg=w["shoulder_pitch_deg"],
                upper_arm_length=w["upper_arm_length"], forearm_length=w["forearm_length"],
                hand_length=w["hand_length"], leading_edge_offset=w["leading_edge_offset"],
                primary_mass=w["primary_mass_g"] * g, secondary_mass=w["secondary_mass_g"] * g,
                tertial_mass=w["tertial_mass_g"] * g,
                primary_angle_deg=tuple(p["angle_deg"]), primary_length=tuple(p["length"]),
                primary_root_width=p["root_width"], primary_tip_width=p["tip_width"],
                primary_lead_fraction=p["leading_vane_fraction"],
                twist_stiffness=p["twist_stiffness"], twist_damping=p["twist_damping"],
                twist_max_deg=p["twist_max_deg"], fan_fold_wrist_deg=p["fan_fold_wrist_deg"],
                fan_stiffness=p["fan_stiffness"], fan_damping=p["fan_damping"],
                primary_segments=p["segments"],
                secondary_length=tuple(s["length"]), secondary_outward_deg=tuple(s["outward_deg"]),
                secondary_segments=s["segments"],
                tertial_length=tuple(tl["length"]), tertial_inward_deg=tuple(tl["inward_deg"]),
                tertial_segments=tl["segments"],
                tail_root_pos=tuple(t["root_pos"]), rectrices_per_side=t["rectrices_per_side"],
                rectrix_length=t["length"], rectrix_width=t["width"],
                tail_spacing_deg=t["closed_spacing_deg"], tail_fan_stiffness=t["fan_stiffness"],
                tail_fan_damping=t["fan_damping"], rectrix_segments=t["segments"],
                joint_damping=j["damping"], joint_armature=j["armature"],
                pd_kp=pd["kp"], pd_kv=pd["kv"], timestep=pd["timestep"],
                dof_range_deg=_per_dof(raw["limits"], "_deg"),
                limit_solref=tuple(raw["limits"]["solref"]),
                dof_torque_limit=_per_dof(raw["torque"], ""),
                source=str(path),
            )
        except KeyError as exc:
            raise DataFileError(f"dove parameter file {path} lacks key {exc}") from None
        params.validate()
        return params

    def validate(self) -> None:
        n = len(self.primary_angle_deg)
        if len(self.primary_length) != n:
            raise DataFileError("primaries: angle_deg and length need the same count")
        if len(self.secondary_length) != len(self.secondary_outward_deg):
            raise DataFileError("secondaries: length and outward_deg need the same count")
        if len(self.tertial_length) != len(self.tertial_inward_deg):
            raise DataFileError("tertials: length and inward_deg need the same count")
        wing_parts = 10 * 0 + self.upper_arm_mass + self.forearm_mass + self.hand_mass
        if self.total_mass <= 2 * wing_parts + self.tail_mass:
            raise DataFileError("body: total_mass must exceed the wing and tail masses")
        if self.hand_mass <= n * self.primary_mass:
            raise DataFileError("hand mass must exceed the primaries' mass")
        for label, pairs in (("limits", self.dof_range_deg), ("torque", self.dof_torque_limit)):
            if len(pairs) != N_DOF:
                raise DataFileError(f"{label}: need (lo, hi) for each of the {N_DOF} DOF")
            for name, (lo, hi) in zip(DOF_NAMES, pairs, strict=True):
                if not lo < hi:
                    raise DataFileError(f"{label}: {name} needs lo < hi, got [{lo}, {hi}]")
                if label == "torque" and not lo < 0 < hi:
                    raise DataFileError(f"torque: {name} must allow both directions (lo < 0 < hi)")

    @property
    def trunk_mass(self) -> float:
        """Trunk + head mass: the total minus wings and tail, kg."""
        return self.total_mass - 2 * (self.upper_arm_mass + self.forearm_mass + self.hand_mass) \
            - self.tail_mass


def _per_dof(section: dict, suffix: str) -> tuple[tuple[float, float], ...]:
    """(lo, hi) per DOF in :data:`DOF_NAMES` order from a TOML section keyed by the
    side-free DOF name (``shoulder_flap``, ..., ``tail_spread``) + ``suffix``."""
    out = []
    for name in DOF_NAMES:
        key = (name[2:] if name[:2] in ("l_", "r_") else name) + suffix
        lo, hi = section[key]
        out.append((float(lo), float(hi)))
    return tuple(out)


def dof_ranges(params: DoveParams) -> tuple[np.ndarray, np.ndarray]:
    """Joint ranges of the 14 actuated DOF: (lo (14,), hi (14,)) in rad, in
    :data:`DOF_NAMES` order (the tail spread's is its tendon's). A commanded wingbeat
    whose targets leave them asks for an anatomically impossible pose."""
    r = np.radians(np.array(params.dof_range_deg, dtype=float).reshape(N_DOF, 2))
    return r[:, 0].copy(), r[:, 1].copy()


def torque_limits(params: DoveParams) -> tuple[np.ndarray, np.ndarray]:
    """Actuator torque limits of the 14 DOF: (lo (14,), hi (14,)), N m, DOF_NAMES order."""
    t = np.array(params.dof_torque_limit, dtype=float).reshape(N_DOF, 2)
    return t[:, 0].copy(), t[:, 1].copy()


# -- geometry --------------------------------------------------------------------------------


def left_feathers(p: DoveParams) -> list[fz.Feather]:
    """All left-wing feathers and the left half of the tail fan, in their bodies' frames."""
    out: list[fz.Feather] = []
    le = p.leading_edge_offset
    # tertials on the upper arm (body frame origin at the shoulder, bone along +y)
    nt = len(p.tertial_length)
    spacing = p.upper_arm_length / nt
    for k, (length, inward) in enumerate(zip(p.tertial_length, p.tertial_inward_deg, strict=True)):
        a = np.radians(inward)
        shaft = np.array([-np.cos(a), -np.sin(a), 0.0])
        root = np.array([le, (k + 0.5) * spacing, 0.0])
        v, f = fz.strip(root, shaft, np.array([np.sin(a), -np.cos(a), 0.0]) * -1, length + le,
                        spacing, spacing, 0.5, p.tertial_segments, tip_taper=0.8)
        out.append(_feather(f"l_t{k + 1}", "tertial", "l_humerus", v, f, shaft, p.tertial_mass))
    # secondaries on the forearm, listed inner (S9) -> outer (S1)
    ns = len(p.secondary_length)
    spacing = p.forearm_length / ns
    for k, (length, out_deg) in enumerate(zip(p.secondary_length, p.secondary_outward_deg,
                                              strict=True)):
        a = np.radians(out_deg)
        shaft = np.array([-np.cos(a), np.sin(a), 0.0])
        root = np.array([le, (k + 0.5) * spacing, 0.0])
        v, f = fz.strip(root, shaft, np.array([np.sin(a), np.cos(a), 0.0]), length + le,
                        spacing, spacing, 0.5, p.secondary_segments, tip_taper=0.8)
        out.append(_feather(f"l_s{ns - k}", "secondary", "l_forearm", v, f, shaft,
                            p.secondary_mass))
    # primaries: each in its own body whose origin is the feather root
    for k, (ang, length) in enumerate(zip(p.primary_angle_deg, p.primary_length, strict=True)):
        a = np.radians(ang)
        shaft = np.array([-np.sin(a), np.cos(a), 0.0])
        lead = np.array([np.cos(a), np.sin(a), 0.0])
        v, f = fz.strip(np.zeros(3), shaft, lead, length, p.primary_root_width,
                        p.primary_tip_width, p.primary_lead_fraction, p.primary_segments)
        out.append(_feather(f"l_p{k + 1}", "primary", f"l_p{k + 1}", v, f, shaft, p.primary_mass))
    # left rectrices, central -> outer: each its own body with its origin at the tail root,
    # meshed at its closed-fan angle (the fan hinge turns it from there)
    for k in range(p.rectrices_per_side):
        a = np.radians((k + 0.5) * p.tail_spacing_deg)
        shaft = np.array([-np.cos(a), np.sin(a), 0.0])
        lead = np.array([np.sin(a), np.cos(a), 0.0])
        v, f = fz.strip(np.zeros(3), shaft, lead, p.rectrix_length, 0.6 * p.rectrix_width,
                        p.rectrix_width, 0.5, p.rectrix_segments, tip_taper=0.8)
        out.append(_feather(f"l_r{k + 1}", "rectrix", f"l_r{k + 1}", v, f, shaft,
                            rectrix_mass(p)))
    return out


def rectrix_mass(p: DoveParams) -> float:
    """Each rectrix carries an equal share of 80% of the tail mass (the rest is the base)."""
    return 0.8 * p.tail_mass / (2 * p.rectrices_per_side)


def _feather(name, kind, body, v, f, shaft, mass) -> fz.Feather:
    fwd = fz.in_plane_forward(v[f])
    return fz.Feather(name, kind, body, v, f, np.asarray(shaft, float), fwd, float(mass))


def mirror_feather(fe: fz.Feather) -> fz.Feather:
    """The right-side twin of a left feather."""
    return fz.Feather(
        "r" + fe.name[1:], fe.kind, _mirror_name(fe.body), fz.mirror_point(fe.vertices),
        fz.mirror_faces(fe.faces), fz.mirror_point(fe.shaft), fz.mirror_point(fe.forward), fe.mass,
    )


def _mirror_name(name: str) -> str:
    if name.startswith("l_"):
        return "r_" + name[2:]
    return name


def all_feathers(p: DoveParams) -> list[fz.Feather]:
    left = left_feathers(p)
    return left + [mirror_feather(f) for f in left]


def primary_root(p: DoveParams, k: int) -> np.ndarray:
    """Root of primary k (0-based, P1 innermost) in the hand frame: spread along the hand."""
    n = len(p.primary_angle_deg)
    return np.array([0.0, p.hand_length * k / (n - 1), 0.0])


def rectrix_joints(p: DoveParams) -> list[str]:
    """Fan hinge of every rectrix: left central -> outer, then right central -> outer."""
    n = p.rectrices_per_side
    return [f"{s}_r{k + 1}_fan" for s in "lr" for k in range(n)]


def rectrix_spread_gains(p: DoveParams) -> tuple[np.ndarray, np.ndarray]:
    """How the one fan spreads: (g, c), each (2 n,) in :func:`rectrix_joints` order.

    Rectrix k turns by ``g_k s`` when the fan spreads by ``s`` (the tail_spread DOF: the
    outermost pair's angle beyond the closed fan), ``g_k = (j - 1/2) / (n - 1/2)`` for the
    j-th rectrix from the centre (1..n): uniform spacing at every spread. The tail_spread
    tendon reads ``s = c . q`` with ``c = g / |g|^2`` (so ``c . g = 1``), and the coupling
    springs act on ``q - g (c . q)``: an orthogonal projector whose null space is exactly the
    spread mode, so they resist every distortion of the fan and never the spread itself.
    """
    n = p.rectrices_per_side
    half = (np.arange(n) + 0.5) / (n - 0.5)
    g = np.concatenate([half, half])
    return g, g / (g @ g)


def fan_ratio(p: DoveParams, k: int) -> float:
    """Fan-in angle of primary k per radian of wrist flexion (it reaches the hand axis at
    ``fan_fold_wrist_deg``)."""
    return float(p.primary_angle_deg[k] / p.fan_fold_wrist_deg)


# -- inertia ---------------------------------------------------------------------------------


class _Inertia:
    """Sum of rigid parts: mass, centre of mass and inertia tensor (about the com)."""

    def __init__(self) -> None:
        self.parts: list[tuple[float, np.ndarray, np.ndarray]] = []

    def add(self, mass: float, com, inertia) -> None:
        self.parts.append((float(mass), np.asarray(com, float), np.asarray(inertia, float)))

    def rod(self, mass: float, a, b, radius: float = 0.003) -> None:
        a, b = np.asarray(a, float), np.asarray(b, float)
        L = np.linalg.norm(b - a)
        u = (b - a) / L
        i_perp = mass * (L**2 / 12 + radius**2 / 4)
        i_ax = mass * radius**2 / 2
        self.add(mass, (a + b) / 2, i_perp * np.eye(3) + (i_ax - i_perp) * np.outer(u, u))

    def ellipsoid(self, mass: float, c, semi) -> None:
        a, b, cc = semi
        self.add(mass, c, mass / 5 * np.diag([b * b + cc * cc, a * a + cc * cc, a * a + b * b]))

    def plates(self, feathers: list[fz.Feather]) -> None:
        for fe in feathers:
            com, inertia = fz.plate_inertia(fe.triangles, fe.mass)
            self.add(fe.mass, com, inertia)

    def total(self) -> tuple[float, np.ndarray, np.ndarray]:
        m = sum(p[0] for p in self.parts)
        com = sum(p[0] * p[1] for p in self.parts) / m
        inertia = np.zeros((3, 3))
        for mi, ci, ii in self.parts:
            r = ci - com
            inertia += ii + mi * (r @ r * np.eye(3) - np.outer(r, r))
        return m, com, inertia


def _inertial_xml(inert: _Inertia) -> str:
    m, com, i = inert.total()
    full = (i[0, 0], i[1, 1], i[2, 2], i[0, 1], i[0, 2], i[1, 2])
    return (f'<inertial pos="{_v(com)}" mass="{m:.6g}" '
            f'fullinertia="{" ".join(f"{x:.6g}" for x in full)}"/>')


def _v(a) -> str:
    return " ".join(f"{x:.6g}" for x in np.asarray(a, float).ravel())


# -- MJCF ------------------------------------------------------------------------------------

_HEADER = """<mujoco model="dove">
  <!-- GENERATED by scripts/dove_generate.py from {source}; do not edit by hand.
       Collared dove (Streptopelia decaocto), {mass:.3f} kg, wingspan {span:.3f} m,
       14 actuated DOF, {nfeather} feathers, {ntri} feather triangles. -->
  <compiler angle="radian" inertiafromgeom="false" autolimits="true"/>
  <option timestep="{dt:.10g}" integrator="implicitfast" gravity="0 0 -9.81"
          density="0" viscosity="0" iterations="20" ls_iterations="10">
    <flag energy="disable"/>
  </option>
  <size memory="4M"/>
  <visual>
    <global offwidth="1280" offheight="720"/>
    <quality shadowsize="2048"/>
    <map znear="0.01" zfar="500"/>
  </visual>
  <!-- extent sets the clip planes and visual scales: the bird's size, not the ground's -->
  <statistic extent="0.5" center="0 0 10"/>
  <default>
    <joint damping="{jdamp:.6g}" armature="{jarm:.6g}"/>
    <geom contype="0" conaffinity="0"/>
    <general gaintype="fixed" biastype="affine" gainprm="1" biasprm="0 {nkp:.6g} {nkv:.6g}"/>
    <default class="bone">
      <geom type="capsule" size="0.004" rgba="0.55 0.48 0.42 1" contype="2" conaffinity="1"/>
    </default>
    <default class="feather">
      <geom type="mesh" rgba="0.70 0.66 0.62 1"/>
    </default>
    <default class="primary">
      <geom type="mesh" rgba="0.50 0.47 0.45 1"/>
      <joint damping="0" armature="0"/>
    </default>
    <default class="rectrix">
      <geom type="mesh" rgba="0.60 0.56 0.52 1"/>
    </default>
  </default>
  <asset>
    <texture name="sky" type="skybox" builtin="gradient" rgb1="0.55 0.70 0.90" rgb2="0.95 0.97 1"
             width="512" height="512"/>
    <texture name="grid" type="2d" builtin="checker" rgb1="0.42 0.55 0.33" rgb2="0.36 0.48 0.28"
             width="512" height="512" mark="edge" markrgb="0.3 0.4 0.25"/>
    <material name="grid" texture="grid" texrepeat="200 200" reflectance="0"/>
    <material name="plumage" rgba="0.80 0.76 0.70 1" specular="0.1"/>
{meshes}
  </asset>
  <worldbody>
    <light name="sun" directional="true" pos="0 0 50" dir="-0.3 0.2 -1" diffuse="0.8 0.8 0.8"/>
    <geom name="ground" type="plane" size="2000 2000 0.1" material="grid" contype="0"
          conaffinity="0"/>
"""


def build_xml(p: DoveParams, fixed_trunk_pitch_deg: float | None = None,
              modal: object | None = None, twist: str | None = None) -> str:
    """The complete dove MJCF as a string (meshes inline).

    ``fixed_trunk_pitch_deg``: weld the trunk to the world (no free joint) at this nose-up
    pitch, for "wind tunnel" measurements. ``modal``: a
    :class:`~flapsim.bird.body.feather_modes.ModalParams`: with ``integration="engine"`` (its
    default) the rigid model with room in ``userdata`` for the modes the force engine
    integrates (:func:`flapsim.bird.body.feather_dynamics.modal_engine`); with ``"joints"`` each
    feather's modes as point-mass bodies on slide joints
    (:func:`flapsim.bird.body.feather_dynamics.modal_xml`); ``None`` (default) is the rigid-feather
    model, unchanged. ``twist``: where the primaries' twist
    hinges are: ``"separate"`` (the rigid default) on weightless bodies hung from the world,
    integrated and clamped by the force engine (:mod:`flapsim.fluid.hinges`), or ``"tree"``
    (the modal joints' default, and the drawing model :meth:`Dove.drawing`) in each primary's
    body, with a MuJoCo joint limit as the stop.
    """
    joints = modal is not None and modal.integration == "joints"
    twist = twist or ("tree" if joints else "separate")
    if twist not in ("separate", "tree"):
        raise ModelError(f"twist must be 'separate' or 'tree', got {twist!r}")
    if twist == "separate" and joints:
        raise ModelError("modal feathers on joints hang their modes on the twisted feather: twist='tree'")
    if twist == "tree" and modal is not None and not joints:
        raise ModelError("engine-integrated modal feathers ride the separate twist hinges: twist='separate'")
    feathers = all_feathers(p)
    by_body: dict[str, list[fz.Feather]] = {}
    for fe in feathers:
        by_body.setdefault(fe.body, []).append(fe)
    meshes = []
    for fe in feathers:
        meshes.append(f'    <mesh name="{fe.name}" vertex="{_v(fe.vertices)}" '
                      f'face="{" ".join(str(int(i)) for i in fe.faces.ravel())}" inertia="shell"/>')
        # the underside: MuJoCo culls back faces, so a visual twin with reversed winding
        meshes.append(f'    <mesh name="{fe.name}{UNDERSIDE}" vertex="{_v(fe.vertices)}" '
                      f'face="{" ".join(str(int(i)) for i in fe.faces[:, ::-1].ravel())}" '
                      'inertia="shell"/>')
    span = 2 * max(np.max(np.abs(_world_tip_y(p))), 0)
    out = [_HEADER.format(
        source=Path(p.source).name or "dove.toml", mass=p.total_mass, span=span,
        nfeather=len(feathers), ntri=sum(len(f.faces) for f in feathers), dt=p.timestep,
        jdamp=p.joint_damping, jarm=p.joint_armature, nkp=-p.pd_kp, nkv=-p.pd_kv,
        meshes="\n".join(meshes),
    )]
    trunk = _trunk_xml(p, by_body, twist)
    if fixed_trunk_pitch_deg is not None:
        th = np.radians(fixed_trunk_pitch_deg)
        trunk = trunk.replace('      <freejoint name="root"/>\n', "").replace(
            '<body name="trunk" pos="0 0 10">',
            f'<body name="trunk" pos="0 0 10" quat="{_v((np.cos(th / 2), 0, -np.sin(th / 2), 0))}">')
    out.append(trunk)
    if twist == "separate":
        out.append(_twist_bodies_xml(p, by_body))
        # the hinges' memory of their bones' velocities (flapsim.fluid.hinges), then the
        # engine-integrated modes' state (flapsim.bird.body.feather_dynamics)
        nud = userdata_size(2 * len(p.primary_angle_deg))
        if modal is not None:
            from flapsim.bird.body.feather_dynamics import engine_userdata_size

            nud += engine_userdata_size(len(feathers), modal.modes)
        out[0] = out[0].replace('<size memory="4M"/>', f'<size memory="4M" nuserdata="{nud}"/>')
    out.append("  </worldbody>\n")
    out.append(_tendons_xml(p))
    out.append(_actuators_xml(p))
    out.append(_sensors_xml())
    out.append("</mujoco>\n")
    if joints:
        from flapsim.bird.body.feather_dynamics import modal_xml

        return modal_xml("".join(out), p, modal)
    return "".join(out)


def _world_tip_y(p: DoveParams) -> np.ndarray:
    y0 = p.shoulder_pos[1] + p.upper_arm_length + p.forearm_length
    tips = []
    for k, (a, L) in enumerate(zip(p.primary_angle_deg, p.primary_length, strict=True)):
        tips.append(y0 + primary_root(p, k)[1] + L * np.cos(np.radians(a)))
    return np.array(tips)


def _trunk_xml(p: DoveParams, by_body: dict[str, list[fz.Feather]], twist: str = "tree") -> str:
    tr = _Inertia()
    mh = p.trunk_mass * p.head_mass_fraction
    tr.ellipsoid(p.trunk_mass - mh, (0, 0, 0), p.trunk_semi_axes)
    r = p.head_radius
    tr.ellipsoid(mh, p.head_offset, (r, r, r))
    ho = np.asarray(p.head_offset)
    beak_a = ho + np.array([0.8 * r, 0, -0.2 * r])
    beak_b = ho + np.array([1.9 * r, 0, -0.45 * r])
    eye = ho + np.array([0.45 * r, 0.62 * r, 0.35 * r])
    ax, ay, az = p.trunk_semi_axes
    lines = [
        '    <body name="trunk" pos="0 0 10">',
        '      <freejoint name="root"/>',
        f"      {_inertial_xml(tr)}",
        f'      <geom name="trunk" type="ellipsoid" size="{ax} {ay} {az}" material="plumage"'
        ' contype="2" conaffinity="1"/>',
        f'      <geom name="neck" type="ellipsoid" size="{0.55 * ax:.4g} {0.8 * ay:.4g} '
        f'{0.8 * az:.4g}" pos="{_v(0.5 * ho + np.array([0, 0, 0.004]))}" euler="0 -0.5 0" '
        'material="plumage"/>',
        f'      <geom name="head" type="sphere" size="{r}" pos="{_v(ho)}" '
        'rgba="0.72 0.68 0.66 1" contype="2" conaffinity="1"/>',
        f'      <geom name="beak" type="capsule" size="{0.22 * r:.4g}" fromto="{_v(beak_a)} '
        f'{_v(beak_b)}" rgba="0.15 0.12 0.12 1"/>',
        f'      <geom name="l_eye" type="sphere" size="{0.16 * r:.4g}" pos="{_v(eye)}" '
        'rgba="0.05 0.02 0.02 1"/>',
        f'      <geom name="r_eye" type="sphere" size="{0.16 * r:.4g}" '
        f'pos="{_v(fz.mirror_point(eye))}" rgba="0.05 0.02 0.02 1"/>',
        '      <site name="com_marker" pos="0 0 0" size="0.004"/>',
        '      <camera name="side" pos="0 -0.9 0.05" xyaxes="1 0 0 0 0.1 1" mode="trackcom"/>',
    ]
    for side in ("l", "r"):
        lines.append(_wing_xml(p, side, by_body, twist))
    lines.append(_tail_xml(p, by_body))
    lines.append("    </body>")
    return "\n".join(lines) + "\n"


def _ax(side: str, a) -> str:
    a = np.asarray(a, float)
    return _v(a if side == "l" else fz.mirror_axis(a))


def _pt(side: str, a) -> str:
    a = np.asarray(a, float)
    return _v(a if side == "l" else fz.mirror_point(a))


def _feather_geoms(fes: list[fz.Feather], cls: str, indent: str) -> list[str]:
    out = []
    for fe in fes:
        out.append(f'{indent}<geom name="{fe.name}" class="{cls}" mesh="{fe.name}"/>')
        out.append(f'{indent}<geom name="{fe.name}{UNDERSIDE}" class="{cls}" '
                   f'mesh="{fe.name}{UNDERSIDE}"/>')
    return out


def _wing_xml(p: DoveParams, s: str, by_body, twist: str = "tree") -> str:
    th = np.radians(p.shoulder_pitch_deg)
    quat = (np.cos(-th / 2), 0.0, np.sin(-th / 2), 0.0)  # nose-up incidence about +y (both sides)
    Lh, Lf, Lw = p.upper_arm_length, p.forearm_length, p.hand_length
    tert = by_body[f"{s}_humerus"]
    sec = by_body[f"{s}_forearm"]
    hum = _Inertia()
    hum.rod(p.upper_arm_mass - sum(f.mass for f in tert), (0, 0, 0), (0, Lh if s == "l" else -Lh, 0))
    hum.plates(tert)
    fore = _Inertia()
    fore.rod(p.forearm_mass - sum(f.mass for f in sec), (0, 0, 0), (0, Lf if s == "l" else -Lf, 0))
    fore.plates(sec)
    hand = _Inertia()
    n_prim = len(p.primary_angle_deg)
    hand.rod(p.hand_mass - n_prim * p.primary_mass, (0, 0, 0), (0, Lw if s == "l" else -Lw, 0),
             radius=0.005)
    i1, i2, i3 = "      ", "        ", "          "
    L = [
        f'{i1}<body name="{s}_humerus" pos="{_pt(s, p.shoulder_pos)}" quat="{_v(quat)}">',
        f"{i2}{_inertial_xml(hum)}",
        f'{i2}<joint name="{s}_shoulder_flap" axis="{_ax(s, (1, 0, 0))}"'
        f'{_lim(p, "shoulder_flap")}/>',
        f'{i2}<joint name="{s}_shoulder_sweep" axis="{_ax(s, (0, 0, 1))}"'
        f'{_lim(p, "shoulder_sweep")}/>',
        f'{i2}<joint name="{s}_shoulder_twist" axis="{_ax(s, (0, 1, 0))}"'
        f'{_lim(p, "shoulder_twist")}/>',
        f'{i2}<geom name="{s}_humerus" class="bone" fromto="0 0 0 {_pt(s, (0, Lh, 0))}"/>',
        *_feather_geoms(tert, "feather", i2),
        f'{i2}<body name="{s}_forearm" pos="{_pt(s, (0, Lh, 0))}">',
        f"{i3}{_inertial_xml(fore)}",
        f'{i3}<joint name="{s}_elbow_flex" axis="{_ax(s, (0, 0, -1))}"'
        f'{_lim(p, "elbow_flex")}/>',
        f'{i3}<joint name="{s}_elbow_twist" axis="{_ax(s, (0, 1, 0))}"'
        f'{_lim(p, "elbow_twist")}/>',
        f'{i3}<geom name="{s}_forearm" class="bone" fromto="0 0 0 {_pt(s, (0, Lf, 0))}"/>',
        *_feather_geoms(sec, "feather", i3),
        f'{i3}<body name="{s}_hand" pos="{_pt(s, (0, Lf, 0))}">',
        f"{i3}  {_inertial_xml(hand)}",
        f'{i3}  <joint name="{s}_wrist_flex" axis="{_ax(s, (0, 0, 1))}"'
        f'{_lim(p, "wrist_flex")}/>',
        f'{i3}  <geom name="{s}_hand" class="bone" size="0.0035" '
        f'fromto="0 0 0 {_pt(s, (0, Lw, 0))}"/>',
    ]
    tw = np.radians(p.twist_max_deg)
    for k in range(n_prim):
        fe = by_body[f"{s}_p{k + 1}"][0]
        pi = _Inertia()
        pi.plates([fe])
        left_shaft = fe.shaft if s == "l" else fz.mirror_point(fe.shaft)
        L += [
            f'{i3}  <body name="{s}_p{k + 1}" pos="{_pt(s, primary_root(p, k))}">',
            f"{i3}    {_inertial_xml(pi)}",
            f'{i3}    <joint name="{s}_p{k + 1}_fan" class="primary" axis="{_ax(s, (0, 0, -1))}" '
            f'stiffness="0" damping="0"/>',
        ]
        if twist == "tree":
            # axis -shaft: + turns the trailing vane down (open); the range blocks the other way
            L.append(f'{i3}    <joint name="{s}_p{k + 1}_twist" class="primary" '
                     f'axis="{_ax(s, -left_shaft)}" range="0 {tw:.6g}" '
                     f'stiffness="{p.twist_stiffness:.6g}" damping="{p.twist_damping:.6g}" '
                     'solreflimit="0.001 1" solimplimit="0.95 0.99 0.001"/>')
        else:
            # the twist axis, for the force engine (its DOF is a body of its own: _twist_bodies_xml)
            L.append(f'{i3}    <site name="{s}_p{k + 1}_twist" zaxis="{_ax(s, -left_shaft)}" '
                     'size="0.001" group="5"/>')
        L += [
            *_feather_geoms([fe], "primary", i3 + "    "),
            f"{i3}  </body>",
        ]
    L += [f"{i3}</body>", f"{i2}</body>", f"{i1}</body>"]
    return "\n".join(L)


def can_touch_anything(model: mujoco.MjModel) -> bool:
    """Whether any two geoms of ``model`` could ever make a contact: explicit contact pairs, or
    two geoms on different bodies whose ``contype``/``conaffinity`` bits match. The generated
    dove's bones collide only with the world, and its world has no collider (the forest's
    trees are checked analytically, :mod:`flapsim.bird.tasks.flight_tasks`): then nothing can."""
    if model.npair > 0:
        return True
    ct, ca, body = model.geom_contype, model.geom_conaffinity, model.geom_bodyid
    live = np.flatnonzero((ct | ca) != 0)
    for i, g in enumerate(live):
        h = live[i + 1:]
        hit = ((ct[g] & ca[h]) != 0) | ((ct[h] & ca[g]) != 0)
        if np.any(hit & (body[h] != body[g])):
            return True
    return False


def twist_inertia(fe: fz.Feather, axis) -> float:
    """A primary's moment of inertia about its twist axis through its root (its body's
    origin): the plate inertia (:func:`~flapsim.bird.body.feather_geometry.plate_inertia`), kg m^2."""
    pi = _Inertia()
    pi.plates([fe])
    m, c, i = pi.total()
    u = np.asarray(axis, float) / np.linalg.norm(axis)
    return float(u @ (i + m * (c @ c * np.eye(3) - np.outer(c, c))) @ u)


def _twist_bodies_xml(p: DoveParams, by_body) -> str:
    """The primaries' twist DOF as the paper integrates them (sec. 6, eq. 10), outside the
    skeleton: per primary a weightless body hung from the world on a hinge with the plate's
    inertia about its twist axis as armature, the paper's spring and damper, and the one-sided
    range that the force engine enforces (:mod:`flapsim.fluid.hinges`). Its axis in the world
    means nothing: the engine turns the feather's polygons about the axis of the feather's
    ``*_twist`` site."""
    tw = np.radians(p.twist_max_deg)
    L = []
    for s in ("l", "r"):
        for k in range(len(p.primary_angle_deg)):
            fe = by_body[f"{s}_p{k + 1}"][0]
            left_shaft = fe.shaft if s == "l" else fz.mirror_point(fe.shaft)
            h = twist_inertia(fe, -(left_shaft if s == "l" else fz.mirror_axis(left_shaft)))
            L += [
                f'    <body name="{s}_p{k + 1}_twist">',
                '      <inertial pos="0 0 0" mass="1e-9" diaginertia="1e-15 1e-15 1e-15"/>',
                f'      <joint name="{s}_p{k + 1}_twist" type="hinge" axis="1 0 0" limited="false" '
                f'range="0 {tw:.6g}" stiffness="{p.twist_stiffness:.6g}" '
                f'damping="{p.twist_damping:.6g}" armature="{h:.6g}"/>',
                "    </body>",
            ]
    return "\n".join(L) + "\n"


def _tail_xml(p: DoveParams, by_body) -> str:
    base = _Inertia()
    base.rod(0.2 * p.tail_mass, (0, 0, 0), (-0.02, 0, 0), radius=0.006)
    L = [
        f'      <body name="tail" pos="{_v(p.tail_root_pos)}">',
        f"        {_inertial_xml(base)}",
        f'        <joint name="tail_bend" axis="0 1 0"{_lim(p, "tail_bend")}/>',
        '        <geom name="tail_base" class="bone" size="0.007" fromto="0.01 0 0 -0.02 0 0"/>',
    ]
    for s in ("l", "r"):
        for k in range(p.rectrices_per_side):
            name = f"{s}_r{k + 1}"
            fe = by_body[name][0]
            ri = _Inertia()
            ri.plates([fe])
            # + turns the rectrix outward (away from the centre line) on both sides; the hinge
            # takes the actuated DOF's damping and armature ([joints]), as the half-fans did
            L += [
                f'        <body name="{name}">',
                f"          {_inertial_xml(ri)}",
                f'          <joint name="{name}_fan" class="rectrix" axis="{_ax(s, (0, 0, -1))}"/>',
                *_feather_geoms([fe], "rectrix", "          "),
                "        </body>",
            ]
    L.append("      </body>")
    return "\n".join(L)


def _tendons_xml(p: DoveParams) -> str:
    joints = rectrix_joints(p)
    g, c = rectrix_spread_gains(p)
    L = ["  <tendon>",
         f'    <fixed name="tail_spread"{_lim(p, "tail_spread", joint=False)}>',
         "      " + "".join(f'<joint joint="{j}" coef="{ck:.9g}"/>'
                            for j, ck in zip(joints, c, strict=True)),
         "    </fixed>"]
    # one coupling spring per rectrix on q_k - g_k (c . q): the fan keeps its shape
    for k, jk in enumerate(joints):
        coef = -g[k] * c
        coef[k] += 1.0
        L += [f'    <fixed name="{jk}" stiffness="{p.tail_fan_stiffness:.6g}" '
              f'damping="{p.tail_fan_damping:.6g}" springlength="0">',
              "      " + "".join(f'<joint joint="{j}" coef="{a:.9g}"/>'
                                 for j, a in zip(joints, coef, strict=True)),
              "    </fixed>"]
    for s in ("l", "r"):
        for k in range(len(p.primary_angle_deg)):
            L += [f'    <fixed name="{s}_p{k + 1}_fan" stiffness="{p.fan_stiffness:.6g}" '
                  f'damping="{p.fan_damping:.6g}" springlength="0">',
                  f'      <joint joint="{s}_p{k + 1}_fan" coef="1"/>'
                  f'<joint joint="{s}_wrist_flex" coef="{-fan_ratio(p, k):.6g}"/>',
                  "    </fixed>"]
    L.append("  </tendon>")
    return "\n".join(L) + "\n"


def _lim(p: DoveParams, dof: str, joint: bool = True) -> str:
    """Range attributes of an actuated DOF (side-free name; left and right are equal)."""
    lo, hi = p.dof_range_deg[DOF_NAMES.index(dof if dof.startswith("tail") else f"l_{dof}")]
    out = f' limited="true" range="{np.radians(lo):.6g} {np.radians(hi):.6g}"'
    return out + (f' solreflimit="{_v(p.limit_solref)}"' if joint else "")


def _actuators_xml(p: DoveParams) -> str:
    L = ["  <actuator>"]
    for name, (lo, hi) in zip(DOF_NAMES, p.dof_torque_limit, strict=True):
        target = 'tendon="tail_spread"' if name == "tail_spread" else f'joint="{name}"'
        L.append(f'    <general name="{name}" {target} forcelimited="true" '
                 f'forcerange="{lo:.6g} {hi:.6g}"/>')
    L.append("  </actuator>")
    return "\n".join(L) + "\n"


def _sensors_xml() -> str:
    return ("  <sensor>\n"
            '    <framepos name="trunk_pos" objtype="body" objname="trunk"/>\n'
            '    <framequat name="trunk_quat" objtype="body" objname="trunk"/>\n'
            "  </sensor>\n")


# -- the compiled model ----------------------------------------------------------------------


def model_path() -> Path:
    """The bundled ``bird_mjcf/dove.xml``."""
    return asset_path("bird_mjcf", "dove.xml")


@dataclass
class Dove:
    """A compiled dove: the MuJoCo model plus the indices flight code needs."""

    model: mujoco.MjModel
    params: DoveParams
    trunk: int = 0
    """Body id of the trunk."""
    qadr: np.ndarray = field(default_factory=lambda: np.zeros(0, int))
    """qpos address of each of the 14 DOF (the tail spread: -1, it is a tendon)."""
    dadr: np.ndarray = field(default_factory=lambda: np.zeros(0, int))
    """qvel address of each of the 14 DOF (-1 for the tail spread)."""
    modal: object | None = None
    """The :class:`~flapsim.bird.body.feather_modes.ModalParams` of a modal-feather dove, or None
    (rigid feathers, the default)."""

    @property
    def feathers(self) -> str:
        """``rigid`` or ``modal``."""
        return "rigid" if self.modal is None else "modal"

    @classmethod
    def load(cls, path: str | Path | None = None, params: DoveParams | None = None,
             feathers: str = "rigid", modal: object | None = None) -> Dove:
        """The bundled dove (``feathers="rigid"``, from ``bird_mjcf/dove.xml``), or the same
        bird with modal feathers (``feathers="modal"``: generated from the parameters with
        ``modal`` or the default :class:`~flapsim.bird.body.feather_modes.ModalParams`)."""
        from flapsim.core.loading import load_model

        params = params or DoveParams.load()
        if feathers == "modal":
            from flapsim.bird.body.feather_modes import ModalParams

            if path is not None:
                raise ModelError("modal feathers are generated from the parameters, not a file")
            return cls.from_params(params, modal or ModalParams())
        if feathers != "rigid":
            raise ModelError(f"feathers must be 'rigid' or 'modal', got {feathers!r}")
        model = load_model(path or model_path())
        return cls.from_model(model, params)

    @classmethod
    def from_params(cls, params: DoveParams, modal: object | None = None) -> Dove:
        """Compile straight from parameters (no file): for studies that vary the model."""
        from flapsim.core.loading import load_model

        return cls.from_model(load_model(build_xml(params, modal=modal), is_xml=True), params, modal)

    @classmethod
    def from_model(cls, model: mujoco.MjModel, params: DoveParams,
                   modal: object | None = None) -> Dove:
        if model.nu != N_DOF:
            raise ModelError(f"dove model has {model.nu} actuators, expected {N_DOF} ({DOF_NAMES})")
        names = [mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_ACTUATOR, i) for i in range(model.nu)]
        if tuple(names) != DOF_NAMES:
            raise ModelError(f"dove actuators are {names}, expected {list(DOF_NAMES)}")
        qadr, dadr = [], []
        for name in DOF_NAMES:
            j = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, name)
            qadr.append(model.jnt_qposadr[j] if j >= 0 else -1)
            dadr.append(model.jnt_dofadr[j] if j >= 0 else -1)
        trunk = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, "trunk")
        if not can_touch_anything(model):
            # collision detection finds nothing, every step, for ~2 of a step's 40 us
            model.opt.disableflags |= mujoco.mjtDisableBit.mjDSBL_CONTACT
        return cls(model, params, trunk, np.array(qadr), np.array(dadr), modal)

    @property
    def mass(self) -> float:
        return float(self.model.body_subtreemass[self.trunk])

    @property
    def weight(self) -> float:
        return self.mass * float(-self.model.opt.gravity[2])

    def feather_geoms(self) -> list[int]:
        """Geom ids of every feather mesh."""
        m = self.model
        return [g for g in range(m.ngeom) if m.geom_type[g] == mujoco.mjtGeom.mjGEOM_MESH
                and not mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_GEOM, g).endswith(UNDERSIDE)]

    def feather_triangles(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, list[str]]:
        """Every feather triangle from the COMPILED meshes: (body ids (n,), corners in the body
        frame (n, 3, 3), forward (n, 3), feather name per triangle)."""
        m = self.model
        bodies, tris, fwd, names = [], [], [], []
        for g in self.feather_geoms():
            mesh = m.geom_dataid[g]
            v0, nv = m.mesh_vertadr[mesh], m.mesh_vertnum[mesh]
            f0, nf = m.mesh_faceadr[mesh], m.mesh_facenum[mesh]
            verts = m.mesh_vert[v0:v0 + nv].astype(float)
            faces = m.mesh_face[f0:f0 + nf]
            rot = np.zeros(9)
            mujoco.mju_quat2Mat(rot, m.geom_quat[g])
            rot = rot.reshape(3, 3)
            vb = verts @ rot.T + m.geom_pos[g]
            t = vb[faces]
            n = np.cross(t[:, 1] - t[:, 0], t[:, 2] - t[:, 0])
            n /= np.linalg.norm(n, axis=1, keepdims=True)
            # chordwise direction toward the leading edge: the body's +x in the feather plane
            ex = np.array([1.0, 0.0, 0.0])
            f = ex - n * (n @ ex)[:, None]
            f /= np.linalg.norm(f, axis=1, keepdims=True)
            name = mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_GEOM, g)
            bodies.append(np.full(nf, m.geom_bodyid[g]))
            tris.append(t)
            fwd.append(f)
            names += [name] * nf
        return np.concatenate(bodies), np.concatenate(tris), np.concatenate(fwd), names

    def twist_hinges(self):
        """The primaries' twist hinges for the force engine
        (:class:`~flapsim.fluid.hinges.PolygonHinges`), or None when the model has them in the
        skeleton (``twist="tree"``: modal feathers, or a model generated so)."""
        from flapsim.fluid.hinges import PolygonHinges

        m = self.model
        labels, joints, axes, origins, masses, coms, inertias = [], [], [], [], [], [], []
        for s in ("l", "r"):
            for k in range(len(self.params.primary_angle_deg)):
                name = f"{s}_p{k + 1}"
                site = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_SITE, f"{name}_twist")
                if site < 0:
                    return None
                b = m.site_bodyid[site]
                R = np.zeros(9)
                mujoco.mju_quat2Mat(R, m.body_iquat[b])
                R = R.reshape(3, 3)
                c = m.body_ipos[b].copy()
                mass = float(m.body_mass[b])
                io = R @ np.diag(m.body_inertia[b]) @ R.T + mass * (c @ c * np.eye(3) - np.outer(c, c))
                sq = np.zeros(9)
                mujoco.mju_quat2Mat(sq, m.site_quat[site])
                labels.append(name)
                joints.append(f"{name}_twist")
                axes.append(sq.reshape(3, 3)[:, 2])
                origins.append(m.site_pos[site].copy())
                masses.append(mass)
                coms.append(c)
                inertias.append([io[0, 0], io[1, 1], io[2, 2], io[0, 1], io[0, 2], io[1, 2]])
        return PolygonHinges(tuple(labels), tuple(labels), tuple(joints), np.array(axes), np.array(origins),
                             np.array(masses), np.array(coms), np.array(inertias))

    def drawing(self) -> tuple[mujoco.MjModel, np.ndarray]:
        """What videos and the viewer draw: (a model, the index array ``ix`` with which a
        state's ``qpos[ix]`` is that model's ``qpos``). For the separate twist hinges
        (:meth:`twist_hinges`) it is this dove generated with the hinges in the primaries'
        bodies, so MuJoCo draws them twisted; otherwise this model and the identity."""
        if self.twist_hinges() is None:
            return self.model, np.arange(self.model.nq)
        if getattr(self, "_drawing", None) is None:
            from flapsim.core.loading import load_model

            shown = load_model(build_xml(self.params, twist="tree"), is_xml=True)
            m = self.model
            ix = np.zeros(shown.nq, dtype=int)
            for j in range(shown.njnt):
                name = mujoco.mj_id2name(shown, mujoco.mjtObj.mjOBJ_JOINT, j)
                jj = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, name)
                if jj < 0 or m.jnt_type[jj] != shown.jnt_type[j]:
                    raise ModelError(f"the drawing model's joint {name!r} is not this dove's "
                                     "(a model file not generated from these parameters?)")
                n = {0: 7, 1: 4}.get(int(shown.jnt_type[j]), 1)
                ix[shown.jnt_qposadr[j]:shown.jnt_qposadr[j] + n] = np.arange(
                    m.jnt_qposadr[jj], m.jnt_qposadr[jj] + n)
            self._drawing = (shown, ix)
        return self._drawing

    def hash(self) -> str:
        """Short hash of the model (provenance in result files)."""
        h = hashlib.sha256()
        m = self.model
        # what a trained database depends on: geometry, inertia, joints and their limits,
        # servos and their torque limits, springs and dampers, the timestep
        for a in (m.body_mass, m.body_pos, m.mesh_vert, m.jnt_axis, m.actuator_biasprm,
                  m.actuator_gainprm, m.actuator_forcerange, m.jnt_range, m.jnt_stiffness,
                  m.dof_damping, np.array([m.opt.timestep])):
            h.update(np.ascontiguousarray(a).tobytes())
        if self.modal is not None:  # the feathers' elasticity and how it is integrated
            h.update(repr(self.modal).encode())
        return h.hexdigest()[:12]
