"""What is drawn into a scene besides the model: paths, targets, trees, arrows and fading
trails, as MuJoCo's decorative geoms (``mjvScene.geoms`` after ``mjv_updateScene``). The
videos (:mod:`flapsim.render.video`) and the viewer (:mod:`flapsim.render.viewer`) draw them
the same way. Decorative geoms exist only in the picture: the model and its physics never
see them."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import mujoco
import numpy as np

PATH_RGBA = (0.5, 0.25, 0.0, 1.0)
"""The path asked, as given to MuJoCo: lines come out at twice their colour (clipped; the
headlight and the sun both light them, measured), so it is drawn as :data:`PATH_SHOWN`."""
PATH_SHOWN = (255, 128, 0)
"""The path's colour in the picture: an opaque orange that neither the sky, the ground nor
the dove has (tests look for it in the frames), RGB 0-255."""
TRAIL_RGB = (0.10, 0.45, 1.0)
"""The trajectory flown: blue, fading with age."""


@dataclass(frozen=True)
class Marker:
    """A sphere drawn in the scene (a target), m."""

    pos: Sequence[float]
    radius: float = 0.15
    rgba: Sequence[float] = (0.9, 0.15, 0.1, 0.9)


@dataclass(frozen=True)
class Polyline:
    """A path through ``points`` (n, 3), m: a line ``line_px`` pixels wide whatever its
    distance (seen far ahead, never hiding the animal on it), or (``line_px`` None) capsules
    of radius ``width``, m."""

    points: np.ndarray
    width: float = 0.03
    rgba: Sequence[float] = PATH_RGBA
    line_px: float | None = 3.0


@dataclass(frozen=True)
class Cylinder:
    """An upright cylinder standing on the ground at (x, y): a tree's trunk, m."""

    x: float
    y: float
    radius: float
    height: float
    rgba: Sequence[float] = (0.45, 0.30, 0.18, 1.0)


@dataclass(frozen=True)
class Arrow:
    """An arrow from ``start`` along ``vector`` (m; its length is drawn as given)."""

    start: Sequence[float]
    vector: Sequence[float]
    width: float = 0.02
    rgba: Sequence[float] = (0.95, 0.1, 0.1, 1.0)


@dataclass(frozen=True)
class Trail:
    """A trajectory drawn as capsules whose opacity fades from the newest point (last row,
    ``alpha``) to the oldest (transparent), m."""

    points: np.ndarray
    width: float = 0.02
    rgb: Sequence[float] = TRAIL_RGB
    alpha: float = 0.9
    max_segments: int = 150
    line_px: float | None = 4.0
    """As :attr:`Polyline.line_px`."""


Item = Marker | Polyline | Cylinder | Arrow | Trail


def tree_items(forest) -> list[Item]:
    """A forest's trees (:class:`~flapsim.bird.tasks.flight_tasks.Forest`): trunk and crown."""
    out: list[Item] = []
    for t in getattr(forest, "trees", ()):
        out.append(Cylinder(t.x, t.y, t.trunk_radius, t.height))
        out.append(Marker((t.x, t.y, t.height), t.crown_radius, (0.20, 0.50, 0.18, 0.85)))
    return out


def _free(scn: mujoco.MjvScene) -> bool:
    return scn.ngeom < scn.maxgeom


def _segment(scn: mujoco.MjvScene, a, b, width: float, rgba, line_px: float | None) -> None:
    kind = mujoco.mjtGeom.mjGEOM_CAPSULE if line_px is None else mujoco.mjtGeom.mjGEOM_LINE
    g = scn.geoms[scn.ngeom]
    mujoco.mjv_initGeom(g, kind, np.zeros(3), np.zeros(3), np.eye(3).ravel(),
                        np.asarray(rgba, np.float32))
    mujoco.mjv_connector(g, kind, width if line_px is None else line_px, np.asarray(a, float),
                         np.asarray(b, float))
    scn.ngeom += 1


def add_items(scn: mujoco.MjvScene, items: Sequence[Item]) -> None:
    """Append ``items`` to ``scn`` after the model's own geoms (call after updating the
    scene); what does not fit in ``scn.maxgeom`` is left out, long lines first thinned."""
    for it in items:
        if not _free(scn):
            return
        if isinstance(it, Marker):
            mujoco.mjv_initGeom(scn.geoms[scn.ngeom], mujoco.mjtGeom.mjGEOM_SPHERE,
                                np.array([it.radius, 0, 0]), np.asarray(it.pos, float),
                                np.eye(3).ravel(), np.asarray(it.rgba, np.float32))
            scn.ngeom += 1
        elif isinstance(it, Cylinder):
            mujoco.mjv_initGeom(scn.geoms[scn.ngeom], mujoco.mjtGeom.mjGEOM_CYLINDER,
                                np.array([it.radius, 0.5 * it.height, 0]),
                                np.array([it.x, it.y, 0.5 * it.height]), np.eye(3).ravel(),
                                np.asarray(it.rgba, np.float32))
            scn.ngeom += 1
        elif isinstance(it, Arrow):
            a = np.asarray(it.start, float)
            b = a + np.asarray(it.vector, float)
            if np.linalg.norm(b - a) > 1e-9:
                g = scn.geoms[scn.ngeom]
                mujoco.mjv_initGeom(g, mujoco.mjtGeom.mjGEOM_ARROW, np.zeros(3), np.zeros(3),
                                    np.eye(3).ravel(), np.asarray(it.rgba, np.float32))
                mujoco.mjv_connector(g, mujoco.mjtGeom.mjGEOM_ARROW, it.width, a, b)
                scn.ngeom += 1
        elif isinstance(it, Trail):
            pts = np.asarray(it.points, float)
            step = max(1, int(np.ceil((len(pts) - 1) / it.max_segments)))
            pts = pts[::-1][::step][::-1]  # thinned from the newest point back
            n = len(pts) - 1
            for i in range(n):
                if not _free(scn):
                    return
                alpha = it.alpha * (i + 1) / n
                _segment(scn, pts[i], pts[i + 1], it.width, (*it.rgb, alpha), it.line_px)
        else:
            pts = np.asarray(it.points, float)
            room = max(1, scn.maxgeom - scn.ngeom - 8)
            pts = pts[::max(1, int(np.ceil(len(pts) / room)))]
            for a, b in zip(pts[:-1], pts[1:], strict=True):
                if not _free(scn):
                    return
                _segment(scn, a, b, it.width, it.rgba, it.line_px)
