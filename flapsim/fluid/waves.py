"""Wave-making resistance of the polygons near a free surface.

A body moving at or just under a free surface pushes the surface up ahead of it and
leaves a train of gravity waves behind; the energy they carry away is felt as a
resistance that the deeply submerged body does not meet. Per wetted polygon, at its
world centroid ``p`` a depth ``d = max(0, surface_z - p_z)`` under the surface and with
``V_h`` the horizontal part of the relative flow there (the polygon's motion through the
water, reversed):

    F = 1/2 rho C_w(Fr) A s exp(-2 k d) |V_h| V_h,   k = g / |V_h|^2,   Fr = |V_h| / sqrt(g L)

along ``V_h`` (against the polygon's horizontal motion through the water), applied at the
centroid, where ``A`` is the polygon's area, ``s`` its submerged fraction (the surface
engine's rule: along its vertical extent) and ``L`` the body's length.

Why this form:

* ``exp(-2 k d)``: a source a depth ``d`` under the surface makes Kelvin waves of wave
  number ``k = g / v^2`` whose amplitude decays as ``exp(-k d)`` (the linear potential
  flow of a travelling disturbance, Havelock's submerged bodies); the resistance is the
  energy flux of the waves, the amplitude squared. A polygon a wavelength under the
  surface makes no waves.
* ``C_w(Fr) = C_hump (min(Fr, FR_HUMP) / FR_HUMP)^4``: the classical low-Froude-number
  behaviour of a displacement hull, wave resistance rising as ~v^6 (thin-ship theory) up
  to the main hump near ``Fr ~ 0.5`` (its waves as long as the hull: the "hull speed"),
  beyond which a displacement hull's wave coefficient stops rising; held there, never
  extrapolated. Together with the depth factor the swimmer's surface waves are negligible
  at ~1 m/s and steep above 1.6 m/s, as measured on people (below).
* one coefficient, ``C_hump`` (referred to the wetted area, like a ship's C_w), fitted to
  one measurement: Toussaint, van Stralen & Stevens 2002 (Proceedings of the XXth
  International Symposium on Biomechanics in Sports 20:279-282, "Wave drag in front crawl
  swimming") found wave drag negligible below 1.6 m/s and, at a mean 1.89 m/s, 11.5 N,
  12.1 % of the active drag. Vennell, Pease & Wilson 2006 (J Biomech 39:664) found the
  wave drag of a towed mannequin large at the surface and small once ~0.5-0.7 m under it:
  the depth factor's check.

This is a local model: the interference between the waves of different parts of a hull
(the humps and hollows of a ship's C_w curve) is not modelled, each polygon's waves add.
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np
from numba import njit

from flapsim.core.callbacks import CompiledProvider, Registration, register, register_kernel, time_view
from flapsim.core.errors import InputError
from flapsim.core.wrench import add_force, body_point
from flapsim.fluid.flow import FlowField, flow_at
from flapsim.fluid.surfaces import PolygonSet

#: Froude number of the main wave-resistance hump of a displacement hull (waves as long as
#: the hull), where C_w stops rising
FR_HUMP = 0.5


@dataclass(frozen=True)
class WaveParams:
    """The water, its surface and the wave coefficient."""

    #: fluid density [kg/m^3]
    density: float = 1000.0
    #: height of the free surface [m]; the fluid fills z < surface_z
    surface_z: float = 0.0
    #: the body's length L [m] in Fr = v / sqrt(g L)
    length: float = 1.8
    #: wave resistance coefficient at the hump, C_w(FR_HUMP), per wetted area [-]
    c_hump: float = 0.0
    #: gravitational acceleration [m/s^2]
    gravity: float = 9.81

    def __post_init__(self) -> None:
        for name in ("density", "length", "gravity"):
            v = getattr(self, name)
            if not (np.isfinite(v) and v > 0):
                raise InputError(f"wave drag: {name} must be > 0, got {v}")
        if not np.isfinite(self.surface_z):
            raise InputError("wave drag: surface_z must be a finite height in metres")
        if not (np.isfinite(self.c_hump) and 0.0 <= self.c_hump <= 0.1):
            raise InputError(f"wave drag: c_hump must be 0..0.1 (a hull's wave coefficient), "
                             f"got {self.c_hump}")

    def pack(self) -> np.ndarray:
        return np.array([self.density, self.surface_z, self.length, self.c_hump, self.gravity])


@njit(cache=True, inline="always")
def wave_coefficient(v, length, c_hump, g):
    """C_w [-] at horizontal speed ``v`` [m/s] of a body ``length`` long (see the module)."""
    fr = min(v / np.sqrt(g * length), FR_HUMP) / FR_HUMP
    return c_hump * fr * fr * fr * fr


@njit(cache=True, fastmath={"contract", "arcp", "afn", "nsz"})
def wave_kernel(w, xpos, xmat, cvel, scom, rootid, pbody, pc, pn, parea, pext, flow, params,
                tnow, ext_flow, rec):
    """Add every wetted polygon's wave resistance to the wrench accumulator ``w``;
    ``params`` = WaveParams.pack(); ``rec`` (3 per polygon) receives the forces when its
    size allows."""
    rho = params[0]
    zs = params[1]
    length = params[2]
    c_hump = params[3]
    g = params[4]
    record = rec.size >= 3 * pbody.size
    t = tnow[0]
    for i in range(pbody.size):
        if record:
            rec[3 * i] = 0.0
            rec[3 * i + 1] = 0.0
            rec[3 * i + 2] = 0.0
        b = pbody[i]
        px, py, pz = body_point(xpos, xmat, b, pc[3 * i], pc[3 * i + 1], pc[3 * i + 2])
        # the submerged fraction, as the surface engine counts it
        m = 9 * b
        nz = xmat[m + 6] * pn[3 * i] + xmat[m + 7] * pn[3 * i + 1] + xmat[m + 8] * pn[3 * i + 2]
        half = pext[i] * np.sqrt(max(0.0, 1.0 - nz * nz))
        if half > 1e-12:
            frac = min(1.0, max(0.0, 0.5 + (zs - pz) / (2.0 * half)))
        else:
            frac = 1.0 if pz < zs else 0.0
        if frac <= 0.0:
            continue
        r = rootid[b]
        dx = px - scom[3 * r]
        dy = py - scom[3 * r + 1]
        dz = pz - scom[3 * r + 2]
        wx = cvel[6 * b]
        wy = cvel[6 * b + 1]
        wz = cvel[6 * b + 2]
        ux, uy, uz = flow_at(flow, px, py, pz, t)
        ux += ext_flow[3 * i]
        uy += ext_flow[3 * i + 1]
        vx = ux - (cvel[6 * b + 3] + wy * dz - wz * dy)
        vy = uy - (cvel[6 * b + 4] + wz * dx - wx * dz)
        v2 = vx * vx + vy * vy
        if v2 < 1e-12:
            continue
        v = np.sqrt(v2)
        depth = max(0.0, zs - pz)
        decay = np.exp(-2.0 * g * depth / v2)
        q = 0.5 * rho * wave_coefficient(v, length, c_hump, g) * parea[i] * frac * decay * v
        fx = q * vx
        fy = q * vy
        add_force(w, b, fx, fy, 0.0, px, py, pz)
        if record:
            rec[3 * i] = fx
            rec[3 * i + 1] = fy
    return 0


register_kernel("surface_waves", wave_kernel, "ffffiifffffffff")


class WaveDrag(CompiledProvider):
    """Wave-making resistance on a :class:`PolygonSet` under a free surface (see the module)."""

    kernel = "surface_waves"

    def __init__(self, model: mujoco.MjModel, polygons: PolygonSet, params: WaveParams,
                 flow: FlowField | None = None, ext_flow: np.ndarray | None = None,
                 name: str = "wave drag") -> None:
        if len(polygons) == 0:
            raise InputError("WaveDrag needs at least one polygon")
        if polygons.body.min() < 1 or polygons.body.max() >= model.nbody:
            raise InputError(f"polygon body ids must be in 1..{model.nbody - 1} for this model")
        self.model = model
        self.polygons = polygons
        self.name = name
        self.params = params
        self.flow = flow or FlowField()
        self._param_array = params.pack()
        self._rootid = np.ascontiguousarray(model.body_rootid, dtype=np.int64)
        # a flow's Python fields, sampled at the centroids by the surface engine that shares
        # these polygons (its array; zeros for compiled flows, the swimmer's kind)
        self._ext = np.zeros(3 * len(polygons)) if ext_flow is None else ext_flow
        if self._ext.size != 3 * len(polygons):
            raise InputError("WaveDrag: ext_flow must hold 3 numbers per polygon")
        self._no_record = np.zeros(1)

    def set_params(self, params: WaveParams) -> None:
        """Change the water, the surface or the coefficient in place (effective at once)."""
        self.params = params
        self._param_array[:] = params.pack()

    def arrays(self, model: mujoco.MjModel, data: mujoco.MjData, record: np.ndarray | None = None
               ) -> list[np.ndarray]:
        if model.nbody != self.model.nbody:
            raise InputError("WaveDrag used with a different model than it was built for")
        p = self.polygons
        return [
            data.xpos.reshape(-1), data.xmat.reshape(-1), data.cvel.reshape(-1),
            data.subtree_com.reshape(-1), self._rootid, p.body, p.centroid.reshape(-1),
            p.normal.reshape(-1), p.area, p.extent, self.flow.params, self._param_array,
            time_view(data), self._ext, self._no_record if record is None else record,
        ]

    def register(self, data: mujoco.MjData) -> Registration:
        """Apply the wave resistance whenever MuJoCo steps ``data``."""
        return register(self.model, data, self)

    def evaluate(self, data: mujoco.MjData) -> tuple[np.ndarray, np.ndarray]:
        """(per-polygon force (n, 3) [N], per-body force (nbody, 3) [N]) for the current
        state (call ``mj_forward`` first); nothing is applied."""
        n = len(self.polygons)
        rec = np.zeros(3 * n)
        w = np.zeros(6 * self.model.nbody)
        wave_kernel(w, *self.arrays(self.model, data, record=rec))
        return rec.reshape(n, 3), w.reshape(-1, 6)[:, 3:6].copy()
