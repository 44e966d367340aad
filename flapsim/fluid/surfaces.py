"""Oriented polygons on bodies -> drag, lift and friction -> body wrenches, every step.

One engine serves air (feathers) and water (swimmer); they differ only in coefficient
tables and :class:`FluidParams`. Per polygon, at its world centroid ``p`` on body ``b``:

* relative flow ``V = u(p, t) - v_b(p)``: fluid velocity field minus the body's point
  velocity ``cvel[b,3:] + cvel[b,:3] x (p - subtree_com[root(b)])``;
* with a forward vector ``F`` (the plate's long side / a feather's leading-edge chord
  direction, as in the swimming paper): ``V`` splits into its part ``V_d`` in the plane
  of ``N`` and ``F`` (drag and lift) and its part along ``S = N x F`` (friction only);
  angle of attack ``a = atan2(|V_d.N|, -V_d.F)`` in 0..180 deg (below 90 deg when the flow
  meets the +F edge first). Without ``F``: ``V_d = V`` and ``a = atan2(|V.N|, |V_t|)``
  in 0..90 deg (the flight paper's eq. 8);
* drag ``1/2 rho |V_d|^2 A CD(a)`` along ``V_d``; lift ``1/2 rho |V_d|^2 A CL(a)``
  perpendicular to ``V_d`` in the plane of ``N``, on the side the flow pushes the plate
  (towards ``sign(V_d.N) N``), with the sign of CL flipped past 90 deg, where a
  symmetric table's CL turns negative only because its lift axis turned over;
* friction ``eta A v_t`` along the tangential flow (``eta`` [N s/m^3] is a skin-friction
  coefficient per unit area and speed, the swimming paper's eq. 2);
* optional rules: only front-facing polygons (flow hits the face: ``V.N < 0`` for an
  outward normal), and a free surface at height ``surface_z`` (fluid only below it; a
  polygon straddling it is scaled by its submerged fraction along its vertical extent).

The swimming paper writes drag as ``1/2 C rho a_n |v_n|^2`` (projected area times the
normal speed squared). Hoerner's plate coefficients are referenced to the plate area
and the full dynamic pressure, so using them with ``a_n |v_n|^2`` would count the angle
dependence twice; flapsim uses ``A |V_d|^2`` for both fluids.

Force terms are inspectable one by one with :meth:`SurfaceForces.evaluate`.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import mujoco
import numpy as np
from numba import njit

from flapsim.core.callbacks import (
    CompiledProvider,
    Registration,
    register,
    register_kernel,
    time_view,
)
from flapsim.core.errors import InputError
from flapsim.core.wrench import add_force, body_point, body_vector, map_wrenches
from flapsim.fluid.coefficients import CoefficientTable, get_table
from flapsim.fluid.flow import FlowField, flow_at
from flapsim.fluid.hinges import (
    HF,
    HS,
    PolygonHinges,
    hinge_arrays,
    hinge_frames,
    hinge_torque,
    hinged_point,
    hinged_vector,
    integrator_damping,
)
from flapsim.fluid.induced import InducedFlow, momentum_downwash

RECORD = 16  # floats recorded per polygon by evaluate(): see SurfaceReport
QFRC_ARG = 26  # surface_kernel's qfrc argument, counted after ``w``


def _rows(name: str, a: np.ndarray | Sequence, n: int, width: int) -> np.ndarray:
    arr = np.asarray(a, dtype=float)
    if width == 1:
        arr = np.broadcast_to(arr, (n,)).astype(float) if arr.ndim == 0 else arr
        shape = (n,)
    else:
        shape = (n, width)
    if arr.shape != shape:
        raise InputError(f"PolygonSet.{name} must have shape {shape}, got {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise InputError(f"PolygonSet.{name} contains NaN or inf")
    return np.ascontiguousarray(arr)


@dataclass(frozen=True)
class PolygonSet:
    """Oriented polygons attached to bodies. Geometry is in each body's local frame."""

    #: MuJoCo body id each polygon is attached to (>= 1; the world body cannot move)
    body: np.ndarray
    #: polygon centroid in the body frame [m], (n, 3)
    centroid: np.ndarray
    #: unit normal in the body frame, (n, 3)
    normal: np.ndarray
    #: polygon area [m^2], (n,)
    area: np.ndarray
    #: unit in-plane forward vector (long side / leading edge) or zeros, (n, 3)
    forward: np.ndarray
    #: index into the coefficient table list of the :class:`SurfaceForces`, (n,)
    table: np.ndarray
    #: half-size [m]: largest centroid-to-vertex distance, for the free-surface cut, (n,)
    extent: np.ndarray
    #: optional label per polygon (e.g. feather name), for plucking and reports
    labels: tuple[str, ...] = field(default=(), compare=False)

    def __post_init__(self) -> None:
        n = int(np.asarray(self.body).shape[0]) if np.ndim(self.body) else 0
        body = np.ascontiguousarray(self.body, dtype=np.int64).reshape(-1)
        table = np.ascontiguousarray(np.broadcast_to(np.asarray(self.table, dtype=np.int64), (n,)))
        object.__setattr__(self, "body", body)
        object.__setattr__(self, "table", table)
        object.__setattr__(self, "centroid", _rows("centroid", self.centroid, n, 3))
        normal = _rows("normal", self.normal, n, 3)
        if n and np.any(np.abs(np.linalg.norm(normal, axis=1) - 1.0) > 1e-6):
            raise InputError("PolygonSet.normal must be unit vectors")
        object.__setattr__(self, "normal", normal)
        area = _rows("area", self.area, n, 1)
        if np.any(area <= 0):
            raise InputError("PolygonSet.area must be > 0 (degenerate polygon?)")
        object.__setattr__(self, "area", area)
        fwd = _rows("forward", self.forward, n, 3)
        fn = np.linalg.norm(fwd, axis=1)
        if np.any((fn > 1e-12) & (np.abs(fn - 1.0) > 1e-6)):
            raise InputError("PolygonSet.forward must be unit vectors or zeros")
        if np.any(np.abs(np.einsum("ij,ij->i", fwd, normal)) > 1e-6):
            raise InputError("PolygonSet.forward must lie in the polygon plane (F . N = 0)")
        object.__setattr__(self, "forward", fwd)
        object.__setattr__(self, "extent", _rows("extent", self.extent, n, 1))
        if self.labels and len(self.labels) != n:
            raise InputError("PolygonSet.labels needs one label per polygon")

    def __len__(self) -> int:
        return int(self.body.shape[0])

    @classmethod
    def from_polygons(
        cls,
        body: int | np.ndarray,
        vertices: np.ndarray,
        forward: np.ndarray | Sequence[float] | None = None,
        table: int | np.ndarray = 0,
        labels: Sequence[str] = (),
    ) -> PolygonSet:
        """Planar convex polygons (n, k, 3), k >= 3 (triangles: k = 3), in the body frame,
        vertices in order (normal by the right-hand rule). ``forward`` (3,) or (n, 3) is
        projected into each polygon's plane."""
        v = np.asarray(vertices, dtype=float)
        if v.ndim != 3 or v.shape[1] < 3 or v.shape[2] != 3:
            raise InputError(f"vertices must have shape (n, k>=3, 3), got {v.shape}")
        n = v.shape[0]
        # area vector of a polygon: half the sum of cross products of a fan from vertex 0
        e = v[:, 1:, :] - v[:, :1, :]
        av = 0.5 * np.cross(e[:, :-1], e[:, 1:]).sum(axis=1)
        area = np.linalg.norm(av, axis=1)
        if np.any(area <= 1e-15):
            bad = int(np.argmin(area))
            raise InputError(f"polygon {bad} has zero area (collinear vertices)")
        normal = av / area[:, None]
        # area-weighted centroid of the fan triangles
        tri_c = (v[:, :1, :] + v[:, 1:-1, :] + v[:, 2:, :]) / 3.0
        tri_a = 0.5 * np.linalg.norm(np.cross(e[:, :-1], e[:, 1:]), axis=2)
        centroid = (tri_c * tri_a[:, :, None]).sum(axis=1) / tri_a.sum(axis=1)[:, None]
        extent = np.linalg.norm(v - centroid[:, None, :], axis=2).max(axis=1)
        fwd = np.zeros((n, 3))
        if forward is not None:
            f = np.broadcast_to(np.asarray(forward, dtype=float), (n, 3))
            f = f - np.einsum("ij,ij->i", f, normal)[:, None] * normal
            norm = np.linalg.norm(f, axis=1)
            if np.any(norm < 1e-9):
                raise InputError("forward vector is normal to a polygon; it must lie in its plane")
            fwd = f / norm[:, None]
        bodies = np.broadcast_to(np.asarray(body, dtype=np.int64), (n,))
        return cls(bodies, centroid, normal, area, fwd, table, extent, tuple(labels))

    #: triangles (n, 3, 3) are polygons with three vertices
    from_triangles = from_polygons

    @classmethod
    def from_box(
        cls, body: int, half_sizes: Sequence[float], pos: Sequence[float] = (0, 0, 0),
        quat: Sequence[float] = (1, 0, 0, 0), subdivisions: int = 1, table: int = 0,
        label: str = "",
    ) -> PolygonSet:
        """The six faces of a box (outward normals, forward = the face's longer side),
        each split into ``subdivisions`` x ``subdivisions`` patches so that a free
        surface cuts them finely. Box pose (``pos``, ``quat``) is in the body frame."""
        h = np.asarray(half_sizes, dtype=float)
        if h.shape != (3,) or np.any(h <= 0):
            raise InputError("box half_sizes must be 3 positive numbers")
        k = int(subdivisions)
        if k < 1:
            raise InputError("subdivisions must be >= 1")
        R = np.zeros(9)
        mujoco.mju_quat2Mat(R, np.asarray(quat, dtype=float))
        R = R.reshape(3, 3)
        polys, fwds = [], []
        for axis in range(3):
            u_ax, v_ax = [a for a in range(3) if a != axis]
            for sign in (1.0, -1.0):
                # order (u, v) so that u x v points along sign * axis (outward)
                u, v = (u_ax, v_ax) if sign > 0 else (v_ax, u_ax)
                grid = np.linspace(-1.0, 1.0, k + 1)
                for i in range(k):
                    for j in range(k):
                        corners = []
                        for du, dv in ((0, 0), (1, 0), (1, 1), (0, 1)):
                            c = np.zeros(3)
                            c[axis] = sign * h[axis]
                            c[u] = grid[i + du] * h[u]
                            c[v] = grid[j + dv] * h[v]
                            corners.append(c)
                        polys.append(corners)
                        long_ax = u if h[u] >= h[v] else v
                        f = np.zeros(3)
                        f[long_ax] = 1.0
                        fwds.append(f)
        verts = np.einsum("ij,nkj->nki", R, np.asarray(polys)) + np.asarray(pos, dtype=float)
        fwd = np.asarray(fwds) @ R.T
        labels = (label,) * len(polys) if label else ()
        return cls.from_polygons(body, verts, fwd, table, labels)

    @staticmethod
    def concat(sets: Sequence[PolygonSet]) -> PolygonSet:
        """One set from several (labels kept only if every set has them)."""
        if not sets:
            raise InputError("concat needs at least one PolygonSet")
        labels: tuple[str, ...] = ()
        if all(len(s.labels) == len(s) for s in sets):
            labels = tuple(lbl for s in sets for lbl in s.labels)
        return PolygonSet(
            np.concatenate([s.body for s in sets]),
            np.concatenate([s.centroid for s in sets]),
            np.concatenate([s.normal for s in sets]),
            np.concatenate([s.area for s in sets]),
            np.concatenate([s.forward for s in sets]),
            np.concatenate([s.table for s in sets]),
            np.concatenate([s.extent for s in sets]),
            labels,
        )

    def subset(self, mask: np.ndarray) -> PolygonSet:
        """The polygons where ``mask`` is true (e.g. plucking feathers)."""
        m = np.asarray(mask, dtype=bool)
        if m.shape != (len(self),):
            raise InputError(f"mask must have shape ({len(self)},), got {m.shape}")
        labels = tuple(lbl for lbl, keep in zip(self.labels, m, strict=False) if keep)
        return PolygonSet(self.body[m], self.centroid[m], self.normal[m], self.area[m],
                          self.forward[m], self.table[m], self.extent[m], labels)


@dataclass(frozen=True)
class FluidParams:
    """The medium and the rules of the force model."""

    #: fluid density [kg/m^3]; air 1.225 (ISA sea level, the flight paper), water ~1000
    density: float = 1.225
    #: skin-friction coefficient eta [N s/m^3]: friction = eta * area * tangential speed
    friction: float = 0.0
    #: only polygons whose outward normal faces the oncoming flow feel force (swimming paper)
    front_facing_only: bool = False
    #: height of a free surface [m]: the fluid fills z < surface_z; None = unbounded
    surface_z: float | None = None

    def __post_init__(self) -> None:
        if not (np.isfinite(self.density) and self.density > 0):
            raise InputError(f"fluid density must be > 0 kg/m^3, got {self.density}")
        if not (np.isfinite(self.friction) and self.friction >= 0):
            raise InputError(f"friction coefficient must be >= 0, got {self.friction}")
        if self.surface_z is not None and not np.isfinite(self.surface_z):
            raise InputError("surface_z must be finite or None")

    def pack(self) -> np.ndarray:
        z = np.inf if self.surface_z is None else float(self.surface_z)
        return np.array([self.density, self.friction, float(self.front_facing_only), z, 0.0])


#: samples of the kernel's tables over the pseudo-angle d in [0, 2] (see ``pseudo_angle_tables``)
KERNEL_SAMPLES = 721


def pseudo_angle_tables(table: CoefficientTable) -> tuple[np.ndarray, np.ndarray]:
    """Resample a table on a uniform grid of the pseudo-angle ``d`` the kernel uses.

    With ``y = |V_d . N|`` and ``x`` the signed in-plane flow (``-V_d . F``, or ``|V_t|``),
    ``d = y / (|x| + y)`` for ``x >= 0`` and ``2 - y / (|x| + y)`` otherwise: monotone in
    the angle of attack (``tan a = d / (1 - d)`` on the first half) and needs one
    division instead of an ``atan2``. The grid is 0.32-0.64 deg apart in angle.
    """
    d = np.linspace(0.0, 2.0, KERNEL_SAMPLES)
    aoa = np.where(d <= 1.0, np.arctan2(d, 1.0 - d), np.pi - np.arctan2(2.0 - d, d - 1.0))
    cl, cd = table.at(np.rad2deg(aoa))
    return cl, cd


@njit(cache=True, inline="always", fastmath={"contract", "arcp", "afn", "nsz"})
def plate_force(rho, eta, area, nx, ny, nz, vx, vy, vz, vn, tx, ty, tz, x, has_f, tab_index,
                cl_tab, cd_tab):
    """Drag, lift and friction (9 numbers, world frame) on one polygon of ``area`` and unit
    normal ``n`` in the relative flow ``v``, with ``vn = v.N``, ``t`` the friction (or
    tangential) part and ``x`` the signed in-plane flow (see :func:`surface_kernel`)."""
    dvx = vx - tx if has_f else vx
    dvy = vy - ty if has_f else vy
    dvz = vz - tz if has_f else vz
    frx = eta * area * tx
    fry = eta * area * ty
    frz = eta * area * tz
    y = abs(vn)
    ax = abs(x)
    sp2 = vn * vn + x * x
    drx = 0.0
    dry = 0.0
    drz = 0.0
    lfx = 0.0
    lfy = 0.0
    lfz = 0.0
    if sp2 > 1e-24:
        s = y / (ax + y)
        dd = s if x >= 0.0 else 2.0 - s
        nsamp = 721  # KERNEL_SAMPLES
        tab = tab_index * nsamp
        u = dd * (0.5 * (nsamp - 1))
        k0 = min(int(u), nsamp - 2)
        fr = u - k0
        cl = cl_tab[tab + k0] * (1.0 - fr) + cl_tab[tab + k0 + 1] * fr
        cd = cd_tab[tab + k0] * (1.0 - fr) + cd_tab[tab + k0 + 1] * fr
        if x < 0.0:
            cl = -cl  # past 90 deg a symmetric table's lift axis has turned over
        sp = np.sqrt(sp2)
        q = 0.5 * rho * sp2 * area
        g = q * cd / sp
        drx = g * dvx
        dry = g * dvy
        drz = g * dvz
        # unit lift: (sg N - (y/sp) e) / (|x|/sp), with e = V_d/sp and sg = sign(V_d.N)
        if ax > 1e-12 * sp:
            h = q * cl / ax
            sg = sp if vn >= 0.0 else -sp
            k = y / sp
            lfx = h * (sg * nx - k * dvx)
            lfy = h * (sg * ny - k * dvy)
            lfz = h * (sg * nz - k * dvz)
    return drx, dry, drz, lfx, lfy, lfz, frx, fry, frz


@njit(cache=True, fastmath={"contract", "arcp", "afn", "nsz"})
def surface_kernel(w, xpos, xmat, cvel, scom, rootid, pbody, pc, pn, pf, parea, pext, ptab,
                   cl_tab, cd_tab, flow, params, tnow, ext_flow, rec, phinge, hint, hflt, hs, qpos,
                   qvel, qacc, qfrc, qfrc_applied, qM, damping, parent, dofadr, dofnum, cdof,
                   cdof_dot, cacc, opt, userdata, pgroup, gint, gflt, gacc):
    """Add every polygon's force to the body wrench accumulator ``w``.

    ``params`` = (density, friction, front_only, surface_z, use_ext_flow); ``cl_tab`` and
    ``cd_tab`` are the tables on the pseudo-angle grid (:func:`pseudo_angle_tables`);
    ``rec`` is filled per polygon when its size allows (see :class:`SurfaceReport`).
    Polygons with ``phinge >= 0`` ride that hinge (:mod:`flapsim.fluid.hinges`: ``hint``,
    ``hflt``, scratch ``hs``); the hinges' torques go to their DOF in ``qfrc`` (the
    remaining arrays are the MuJoCo data and model arrays the hinges read, ``cacc`` scratch).
    Polygons with ``pgroup >= 0`` push and see their group's induced flow
    (:mod:`flapsim.fluid.induced`: DOF addresses and the free stream's body in ``gint``, disk
    areas in ``gflt``, the groups' summed forces in the scratch ``gacc``); the downwash's
    drive goes to its DOF in ``qfrc``.
    """
    rho = params[0]
    eta = params[1]
    front_only = params[2] > 0.5
    zs = params[3]
    use_ext = params[4] > 0.5
    record = rec.size >= 16 * pbody.size
    t = tnow[0]
    nh = hint.size // 4
    if nh > 0:
        hinge_frames(xpos, xmat, qpos, qvel, hint, hflt, hs)
    ng = gflt.size
    for k in range(3 * ng):
        gacc[k] = 0.0
    for i in range(pbody.size):
        b = pbody[i]
        h = phinge[i] if nh > 0 else -1
        if h >= 0:
            px, py, pz = hinged_point(hflt, hs, h, pc[3 * i], pc[3 * i + 1], pc[3 * i + 2])
        else:
            px, py, pz = body_point(xpos, xmat, b, pc[3 * i], pc[3 * i + 1], pc[3 * i + 2])
        if record:
            for k in range(16):
                rec[16 * i + k] = 0.0
            rec[16 * i + 13] = px
            rec[16 * i + 14] = py
            rec[16 * i + 15] = pz
        # world normal and forward
        if h >= 0:
            nx, ny, nz = hinged_vector(hs, h, pn[3 * i], pn[3 * i + 1], pn[3 * i + 2])
        else:
            nx, ny, nz = body_vector(xmat, b, pn[3 * i], pn[3 * i + 1], pn[3 * i + 2])
        # submerged fraction under a free surface
        frac = 1.0
        if zs < 1e300:
            half = pext[i] * np.sqrt(max(0.0, 1.0 - nz * nz))
            if half > 1e-12:
                frac = min(1.0, max(0.0, 0.5 + (zs - pz) / (2.0 * half)))
            else:
                frac = 1.0 if pz < zs else 0.0
            if frac <= 0.0:
                continue
        a = pf[3 * i]
        c = pf[3 * i + 1]
        e = pf[3 * i + 2]
        has_f = a * a + c * c + e * e > 0.5
        # body point velocity (cvel = [omega, v] at the root's subtree com)
        r = rootid[b]
        dx = px - scom[3 * r]
        dy = py - scom[3 * r + 1]
        dz = pz - scom[3 * r + 2]
        wx = cvel[6 * b]
        wy = cvel[6 * b + 1]
        wz = cvel[6 * b + 2]
        ux, uy, uz = flow_at(flow, px, py, pz, t)
        if use_ext:
            ux += ext_flow[3 * i]
            uy += ext_flow[3 * i + 1]
            uz += ext_flow[3 * i + 2]
        grp = pgroup[i] if ng > 0 else -1
        if grp >= 0:  # the group's own downwash: the velocity of its DOF
            ux += qvel[gint[3 * grp]]
            uy += qvel[gint[3 * grp + 1]]
            uz += qvel[gint[3 * grp + 2]]
        vx = ux - (cvel[6 * b + 3] + wy * dz - wz * dy)
        vy = uy - (cvel[6 * b + 4] + wz * dx - wx * dz)
        vz = uz - (cvel[6 * b + 5] + wx * dy - wy * dx)
        so = HS * h
        rx = ry = rz = 0.0  # the centroid from its hinge's axis (hinged polygons only)
        if h >= 0:  # and the plate's turning about its hinge
            rx = px - hs[so + 4]
            ry = py - hs[so + 5]
            rz = pz - hs[so + 6]
            ex = hs[so] * hs[so + 1]
            ey = hs[so] * hs[so + 2]
            ez = hs[so] * hs[so + 3]
            vx -= ey * rz - ez * ry
            vy -= ez * rx - ex * rz
            vz -= ex * ry - ey * rx
        vn = vx * nx + vy * ny + vz * nz
        if front_only and vn >= 0.0:
            continue
        area = parea[i] * frac
        # split: drag/lift part (in the N-F plane, or everything) and friction part
        if has_f:
            if h >= 0:
                fx, fy, fz = hinged_vector(hs, h, a, c, e)
            else:
                fx, fy, fz = body_vector(xmat, b, a, c, e)
            sx = ny * fz - nz * fy
            sy = nz * fx - nx * fz
            sz = nx * fy - ny * fx
            vs = vx * sx + vy * sy + vz * sz
            tx = vs * sx
            ty = vs * sy
            tz = vs * sz
            # in-plane flow: its normal part vn (V.N is unchanged by removing V.S) and
            # its chordwise part x, positive when the flow meets the +F edge first
            x = -(vx * fx + vy * fy + vz * fz)
        else:
            tx = vx - vn * nx
            ty = vy - vn * ny
            tz = vz - vn * nz
            x = np.sqrt(tx * tx + ty * ty + tz * tz)
        (drx, dry, drz, lfx, lfy, lfz, frx, fry, frz) = plate_force(
            rho, eta, area, nx, ny, nz, vx, vy, vz, vn, tx, ty, tz, x, has_f, ptab[i], cl_tab,
            cd_tab)
        y = abs(vn)
        Fx = drx + lfx + frx
        Fy = dry + lfy + fry
        Fz = drz + lfz + frz
        add_force(w, b, Fx, Fy, Fz, px, py, pz)
        if grp >= 0:
            gacc[3 * grp] += Fx
            gacc[3 * grp + 1] += Fy
            gacc[3 * grp + 2] += Fz
        if h >= 0:  # the force's torque about the hinge axis
            hs[so + 16] += (hs[so + 1] * (ry * Fz - rz * Fy) + hs[so + 2] * (rz * Fx - rx * Fz)
                            + hs[so + 3] * (rx * Fy - ry * Fx))
        if record:
            o = 16 * i
            rec[o] = drx
            rec[o + 1] = dry
            rec[o + 2] = drz
            rec[o + 3] = lfx
            rec[o + 4] = lfy
            rec[o + 5] = lfz
            rec[o + 6] = frx
            rec[o + 7] = fry
            rec[o + 8] = frz
            rec[o + 9] = np.arctan2(y, x)
            rec[o + 10] = frac
    if ng > 0:
        # the free stream: the air at the reference body relative to its frame origin
        rb = gint[3 * ng]
        r = rootid[rb]
        bx = xpos[3 * rb]
        by = xpos[3 * rb + 1]
        bz = xpos[3 * rb + 2]
        dx = bx - scom[3 * r]
        dy = by - scom[3 * r + 1]
        dz = bz - scom[3 * r + 2]
        wx = cvel[6 * rb]
        wy = cvel[6 * rb + 1]
        wz = cvel[6 * rb + 2]
        ux, uy, uz = flow_at(flow, bx, by, bz, t)
        vfx = ux - (cvel[6 * rb + 3] + wy * dz - wz * dy)
        vfy = uy - (cvel[6 * rb + 4] + wz * dx - wx * dz)
        vfz = uz - (cvel[6 * rb + 5] + wx * dy - wy * dx)
        for g in range(ng):
            a0 = gint[3 * g]
            a1 = gint[3 * g + 1]
            a2 = gint[3 * g + 2]
            qx, qy, qz = momentum_downwash(gacc[3 * g], gacc[3 * g + 1], gacc[3 * g + 2], vfx, vfy,
                                           vfz, qvel[a0], qvel[a1], qvel[a2], rho, gflt[g])
            # with the DOF's own damping c, c (w_momentum - w): tau dw/dt = w_momentum - w
            qfrc[a0] += damping[a0] * qx
            qfrc[a1] += damping[a1] * qy
            qfrc[a2] += damping[a2] * qz
    if nh > 0:
        hinge_torque(hint, hflt, hs, cvel, cacc, scom, rootid, qpos, qvel, qfrc, qfrc_applied, qM,
                     damping, opt, t, userdata, parent, dofadr, dofnum, cdof, cdof_dot, qacc)
    return 0


register_kernel("surfaces", surface_kernel,
                "ffffiifffffifffffff" + "iiff" + "fffffff" + "iiifffff" + "iiff")


@dataclass
class SurfaceReport:
    """Per-polygon force terms from :meth:`SurfaceForces.evaluate` (world frame, SI)."""

    drag: np.ndarray  #: (n, 3) drag force [N]
    lift: np.ndarray  #: (n, 3) lift force [N]
    friction: np.ndarray  #: (n, 3) friction force [N]
    aoa: np.ndarray  #: (n,) angle of attack [rad]
    submerged: np.ndarray  #: (n,) fraction of the polygon in the fluid
    points: np.ndarray  #: (n, 3) world centroids [m]
    body_force: np.ndarray  #: (nbody, 3) summed force per body [N]
    body_torque: np.ndarray  #: (nbody, 3) summed torque per body about the world origin [N m]

    @property
    def force(self) -> np.ndarray:
        """(n, 3) total force per polygon [N]."""
        return self.drag + self.lift + self.friction

    @property
    def total_force(self) -> np.ndarray:
        return self.body_force.sum(axis=0)


class SurfaceForces(CompiledProvider):
    """Fluid forces on a :class:`PolygonSet`, applied through the passive dispatcher."""

    kernel = "surfaces"

    def __init__(
        self,
        model: mujoco.MjModel,
        polygons: PolygonSet,
        tables: Sequence[CoefficientTable | str] = ("flat_plate",),
        params: FluidParams | None = None,
        flow: FlowField | None = None,
        name: str = "surface forces",
        hinges: PolygonHinges | None = None,
        induced: InducedFlow | None = None,
    ) -> None:
        self.model = model
        self.polygons = polygons
        self.name = name
        self.hinges = hinges
        if len(polygons) == 0:
            raise InputError("SurfaceForces needs at least one polygon")
        if polygons.body.min() < 1 or polygons.body.max() >= model.nbody:
            raise InputError(
                f"polygon body ids must be in 1..{model.nbody - 1} for this model "
                f"(got {polygons.body.min()}..{polygons.body.max()})"
            )
        self.tables = [get_table(t) for t in tables]
        if polygons.table.min() < 0 or polygons.table.max() >= len(self.tables):
            raise InputError(
                f"polygon table indices must be in 0..{len(self.tables) - 1} "
                f"({len(self.tables)} tables given)"
            )
        self.params = params or FluidParams()
        self.flow = flow or FlowField()
        self._param_array = self.params.pack()
        resampled = [pseudo_angle_tables(t) for t in self.tables]
        self._cl = np.concatenate([cl for cl, _ in resampled])
        self._cd = np.concatenate([cd for _, cd in resampled])
        self._rootid = np.ascontiguousarray(model.body_rootid, dtype=np.int64)
        self._ext = np.zeros(3 * len(polygons))
        self._no_record = np.zeros(1)
        none_i, none_f = np.zeros(0, dtype=np.int64), np.zeros(0)
        self._phinge, self._hint, self._hflt = none_i, none_i, none_f
        if hinges is not None and len(hinges):
            self._phinge, self._hint, self._hflt = hinges.tables(model, polygons.labels, polygons.body)
            integrator_damping(model)  # an RK4 model is refused here, not at the first step
        self.induced = induced
        self._pgroup, self._gint, self._gflt = none_i, none_i, none_f
        if induced is not None:
            if induced.polygon_group.size != len(polygons):
                raise InputError(f"InducedFlow.polygon_group has {induced.polygon_group.size} "
                                 f"entries for {len(polygons)} polygons")
            self._pgroup = induced.polygon_group
            self._gint, self._gflt = induced.tables(model)
            integrator_damping(model)

    @property
    def induced_dofs(self) -> np.ndarray:
        """The DOF addresses holding the induced flow's downwash (empty without it)."""
        return self._gint[:-1].copy() if self._gint.size else np.zeros(0, dtype=np.int64)

    def set_params(self, params: FluidParams) -> None:
        """Change density, friction or the free surface in place (takes effect at once)."""
        self.params = params
        self._param_array[:4] = params.pack()[:4]

    def arrays(self, model: mujoco.MjModel, data: mujoco.MjData, record: np.ndarray | None = None
               ) -> list[np.ndarray]:
        if model is not self.model and model.nbody != self.model.nbody:
            raise InputError("SurfaceForces used with a different model than it was built for")
        p = self.polygons
        return [
            data.xpos.reshape(-1), data.xmat.reshape(-1), data.cvel.reshape(-1),
            data.subtree_com.reshape(-1), self._rootid, p.body, p.centroid.reshape(-1),
            p.normal.reshape(-1), p.forward.reshape(-1), p.area, p.extent, p.table, self._cl,
            self._cd, self.flow.params, self._param_array, time_view(data), self._ext,
            self._no_record if record is None else record, *self._hinge_arrays(model, data),
        ]

    def _hinge_arrays(self, model: mujoco.MjModel, data: mujoco.MjData) -> list[np.ndarray]:
        """The hinges' arrays (:mod:`flapsim.fluid.hinges`) for one (model, data): their
        scratch is per registration, the timestep the model's own (a coarser copy, say)."""
        # the groups' force sums are scratch of each registration too: a flight and its copy
        # stepped in two threads (the learned controller's look-ahead) would otherwise sum
        # into one array, each seeing part of the other's lift in its downwash
        induced = [self._pgroup, self._gint, self._gflt, np.zeros(3 * self._gflt.size)]
        if self._hint.size == 0 and self._gflt.size == 0:
            return [self._phinge, self._hint, self._hflt, *[np.zeros(0)] * 8,
                    *[np.zeros(0, dtype=np.int64)] * 3, *[np.zeros(0)] * 5, *induced]
        # the induced flow reads and drives its DOF through the same data arrays as the hinges
        return [self._phinge, *hinge_arrays(model, data, self._hint, self._hflt), *induced]

    def register(self, data: mujoco.MjData, model: mujoco.MjModel | None = None) -> Registration:
        """Apply these forces whenever MuJoCo steps ``data`` (until the handle is removed);
        ``model``: a copy of this one that ``data`` was made from (same bodies; another
        timestep, say) instead of this one."""
        model = self.model if model is None else model
        if model.nbody != self.model.nbody or model.nv != self.model.nv:
            raise InputError("register: the model is not a copy of the forces' own (bodies or DOF differ)")
        if self.flow.has_python:
            return register(model, data, self._python_provider(data), self.name)
        return register(model, data, self)

    def _python_provider(self, data: mujoco.MjData):
        """Provider for flows with Python fields: evaluate them for all centroids, then run
        the same kernel and mapping (this path runs Python every step)."""
        arrays = self.arrays(self.model, data)
        w = np.zeros(6 * self.model.nbody)
        ints = [np.ascontiguousarray(a, dtype=np.int64) for a in
                (self.model.body_parentid, self.model.body_rootid, self.model.dof_bodyid)]
        self._param_array[4] = 1.0

        def provider(m: mujoco.MjModel, d: mujoco.MjData) -> None:
            pts = self.world_centroids(d)
            ext = np.zeros_like(pts)
            for f in self.flow.python_fields:
                v = np.asarray(f.fn(pts, d.time), dtype=float)
                if v.shape != pts.shape:
                    raise InputError(f"flow field returned shape {v.shape}, expected {pts.shape}")
                ext += v
            self._ext[:] = ext.reshape(-1)
            w[:] = 0.0
            surface_kernel(w, *arrays)
            if map_wrenches(w, m.nbody, m.nv, *ints, d.cdof.reshape(-1),
                            d.subtree_com.reshape(-1), d.qfrc_passive) != 0:
                raise InputError("non-finite fluid force (diverged state or NaN in the flow field)")

        provider.name = self.name  # type: ignore[attr-defined]
        return provider

    def world_centroids(self, data: mujoco.MjData) -> np.ndarray:
        """(n, 3) world positions of the polygon centroids (hinged ones turned)."""
        return self._world(data)[0]

    def world_normals(self, data: mujoco.MjData) -> np.ndarray:
        """(n, 3) world unit normals of the polygons (hinged ones turned)."""
        return self._world(data)[1]

    def _world(self, data: mujoco.MjData) -> tuple[np.ndarray, np.ndarray]:
        p = self.polygons
        R = data.xmat[p.body].reshape(-1, 3, 3)
        pts = data.xpos[p.body] + np.einsum("nij,nj->ni", R, p.centroid)
        nrm = np.einsum("nij,nj->ni", R, p.normal)
        if self._hint.size:
            hs = np.zeros(self._hint.size // 4 * HS)
            hinge_frames(data.xpos.reshape(-1), data.xmat.reshape(-1), data.qpos, data.qvel,
                         self._hint, self._hflt, hs)
            on = self._phinge >= 0
            h = self._phinge[on]
            Rw = hs.reshape(-1, HS)[h, 7:16].reshape(-1, 3, 3)
            ow = hs.reshape(-1, HS)[h, 4:7]
            o = self._hflt.reshape(-1, HF)[h, 3:6]
            pts[on] = ow + np.einsum("nij,nj->ni", Rw, p.centroid[on] - o)
            nrm[on] = np.einsum("nij,nj->ni", Rw, p.normal[on])
        return pts, nrm

    def evaluate(self, data: mujoco.MjData) -> SurfaceReport:
        """Every force term per polygon for the current state (positions and velocities
        must be current: call ``mj_forward`` first). Does not touch ``qfrc_passive``."""
        n = len(self.polygons)
        rec = np.zeros(16 * n)
        w = np.zeros(6 * self.model.nbody)
        arrays = self.arrays(self.model, data, record=rec)
        if self.flow.has_python:
            pts = self.world_centroids(data)
            ext = sum(np.asarray(f.fn(pts, data.time), dtype=float) for f in self.flow.python_fields)
            arrays[17] = np.ascontiguousarray(ext, dtype=float).reshape(-1)
            arrays[15] = self._param_array.copy()
            arrays[15][4] = 1.0
        if self._hint.size:
            # the hinges' torques and velocity memory: neither applied nor kept
            arrays[QFRC_ARG] = np.zeros_like(data.qfrc_passive)
            arrays[-1] = data.userdata.copy()
        surface_kernel(w, *arrays)
        r = rec.reshape(n, 16)
        wb = w.reshape(-1, 6)
        return SurfaceReport(
            drag=r[:, 0:3].copy(), lift=r[:, 3:6].copy(), friction=r[:, 6:9].copy(),
            aoa=r[:, 9].copy(), submerged=r[:, 10].copy(), points=r[:, 13:16].copy(),
            body_force=wb[:, 3:6].copy(), body_torque=wb[:, 0:3].copy(),
        )
