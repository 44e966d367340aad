"""The swimmer: its MJCF model, hydrodynamic polygons, buoyancy and the water it swims in.

``Swimmer(params)`` loads ``swimmer_mjcf/pool.xml`` (or ``swimmer.xml``), sets the lung
volume, and attaches three force providers to its ``MjData``:

* hydrodynamics (:class:`flapsim.fluid.surfaces.SurfaceForces`): every box face is a
  polygon with the paper's forward vector F along its long side, the Hoerner thin-plate
  table for aspect ratio 0.2, friction ``eta a_t v_t``, front-facing polygons only, and
  the free surface at the water level (a face above it feels nothing: air forces on a
  swimmer are ~1000x smaller). Faces are split into patches no longer than
  ``patch_length`` so the force on a rotating limb follows its speed along it. Where two
  segments meet end to end at a joint (spine, neck, hips, knees, elbows, wrists, ankles)
  the touching parts of their end faces are inside the body, never wetted, and removed;
* wave-making resistance (:class:`flapsim.fluid.waves.WaveDrag`) on the same polygons
  near the surface, steep in the Froude number on the standing height and fading with
  depth as exp(-2 g d / v^2);
* buoyancy (:class:`flapsim.fluid.buoyancy.Buoyancy`): one ellipsoid per segment with
  the segment's volume (box volume, the thorax's including the lungs).

The paper's swimmer-induced flow (its eq. 5) is :meth:`Swimmer.update_flow`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import mujoco
import numpy as np

from flapsim.core.assets import asset_path
from flapsim.core.callbacks import DISPATCHER, Registration
from flapsim.core.errors import InputError, ModelError, SimulationError
from flapsim.fluid.buoyancy import Buoyancy, BuoyancyParams
from flapsim.fluid.coefficients import hoerner_plate, rounded_surface
from flapsim.fluid.flow import FlowField
from flapsim.fluid.surfaces import FluidParams, PolygonSet, SurfaceForces
from flapsim.fluid.waves import WaveDrag, WaveParams

#: segment (body and box geom) names, parent first
SEGMENTS = (
    "pelvis", "abdomen", "thorax", "head",
    "upper_arm_l", "forearm_l", "hand_l", "upper_arm_r", "forearm_r", "hand_r",
    "thigh_l", "shank_l", "foot_l", "thigh_r", "shank_r", "foot_r",
)
#: mass density of the segments before the lungs (the paper) [kg/m^3]
BODY_DENSITY = 1044.0
#: lung volume built into swimmer.xml [L] (flapsim.swim.build.swimmer)
XML_LUNG_L = 3.0
#: see SwimmerParams.wave_c_hump (flapsim.swim.tow.calibrate_waves recomputes it)
WAVE_C_HUMP = 0.00873
#: the upper trunk box's depth, width and length [m] at XML_LUNG_L is read from the model


@dataclass(frozen=True)
class SwimmerParams:
    """Swimmer body, water and fluid-model settings (defaults: the paper, see each field)."""

    #: extra upper-trunk volume of air-filled lungs [L]; the paper: "up to 3 L", which
    #: turns its cadaveric (1.044 g/mL) swimmer from a sinker into a floater
    lung_volume_l: float = 3.0
    #: water density [kg/m^3]; 1025 (sea water) reproduces the paper's 91 kg buoyancy for
    #: 85.8 L + 3 L (at 998, fresh water, the 3 L swimmer sinks slowly)
    water_density: float = 1025.0
    #: skin-friction coefficient eta [N s/m^3] of the paper's eq. 2: 1/2 rho Cf v with a
    #: turbulent flat-plate Cf ~ 0.004 (Re ~ 2e6, 0.074 Re^-0.2) at 1 m/s
    friction: float = 2.0
    #: height of the water surface [m]
    water_level: float = 0.0
    #: buoyancy: "exact" spherical cap, or the paper's "linear" (1 + cos theta)/2
    buoyancy_method: str = "exact"
    #: swimmer-induced flow ratios of the paper's eq. 5 (user-defined there; 0 = off)
    r_min: float = 0.0
    #: see r_min
    r_max: float = 0.0
    #: longest patch a box face is split into [m] (force distribution along limbs)
    patch_length: float = 0.12
    #: drop the parts of end faces that touch the neighbouring segment at a joint
    hide_joint_faces: bool = True
    #: normal drag coefficient of the AR-0.2 plate at 90 deg (Hoerner: 1.17 square .. 1.98 2-D)
    cd_normal: float = 1.2
    #: hydrodynamic surface: "box" (the paper's 16 boxes; the strokes and steering are
    #: tuned on it) or "rounded" (elliptic tubes with ellipsoidal shoulders and head, flat
    #: hands and feet: a towed person's drag, see flapsim.swim.tow)
    body_shape: str = "box"
    #: stagnation pressure coefficient of the rounded ends (the head, the shoulders): 0.6
    #: makes them a bullet's nose, CD 0.5 x 0.6 = 0.30 on the frontal area (a bullet-shaped
    #: body of revolution, CD 0.295, Hoerner 1965; the engine has no base suction, so the
    #: whole body's drag sits on its front); 1 (exact stagnation) would make the head an
    #: isolated sphere (CD 0.5, measured 0.47)
    cp_nose: float = 0.6
    #: stagnation pressure coefficient of the tubes' sides, trunk and limbs (1.8: a
    #: cylinder in cross flow CD 1.2, Hoerner 1965's 1.0-1.2 at Re 1e4-2e5)
    cp_tube: float = 1.8
    #: wave-making resistance at the hump (Fr 0.5) per wetted area
    #: (:mod:`flapsim.fluid.waves`), fitted to 11.5 N of wave drag at 1.89 m/s at the
    #: surface (Toussaint et al. 2002) on the rounded body in the towed streamline; 0 = no
    #: waves
    wave_c_hump: float = WAVE_C_HUMP
    #: "pool" (floor 3 m down, visible water) or "bare" (swimmer.xml only)
    world: str = "pool"
    #: physics timestep [s]; 4 ms is stable with the PD gains of flapsim.swim.muscles
    timestep: float = 0.004

    def __post_init__(self) -> None:
        if not (0.0 <= self.lung_volume_l <= 6.0):
            raise InputError(f"lung_volume_l must be 0..6 L (human vital capacity), got "
                             f"{self.lung_volume_l}")
        if not (self.water_density > 0 and math.isfinite(self.water_density)):
            raise InputError(f"water_density must be > 0 kg/m^3, got {self.water_density}")
        if self.body_shape not in ("rounded", "box"):
            raise InputError(f"body_shape must be 'rounded' or 'box', got {self.body_shape!r}")
        if not (0.5 <= self.cp_nose <= 2.0 and 0.5 <= self.cp_tube <= 2.0):
            raise InputError("cp_nose and cp_tube must be 0.5..2 (stagnation pressure "
                             "coefficients: 1 exact, up to ~2 with a bluff body's wake)")
        if self.world not in ("pool", "bare"):
            raise InputError(f"world must be 'pool' or 'bare', got {self.world!r}")
        if not (1e-4 <= self.timestep <= 0.01):
            raise InputError(f"timestep must be 0.0001..0.01 s, got {self.timestep}")
        if self.r_min < 0 or self.r_max < 0 or self.r_min > 1 or self.r_max > 1:
            raise InputError("r_min and r_max are ratios in 0..1")
        if self.patch_length <= 0:
            raise InputError("patch_length must be > 0 m")
        if not (math.isfinite(self.wave_c_hump) and 0.0 <= self.wave_c_hump <= 0.1):
            raise InputError(f"wave_c_hump must be 0..0.1 (a hull's wave coefficient), got "
                             f"{self.wave_c_hump}")


def load_swimmer_model(lung_volume_l: float = XML_LUNG_L, world: str = "pool",
                       timestep: float | None = None, skin: bool = False) -> mujoco.MjModel:
    """Compile the swimmer with the upper trunk holding ``lung_volume_l`` litres of air;
    ``skin`` draws the rounded segments (see :func:`_add_skin`) instead of the boxes.

    The thorax box keeps its length and width:depth ratio and its mass; its volume is
    its cadaveric volume (mass / 1044 kg/m^3) plus the lungs.
    """
    path = asset_path("swimmer_mjcf", "pool.xml" if world == "pool" else "swimmer.xml")
    spec = mujoco.MjSpec.from_file(str(path))
    g = spec.geom("thorax")
    if g is None:
        raise ModelError(f"{path} has no geom 'thorax'; regenerate it with "
                         "python -m flapsim.swim.build.swimmer")
    half = np.array(g.size[:3], dtype=float)
    base = g.mass / BODY_DENSITY
    vol = base + lung_volume_l * 1e-3
    scale = math.sqrt(vol / (8.0 * half.prod()))
    g.size = [half[0] * scale, half[1] * scale, half[2]]
    if timestep is not None:
        spec.option.timestep = timestep
    with DISPATCHER.suspended():
        try:
            model = spec.compile()
            if skin:
                _add_skin(spec, model)
                model = spec.compile()
            return model
        except ValueError as exc:  # pragma: no cover - the shipped file compiles
            raise ModelError(f"cannot compile {path}: {exc}") from None


def _add_skin(spec: mujoco.MjSpec, model: mujoco.MjModel) -> None:
    """Draw the rounded segments the water sees (:func:`rounded_segments`), each a convex
    mesh of its tessellation on its body, massless and without contacts; their boxes, which
    keep the mass, inertia and contacts, become invisible."""
    data = mujoco.MjData(model)
    mujoco.mj_kinematics(model, data)
    for name, seg in rounded_segments(model).items():
        b = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, name)
        xpos, xR = data.xpos[b], data.xmat[b].reshape(3, 3)
        verts = np.concatenate([q for q, _ in tessellate(seg, 0.06, 24, 6)])
        verts = np.unique(np.round((verts - xpos) @ xR, 9), axis=0)
        mesh = spec.add_mesh()
        mesh.name = f"{name}_skin"
        mesh.uservert = verts.ravel().tolist()
        g = spec.body(name).add_geom()
        g.name = f"{name}_skin"
        g.type = mujoco.mjtGeom.mjGEOM_MESH
        g.meshname = mesh.name
        g.mass = 0.0
        g.contype = 0
        g.conaffinity = 0
        box = spec.geom(name)
        g.rgba = list(box.rgba)
        box.rgba = [box.rgba[0], box.rgba[1], box.rgba[2], 0.0]


# -- polygons --------------------------------------------------------------------------
def _box_faces(half: np.ndarray) -> list[tuple[int, float, np.ndarray, np.ndarray]]:
    """(axis, sign, rect lo, rect hi) per face; rect in the face's two other axes."""
    out = []
    for axis in range(3):
        others = [a for a in range(3) if a != axis]
        for sign in (1.0, -1.0):
            out.append((axis, sign, -half[others], half[others].copy()))
    return out


def _rect_minus(lo: np.ndarray, hi: np.ndarray, clo: np.ndarray, chi: np.ndarray
                ) -> list[tuple[np.ndarray, np.ndarray]]:
    """Rectangle [lo, hi] minus [clo, chi] as up to four rectangles."""
    clo = np.maximum(clo, lo)
    chi = np.minimum(chi, hi)
    if np.any(chi - clo <= 1e-9):
        return [(lo, hi)]
    parts = []
    if clo[0] - lo[0] > 1e-9:
        parts.append((lo.copy(), np.array([clo[0], hi[1]])))
    if hi[0] - chi[0] > 1e-9:
        parts.append((np.array([chi[0], lo[1]]), hi.copy()))
    if clo[1] - lo[1] > 1e-9:
        parts.append((np.array([clo[0], lo[1]]), np.array([chi[0], clo[1]])))
    if hi[1] - chi[1] > 1e-9:
        parts.append((np.array([clo[0], chi[1]]), np.array([chi[0], hi[1]])))
    return parts


def swimmer_polygons(model: mujoco.MjModel, patch_length: float = 0.12,
                     hide_joint_faces: bool = True) -> PolygonSet:
    """The box faces of every segment as a :class:`PolygonSet` (table 0).

    Requires axis-aligned boxes in the zero pose (true for swimmer.xml). Each face's
    forward vector F is its long side (the paper's Fig. 4).
    """
    data = mujoco.MjData(model)
    mujoco.mj_kinematics(model, data)
    boxes = {}
    for name in SEGMENTS:
        gid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, name)
        if gid < 0:
            raise ModelError(f"swimmer model has no box geom {name!r}")
        boxes[name] = gid
    # faces in the zero pose (world frame == standing frame, axis-aligned)
    faces = {}
    for name, gid in boxes.items():
        half = model.geom_size[gid].copy()
        R = data.geom_xmat[gid].reshape(3, 3)
        if not np.allclose(np.abs(R), np.eye(3), atol=1e-9):
            raise ModelError(f"box {name!r} is not axis-aligned in the zero pose")
        center = data.geom_xpos[gid].copy()
        # work in world axes: half sizes along world x, y, z
        whalf = np.abs(R) @ half
        faces[name] = [(axis, sign, [(lo, hi)]) for axis, sign, lo, hi in _box_faces(whalf)]
        boxes[name] = (gid, center, whalf)
    if hide_joint_faces:
        for name in SEGMENTS:
            gid, c, h = boxes[name]
            bid = model.geom_bodyid[gid]
            parent = model.body_parentid[bid]
            if parent < 1:
                continue
            pname = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_BODY, parent)
            pg, pc, ph = boxes[pname]
            for i, (axis, sign, rects) in enumerate(faces[name]):
                plane = c[axis] + sign * h[axis]
                for j, (paxis, psign, prects) in enumerate(faces[pname]):
                    if paxis != axis or psign != -sign:
                        continue
                    if abs(pc[paxis] + psign * ph[paxis] - plane) > 1e-6:
                        continue
                    others = [a for a in range(3) if a != axis]
                    # overlap of the two faces in world coordinates of the other axes
                    clo = np.maximum(c[others] - h[others], pc[others] - ph[others])
                    chi = np.minimum(c[others] + h[others], pc[others] + ph[others])
                    if np.any(chi <= clo):
                        continue
                    faces[name][i] = (axis, sign, [
                        r for lo, hi in rects
                        for r in _rect_minus(lo, hi, clo - c[others], chi - c[others])])
                    faces[pname][j] = (paxis, psign, [
                        r for lo, hi in prects
                        for r in _rect_minus(lo, hi, clo - pc[others], chi - pc[others])])
    sets = []
    for name in SEGMENTS:
        gid, c, h = boxes[name]
        bid = int(model.geom_bodyid[gid])
        xpos = data.xpos[bid]
        xR = data.xmat[bid].reshape(3, 3)
        polys, fwds = [], []
        for axis, sign, rects in faces[name]:
            others = [a for a in range(3) if a != axis]
            # F: the long side of the whole face (not of a patch), as in the paper
            long_ax = others[0] if h[others[0]] >= h[others[1]] else others[1]
            for lo, hi in rects:
                size = hi - lo
                if size.min() < 1e-6:
                    continue
                n_u = max(1, math.ceil(size[0] / patch_length - 1e-9))
                n_v = max(1, math.ceil(size[1] / patch_length - 1e-9))
                for iu in range(n_u):
                    for iv in range(n_v):
                        u0 = lo[0] + size[0] * iu / n_u
                        u1 = lo[0] + size[0] * (iu + 1) / n_u
                        v0 = lo[1] + size[1] * iv / n_v
                        v1 = lo[1] + size[1] * (iv + 1) / n_v
                        quad = []
                        order = ((u0, v0), (u1, v0), (u1, v1), (u0, v1))
                        if sign < 0:
                            order = order[::-1]
                        for u, v in order:
                            p = c.copy()
                            p[axis] += sign * h[axis]
                            p[others[0]] += u
                            p[others[1]] += v
                            quad.append(p)
                        quad = np.asarray(quad)
                        # right-hand normal must point outward: fix the winding if not
                        nrm = np.cross(quad[1] - quad[0], quad[2] - quad[0])
                        if nrm[axis] * sign < 0:
                            quad = quad[::-1]
                        polys.append((quad - xpos) @ xR)  # world -> body frame
                        f = np.zeros(3)
                        f[long_ax] = 1.0
                        fwds.append(xR.T @ f)
        sets.append(PolygonSet.from_polygons(bid, np.asarray(polys), np.asarray(fwds), 0,
                                             labels=[name] * len(polys)))
    return PolygonSet.concat(sets)


# -- the rounded body -------------------------------------------------------------------
#: segments drawn and wetted as flat plates (the hand's paddle, the foot's fin)
FLAT_SEGMENTS = ("hand_l", "hand_r", "foot_l", "foot_r")
#: which ends of a segment are rounded (top, bottom) in the standing zero pose; the
#: others continue into their neighbour: the trunk is one tube from the hips to the
#: shoulders, each limb one tube from shoulder to wrist and hip to ankle, so a flat end has
#: no wetted surface (the steps of 1-3 cm between neighbouring cross sections and the bend
#: of a joint are not modelled as ledges or gaps). Rounded: the shoulders (the thorax's
#: top and the upper arms' heads) and the head.
_ROUNDED_ENDS = {"thorax": (True, False), "head": (True, True), "upper_arm_l": (True, False),
                 "upper_arm_r": (True, False)}
#: coefficient table of each kind of surface (see Swimmer): the hands' and feet's plates,
#: the rounded ends (a nose in the flow along the body), the tubes' sides (a cylinder in
#: the flow across it)
TABLE_PLATE, TABLE_NOSE, TABLE_TUBE = 0, 1, 2


@dataclass(frozen=True)
class RoundedSegment:
    """A segment's rounded solid, in the standing zero pose (world axes, long axis z):
    an elliptic cylinder with half-ellipsoid caps at its rounded ends."""

    name: str
    #: centre of the segment's box [m]
    center: np.ndarray
    #: cross-section semi-axes along x and y [m]: the box's cross-section area (x 2/sqrt(pi))
    rx: float
    #: see rx
    ry: float
    #: half length along z [m] (the box's)
    hz: float
    #: length of each cap along z [m]
    cap: float
    #: (top, bottom) rounded; a flat end has no surface (it continues into a neighbour)
    rounded: tuple[bool, bool]

    def inside(self, p: np.ndarray) -> bool:
        """Whether the point ``p`` (world, zero pose) is strictly inside the solid."""
        d = np.asarray(p, dtype=float) - self.center
        if abs(d[2]) >= self.hz:
            return False
        zc = 0.0
        top = d[2] > 0
        if self.rounded[0 if top else 1]:
            zc = max(0.0, abs(d[2]) - (self.hz - self.cap)) / self.cap
        return (d[0] / self.rx) ** 2 + (d[1] / self.ry) ** 2 + zc * zc < 1.0 - 1e-9

    def point(self, z: float, r: float, phi: float) -> np.ndarray:
        return self.center + np.array([self.rx * r * math.cos(phi),
                                       self.ry * r * math.sin(phi), z])


def rounded_segments(model: mujoco.MjModel) -> dict[str, RoundedSegment]:
    """Every segment but the flat hands and feet as a :class:`RoundedSegment`, from its box."""
    data = mujoco.MjData(model)
    mujoco.mj_kinematics(model, data)
    out = {}
    for name in SEGMENTS:
        if name in FLAT_SEGMENTS:
            continue
        gid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, name)
        if gid < 0:
            raise ModelError(f"swimmer model has no box geom {name!r}")
        R = data.geom_xmat[gid].reshape(3, 3)
        if not np.allclose(np.abs(R), np.eye(3), atol=1e-9):
            raise ModelError(f"box {name!r} is not axis-aligned in the zero pose")
        h = np.abs(R) @ model.geom_size[gid]
        k = 2.0 / math.sqrt(math.pi)
        rx, ry, hz = k * h[0], k * h[1], h[2]
        rounded = _ROUNDED_ENDS.get(name, (False, False))
        out[name] = RoundedSegment(name, data.geom_xpos[gid].copy(), rx, ry, hz,
                                   min(rx, ry, hz), rounded)
    return out


def _profile(s: RoundedSegment, patch_length: float, cap_bands: int
             ) -> list[tuple[float, float]]:
    """(z, r) rings from bottom to top: caps in ``cap_bands`` latitude bands each, the
    cylinder in bands no longer than ``patch_length``."""
    top, bottom = s.rounded
    z0 = -(s.hz - s.cap) if bottom else -s.hz
    z1 = (s.hz - s.cap) if top else s.hz
    rings = []
    if bottom:
        for k in range(cap_bands):
            t = 0.5 * math.pi * k / cap_bands
            rings.append((-(s.hz - s.cap) - s.cap * math.cos(t), math.sin(t)))
    n = max(1, math.ceil((z1 - z0) / patch_length - 1e-9)) if z1 - z0 > 1e-9 else 0
    rings += [(z0 + (z1 - z0) * i / max(n, 1), 1.0) for i in range(n + 1)]
    if top:
        for k in range(cap_bands - 1, -1, -1):
            t = 0.5 * math.pi * k / cap_bands
            rings.append(((s.hz - s.cap) + s.cap * math.cos(t), math.sin(t)))
    return rings


def tessellate(s: RoundedSegment, patch_length: float = 0.12, around: int = 10,
               cap_bands: int = 2) -> list[tuple[np.ndarray, bool]]:
    """The surface of ``s`` as (vertices (4, 3) world, on a cap) patches with outward
    normals by the right-hand rule; a pole's triangles repeat their last vertex."""
    rings = _profile(s, patch_length, cap_bands)
    out = []
    for i in range(len(rings) - 1):
        (za, ra), (zb, rb) = rings[i], rings[i + 1]
        cap = (s.rounded[1] and i < cap_bands) or (s.rounded[0]
                                                   and i >= len(rings) - 1 - cap_bands)
        for j in range(around):
            p0, p1 = 2 * math.pi * j / around, 2 * math.pi * (j + 1) / around
            quad = [s.point(za, ra, p0)]
            if ra > 1e-12:  # a ring of radius 0 is a pole: the patch is a triangle
                quad.append(s.point(za, ra, p1))
            quad.append(s.point(zb, rb, p1))
            if rb > 1e-12:
                quad.append(s.point(zb, rb, p0))
            quad = np.asarray(quad)
            # outward: along the solid's gradient (x / rx^2, y / ry^2, zc / cap^2)
            nrm = np.cross(quad[1] - quad[0], quad[2] - quad[0])
            d = quad.mean(axis=0) - s.center
            zc = math.copysign(max(0.0, abs(d[2]) - (s.hz - s.cap)), d[2]) if cap else 0.0
            grad = np.array([d[0] / s.rx ** 2, d[1] / s.ry ** 2, zc / s.cap ** 2])
            if nrm @ grad < 0:
                quad = quad[::-1]
            if len(quad) == 3:
                quad = np.vstack([quad, quad[-1:]])
            out.append((quad, cap))
    return out


def rounded_polygons(model: mujoco.MjModel, patch_length: float = 0.12, around: int = 10,
                     cap_bands: int = 2) -> PolygonSet:
    """The swimmer's rounded surface as a :class:`PolygonSet`: every segment but the hands
    and feet an elliptic cylinder with ellipsoidal caps (``around`` patches round it,
    ``cap_bands`` latitude bands per cap; table 1 the caps, 2 the tubes), the hands and
    feet their box faces (table 0, the plate). A cap's patch inside a joint neighbour (its
    parent or child) in the zero pose is never wetted and left out. No forward vector: a
    rounded patch's force depends on the angle of the flow to it alone."""
    segs = rounded_segments(model)
    data = mujoco.MjData(model)
    mujoco.mj_kinematics(model, data)
    bid = {n: mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, n) for n in SEGMENTS}
    neighbours: dict[str, list[str]] = {n: [] for n in SEGMENTS}
    for n in SEGMENTS:
        pname = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_BODY, model.body_parentid[bid[n]])
        if pname in neighbours:
            neighbours[n].append(pname)
            neighbours[pname].append(n)
    flat = swimmer_polygons(model, patch_length, hide_joint_faces=True)
    sets = [flat.subset(np.array([lbl in FLAT_SEGMENTS for lbl in flat.labels]))]
    for name, s in segs.items():
        xpos = data.xpos[bid[name]]
        xR = data.xmat[bid[name]].reshape(3, 3)
        kept = [(quad, cap) for quad, cap in tessellate(s, patch_length, around, cap_bands)
                if not (cap and any(segs[o].inside(quad.mean(axis=0))
                                    for o in neighbours[name] if o in segs))]
        polys = np.asarray([(quad - xpos) @ xR for quad, _ in kept])
        tables = np.array([TABLE_NOSE if cap else TABLE_TUBE for _, cap in kept])
        sets.append(PolygonSet.from_polygons(bid[name], polys, None, tables,
                                             labels=[name] * len(polys)))
    return PolygonSet.concat(sets)


# -- the swimmer -----------------------------------------------------------------------
@dataclass
class JointInfo:
    """The swimmer's actuated joints in MuJoCo order."""

    names: list[str]
    types: np.ndarray  # 0 hinge, 1 ball
    qadr: np.ndarray
    dadr: np.ndarray
    actuator: np.ndarray  # first actuator of each joint (balls: 3 consecutive)
    nq: int = 0
    nv: int = 0
    extra: dict = field(default_factory=dict)


def joint_info(model: mujoco.MjModel) -> JointInfo:
    """Every non-root joint with its qpos/qvel addresses and its motors (checked)."""
    names, types, qadr, dadr, act = [], [], [], [], []
    for j in range(model.njnt):
        t = int(model.jnt_type[j])
        if t == int(mujoco.mjtJoint.mjJNT_FREE):
            continue
        if t not in (int(mujoco.mjtJoint.mjJNT_HINGE), int(mujoco.mjtJoint.mjJNT_BALL)):
            raise ModelError("swimmer joints must be hinges or balls")
        name = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_JOINT, j)
        motors = [a for a in range(model.nu) if model.actuator_trnid[a, 0] == j]
        ndof = 3 if t == int(mujoco.mjtJoint.mjJNT_BALL) else 1
        if len(motors) != ndof:
            raise ModelError(f"joint {name!r} needs {ndof} motor(s), has {len(motors)}")
        if ndof == 3:
            for k, a in enumerate(motors):
                if not np.allclose(model.actuator_gear[a, :3], np.eye(3)[k]):
                    raise ModelError(f"ball joint {name!r}: motor {k} must have gear along "
                                     "local axis {k}")
        names.append(name)
        types.append(1 if ndof == 3 else 0)
        qadr.append(model.jnt_qposadr[j])
        dadr.append(model.jnt_dofadr[j])
        act.append(motors[0])
    return JointInfo(names, np.asarray(types, dtype=np.int64), np.asarray(qadr, dtype=np.int64),
                     np.asarray(dadr, dtype=np.int64), np.asarray(act, dtype=np.int64))


def _quat_y(angle: float) -> np.ndarray:
    return np.array([math.cos(angle / 2), 0.0, math.sin(angle / 2), 0.0])


#: root orientations: prone = face down, head towards +x (a +90 deg turn about y)
POSTURES = {"prone": _quat_y(math.pi / 2), "upright": np.array([1.0, 0.0, 0.0, 0.0])}


class Swimmer:
    """The swimmer model, its data, and the water's forces on it."""

    def __init__(self, params: SwimmerParams | None = None, flow: FlowField | None = None
                 ) -> None:
        self.params = params or SwimmerParams()
        p = self.params
        self.model = load_swimmer_model(p.lung_volume_l, p.world, p.timestep,
                                        skin=p.body_shape == "rounded")
        self.data = mujoco.MjData(self.model)
        self.joints = joint_info(self.model)
        self.body = {n: mujoco.mj_name2id(self.model, mujoco.mjtObj.mjOBJ_BODY, n)
                     for n in SEGMENTS}
        if p.body_shape == "rounded":
            self.polygons = rounded_polygons(self.model, p.patch_length)
        else:
            self.polygons = swimmer_polygons(self.model, p.patch_length, p.hide_joint_faces)
        self.flow = flow or FlowField()
        self._current = self.flow.params[1:4].copy()  # the user's uniform current
        tables = [hoerner_plate(0.2, cd_crossflow=p.cd_normal), rounded_surface(p.cp_nose),
                  rounded_surface(p.cp_tube)]
        self.hydro = SurfaceForces(
            self.model, self.polygons, tables,
            FluidParams(density=p.water_density, friction=p.friction, front_facing_only=True,
                        surface_z=p.water_level),
            self.flow, name="swimmer hydrodynamics",
        )
        # the same wetted polygons make the waves; Fr on the standing height
        self.waves = WaveDrag(
            self.model, self.polygons,
            WaveParams(p.water_density, p.water_level, standing_height(self.model),
                       p.wave_c_hump, float(np.linalg.norm(self.model.opt.gravity))),
            self.flow, self.hydro._ext, name="swimmer wave drag")
        volumes = {}
        for n in SEGMENTS:
            gid = mujoco.mj_name2id(self.model, mujoco.mjtObj.mjOBJ_GEOM, n)
            volumes[n] = 8.0 * float(np.prod(self.model.geom_size[gid]))
        self.buoyancy = Buoyancy.for_bodies(
            self.model, list(SEGMENTS), p.water_level, p.water_density, p.buoyancy_method,
            volumes=volumes,
        )
        self._regs: list[Registration] = []

    # -- forces ------------------------------------------------------------------------
    def attach(self) -> None:
        """Start applying hydrodynamics and buoyancy at every step."""
        if not self._regs:
            self._regs = [self.hydro.register(self.data), self.buoyancy.register(self.data)]
            if self.params.wave_c_hump > 0:
                self._regs.append(self.waves.register(self.data))

    def detach(self) -> None:
        for r in self._regs:
            r.remove()
        self._regs = []

    def __enter__(self) -> Swimmer:
        self.attach()
        return self

    def __exit__(self, *exc: object) -> None:
        self.detach()

    def set_water_density(self, rho: float) -> None:
        """Change the water density for both buoyancy and hydrodynamics, in place."""
        p = self.hydro.params
        self.hydro.set_params(FluidParams(rho, p.friction, p.front_facing_only, p.surface_z))
        b = self.buoyancy.params
        self.buoyancy.set_params(BuoyancyParams(b.water_level, rho, b.method))
        w = self.waves.params
        self.waves.set_params(WaveParams(rho, w.surface_z, w.length, w.c_hump, w.gravity))

    def update_flow(self) -> np.ndarray:
        """Swimmer-induced flow (paper eq. 5) plus the user's uniform current, set as the
        flow field's uniform part. Call once per control step; returns V_F [m/s]."""
        p = self.params
        vs = self.com_velocity()
        speed = float(np.linalg.norm(vs))
        vf = np.zeros(3)
        if speed > 1e-9 and (p.r_min > 0 or p.r_max > 0):
            axis = self.data.xmat[self.body["pelvis"]].reshape(3, 3)[:, 2]
            cos_a = abs(float(vs @ axis)) / speed
            sin3 = max(0.0, 1.0 - cos_a * cos_a) ** 1.5
            vf = ((p.r_max - p.r_min) * sin3 + p.r_min) * vs
        self.flow.set_uniform(self._current + vf)
        return vf

    def set_current(self, velocity: np.ndarray) -> None:
        """The user's uniform water current [m/s] (world frame)."""
        self._current = np.asarray(velocity, dtype=float).copy()
        self.update_flow()

    # -- state -------------------------------------------------------------------------
    def reset(self, posture: str = "prone", height: float | None = None,
              qpos_joints: np.ndarray | None = None) -> None:
        """Put the swimmer at rest in ``posture`` with its pelvis at ``height`` [m]
        (default: the thorax at the surface when prone, the head's centre at the
        surface when upright). ``qpos_joints`` sets the non-root joints."""
        if posture not in POSTURES:
            raise InputError(f"posture must be one of {', '.join(POSTURES)}, got {posture!r}")
        m, d = self.model, self.data
        mujoco.mj_resetData(m, d)
        if qpos_joints is not None:
            d.qpos[7:] = qpos_joints
        if height is None:
            head = m.body_pos[self.body["head"]][2] + m.body_pos[self.body["thorax"]][2] + \
                m.body_pos[self.body["abdomen"]][2]
            gid = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, "head")
            head += m.geom_pos[gid][2]
            height = self.params.water_level + (-0.12 if posture == "prone" else -head)
        d.qpos[:3] = (0.0, 0.0, height)
        d.qpos[3:7] = POSTURES[posture]
        mujoco.mj_forward(m, d)

    def com(self) -> np.ndarray:
        """Whole-body centre of mass [m]."""
        return self.data.subtree_com[self.body["pelvis"]].copy()

    def com_velocity(self) -> np.ndarray:
        """Whole-body centre-of-mass velocity [m/s] (world)."""
        mujoco.mj_subtreeVel(self.model, self.data)
        return self.data.subtree_linvel[self.body["pelvis"]].copy()

    def head_height(self) -> float:
        """Height of the head box's centre above the water surface [m]."""
        gid = mujoco.mj_name2id(self.model, mujoco.mjtObj.mjOBJ_GEOM, "head")
        return float(self.data.geom_xpos[gid][2] - self.params.water_level)

    def displaced_mass(self) -> float:
        """Mass of water displaced now [kg]."""
        return self.buoyancy.submerged_mass(self.data)

    @property
    def mass(self) -> float:
        return float(self.model.body_subtreemass[self.body["pelvis"]])

    @property
    def volume(self) -> float:
        """Body volume including the lungs [m^3]."""
        return self.buoyancy.total_volume


#: MuJoCo's divergence warnings: it resets a diverged state (finite again) and only counts
#: these, so they are read after every step.
_BAD = [int(w) for w in (mujoco.mjtWarning.mjWARN_BADQPOS, mujoco.mjtWarning.mjWARN_BADQVEL,
                         mujoco.mjtWarning.mjWARN_BADQACC)]


def standing_height(model: mujoco.MjModel) -> float:
    """The swimmer's height [m] standing in its zero pose: sole to the top of the head."""
    d = mujoco.MjData(model)
    mujoco.mj_forward(model, d)
    lo, hi = np.inf, -np.inf
    for n in SEGMENTS:
        g = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, n)
        h = float(np.abs(d.geom_xmat[g].reshape(3, 3))[2] @ model.geom_size[g])
        lo = min(lo, d.geom_xpos[g][2] - h)
        hi = max(hi, d.geom_xpos[g][2] + h)
    return float(hi - lo)


def check_diverged(m: mujoco.MjModel, d: mujoco.MjData) -> None:
    """One-line :class:`SimulationError` when the swim diverged: a force provider's own
    check, MuJoCo's divergence warnings, or a non-finite state."""
    DISPATCHER.check(d)
    if (any(d.warning[w].number for w in _BAD)
            or not (np.all(np.isfinite(d.qpos)) and np.all(np.isfinite(d.qvel)))):
        raise SimulationError(
            f"the swimmer diverged at t={d.time:.3f} s: lower the timestep (now "
            f"{m.opt.timestep:g} s) or the PD gains"
        )
