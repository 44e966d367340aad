"""Feather geometry: flat triangle meshes whose triangles are the force engine's polygons.

A feather is a strip along its shaft from the root to the tip, split into ``segments``
quads (two triangles each). The shaft sits ``lead_fraction`` of the width from the
leading vane, so the narrow outer vane leads and the broad inner vane trails: the
aerodynamic centre of a primary lies behind its twist axis, which is what makes the
primaries twist open at the upstroke (the flight paper, sec. 6, eq. 10-11).

Widths are *exposed* widths: real flight feathers overlap, but each strip here covers
only the part of the wing no other feather covers, so summed polygon areas equal the
wing's planform area instead of counting overlaps twice.

Everything is generated for the LEFT side (wing along +y, dorsal normal +z) in the
frame of the body the feather hangs on; :func:`mirror_triangles` gives the right side.

By default (the bundled ``bird_mjcf/dove.xml``) these meshes are rigid plates and only the
primaries twist, on a one-sided spring hinge (see :mod:`flapsim.bird.body.model`). The paper's
deformable feathers (thin shells with 4 deformation modes) are an option:
``Dove.load(feathers="modal")`` (:mod:`flapsim.bird.body.feather_modes`,
:mod:`flapsim.bird.body.feather_dynamics`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Feather:
    """One feather's mesh in its body frame (left side)."""

    name: str
    """Unique name, e.g. ``l_p10`` (left primary 10, outermost)."""
    kind: str
    """``primary``, ``secondary``, ``tertial`` or ``rectrix``."""
    body: str
    """Name of the body the mesh is attached to."""
    vertices: np.ndarray
    """(nv, 3) mesh vertices in the body frame, m."""
    faces: np.ndarray
    """(nf, 3) vertex indices, counter-clockwise seen from the dorsal side (+z on the left)."""
    shaft: np.ndarray
    """Unit shaft direction (root -> tip) in the body frame."""
    forward: np.ndarray
    """Unit in-plane chordwise direction toward the wing's leading edge, in the body frame."""
    mass: float
    """Feather mass, kg."""

    @property
    def triangles(self) -> np.ndarray:
        """(nf, 3, 3) triangle corners in the body frame."""
        return self.vertices[self.faces]

    @property
    def area(self) -> float:
        t = self.triangles
        return float(0.5 * np.linalg.norm(np.cross(t[:, 1] - t[:, 0], t[:, 2] - t[:, 0]), axis=1).sum())


def strip(
    root: np.ndarray,
    shaft: np.ndarray,
    lead: np.ndarray,
    length: float,
    root_width: float,
    tip_width: float,
    lead_fraction: float,
    segments: int,
    tip_taper: float = 0.5,
) -> tuple[np.ndarray, np.ndarray]:
    """Vertices and faces of a feather strip (normals toward ``shaft x lead`` flipped to +z).

    ``lead`` is the in-plane unit vector toward the leading vane; widths vary linearly
    from root to tip, and the last station is narrowed by ``tip_taper`` (rounded tip).
    """
    root, shaft, lead = (np.asarray(v, dtype=float) for v in (root, shaft, lead))
    verts = []
    for k in range(segments + 1):
        s = k / segments
        w = root_width + (tip_width - root_width) * s
        if k == segments:
            w *= tip_taper
        c = root + s * length * shaft
        verts.append(c + lead_fraction * w * lead)
        verts.append(c - (1.0 - lead_fraction) * w * lead)
    faces = []
    for k in range(segments):
        a, b, c, d = 2 * k, 2 * k + 1, 2 * k + 2, 2 * k + 3
        faces += [(a, b, d), (a, d, c)]
    v = np.array(verts)
    f = np.array(faces, dtype=np.int64)
    # orient every triangle's normal to the dorsal side (+z)
    t = v[f]
    n = np.cross(t[:, 1] - t[:, 0], t[:, 2] - t[:, 0])
    flip = n[:, 2] < 0
    f[flip] = f[flip][:, ::-1]
    return v, f


def in_plane_forward(faces_vertices: np.ndarray, direction=(1.0, 0.0, 0.0)) -> np.ndarray:
    """``direction`` projected on the plane of the first triangle, normalised."""
    t = faces_vertices[0]
    n = np.cross(t[1] - t[0], t[2] - t[0])
    n /= np.linalg.norm(n)
    d = np.asarray(direction, dtype=float)
    f = d - n * (n @ d)
    return f / np.linalg.norm(f)


def mirror_point(p: np.ndarray) -> np.ndarray:
    """Reflect points through the sagittal (x-z) plane: y -> -y."""
    q = np.array(p, dtype=float, copy=True)
    q[..., 1] *= -1.0
    return q


def mirror_axis(a: np.ndarray) -> np.ndarray:
    """Mirror a rotation axis (a pseudo-vector): the same joint angle gives the mirror motion."""
    a = np.asarray(a, dtype=float)
    return np.array([-a[0], a[1], -a[2]])


def mirror_faces(faces: np.ndarray) -> np.ndarray:
    """Reverse the winding so mirrored triangles keep their dorsal normals."""
    return np.asarray(faces)[:, ::-1].copy()


def plate_inertia(
    tris: np.ndarray, mass: float, thickness: float = 1e-3
) -> tuple[np.ndarray, np.ndarray]:
    """Centre of mass and inertia (about it) of thin triangles with uniform areal density.

    Uses the exact second moment of a triangle (vertices a, b, c):
    ``int x x^T dA = A/12 (sum v v^T + (sum v)(sum v)^T)`` over its three corners. The
    plate's ``thickness`` (shaft and vane depth, ~1 mm) adds ``m h^2 / 12`` about every
    axis, which also keeps the tensor strictly physical (A + B > C).
    """
    tris = np.asarray(tris, dtype=float)
    areas = 0.5 * np.linalg.norm(np.cross(tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0]), axis=1)
    rho = mass / areas.sum()
    com = (areas[:, None] * tris.mean(axis=1)).sum(axis=0) / areas.sum()
    second = np.zeros((3, 3))
    for a, t in zip(areas, tris - com, strict=True):
        s = t.sum(axis=0)
        second += a / 12.0 * (t.T @ t + np.outer(s, s))
    second *= rho
    inertia = np.trace(second) * np.eye(3) - second + mass * thickness**2 / 12 * np.eye(3)
    return com, inertia
