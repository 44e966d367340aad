"""Modal feathers in the simulation: the modes integrated by the force engine (default), or
as extra MuJoCo DOF (the fully coupled reference).

**Engine-integrated modes** (``ModalParams(integration="engine")``, :func:`modal_engine`), as
the paper integrates them (sec. 6): the MuJoCo model is the rigid dove's (the primaries' twist
hinges outside the skeleton, :mod:`flapsim.fluid.hinges`), and each feather's modal
coordinates and rates live in MuJoCo's ``userdata``, so snapshots that carry ``userdata``
(:class:`flapsim.bird.flight.cycle.Snapshot`), ``mujoco.rollout`` and repeated ``mj_forward`` calls
carry or leave them. Every step the kernel, for every feather:

1. builds the deformed feather by modal warping in the feather's frame (its bone's, or for a
   primary the bone's turned by the twist hinge angle) and the vertex Jacobians;
2. computes drag and lift on every deformed triangle (the shared plate formula), with the
   point velocity of the bone, the twist rate and the deformation rate; applies them to the
   bone (eq. 9), their torque about the twist axis to the hinge, and, spread equally to the
   triangle's vertices, to the modes (virtual work);
3. adds the D'Alembert load of the feather frame's rigid motion (James & Pai 2002):
   ``-Gamma n.(a_o + alpha x c + w x (w x c) - g)`` with ``c = S / Gamma`` the mode's
   centre, plus the deflection's own centrifugal load; the frame's accelerations are finite
   differences of its velocities over the last step (kept in ``userdata``, as the twist
   hinges do);
4. steps each mode's oscillator ``mu q'' + c q' + k q = Q`` exactly over the step (the matrix
   exponential, :func:`mode_transitions`): stable at any frequency, no energy drift without
   damping.

The feather's reaction on its bone is its aerodynamic force (eq. 9): its rigid mass rides the
bone, the vibrating part does not push back, as in the paper. The cost over rigid feathers is
the kernel's alone: no MuJoCo DOF, no bigger factorization.

**Modes on joints** (``integration="joints"``, :func:`modal_kernel`): each mode of each
feather (:mod:`flapsim.bird.body.feather_modes`) is one slide joint of a point-mass body on its
bone: its ``qpos``/``qvel`` are the modal coordinate and rate, the joint's ``stiffness`` the
modal stiffness and its ``damping`` the structural damping (implicit in ``implicitfast``).
Modes the timestep cannot resolve (``omega dt > ModalParams.implicit_above``) also get
``k dt`` of damping: with the explicit spring that is backward Euler for them. MuJoCo then
carries the D'Alembert load, gravity and the deforming feather's inertial reaction back onto
the bone (fully coupled); the kernel puts drag and lift on the deformed triangles and spreads
them to the bone and the modes. The twist of the primaries stays on their MuJoCo hinges in the
skeleton (spring, damper, one-sided range). It costs ~1.8x a rigid step (the modes' bodies
and DOF); it is kept as the reference the engine is checked against
(``tests/bird/body/test_feather_dynamics.py``: the tip deflection in flight).
"""

from __future__ import annotations

import dataclasses
import functools
import xml.etree.ElementTree as ET
from collections.abc import Sequence
from dataclasses import dataclass

import mujoco
import numpy as np
import scipy.linalg
from numba import njit

from flapsim.bird.body.feather_modes import FeatherModes, ModalParams, feather_modes
from flapsim.bird.body.inertia import _Inertia
from flapsim.bird.body.params import all_feathers
from flapsim.core.callbacks import CompiledProvider, Registration, register, register_kernel, time_view
from flapsim.core.errors import InputError, ModelError
from flapsim.fluid.coefficients import CoefficientTable
from flapsim.fluid.flow import FlowField, flow_at
from flapsim.fluid.hinges import (
    HF,
    HI,
    HS,
    PolygonHinges,
    advance_clock,
    bone_accelerations,
    hinge_arrays,
    hinge_frames,
    hinge_torque,
    integrator_damping,
    memory_acceleration,
    shift_memory,
    userdata_size,
)
from flapsim.fluid.surfaces import plate_force, pseudo_angle_tables

FI = 11  # ints per feather (see ModalFeathers.__init__)
REC = 16  # floats recorded per triangle (force 3, point 3, normal 3, area 1, spare)


def _lead_fraction(p, kind: str) -> float:
    return p.primary_lead_fraction if kind == "primary" else 0.5


def _segments(p, kind: str) -> int:
    return {"primary": p.primary_segments, "secondary": p.secondary_segments,
            "tertial": p.tertial_segments, "rectrix": p.rectrix_segments}[kind]


def mass_scaled(fm: FeatherModes) -> FeatherModes:
    """The same modes with each coordinate scaled so that its generalized mass equals its
    ``Gamma`` (``s = Gamma / mu``, sign making ``Gamma > 0``): then one point mass
    ``m = Gamma`` at ``c = S / Gamma`` on a slide joint along the normal carries the mode's
    whole inertial coupling with its bone (see :func:`modal_xml`)."""
    s = fm.gamma / fm.mu
    s = np.where(np.abs(s) < 1e-9, 1e-9, s)
    return dataclasses.replace(
        fm, slope=fm.slope * s, twist=fm.twist * s, shape=fm.shape * s, mu=fm.mu * s**2,
        gamma=fm.gamma * s, first_moment=fm.first_moment * s[:, None], unit=fm.unit * s)


@functools.lru_cache(maxsize=8)
def dove_feather_modes(p, mp: ModalParams) -> tuple[FeatherModes, ...]:
    """Mass-scaled modes (:func:`mass_scaled`) of every dove feather (left wing, left tail
    half, then the right side)."""

    return tuple(mass_scaled(feather_modes(fe, _lead_fraction(p, fe.kind), _segments(p, fe.kind),
                                           mp)) for fe in all_feathers(p))


def mode_joint_gains(fm: FeatherModes, mp: ModalParams, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """(stiffness, damping) of each mode's slide joint: ``mu omega^2`` and the structural
    ``2 zeta omega mu``, plus ``k dt`` for modes the step cannot resolve (backward Euler)."""
    k = fm.stiffness
    c = 2 * mp.damping_ratio * fm.omega * fm.mu
    return k, c + np.where(fm.omega * dt > mp.implicit_above, k * dt, 0.0)


def _point_inertia(m: float) -> float:
    """Rotational inertia of a mode's point mass: MuJoCo needs one; it is negligible (the
    bone loses it too)."""
    return 1e-14


def modal_xml(xml: str, p, mp: ModalParams) -> str:
    """Add the modes to the rigid dove's MJCF: per feather and mode a child body of the
    feather's bone holding a point mass ``Gamma`` at ``S / Gamma`` on a slide joint along the
    feather's normal (stiffness and damping from :func:`mode_joint_gains`); the bone's own
    inertial loses the same point masses, so the undeformed bird's mass distribution is
    unchanged. For a flat feather whose modes deflect it out of its plane, this reproduces
    MuJoCo-exactly every inertial term linear in the modes: the D'Alembert load of the bone's
    linear and angular acceleration, centrifugal load, gravity, and the reaction of the
    feather's deformation back onto the bone. The primaries' twist hinges get
    :func:`twist_armature`; the model's constraint solver is PGS (see below)."""

    root = ET.fromstring(xml)
    # the same constraint problem (joint limits) over 4x the DOF: Newton's Hessian factorization
    # cost ~60 us per step there, PGS ~3 us, with the same flight to 4 digits (10 wingbeats)
    root.find("option").set("solver", "PGS")
    bodies = {b.get("name"): b for b in root.iter("body")}
    by_bone: dict[str, list[FeatherModes]] = {}
    for fm in dove_feather_modes(p, mp):
        by_bone.setdefault(fm.body, []).append(fm)
    for bone, fms in by_bone.items():
        el = bodies[bone]
        inert = el.find("inertial")
        mass = float(inert.get("mass"))
        com = np.array(inert.get("pos").split(), float)
        fi = np.array(inert.get("fullinertia").split(), float)
        I = np.array([[fi[0], fi[3], fi[4]], [fi[3], fi[1], fi[5]], [fi[4], fi[5], fi[2]]])
        total = _Inertia()
        total.add(mass, com, I)
        for fm in fms:
            for m, pos, i0 in _add_mode_bodies(el, fm, mp, p.timestep):
                total.add(-m, pos, -i0 * np.eye(3))
            twist = el.find(f"joint[@name='{fm.name}_twist']")
            if twist is not None:
                twist.set("armature", f"{twist_armature(fm, np.array(twist.get('axis').split(), float)):.9g}")
        m, com, I = total.total()
        ev = np.linalg.eigvalsh(I)
        if m <= 0 or ev.min() <= 0 or 2 * ev.max() > ev.sum() * (1 + 1e-9):
            raise ModelError(f"body {bone}: the feather modes' point masses leave no physical "
                             f"inertia (mass {m:.3g}, principal moments {ev})")
        inert.set("mass", f"{m:.12g}")
        inert.set("pos", _v(com))
        inert.set("fullinertia", " ".join(f"{x:.12g}" for x in
                                          (I[0, 0], I[1, 1], I[2, 2], I[0, 1], I[0, 2], I[1, 2])))
    return ET.tostring(root, encoding="unicode")


def twist_armature(fm: FeatherModes, axis: np.ndarray) -> float:
    """The primary's inertia about its twist hinge that the free modes take off the hinge:
    ``sum_k (a . (S_k x n))^2 / m_k`` (the hinge at the body origin, ``a`` its axis).

    With the modes free, the hinge alone moves only the root: its effective inertia falls to
    a few per cent of the feather's. MuJoCo's soft joint limit is as hard as the inertia it
    sees, so the one-sided twist stop would yield ~15 deg when the vanes snap shut. This
    armature gives the stop the rigid feather's inertia back (a numerical device, no mass: it
    slows only the hinge's fast transients; the twist's overdamped relaxation time c/k does
    not depend on it, :func:`tests.bird.test_modal_feathers`)."""
    a = np.asarray(axis, float) / np.linalg.norm(axis)
    lever = np.cross(fm.first_moment, fm.normal) @ a
    return float(np.sum(lever**2 / fm.gamma))


def clamped_feather_xml(fm: FeatherModes, mp: ModalParams, timestep: float,
                        gravity: bool = False, free_bone: bool = False) -> str:
    """One feather clamped at its root to a bone (named after ``fm.body``; fixed, or on a free
    joint), its modes as in the dove: the unit model of the tests. ``mp.integration``:
    ``"engine"``, room in ``userdata`` for the engine's modes (:func:`modal_engine`);
    ``"joints"``, the modes' bodies and slide joints (:func:`modal_xml`)."""
    joint = '<freejoint name="bone"/>' if free_bone else ""
    size = (f'<size nuserdata="{engine_userdata_size(1, fm.omega.size)}"/>'
            if mp.integration == "engine" else "")
    xml = (f'<mujoco>{size}<option timestep="{timestep:.10g}" integrator="implicitfast" '
           f'gravity="0 0 {-9.81 if gravity else 0.0}"/>'
           f'<worldbody><body name="{fm.body}" pos="0 0 1">{joint}'
           '<inertial pos="0 0 0" mass="1" diaginertia="1 1 1"/></body></worldbody></mujoco>')
    root = ET.fromstring(xml)
    if mp.integration == "joints":
        _add_mode_bodies(root.find("worldbody/body"), fm, mp, timestep)
    return ET.tostring(root, encoding="unicode")


def _add_mode_bodies(bone: ET.Element, fm: FeatherModes, mp: ModalParams, timestep: float
                     ) -> list[tuple[float, np.ndarray, float]]:
    """Append one point-mass body per mode of ``fm`` to ``bone``; returns (mass, position,
    rotational inertia) of each, for the bone to give up."""
    k, c = mode_joint_gains(fm, mp, timestep)
    out = []
    for j in range(len(k)):
        m = float(fm.gamma[j])
        pos = fm.first_moment[j] / m
        i0 = _point_inertia(m)
        b = ET.SubElement(bone, "body", name=f"{fm.name}_mode{j + 1}", pos=_v(pos))
        ET.SubElement(b, "inertial", pos="0 0 0", mass=f"{m:.12g}",
                      diaginertia=f"{i0:.6g} {i0:.6g} {i0:.6g}")
        ET.SubElement(b, "joint", name=f"{fm.name}_mode{j + 1}", type="slide", axis=_v(fm.normal),
                      stiffness=f"{k[j]:.12g}", damping=f"{c[j]:.12g}", armature="0")
        out.append((m, pos, i0))
    return out


def _v(a) -> str:
    return " ".join(f"{x:.12g}" for x in np.asarray(a, float).ravel())


FASTMATH = {"contract", "arcp", "afn", "nsz"}

# Taylor coefficients of sin and cos: for |a| < 1/2 the first omitted terms are below 2.3e-17
# (sin, through a^13) and 7.3e-19 (cos, through a^14), under half an ulp of the result
_S3, _S5, _S7, _S9, _S11, _S13 = (-1 / 6, 1 / 120, -1 / 5040, 1 / 362880, -1 / 39916800,
                                  1 / 6227020800)
_C2, _C4, _C6, _C8, _C10, _C12, _C14 = (-1 / 2, 1 / 24, -1 / 720, 1 / 40320, -1 / 3628800,
                                        1 / 479001600, -1 / 87178291200)


@njit(cache=True, inline="always", fastmath=FASTMATH)
def _cos_sin(a):
    """(cos a, sin a): a polynomial for |a| < 1/2 (the bends and twists of flight, below
    0.1 rad in the base flight; within 2 ulp of libm's, ``tests/bird/body/test_feather_kernel.py``),
    libm beyond. A third of the warp's cost with libm's sin and cos."""
    if -0.5 < a < 0.5:
        a2 = a * a
        s = a * (1.0 + a2 * (_S3 + a2 * (_S5 + a2 * (_S7 + a2 * (_S9 + a2 * (_S11 + a2 * _S13))))))
        c = 1.0 + a2 * (_C2 + a2 * (_C4 + a2 * (_C6 + a2 * (_C8 + a2 * (_C10 + a2 * (_C12
                                                                                  + a2 * _C14))))))
        return c, s
    return np.cos(a), np.sin(a)


@njit(cache=True, inline="always", fastmath=FASTMATH)
def _stations(K, ff, fo, grid, go, nst, sub, q, qo, buf, bo):
    """Modal warping of one feather's shaft, station by station.

    ``buf[bo + (6 + 6 K) j:]`` for station j: the centreline ``C`` (3, from the root), the
    bent and twisted chord ``c'`` (3), then per mode k ``dC/dq_k`` (3) and ``dc'/dq_k`` (3);
    ``buf[bo + (6 + 6 K) nst:][:3 K]`` is work space. ``ff[fo:]`` holds root, shaft, chord,
    normal, length; ``q[qo:qo + K]`` the coordinates. The shaft section at grid point g is
    rotated by the bend angle ``beta_g = sum_k q_k slope_gk`` about the chord, the chord by the
    twist ``tau = sum_k q_k twist_gk`` about the bent shaft; the centreline integrates the
    rotated shaft direction (Simpson's rule over each pair of grid intervals: ``sub`` is even,
    the stations fall on even points), so a bent feather keeps its length.
    """
    sx, sy, sz = ff[fo + 3], ff[fo + 4], ff[fo + 5]
    cx, cy, cz = ff[fo + 6], ff[fo + 7], ff[fo + 8]
    nx, ny, nz = ff[fo + 9], ff[fo + 10], ff[fo + 11]
    L = ff[fo + 12]
    ng = (nst - 1) * sub + 1
    h = L / (ng - 1)
    SB = 6 + 6 * K
    dw = bo + SB * nst  # running dC/dq_k
    for k in range(3 * K):
        buf[dw + k] = 0.0
    Cx = 0.0
    Cy = 0.0
    Cz = 0.0
    c2 = 1.0  # cos, sin of the bend angle two and one grid points back
    s2 = 0.0
    c1 = 1.0
    s1 = 0.0
    w6 = 2.0 * h / 6.0
    for g in range(ng):
        gk = go + 2 * K * g
        beta = 0.0
        for k in range(K):
            beta += q[qo + k] * grid[gk + 2 * k]
        cb, sb = _cos_sin(beta)
        if g > 0 and g % 2 == 0:
            Cx += w6 * (c2 * sx + s2 * nx + 4.0 * (c1 * sx + s1 * nx) + cb * sx + sb * nx)
            Cy += w6 * (c2 * sy + s2 * ny + 4.0 * (c1 * sy + s1 * ny) + cb * sy + sb * ny)
            Cz += w6 * (c2 * sz + s2 * nz + 4.0 * (c1 * sz + s1 * nz) + cb * sz + sb * nz)
            for k in range(K):
                a0 = grid[gk - 4 * K + 2 * k]
                a1 = 4.0 * grid[gk - 2 * K + 2 * k]
                a2 = grid[gk + 2 * k]
                buf[dw + 3 * k] += w6 * (a0 * (-s2 * sx + c2 * nx) + a1 * (-s1 * sx + c1 * nx)
                                         + a2 * (-sb * sx + cb * nx))
                buf[dw + 3 * k + 1] += w6 * (a0 * (-s2 * sy + c2 * ny) + a1 * (-s1 * sy + c1 * ny)
                                             + a2 * (-sb * sy + cb * ny))
                buf[dw + 3 * k + 2] += w6 * (a0 * (-s2 * sz + c2 * nz) + a1 * (-s1 * sz + c1 * nz)
                                             + a2 * (-sb * sz + cb * nz))
        c2, s2 = c1, s1
        c1, s1 = cb, sb
        if g % sub != 0:
            continue
        o = bo + SB * (g // sub)
        tau = 0.0
        for k in range(K):
            tau += q[qo + k] * grid[gk + 2 * k + 1]
        ct, st = _cos_sin(tau)
        # bent normal n' = -sin(b) s + cos(b) n; twisted chord c' = cos(t) c + sin(t) n'
        npx, npy, npz = -sb * sx + cb * nx, -sb * sy + cb * ny, -sb * sz + cb * nz
        buf[o] = Cx
        buf[o + 1] = Cy
        buf[o + 2] = Cz
        buf[o + 3] = ct * cx + st * npx
        buf[o + 4] = ct * cy + st * npy
        buf[o + 5] = ct * cz + st * npz
        # d c'/d tau and d c'/d beta
        dtx, dty, dtz = -st * cx + ct * npx, -st * cy + ct * npy, -st * cz + ct * npz
        dbx = st * (-cb * sx - sb * nx)
        dby = st * (-cb * sy - sb * ny)
        dbz = st * (-cb * sz - sb * nz)
        for k in range(K):
            sl = grid[gk + 2 * k]
            tw = grid[gk + 2 * k + 1]
            ok = o + 6 + 6 * k
            buf[ok] = buf[dw + 3 * k]
            buf[ok + 1] = buf[dw + 3 * k + 1]
            buf[ok + 2] = buf[dw + 3 * k + 2]
            buf[ok + 3] = tw * dtx + sl * dbx
            buf[ok + 4] = tw * dty + sl * dby
            buf[ok + 5] = tw * dtz + sl * dbz


@njit(cache=True, fastmath=FASTMATH)
def warp(K, ff, fo, grid, go, nst, sub, q, vst, vx, voff, nv, out, wo):
    """Modal warping of one feather: body-frame vertex positions and their Jacobians.

    ``out[(v) * 3 * (1 + K) + 3 * j + c]``: j = 0 the position, j = 1 + k the derivative by
    mode k (see :func:`_stations`); ``out[wo:]`` is work space (``(6 + 6 K) nst + 3 K``).
    ``q`` (K,) coordinates. Returns 1 (nothing written) when ``out`` is too small.
    """
    if out.size < max(wo + (6 + 6 * K) * nst + 3 * K, nv * 3 * (1 + K)) or wo < nv * 3 * (1 + K):
        return 1
    _stations(K, ff, fo, grid, go, nst, sub, q, 0, out, wo)
    SB = 6 + 6 * K
    stride = 3 * (1 + K)
    for i in range(nv):
        s = wo + SB * vst[voff + i]
        x = vx[voff + i]
        o = i * stride
        out[o] = ff[fo] + out[s] + x * out[s + 3]
        out[o + 1] = ff[fo + 1] + out[s + 1] + x * out[s + 4]
        out[o + 2] = ff[fo + 2] + out[s + 2] + x * out[s + 5]
        for k in range(K):
            sk = s + 6 + 6 * k
            out[o + 3 + 3 * k] = out[sk] + x * out[sk + 3]
            out[o + 4 + 3 * k] = out[sk + 1] + x * out[sk + 4]
            out[o + 5 + 3 * k] = out[sk + 2] + x * out[sk + 5]
    return 0


@njit(cache=True, inline="always")
def _add_wrench(w, b, tx, ty, tz, fx, fy, fz):
    """Add a wrench about the world origin (torque, force) to body ``b`` in flat ``w``."""
    o = 6 * b
    w[o] += tx
    w[o + 1] += ty
    w[o + 2] += tz
    w[o + 3] += fx
    w[o + 4] += fy
    w[o + 5] += fz


@njit(cache=True, inline="always")
def _feather_frame(hh, b, xpos, xmat, hflt, hs):
    """A feather's frame (its modes and mesh are in it): the rotation ``R`` (9, row-major),
    the world position of its reference point (3) and that point in the body frame (3), and
    the frame's angular velocity beyond its bone's (3). On twist hinge ``hh >= 0``
    (:func:`~flapsim.fluid.hinges.hinge_frames`' ``hs``): the bone's frame turned by the hinge
    angle, the hinge point, the twist rate about the axis; off a hinge (-1) the bone's frame,
    its origin, zero."""
    if hh >= 0:
        so = HS * hh
        o = HF * hh
        return (hs[so + 7], hs[so + 8], hs[so + 9], hs[so + 10], hs[so + 11], hs[so + 12],
                hs[so + 13], hs[so + 14], hs[so + 15], hs[so + 4], hs[so + 5], hs[so + 6],
                hflt[o + 3], hflt[o + 4], hflt[o + 5], hs[so] * hs[so + 1], hs[so] * hs[so + 2],
                hs[so] * hs[so + 3])
    m = 9 * b
    return (xmat[m], xmat[m + 1], xmat[m + 2], xmat[m + 3], xmat[m + 4], xmat[m + 5], xmat[m + 6],
            xmat[m + 7], xmat[m + 8], xpos[3 * b], xpos[3 * b + 1], xpos[3 * b + 2], 0.0, 0.0, 0.0,
            0.0, 0.0, 0.0)


@njit(cache=True, fastmath=FASTMATH)
def modal_kernel(w, xpos, xmat, cvel, scom, rootid, qpos, qvel, qfrc, fint, ff, grid, vst, vx,
                 tri, scratch, ext, cl_tab, cd_tab, flow, fluid, tnow, rec):
    """Aerodynamic (and external) forces on every deformed feather, to its bone and its
    modes (see the module docstring). ``fluid`` = (density, friction, K, vertex work offset,
    mode work offset); ``scratch`` holds the stations (:func:`_stations`) from 0, per vertex
    (world position 3, deformation velocity 3, Jacobian 3 K: all in the world frame)
    from ``fluid[3]``, the modes' (Q, q, qdot) from ``fluid[4]``."""
    K = int(fluid[2])
    none = np.zeros(0)  # no twist hinges: the modes ride their bones (or in-tree hinges)
    if K == 1:  # the dove's default: compiled with the loops over the modes unrolled
        return _modal_forces(1, w, xpos, xmat, cvel, scom, rootid, qpos, qvel, qfrc, fint, ff,
                             grid, vst, vx, tri, scratch, ext, cl_tab, cd_tab, flow, fluid, tnow,
                             rec, none, none)
    return _modal_forces(K, w, xpos, xmat, cvel, scom, rootid, qpos, qvel, qfrc, fint, ff, grid,
                         vst, vx, tri, scratch, ext, cl_tab, cd_tab, flow, fluid, tnow, rec, none,
                         none)


@njit(cache=True, inline="always", fastmath=FASTMATH)
def _modal_forces(K, w, xpos, xmat, cvel, scom, rootid, qpos, qvel, qfrc, fint, ff, grid, vst,
                  vx, tri, scratch, ext, cl_tab, cd_tab, flow, fluid, tnow, rec, hflt, hs):
    """:func:`modal_kernel` for K modes per feather. A feather whose hinge index
    ``fint[FI f + 10]`` is >= 0 rides that twist hinge (:mod:`flapsim.fluid.hinges`: ``hflt``
    and the frames ``hs`` of :func:`~flapsim.fluid.hinges.hinge_frames`): its frame is the
    twisted plate's, its points move with the twist rate too, and the forces' torque about the
    hinge axis is added to ``hs`` for :func:`~flapsim.fluid.hinges.hinge_torque`."""
    rho = fluid[0]
    eta = fluid[1]
    vo = int(fluid[3])
    qo = int(fluid[4])
    t = tnow[0]
    nfe = fint.size // FI
    FF = 13 + 4 * K
    VS = 6 + 3 * K
    third = 1.0 / 3.0
    record = rec.size >= REC * (tri.size // 3)
    for f in range(nfe):
        b = fint[FI * f]
        qa = fint[FI * f + 1]
        da = fint[FI * f + 2]
        nst = fint[FI * f + 3]
        sub = fint[FI * f + 4]
        voff = fint[FI * f + 5]
        nv = fint[FI * f + 6]
        toff = fint[FI * f + 7]
        nt = fint[FI * f + 8]
        go = fint[FI * f + 9]
        fo = FF * f
        for k in range(K):
            scratch[qo + k] = 0.0
            scratch[qo + K + k] = qpos[qa + k]
            scratch[qo + 2 * K + k] = qvel[da + k]
        _stations(K, ff, fo, grid, go, nst, sub, scratch, qo + K, scratch, 0)
        hh = fint[FI * f + 10]
        (R00, R01, R02, R10, R11, R12, R20, R21, R22, hox, hoy, hoz, lo0, lo1, lo2, ewx, ewy,
         ewz) = _feather_frame(hh, b, xpos, xmat, hflt, hs)
        # the frame's origin: x_world = o + R x_body
        ox = hox - (R00 * lo0 + R01 * lo1 + R02 * lo2)
        oy = hoy - (R10 * lo0 + R11 * lo1 + R12 * lo2)
        oz = hoz - (R20 * lo0 + R21 * lo1 + R22 * lo2)
        r = rootid[b]
        c0, c1, c2 = scom[3 * r], scom[3 * r + 1], scom[3 * r + 2]
        wx, wy, wz = cvel[6 * b], cvel[6 * b + 1], cvel[6 * b + 2]
        lx, ly, lz = cvel[6 * b + 3], cvel[6 * b + 4], cvel[6 * b + 5]
        # the bone's wrench about the world origin, summed over the feather
        Tx = 0.0
        Ty = 0.0
        Tz = 0.0
        Fsx = 0.0
        Fsy = 0.0
        Fsz = 0.0
        rx, ry, rz = ff[fo], ff[fo + 1], ff[fo + 2]
        SB = 6 + 6 * K
        # every vertex once: its Jacobian, world position, deformation velocity; external loads
        for i in range(nv):
            iv = voff + i
            s = SB * vst[iv]
            x = vx[iv]
            bx = rx + scratch[s] + x * scratch[s + 3]
            by = ry + scratch[s + 1] + x * scratch[s + 4]
            bz = rz + scratch[s + 2] + x * scratch[s + 5]
            o = vo + VS * i
            # external vertex loads (body frame; tests and calibration)
            gx, gy, gz = ext[3 * iv], ext[3 * iv + 1], ext[3 * iv + 2]
            u0 = 0.0
            u1 = 0.0
            u2 = 0.0
            for k in range(K):
                sk = s + 6 + 6 * k
                jx = scratch[sk] + x * scratch[sk + 3]
                jy = scratch[sk + 1] + x * scratch[sk + 4]
                jz = scratch[sk + 2] + x * scratch[sk + 5]
                if gx != 0.0 or gy != 0.0 or gz != 0.0:
                    scratch[qo + k] += gx * jx + gy * jy + gz * jz
                # in the world frame from here on
                jwx = R00 * jx + R01 * jy + R02 * jz
                jwy = R10 * jx + R11 * jy + R12 * jz
                jwz = R20 * jx + R21 * jy + R22 * jz
                scratch[o + 6 + 3 * k] = jwx
                scratch[o + 7 + 3 * k] = jwy
                scratch[o + 8 + 3 * k] = jwz
                qd = scratch[qo + 2 * K + k]
                u0 += jwx * qd
                u1 += jwy * qd
                u2 += jwz * qd
            pwx = ox + R00 * bx + R01 * by + R02 * bz
            pwy = oy + R10 * bx + R11 * by + R12 * bz
            pwz = oz + R20 * bx + R21 * by + R22 * bz
            scratch[o] = pwx
            scratch[o + 1] = pwy
            scratch[o + 2] = pwz
            scratch[o + 3] = u0
            scratch[o + 4] = u1
            scratch[o + 5] = u2
            if gx != 0.0 or gy != 0.0 or gz != 0.0:
                Gx = R00 * gx + R01 * gy + R02 * gz
                Gy = R10 * gx + R11 * gy + R12 * gz
                Gz = R20 * gx + R21 * gy + R22 * gz
                Tx += pwy * Gz - pwz * Gy
                Ty += pwz * Gx - pwx * Gz
                Tz += pwx * Gy - pwy * Gx
                Fsx += Gx
                Fsy += Gy
                Fsz += Gz
        # forward: the bone's x axis, projected into each triangle's plane below
        ex, ey, ez = R00, R10, R20
        for it in range(toff, toff + nt):
            oa = vo + VS * (tri[3 * it] - voff)
            ob = vo + VS * (tri[3 * it + 1] - voff)
            oc = vo + VS * (tri[3 * it + 2] - voff)
            ax_, ay_, az_ = scratch[oa], scratch[oa + 1], scratch[oa + 2]
            bx_, by_, bz_ = scratch[ob], scratch[ob + 1], scratch[ob + 2]
            cx_, cy_, cz_ = scratch[oc], scratch[oc + 1], scratch[oc + 2]
            px = (ax_ + bx_ + cx_) * third
            py = (ay_ + by_ + cy_) * third
            pz = (az_ + bz_ + cz_) * third
            uw0 = (scratch[oa + 3] + scratch[ob + 3] + scratch[oc + 3]) * third
            uw1 = (scratch[oa + 4] + scratch[ob + 4] + scratch[oc + 4]) * third
            uw2 = (scratch[oa + 5] + scratch[ob + 5] + scratch[oc + 5]) * third
            e1x, e1y, e1z = bx_ - ax_, by_ - ay_, bz_ - az_
            e2x, e2y, e2z = cx_ - ax_, cy_ - ay_, cz_ - az_
            anx = e1y * e2z - e1z * e2y
            any_ = e1z * e2x - e1x * e2z
            anz = e1x * e2y - e1y * e2x
            an2 = anx * anx + any_ * any_ + anz * anz
            an = np.sqrt(an2)
            area = 0.5 * an
            ia = 1.0 / an
            nx, ny, nz = anx * ia, any_ * ia, anz * ia
            # e minus its normal part, unit: |e - (e.n) n|^2 = 1 - (e.n)^2 with e.n = e.a / |a|
            # (a the area vector): computed beside |a|, not after it (a shorter dependency chain)
            ea = ex * anx + ey * any_ + ez * anz
            ifl = np.sqrt(an2 / (an2 - ea * ea))
            en = ea * ia
            fx, fy, fz = (ex - en * nx) * ifl, (ey - en * ny) * ifl, (ez - en * nz) * ifl
            # relative flow at the deformed centroid
            dx, dy, dz = px - c0, py - c1, pz - c2
            ux, uy, uz = flow_at(flow, px, py, pz, t)
            vx_ = ux - (lx + wy * dz - wz * dy + uw0)
            vy_ = uy - (ly + wz * dx - wx * dz + uw1)
            vz_ = uz - (lz + wx * dy - wy * dx + uw2)
            if hh >= 0:  # the plate's turning about its hinge
                hx, hy, hz = px - hox, py - hoy, pz - hoz
                vx_ -= ewy * hz - ewz * hy
                vy_ -= ewz * hx - ewx * hz
                vz_ -= ewx * hy - ewy * hx
            vn = vx_ * nx + vy_ * ny + vz_ * nz
            sx = ny * fz - nz * fy
            sy = nz * fx - nx * fz
            sz = nx * fy - ny * fx
            vs = vx_ * sx + vy_ * sy + vz_ * sz
            x = -(vx_ * fx + vy_ * fy + vz_ * fz)
            (drx, dry, drz, lfx, lfy, lfz, frx, fry, frz) = plate_force(
                rho, eta, area, nx, ny, nz, vx_, vy_, vz_, vn, vs * sx, vs * sy, vs * sz, x, True,
                0, cl_tab, cd_tab)
            Fx = drx + lfx + frx
            Fy = dry + lfy + fry
            Fz = drz + lfz + frz
            Tx += py * Fz - pz * Fy
            Ty += pz * Fx - px * Fz
            Tz += px * Fy - py * Fx
            Fsx += Fx
            Fsy += Fy
            Fsz += Fz
            if hh >= 0:  # the force's torque about the hinge axis
                hx, hy, hz = px - hox, py - hoy, pz - hoz
                so = HS * hh
                hs[so + 16] += (hs[so + 1] * (hy * Fz - hz * Fy) + hs[so + 2] * (hz * Fx - hx * Fz)
                                + hs[so + 3] * (hx * Fy - hy * Fx))
            # to the modes: F/3 at each vertex, through each vertex's Jacobian
            for k in range(K):
                k3 = 6 + 3 * k
                scratch[qo + k] += third * (
                    Fx * (scratch[oa + k3] + scratch[ob + k3] + scratch[oc + k3])
                    + Fy * (scratch[oa + k3 + 1] + scratch[ob + k3 + 1] + scratch[oc + k3 + 1])
                    + Fz * (scratch[oa + k3 + 2] + scratch[ob + k3 + 2] + scratch[oc + k3 + 2]))
            if record:
                o = REC * it
                rec[o] = Fx
                rec[o + 1] = Fy
                rec[o + 2] = Fz
                rec[o + 3] = px
                rec[o + 4] = py
                rec[o + 5] = pz
                rec[o + 6] = nx
                rec[o + 7] = ny
                rec[o + 8] = nz
                rec[o + 9] = area
                rec[o + 10] = np.arctan2(abs(vn), x)
        _add_wrench(w, b, Tx, Ty, Tz, Fsx, Fsy, Fsz)
        for k in range(K):
            Qk = scratch[qo + k]
            if not np.isfinite(Qk):
                return 1
            qfrc[da + k] += Qk
        if record:
            base = REC * (tri.size // 3)
            if rec.size >= base + 3 * (voff + nv):
                for i in range(nv):
                    o = vo + VS * i
                    rec[base + 3 * (voff + i)] = scratch[o]
                    rec[base + 3 * (voff + i) + 1] = scratch[o + 1]
                    rec[base + 3 * (voff + i) + 2] = scratch[o + 2]
    return 0


SIGNATURE = "ffffi" + "fff" + "iff" + "if" + "i" + "ff" + "fffff" + "f"
register_kernel("modal_feathers", modal_kernel, SIGNATURE)

# userdata of the engine-integrated modes, after the twist hinges' own (ENGINE_* offsets from
# the block's start): the times of the last two calls, then per mode its coordinate and rate
# at the current time (A) and at the next step (B), then per feather the velocity of its
# frame's origin and its frame's angular velocity at the previous and the current time
MODE_SLOTS = 4
FRAME_SLOTS = 12
TRANS = 6  # per mode: the step's transition (q' = a q + b v + e Q, v' = c q + d v + f Q)


def engine_userdata_size(n_feathers: int, K: int) -> int:
    """``userdata`` entries the engine-integrated modes of ``n_feathers`` feathers use."""
    return 2 + MODE_SLOTS * K * n_feathers + FRAME_SLOTS * n_feathers


@njit(cache=True, fastmath=FASTMATH)
def modal_engine(w, xpos, xmat, cvel, scom, rootid, fint, ff, grid, vst, vx, tri, scratch, ext,
                 cl_tab, cd_tab, flow, fluid, tnow, rec, qbuf, vbuf, Qbuf, trans, hint, hflt, hs,
                 qpos, qvel, qacc, qfrc, qfrc_applied, M, damping, parent, dofadr, dofnum, cdof,
                 cdof_dot, cacc, opt, ud):
    """The modes integrated by the force engine itself (no MuJoCo DOF): every step, per
    feather, the aerodynamic forces on the deformed triangles (to the bone, eq. 9, to the twist
    hinge and to the modes: :func:`_modal_forces`), the D'Alembert load of the feather frame's
    rigid motion on each mode (James & Pai 2002; the flight paper, sec. 6), and one exact step
    of each mode's damped oscillator under that load (``trans``: the matrix exponential,
    stable at any frequency, energy-exact without damping). The feather's reaction on its bone
    is the aerodynamic force alone, as in the paper (eq. 9): the vibrating part of its mass
    does not push back (its rigid mass rides the bone).

    ``fluid`` = (density, friction, K, vertex work offset, mode work offset, userdata offset
    of this block); the state lives in ``ud`` (:data:`MODE_SLOTS`, :data:`FRAME_SLOTS`): a
    call at the time of the last call recomputes the next state from the same current one (so
    repeated ``mj_forward`` calls change nothing), a call one step later first makes the next
    state current, any other time (a reset, a jump) keeps the current state and has no frame
    velocities to difference: the bones' explicit accelerations (``qacc_warmstart``) stand in
    once. The hinges (``hint``...) get their torques as in the surface kernel.
    """
    t = tnow[0]
    dt = opt[0]
    gx, gy, gz = opt[1], opt[2], opt[3]
    K = int(fluid[2])
    mo = int(fluid[5])
    nfe = fint.size // FI
    nm = K * nfe
    sa = mo + 2
    fr = sa + MODE_SLOTS * nm
    stepped, diff = advance_clock(ud, mo, t, dt)
    if stepped:  # one step on: the next state is the current one
        for i in range(nm):
            ud[sa + 4 * i] = ud[sa + 4 * i + 2]
            ud[sa + 4 * i + 1] = ud[sa + 4 * i + 3]
        shift_memory(ud, fr, nfe)
    for i in range(nm):
        qbuf[i] = ud[sa + 4 * i]
        vbuf[i] = ud[sa + 4 * i + 1]
        Qbuf[i] = 0.0
    nh = hint.size // HI
    if nh > 0:
        hinge_frames(xpos, xmat, qpos, qvel, hint, hflt, hs)
    if K == 1:
        st = _modal_forces(1, w, xpos, xmat, cvel, scom, rootid, qbuf, vbuf, Qbuf, fint, ff, grid,
                           vst, vx, tri, scratch, ext, cl_tab, cd_tab, flow, fluid, tnow, rec, hflt,
                           hs)
    else:
        st = _modal_forces(K, w, xpos, xmat, cvel, scom, rootid, qbuf, vbuf, Qbuf, fint, ff, grid,
                           vst, vx, tri, scratch, ext, cl_tab, cd_tab, flow, fluid, tnow, rec, hflt,
                           hs)
    if st != 0:
        return st
    if not diff:
        bone_accelerations(parent, dofadr, dofnum, cdof, cdof_dot, qvel, qacc, cacc)
    FF = 13 + 4 * K
    for f in range(nfe):
        b = fint[FI * f]
        hh = fint[FI * f + 10]
        fo = FF * f
        wx, wy, wz = cvel[6 * b], cvel[6 * b + 1], cvel[6 * b + 2]
        # on a hinge the reference point is on its axis and the frame turns with the twist too
        (R00, R01, R02, R10, R11, R12, R20, R21, R22, ox, oy, oz, lo0, lo1, lo2, ewx, ewy,
         ewz) = _feather_frame(hh, b, xpos, xmat, hflt, hs)
        pwx, pwy, pwz = wx + ewx, wy + ewy, wz + ewz
        r = rootid[b]
        dx, dy, dz = ox - scom[3 * r], oy - scom[3 * r + 1], oz - scom[3 * r + 2]
        vox = cvel[6 * b + 3] + wy * dz - wz * dy
        voy = cvel[6 * b + 4] + wz * dx - wx * dz
        voz = cvel[6 * b + 5] + wx * dy - wy * dx
        aox, aoy, aoz, alx, aly, alz = memory_acceleration(diff, dt, gx, gy, gz, ud, fr + 12 * f,
                                                           vox, voy, voz, pwx, pwy, pwz, wx, wy,
                                                           wz, cacc, b, dx, dy, dz)
        n0, n1, n2 = ff[fo + 9], ff[fo + 10], ff[fo + 11]
        nwx = R00 * n0 + R01 * n1 + R02 * n2
        nwy = R10 * n0 + R11 * n1 + R12 * n2
        nwz = R20 * n0 + R21 * n1 + R22 * n2
        wn = pwx * nwx + pwy * nwy + pwz * nwz
        # the deflection's own centrifugal load per unit coordinate: n . (w x (w x n))
        cf = pwx * pwx + pwy * pwy + pwz * pwz - wn * wn
        for k in range(K):
            i = K * f + k
            g = ff[fo + 13 + k]
            c0 = ff[fo + 13 + K + 3 * k] / g - lo0
            c1 = ff[fo + 14 + K + 3 * k] / g - lo1
            c2 = ff[fo + 15 + K + 3 * k] / g - lo2
            rx = R00 * c0 + R01 * c1 + R02 * c2
            ry = R10 * c0 + R11 * c1 + R12 * c2
            rz = R20 * c0 + R21 * c1 + R22 * c2
            # the rigid acceleration at the mode's centre: a_o + alpha x r + w x (w x r)
            qx = pwy * rz - pwz * ry
            qy = pwz * rx - pwx * rz
            qz = pwx * ry - pwy * rx
            acx = aox + aly * rz - alz * ry + pwy * qz - pwz * qy
            acy = aoy + alz * rx - alx * rz + pwz * qx - pwx * qz
            acz = aoz + alx * ry - aly * rx + pwx * qy - pwy * qx
            q = qbuf[i]
            v = vbuf[i]
            Q = Qbuf[i] - g * (nwx * acx + nwy * acy + nwz * acz) + g * cf * q
            if not np.isfinite(Q):
                return 1
            o = TRANS * i
            ud[sa + 4 * i + 2] = trans[o] * q + trans[o + 1] * v + trans[o + 4] * Q
            ud[sa + 4 * i + 3] = trans[o + 2] * q + trans[o + 3] * v + trans[o + 5] * Q
    if nh > 0:
        hinge_torque(hint, hflt, hs, cvel, cacc, scom, rootid, qpos, qvel, qfrc, qfrc_applied, M,
                     damping, opt, t, ud, parent, dofadr, dofnum, cdof, cdof_dot, qacc)
    return 0


ENGINE_SIGNATURE = ("ffffi" + "iffifif" + "ffff" + "fff" + "ffff" + "iff" + "fffffff" + "iii"
                    + "fffff")
register_kernel("modal_engine", modal_engine, ENGINE_SIGNATURE)


def mode_transitions(fm: FeatherModes, mp: ModalParams, dt: float) -> np.ndarray:
    """(K, 6) each mode's exact step over ``dt`` under a load ``Q`` held over the step:
    ``(q', v') = (a q + b v + e Q, c q + d v + f Q)``, the exponential of
    ``mu q'' + c q' + k q = Q`` (stiffness, damping and ``mu`` of :func:`mode_joint_gains`:
    the unresolved modes keep their ``k dt`` of damping, so they stay quasi-static)."""

    k, c = mode_joint_gains(fm, mp, dt)
    out = np.zeros((len(k), TRANS))
    for j in range(len(k)):
        mu = fm.mu[j]
        A = np.array([[0.0, 1.0, 0.0], [-k[j] / mu, -c[j] / mu, 1.0 / mu], [0.0, 0.0, 0.0]])
        E = scipy.linalg.expm(A * dt)
        out[j] = (E[0, 0], E[0, 1], E[1, 0], E[1, 1], E[0, 2], E[1, 2])
    return out


@dataclass
class ModalReport:
    """Per-triangle forces on the deformed feathers (world frame) from :meth:`evaluate`."""

    force: np.ndarray
    """(n, 3) aerodynamic force per triangle, N."""
    points: np.ndarray
    """(n, 3) deformed centroids, m."""
    normal: np.ndarray
    """(n, 3) deformed unit normals."""
    area: np.ndarray
    """(n,) deformed areas, m^2."""
    aoa: np.ndarray
    """(n,) angle of attack, rad."""
    vertices: np.ndarray
    """(nvert, 3) deformed mesh vertices (world), in :attr:`ModalFeathers.modes` order."""
    generalized: np.ndarray
    """(n_feathers, K) the aerodynamic (and external) generalized force on each mode, N."""


class ModalFeathers(CompiledProvider):
    """The modal feathers of one compiled modal dove: the force provider and its geometry."""

    kernel = "modal_feathers"

    def __init__(self, model: mujoco.MjModel, modes: Sequence[FeatherModes], table: CoefficientTable,
                 density: float, flow: FlowField | None = None, name: str = "modal feathers",
                 plucked: tuple[str, ...] = (), hinges: PolygonHinges | None = None,
                 params: ModalParams | None = None):
        """``modes``: mass-scaled modes (:func:`dove_feather_modes`). Two mechanisms, told
        apart by the model: when it has the mode joints ``<name>_mode<k>``
        (:func:`modal_xml`, ``ModalParams(integration="joints")``) the modes are MuJoCo DOF;
        otherwise the engine integrates them in ``userdata`` (:func:`modal_engine`; the
        default), with the damping and step of ``params``, and the primaries ride their
        ``hinges`` (:meth:`~flapsim.bird.body.model.Dove.twist_hinges`, integrated here too)."""
        self.model = model
        self.name = name
        self.flow = flow or FlowField()
        self._built_with = (table, density, plucked, hinges, params)
        if self.flow.has_python:
            raise InputError("modal feathers need compiled flow fields (no PythonField)")
        self.modes = tuple(modes)
        self.K = K = self.modes[0].omega.size
        self.engine = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT,
                                        f"{self.modes[0].name}_mode1") < 0
        if self.engine:
            self.kernel = "modal_engine"
        elif hinges is not None and len(hinges):
            raise InputError("modal feathers on mode joints keep their twist hinges in the skeleton")
        hinge_of = {lab: h for h, lab in enumerate(hinges.label)} if hinges is not None else {}
        fint, ff, grid, vst, vxs, tris = [], [], [], [], [], []
        voff = toff = goff = 0
        self.vert_offset = []
        for f, fm in enumerate(self.modes):
            b = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, fm.body)
            if b < 0:
                raise InputError(f"model lacks feather body {fm.body}")
            h = hinge_of.get(fm.name, -1)
            if h >= 0 and hinges.body[h] != fm.body:
                raise InputError(f"feather {fm.name}: its hinge rides {hinges.body[h]!r}, not {fm.body!r}")
            if self.engine:
                qa = da = K * f
            else:
                j = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, f"{fm.name}_mode1")
                if j < 0:
                    raise InputError(f"model lacks the mode joint {fm.name}_mode1 (build it with "
                                     "ModalParams(integration='joints'))")
                for k in range(1, K):
                    jk = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, f"{fm.name}_mode{k + 1}")
                    if model.jnt_dofadr[jk] != model.jnt_dofadr[j] + k:
                        raise InputError(f"feather {fm.name}: its mode joints are not consecutive DOF")
                qa, da = model.jnt_qposadr[j], model.jnt_dofadr[j]
            nv, nt = len(fm.vert_x), len(fm.faces)
            ng = fm.slope.shape[0]
            # a plucked feather keeps its modes (driven by inertia alone) but no force polygons
            fint.append([b, qa, da, fm.stations, fm.sub, voff, nv, toff,
                         0 if fm.name in plucked else nt, goff, h])
            ff.append(np.concatenate([fm.root, fm.shaft, fm.chord, fm.normal, [fm.length],
                                      fm.gamma, fm.first_moment.ravel()]))
            grid.append(np.stack([fm.slope, fm.twist], axis=-1).ravel())
            vst.append(fm.vert_station)
            vxs.append(fm.vert_x)
            tris.append(fm.faces + voff)
            self.vert_offset.append(voff)
            voff += nv
            toff += nt
            goff += ng * K * 2
        self.nvert, self.ntri = voff, toff
        i64 = lambda a: np.ascontiguousarray(np.concatenate(a) if isinstance(a, list) else a,  # noqa: E731
                                             dtype=np.int64).ravel()
        f64 = lambda a: np.ascontiguousarray(np.concatenate(a) if isinstance(a, list) else a,  # noqa: E731
                                             dtype=float).ravel()
        self._fint = i64(np.array(fint))
        self._ff = f64(ff)
        self._grid = f64(grid)
        self._vst = i64(vst)
        self._vx = f64(vxs)
        self._tri = i64(tris)
        self.ext = np.zeros(3 * self.nvert)
        """External loads on the mesh vertices (body frame, N), for tests and calibration."""
        maxv = max(len(fm.vert_x) for fm in self.modes)
        maxst = max(fm.stations for fm in self.modes)
        vo = (6 + 6 * K) * maxst + 3 * K  # the stations and their work space (see modal_kernel)
        qo = vo + (6 + 3 * K) * maxv
        self._scratch = np.zeros(qo + 3 * K)
        cl, cd = pseudo_angle_tables(table)
        self._cl, self._cd = cl, cd
        self.userdata_offset = 0
        """Where the engine's modal state starts in ``userdata`` (after the hinges' own)."""
        none_i, none_f = np.zeros(0, dtype=np.int64), np.zeros(0)
        self._hint, self._hflt = none_i, none_f
        if self.engine:
            if hinges is not None and len(hinges):
                _, self._hint, self._hflt = hinges.tables(model, [], np.zeros(0, dtype=np.int64))
                self.userdata_offset = userdata_size(len(hinges))
            need = self.userdata_offset + engine_userdata_size(len(self.modes), K)
            if model.nuserdata < need:
                raise ModelError(f"{len(self.modes)} engine-integrated feathers keep their modes in "
                                 f'userdata: the model needs <size nuserdata="{need}"/> or more '
                                 "(build it with Dove.load(feathers='modal'))")
            integrator_damping(model)  # RK4 is refused here, not at the first step
            mp = params or ModalParams()
            self._trans = f64([mode_transitions(fm, mp, model.opt.timestep).ravel() for fm in self.modes])
        self._fluid = np.array([density, 0.0, K, vo, qo, self.userdata_offset], dtype=float)
        self._rootid = np.ascontiguousarray(model.body_rootid, dtype=np.int64)
        self._no_record = np.zeros(1)
        self.qadr = self._fint.reshape(-1, FI)[:, 1].copy()
        self.dadr = self._fint.reshape(-1, FI)[:, 2].copy()

    def for_model(self, model: mujoco.MjModel) -> ModalFeathers:
        """The same feathers (modes, table, flow, plucked feathers, hinges, parameters) on
        another compilation of the same dove, such as a copy with a coarser timestep: the
        modes' step is built for that model's timestep."""
        table, density, plucked, hinges, params = self._built_with
        return ModalFeathers(model, self.modes, table, density, self.flow, name=self.name,
                             plucked=plucked, hinges=hinges, params=params)

    QFRC_ARG_ENGINE = 29
    """Index of ``qfrc_passive`` in the engine kernel's arrays (:meth:`arrays`)."""

    def arrays(self, model, data, record: np.ndarray | None = None):
        rec = self._no_record if record is None else record
        if not self.engine:
            return [data.xpos.reshape(-1), data.xmat.reshape(-1), data.cvel.reshape(-1),
                    data.subtree_com.reshape(-1), self._rootid, data.qpos, data.qvel,
                    data.qfrc_passive, self._fint, self._ff, self._grid, self._vst, self._vx,
                    self._tri, self._scratch, self.ext, self._cl, self._cd, self.flow.params,
                    self._fluid, time_view(data), rec]

        nm = self.K * len(self.modes)
        return [data.xpos.reshape(-1), data.xmat.reshape(-1), data.cvel.reshape(-1),
                data.subtree_com.reshape(-1), self._rootid, self._fint, self._ff, self._grid,
                self._vst, self._vx, self._tri, self._scratch, self.ext, self._cl, self._cd,
                self.flow.params, self._fluid, time_view(data), rec, np.zeros(nm), np.zeros(nm),
                np.zeros(nm), self._trans, *hinge_arrays(model, data, self._hint, self._hflt)]

    def register(self, data: mujoco.MjData) -> Registration:
        return register(self.model, data, self)

    def evaluate(self, data: mujoco.MjData) -> ModalReport:
        """Forces and deformed geometry for the current state (call ``mj_forward`` first);
        touches neither ``qfrc_passive`` nor the state."""
        rec = np.zeros(REC * self.ntri + 3 * self.nvert)
        w = np.zeros(6 * self.model.nbody)
        arrays = self.arrays(self.model, data, record=rec)
        if self.engine:  # scratch torques and state memory: leave the data's alone
            arrays[self.QFRC_ARG_ENGINE] = data.qfrc_passive.copy()
            arrays[-1] = data.userdata.copy()
            if modal_engine(w, *arrays) != 0:
                raise InputError("modal feathers: non-finite force (a diverged state?)")
            Q = arrays[21].reshape(len(self.modes), self.K).copy()
        else:
            arrays[7] = qfrc = np.zeros_like(data.qfrc_passive)  # leave the data's alone
            modal_kernel(w, *arrays)
            Q = np.array([qfrc[a:a + self.K] for a in self.dadr])
        r = rec[:REC * self.ntri].reshape(-1, REC)
        return ModalReport(r[:, 0:3].copy(), r[:, 3:6].copy(), r[:, 6:9].copy(), r[:, 9].copy(),
                           r[:, 10].copy(), rec[REC * self.ntri:].reshape(-1, 3).copy(), Q)

    def coordinates(self, data: mujoco.MjData) -> np.ndarray:
        """(n_feathers, K) modal coordinates at ``data.time``."""
        return self.state(data)[0]

    def state(self, data: mujoco.MjData) -> tuple[np.ndarray, np.ndarray]:
        """(coordinates, rates), each (n_feathers, K), at ``data.time``."""
        K = self.K
        if not self.engine:
            return (np.array([data.qpos[a:a + K] for a in self.qadr]),
                    np.array([data.qvel[a:a + K] for a in self.dadr]))
        ud, mo = data.userdata, self.userdata_offset
        # after mj_step and before the next call, the state at data.time is the next one (B)
        nxt = abs(data.time - ud[mo + 1] - self.model.opt.timestep) < 0.25 * self.model.opt.timestep
        st = ud[mo + 2:mo + 2 + MODE_SLOTS * K * len(self.modes)].reshape(-1, MODE_SLOTS)
        j = 2 if nxt else 0
        return (st[:, j].reshape(len(self.modes), K).copy(),
                st[:, j + 1].reshape(len(self.modes), K).copy())

    def set_coordinates(self, data: mujoco.MjData, q: np.ndarray, qdot: np.ndarray | None = None
                        ) -> None:
        """Put the feathers at coordinates ``q`` (n_feathers, K) and rates ``qdot`` (zero by
        default) at ``data.time`` (engine-integrated modes; joints: ``qpos``/``qvel``)."""
        q = np.asarray(q, float).reshape(len(self.modes), self.K)
        qd = np.zeros_like(q) if qdot is None else np.asarray(qdot, float).reshape(q.shape)
        if not self.engine:
            for i, a in enumerate(self.qadr):
                data.qpos[a:a + self.K] = q[i]
                data.qvel[self.dadr[i]:self.dadr[i] + self.K] = qd[i]
            return
        ud, mo = data.userdata, self.userdata_offset
        ud[mo + 1] = data.time
        st = ud[mo + 2:mo + 2 + MODE_SLOTS * q.size].reshape(-1, MODE_SLOTS)
        st[:, 0], st[:, 1] = q.ravel(), qd.ravel()
        st[:, 2], st[:, 3] = q.ravel(), qd.ravel()

    def warped(self, q: np.ndarray, feather: int) -> tuple[np.ndarray, np.ndarray]:
        """Feather ``feather`` deformed by coordinates ``q`` (K,), in its body frame: its
        vertices (nv, 3) and their Jacobians (nv, K, 3), as the force kernel builds them."""
        fm = self.modes[feather]
        K = self.K
        fi = self._fint.reshape(-1, FI)[feather]
        wo = len(fm.vert_x) * 3 * (1 + K)
        out = np.zeros(wo + (6 + 6 * K) * fm.stations + 3 * K)
        q = np.ascontiguousarray(q, dtype=float)
        if q.shape != (K,) or warp(K, self._ff, (13 + 4 * K) * feather, self._grid, fi[9], fi[3],
                                   fi[4], q, self._vst, self._vx, fi[5], fi[6], out, wo) != 0:
            raise InputError(f"feather {fm.name}: {K} modal coordinates expected, got {q.shape}")
        v = out[:wo].reshape(len(fm.vert_x), 1 + K, 3)
        return v[:, 0, :].copy(), v[:, 1:, :].copy()

    def body_vertices(self, q: np.ndarray, feather: int) -> np.ndarray:
        """(nv, 3) deformed vertices of feather ``feather`` in its body frame for coordinates q."""
        return self.warped(q, feather)[0]

    def feather_index(self, name: str) -> int:
        for i, fm in enumerate(self.modes):
            if fm.name == name:
                return i
        raise InputError(f"no feather named {name!r}")

    def tip(self, data: mujoco.MjData, feather: int) -> tuple[float, float]:
        """(deflection along the rest normal, m; elastic twist, rad) of the shaft tip of
        feather ``feather``: bending and twisting relative to its bone (or twist hinge)."""
        fm = self.modes[feather]
        q = self.coordinates(data)[feather]
        v = self.body_vertices(q, feather)
        tip = np.flatnonzero(fm.vert_station == fm.stations - 1)
        a, b = tip[0], tip[1]
        xa, xb = fm.vert_x[a], fm.vert_x[b]
        shaft = (xb * v[a] - xa * v[b]) / (xb - xa)  # the point at x = 0 between them
        rest = fm.root + fm.length * fm.shaft
        return float((shaft - rest) @ fm.normal), float(q @ fm.twist[-1])


