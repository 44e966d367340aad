"""Buoyancy of partially submerged bodies: one ellipsoid per body, cut by a flat water surface.

MuJoCo has no partial-submersion buoyancy and no water surface (its users keep asking:
google-deepmind/mujoco #452, #1676, #1691, #3452). This module gives any MuJoCo model
one: name the bodies and a water level, and each body gets an ellipsoid (fitted to its
geoms or given explicitly) whose submerged part pushes up with ``rho V_sub |g|`` at the
centre of buoyancy.

Geometry (the swimming paper, Fig. 6): an ellipsoid ``x = c + R S u`` with ``|u| <= 1``
(``R`` its principal axes in the world, ``S = diag(a, b, c)``) is the image of the unit
ball under an affine map, which preserves volume ratios and centroids. The water half
space ``z < h`` maps to the half space ``u . e < d`` of the unit ball, with

    m = S R^T e_z,   e = m / |m|,   d = (h - c_z) / |m|

(``|m|`` is the ellipsoid's vertical half-height). The submerged part is a spherical cap,
so exactly

    fraction  = (1 + d)^2 (2 - d) / 4
    centroid  = t e  in unit-ball coordinates, t = -3 (1 - d)^2 / (4 (2 - d)),

mapped back as ``c + R S t e``. The paper uses ``(1 + cos theta) / 2`` with
``cos theta = d``, a fraction linear in height (``method="linear"``): it is exact at
d = -1, 0, 1 and off by up to 0.096 between (at d = +-1/sqrt(3)). Both methods apply
the force at the cap centroid (the centre of buoyancy), never at the ellipsoid centre,
so a tilted, half-submerged body feels the righting torque it should.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import mujoco
import numpy as np
from numba import njit

from flapsim.core.callbacks import CompiledProvider, Registration, register, register_kernel
from flapsim.core.errors import InputError, ModelError
from flapsim.core.wrench import add_force, body_point

METHODS = ("exact", "linear")
_OUT = 4  # floats reported per ellipsoid: submerged volume, centre of buoyancy xyz


# -- reference geometry (numpy) ------------------------------------------------------
def cap_fraction(d: np.ndarray | float, method: str = "exact") -> np.ndarray:
    """Fraction of the unit ball with ``u . e < d`` (``d`` clipped to [-1, 1])."""
    d = np.clip(np.asarray(d, dtype=float), -1.0, 1.0)
    if method == "exact":
        return (1.0 + d) ** 2 * (2.0 - d) / 4.0
    if method == "linear":
        return (1.0 + d) / 2.0
    raise InputError(f"unknown buoyancy method {method!r}; choose one of {', '.join(METHODS)}")


def cap_centroid(d: np.ndarray | float) -> np.ndarray:
    """Signed distance along ``e`` of the centroid of ``{u . e < d}`` in the unit ball."""
    d = np.clip(np.asarray(d, dtype=float), -1.0, 1.0)
    return -3.0 * (1.0 - d) ** 2 / (4.0 * (2.0 - d))


def ellipsoid_volume(semi_axes: Sequence[float]) -> float:
    """Volume of an ellipsoid with semi-axes (a, b, c) [m^3]."""
    a, b, c = (float(x) for x in semi_axes)
    return 4.0 / 3.0 * np.pi * a * b * c


def submerged(
    center: Sequence[float],
    rotation: np.ndarray,
    semi_axes: Sequence[float],
    water_level: float,
    method: str = "exact",
) -> tuple[float, np.ndarray]:
    """Submerged volume [m^3] and centre of buoyancy (world, [m]) of one ellipsoid.

    ``rotation`` (3, 3) has the ellipsoid's principal axes as columns, in world
    coordinates; the water fills ``z < water_level``.
    """
    c = np.asarray(center, dtype=float)
    R = np.asarray(rotation, dtype=float).reshape(3, 3)
    s = np.asarray(semi_axes, dtype=float)
    m = s * R[2, :]
    half_height = float(np.linalg.norm(m))
    d = (water_level - c[2]) / half_height
    vol = ellipsoid_volume(s) * float(cap_fraction(d, method))
    t = float(cap_centroid(d))
    centroid = c + R @ (s * (t * m / half_height))
    return vol, centroid


# -- compiled kernel -------------------------------------------------------------------
@njit(cache=True)
def buoyancy_kernel(w, xpos, xmat, ebody, ecenter, erot, esemi, params, out):
    """Add each ellipsoid's buoyant force at its centre of buoyancy to ``w``.

    ``params`` = (water level [m], fluid density [kg/m^3], gx, gy, gz, method (0 exact,
    1 linear)); ``ecenter`` (3n) and ``erot`` (9n, row-major, axes as columns) are in the
    body frame; ``out`` (4n) receives the submerged volume and world centre of buoyancy.
    """
    level = params[0]
    rho = params[1]
    gx = params[2]
    gy = params[3]
    gz = params[4]
    linear = params[5] > 0.5
    for i in range(ebody.size):
        b = ebody[i]
        m = 9 * b
        cx, cy, cz = body_point(xpos, xmat, b, ecenter[3 * i], ecenter[3 * i + 1],
                                ecenter[3 * i + 2])
        # world principal axes A = xmat @ erot (columns); only the products needed below
        r = 9 * i
        sa = esemi[3 * i]
        sb = esemi[3 * i + 1]
        sc = esemi[3 * i + 2]
        a0 = 0.0
        a1 = 0.0
        a2 = 0.0
        a3 = 0.0
        a4 = 0.0
        a5 = 0.0
        a6 = 0.0
        a7 = 0.0
        a8 = 0.0
        for k in range(3):
            x0 = xmat[m + k]
            x1 = xmat[m + 3 + k]
            x2 = xmat[m + 6 + k]
            e0 = erot[r + 3 * k]
            e1 = erot[r + 3 * k + 1]
            e2 = erot[r + 3 * k + 2]
            a0 += x0 * e0
            a1 += x0 * e1
            a2 += x0 * e2
            a3 += x1 * e0
            a4 += x1 * e1
            a5 += x1 * e2
            a6 += x2 * e0
            a7 += x2 * e1
            a8 += x2 * e2
        # m_k = s_k * A[2, k]: |m| is the ellipsoid's vertical half-height
        m0 = sa * a6
        m1 = sb * a7
        m2 = sc * a8
        hh = np.sqrt(m0 * m0 + m1 * m1 + m2 * m2)
        d = (level - cz) / hh
        if d <= -1.0:
            out[4 * i] = 0.0
            out[4 * i + 1] = cx
            out[4 * i + 2] = cy
            out[4 * i + 3] = cz
            continue
        if d > 1.0:
            d = 1.0
        if linear:
            frac = 0.5 * (1.0 + d)
        else:
            frac = 0.25 * (1.0 + d) * (1.0 + d) * (2.0 - d)
        vol = 4.0 / 3.0 * np.pi * sa * sb * sc * frac
        t = -0.75 * (1.0 - d) * (1.0 - d) / (2.0 - d) / hh
        # centroid = c + A @ (s * (t * m))
        q0 = sa * t * m0
        q1 = sb * t * m1
        q2 = sc * t * m2
        px = cx + a0 * q0 + a1 * q1 + a2 * q2
        py = cy + a3 * q0 + a4 * q1 + a5 * q2
        pz = cz + a6 * q0 + a7 * q1 + a8 * q2
        f = -rho * vol
        add_force(w, b, f * gx, f * gy, f * gz, px, py, pz)
        out[4 * i] = vol
        out[4 * i + 1] = px
        out[4 * i + 2] = py
        out[4 * i + 3] = pz
    return 0


register_kernel("buoyancy_ellipsoid", buoyancy_kernel, "ffifffff")


# -- geometry of a model's bodies ------------------------------------------------------
def geom_volume(model: mujoco.MjModel, g: int) -> float:
    """Volume [m^3] of geom ``g`` (primitives in closed form, meshes by the divergence
    theorem over their triangles); planes, heightfields and SDFs have none (0)."""
    t = model.geom_type[g]
    s = model.geom_size[g]
    G = mujoco.mjtGeom
    if t == G.mjGEOM_SPHERE:
        return 4.0 / 3.0 * np.pi * s[0] ** 3
    if t == G.mjGEOM_CAPSULE:
        return np.pi * s[0] ** 2 * 2.0 * s[1] + 4.0 / 3.0 * np.pi * s[0] ** 3
    if t == G.mjGEOM_CYLINDER:
        return np.pi * s[0] ** 2 * 2.0 * s[1]
    if t == G.mjGEOM_ELLIPSOID:
        return 4.0 / 3.0 * np.pi * s[0] * s[1] * s[2]
    if t == G.mjGEOM_BOX:
        return 8.0 * s[0] * s[1] * s[2]
    if t == G.mjGEOM_MESH:
        mid = model.geom_dataid[g]
        va, vn = model.mesh_vertadr[mid], model.mesh_vertnum[mid]
        fa, fn = model.mesh_faceadr[mid], model.mesh_facenum[mid]
        v = model.mesh_vert[va:va + vn]
        f = model.mesh_face[fa:fa + fn]
        return abs(float(np.einsum("ij,ij->i", v[f[:, 0]], np.cross(v[f[:, 1]], v[f[:, 2]])).sum())
                   ) / 6.0
    return 0.0


def body_geom_box(model: mujoco.MjModel, body: int) -> tuple[np.ndarray, np.ndarray]:
    """Centre and half-sizes [m] of the body-frame axis-aligned box around a body's geoms."""
    lo = np.full(3, np.inf)
    hi = np.full(3, -np.inf)
    for g in range(model.ngeom):
        if model.geom_bodyid[g] != body or model.geom_type[g] in (
            mujoco.mjtGeom.mjGEOM_PLANE, mujoco.mjtGeom.mjGEOM_HFIELD
        ):
            continue
        c, h = model.geom_aabb[g, :3], model.geom_aabb[g, 3:]
        corners = c + h * np.array([[i, j, k] for i in (-1, 1) for j in (-1, 1) for k in (-1, 1)])
        R = np.zeros(9)
        mujoco.mju_quat2Mat(R, model.geom_quat[g])
        pts = corners @ R.reshape(3, 3).T + model.geom_pos[g]
        lo = np.minimum(lo, pts.min(axis=0))
        hi = np.maximum(hi, pts.max(axis=0))
    if not np.all(np.isfinite(lo)):
        name = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_BODY, body)
        raise ModelError(
            f"body {name!r} has no geoms to fit a buoyancy ellipsoid to; give its ellipsoid "
            "explicitly (Buoyancy.for_bodies(..., ellipsoids={name: (center, semi_axes)}))"
        )
    return 0.5 * (lo + hi), np.maximum(0.5 * (hi - lo), 1e-9)


@dataclass(frozen=True)
class EllipsoidSet:
    """Buoyancy ellipsoids attached to bodies (geometry in each body's frame)."""

    #: MuJoCo body id of each ellipsoid (>= 1), (n,)
    body: np.ndarray
    #: ellipsoid centre in the body frame [m], (n, 3)
    center: np.ndarray
    #: principal axes as the columns of a rotation, body frame, (n, 3, 3)
    rotation: np.ndarray
    #: semi-axes [m], (n, 3)
    semi_axes: np.ndarray

    @property
    def volumes(self) -> np.ndarray:
        """Full volume of each ellipsoid [m^3]."""
        return 4.0 / 3.0 * np.pi * np.prod(self.semi_axes, axis=1)


@dataclass(frozen=True)
class BuoyancyParams:
    """Water surface and fluid for :class:`Buoyancy`."""

    #: height of the flat water surface [m] (water fills z < water_level)
    water_level: float = 0.0
    #: fluid density [kg/m^3]; fresh water 998 at 20 C, sea water ~1025
    fluid_density: float = 1000.0
    #: submerged fraction: "exact" spherical cap, or the paper's linear (1 + cos theta)/2
    method: str = "exact"

    def __post_init__(self) -> None:
        if not np.isfinite(self.water_level):
            raise InputError("water_level must be a finite height in metres")
        if not (np.isfinite(self.fluid_density) and self.fluid_density > 0):
            raise InputError(f"fluid_density must be > 0 kg/m^3, got {self.fluid_density}")
        if self.method not in METHODS:
            raise InputError(
                f"unknown buoyancy method {self.method!r}; choose one of {', '.join(METHODS)}"
            )


class Buoyancy(CompiledProvider):
    """Buoyant forces on ellipsoids attached to bodies, through the passive dispatcher.

    Build one with :meth:`for_bodies` for any MuJoCo model. One instance serves one
    ``MjData`` at a time (it keeps the last submerged volumes in :attr:`report`).
    """

    kernel = "buoyancy_ellipsoid"

    def __init__(
        self,
        model: mujoco.MjModel,
        ellipsoids: EllipsoidSet,
        params: BuoyancyParams | None = None,
        name: str = "buoyancy",
    ) -> None:
        self.model = model
        self.ellipsoids = ellipsoids
        self.name = name
        n = len(ellipsoids.body)
        if n == 0:
            raise InputError("Buoyancy needs at least one ellipsoid")
        if ellipsoids.body.min() < 1 or ellipsoids.body.max() >= model.nbody:
            raise InputError(f"ellipsoid body ids must be in 1..{model.nbody - 1}")
        if np.any(ellipsoids.semi_axes <= 0) or not np.all(np.isfinite(ellipsoids.semi_axes)):
            raise InputError("ellipsoid semi-axes must be finite and > 0")
        self._body = np.ascontiguousarray(ellipsoids.body, dtype=np.int64)
        self._center = np.ascontiguousarray(ellipsoids.center, dtype=float).reshape(-1)
        self._rot = np.ascontiguousarray(ellipsoids.rotation, dtype=float).reshape(-1)
        self._semi = np.ascontiguousarray(ellipsoids.semi_axes, dtype=float).reshape(-1)
        self._params = np.zeros(6)
        self._out = np.zeros(_OUT * n)
        self.set_params(params or BuoyancyParams())

    # -- construction ------------------------------------------------------------------
    @classmethod
    def for_bodies(
        cls,
        model: mujoco.MjModel,
        bodies: Sequence[str] | None = None,
        water_level: float = 0.0,
        fluid_density: float = 1000.0,
        method: str = "exact",
        volumes: Mapping[str, float] | None = None,
        body_density: float | None = None,
        ellipsoids: Mapping[str, tuple[Sequence[float], Sequence[float]]] | None = None,
    ) -> Buoyancy:
        """Buoyancy for the named bodies of any model (all bodies with geoms if None).

        Each body's ellipsoid is centred on the box around its geoms, with semi-axes in
        proportion to that box and scaled so that its volume is the body's volume:
        ``volumes[name]`` [m^3] if given, else ``body_mass / body_density`` if
        ``body_density`` [kg/m^3] is given, else the summed volume of its geoms.
        ``ellipsoids[name] = (center, semi_axes)`` (body frame, axis-aligned) sets one
        explicitly instead (its volume is then its own).
        """
        volumes = dict(volumes or {})
        ellipsoids = dict(ellipsoids or {})
        if bodies is None:
            ids = sorted({int(b) for b in model.geom_bodyid if b > 0})
        else:
            ids = []
            for name in bodies:
                bid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, name)
                if bid < 1:
                    known = [mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_BODY, i)
                             for i in range(1, model.nbody)]
                    raise ModelError(f"no body named {name!r} in the model; bodies: {known}")
                ids.append(bid)
        for label, keys in (("volumes", volumes), ("ellipsoids", ellipsoids)):
            unknown = set(keys) - {mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_BODY, i)
                                   for i in ids}
            if unknown:
                raise InputError(f"{label} names bodies not in the buoyant set: {sorted(unknown)}")
        if body_density is not None and not body_density > 0:
            raise InputError(f"body_density must be > 0 kg/m^3, got {body_density}")
        centers, semis = [], []
        for bid in ids:
            name = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_BODY, bid)
            if name in ellipsoids:
                c, s = (np.asarray(x, dtype=float) for x in ellipsoids[name])
                if c.shape != (3,) or s.shape != (3,):
                    raise InputError(f"ellipsoid of {name!r} needs a 3-vector centre and 3 semi-axes")
                centers.append(c)
                semis.append(s)
                continue
            center, half = body_geom_box(model, bid)
            if name in volumes:
                vol = float(volumes[name])
            elif body_density is not None:
                vol = float(model.body_mass[bid]) / body_density
            else:
                vol = sum(geom_volume(model, g) for g in range(model.ngeom)
                          if model.geom_bodyid[g] == bid)
            if not vol > 0:
                raise InputError(
                    f"body {name!r}: buoyant volume must be > 0 m^3 (got {vol}); pass volumes="
                )
            scale = (vol / ellipsoid_volume(half)) ** (1.0 / 3.0)
            centers.append(center)
            semis.append(half * scale)
        n = len(ids)
        ell = EllipsoidSet(
            np.asarray(ids, dtype=np.int64), np.asarray(centers).reshape(n, 3),
            np.broadcast_to(np.eye(3), (n, 3, 3)).copy(), np.asarray(semis).reshape(n, 3),
        )
        return cls(model, ell, BuoyancyParams(water_level, fluid_density, method))

    # -- parameters --------------------------------------------------------------------
    def set_params(self, params: BuoyancyParams) -> None:
        """Change water level, density or method in place (effective at the next step)."""
        self.params = params
        g = np.asarray(self.model.opt.gravity, dtype=float)
        self._params[:] = (params.water_level, params.fluid_density, g[0], g[1], g[2],
                           float(params.method == "linear"))

    def set_volume_scale(self, index: int, volume: float) -> None:
        """Rescale ellipsoid ``index`` (same shape) to ``volume`` [m^3], in place."""
        if not volume > 0:
            raise InputError(f"volume must be > 0 m^3, got {volume}")
        s = self._semi[3 * index:3 * index + 3]
        s *= (volume / ellipsoid_volume(s)) ** (1.0 / 3.0)

    @property
    def total_volume(self) -> float:
        """Summed full volume of all ellipsoids [m^3]."""
        return float(self.volumes.sum())

    @property
    def volumes(self) -> np.ndarray:
        return 4.0 / 3.0 * np.pi * np.prod(self._semi.reshape(-1, 3), axis=1)

    # -- dispatcher --------------------------------------------------------------------
    def arrays(self, model: mujoco.MjModel, data: mujoco.MjData) -> list[np.ndarray]:
        if model.nbody != self.model.nbody:
            raise InputError("Buoyancy used with a different model than it was built for")
        return [data.xpos.reshape(-1), data.xmat.reshape(-1), self._body, self._center,
                self._rot, self._semi, self._params, self._out]

    def register(self, data: mujoco.MjData) -> Registration:
        """Apply buoyancy whenever MuJoCo steps ``data`` (until the handle is removed)."""
        return register(self.model, data, self)

    @property
    def report(self) -> tuple[np.ndarray, np.ndarray]:
        """(submerged volume [m^3] (n,), centre of buoyancy [m] (n, 3)) from the last
        passive-force evaluation."""
        o = self._out.reshape(-1, _OUT)
        return o[:, 0].copy(), o[:, 1:].copy()

    def evaluate(self, data: mujoco.MjData) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """For the current kinematics (call ``mj_kinematics``/``mj_forward`` first):
        submerged volumes (n,), centres of buoyancy (n, 3) and buoyant forces (n, 3) [N]."""
        n = len(self._body)
        w = np.zeros(6 * self.model.nbody)
        out = np.zeros(_OUT * n)
        buoyancy_kernel(w, data.xpos.reshape(-1), data.xmat.reshape(-1), self._body,
                        self._center, self._rot, self._semi, self._params, out)
        o = out.reshape(n, _OUT)
        g = self._params[2:5]
        force = -self._params[1] * o[:, :1] * g[None, :]
        return o[:, 0].copy(), o[:, 1:].copy(), force

    def submerged_mass(self, data: mujoco.MjData) -> float:
        """Mass of displaced fluid [kg] for the current kinematics."""
        vol, _, _ = self.evaluate(data)
        return float(self._params[1] * vol.sum())
