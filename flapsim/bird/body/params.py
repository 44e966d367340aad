"""The dove's parameters (from ``flapsim/bird/body/data/dove.toml``, each with its source there):
the skeleton's degrees of freedom in wingbeat order, their ranges and torque limits, and the
feathers' geometry per wing and tail."""

from __future__ import annotations

import tomllib
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from flapsim.bird.body import feather_geometry as fz
from flapsim.core.errors import DataFileError
from flapsim.core.validate import require_finite

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
        require_finite(raw, f"dove parameter file {path}")
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
