"""Deformable feathers: each feather's first bending/twisting modes, clamped at its root.

The flight paper (sec. 6-7) simulates every feather as a thin shell reduced to 4 deformation
modes (modal warping, Choi & Ko 2005), driven by the aerodynamic forces on its own triangles
and the D'Alembert load of the bone's motion (James & Pai 2002). This module builds those
modes; :mod:`flapsim.bird.body.feather_dynamics` integrates them.

The shell, reduced: a feather is long and narrow (length/width 5-25), so its out-of-plane
deflection is written ``w(s, x) = v(s) + x theta(s)``: a shaft bending ``v`` and a section
twist ``theta`` along the shaft coordinate ``s``, with ``x`` the chordwise distance from the
shaft (+ toward the leading vane). Each section stays straight chordwise (the vanes are
stiff across the barbs compared with the feather along its length). The shaft is cut into
beam elements (cubic Hermite for ``v``, linear for ``theta``); the stiffness is

* bending ``EI(s)``, linear from root to tip: primaries and secondaries (and tertials)
  0.018 -> 0.0019 N m^2, rectrices 0.009 -> 0.001 N m^2 (the paper's flexural constants,
  written "N m" there, read as the feather's bending stiffness EI: reading them as a plate's
  rigidity D per unit width would put a primary's first mode at ~14 Hz, next to the 9 Hz
  wingbeat, with tips bending half their length at cruise);
* twist ``GJ(s) = 2 (1 - nu) EI(s)``: a plate strip's torsional rigidity for the same
  flexural constant spread over its width (nu = 0.3, assumed);

and the mass is the feather's own (uniform per area, the model's feather mass), integrated
over its triangles. The paper's density, 165 kg/m^3, then means a vane thickness of
``mass / (area * 165)`` (reported by :attr:`FeatherModes.thickness`). In-plane (membrane)
stretch and shear (the paper's 2500 N/m and 2500 N) are not modelled: a feather's in-plane
bending is carried by its rachis and overlapping vanes, far stiffer than out of plane, and
the four lowest modes are all out of plane.

The modes are the lowest ``n`` of the generalized eigenproblem ``K phi = omega^2 M phi``
with the root clamped; each is scaled so that its largest vertex deflection is 1 (the modal
coordinate is then a deflection in metres). What the simulation needs from a mode:

* its shaft slope ``v'`` and twist ``theta`` on a fine grid along the shaft (modal warping:
  the deformed feather is built by rotating each section, so a bent feather keeps its length);
* its generalized mass ``mu``, stiffness ``k = mu omega^2``;
* ``Gamma = int rho w dA`` and ``S = int rho w X dA``: the D'Alembert load of a rigid
  acceleration ``a(X) = a_o + alpha x X + omega x (omega x X)`` of the bone is
  ``Q = -(Gamma n.a_o + n.(alpha x S) + n.(omega x (omega x S)))``.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np
import scipy.linalg

from flapsim.bird.body import feather_geometry as fz
from flapsim.core.errors import InputError


@dataclass(frozen=True)
class ModalParams:
    """Feather elasticity (the flight paper, sec. 7) and the reduction's settings."""

    primary_ei: tuple[float, float] = (0.018, 0.0019)
    """Primary bending stiffness EI at the root and the tip, N m^2 (paper: 0.018 -> 0.0019)."""
    secondary_ei: tuple[float, float] = (0.018, 0.0019)
    """Secondary (and tertial) EI root -> tip, N m^2 (paper: 0.018 -> 0.0019)."""
    rectrix_ei: tuple[float, float] = (0.009, 0.001)
    """Rectrix EI root -> tip, N m^2 (paper: 0.009 -> 0.001)."""
    poisson: float = 0.3
    """Poisson ratio of the shell: twist GJ = 2 (1 - nu) EI (assumed, keratin ~0.3)."""
    density: float = 165.0
    """Shell density, kg/m^3 (paper); sets only the reported thickness (mass comes from the model)."""
    modes: int = 1
    """Modes per feather (paper: 4). One by default: in the base controller's flight the
    first mode carries the feathers' bending (RMS shaft-tip deflection of every feather:
    modes 2-4 add 0.6 %, 0.2 % and 0.07 % of it; their elastic tip twist, 0.16 deg RMS, is
    negligible next to the primaries' hinge twist of ~35 deg), and lift/weight changes by
    0.1 % (0.9672 with 4 modes, 0.9661 with 1; ``studies/dove_feather_participation.py``),
    while a flight step costs 1.29x a rigid one with 1 mode and 1.81x with 4 (the engine's
    integration). ``modes=4`` is the paper's reduction."""
    damping_ratio: float = 0.02
    """Structural damping ratio of every mode: half the loss factor of keratin (~0.04,
    assumed; feathers vibrate with ~2-5 % damping ratios in still air, aerodynamic damping
    is computed separately by the force engine)."""
    elements: int = 16
    """Beam elements along the shaft."""
    grid_per_segment: int = 2
    """Warping integration intervals per mesh segment along the shaft (even: Simpson's rule)."""
    implicit_above: float = 1.0
    """Modes with omega * timestep above this get ``k dt`` of extra (numerical) damping: the
    timestep cannot resolve them, so they are kept quasi-static (with ``integration="joints"``
    that makes MuJoCo's step backward Euler for them; the others are stepped exactly by the
    engine, or semi-implicitly by MuJoCo, both without energy drift)."""
    integration: str = "engine"
    """Who integrates the modes: ``"engine"`` (default): the force engine, in MuJoCo's
    ``userdata``, one exact step of each mode's oscillator per simulation step, driven by the
    aerodynamic and D'Alembert loads, the feather's reaction on its bone being its aerodynamic
    force (the paper's eq. 9), the primaries' twist hinges outside the skeleton as for rigid
    feathers; ``"joints"``: each mode a MuJoCo DOF (a point mass on a slide joint), fully
    coupled to the bone, twist hinges in the skeleton: 1.4x dearer, kept as the reference the
    engine is checked against (:mod:`flapsim.bird.body.feather_dynamics`)."""

    def __post_init__(self) -> None:
        if self.integration not in ("engine", "joints"):
            raise InputError(f"ModalParams.integration must be 'engine' or 'joints', got "
                             f"{self.integration!r}")
        if not 1 <= int(self.modes) <= 8:
            raise InputError(f"ModalParams.modes must be 1..8, got {self.modes}")

    def ei(self, kind: str) -> tuple[float, float]:
        if kind == "primary":
            return self.primary_ei
        if kind in ("secondary", "tertial"):
            return self.secondary_ei
        if kind == "rectrix":
            return self.rectrix_ei
        raise InputError(f"no feather stiffness for kind {kind!r}")


@dataclass(frozen=True)
class FeatherModes:
    """One feather's geometry in its body frame and its modes."""

    name: str
    body: str
    kind: str
    root: np.ndarray
    """(3,) shaft root, body frame, m."""
    shaft: np.ndarray
    """(3,) unit shaft direction (root -> tip)."""
    chord: np.ndarray
    """(3,) unit in-plane direction toward the leading vane."""
    normal: np.ndarray
    """(3,) unit dorsal normal."""
    length: float
    """Shaft length from the root to the last station, m."""
    stations: int
    """Vertex stations along the shaft (segments + 1), evenly spaced."""
    sub: int
    """Grid points per station interval (the warping integration grid has
    ``(stations - 1) * sub + 1`` points)."""
    slope: np.ndarray
    """(grid, K) shaft slope dv/ds of each mode on the grid."""
    twist: np.ndarray
    """(grid, K) section twist of each mode on the grid, rad per unit coordinate."""
    vert_station: np.ndarray
    """(nv,) station index of each mesh vertex."""
    vert_x: np.ndarray
    """(nv,) chordwise offset of each vertex from the shaft, m."""
    faces: np.ndarray
    """(nf, 3) the feather's mesh faces (dorsal winding)."""
    shape: np.ndarray
    """(nv, K) linear deflection of each vertex along the normal per unit coordinate."""
    omega: np.ndarray
    """(K,) angular frequencies, rad/s."""
    mu: np.ndarray
    """(K,) generalized masses, kg."""
    gamma: np.ndarray
    """(K,) int rho w dA, kg."""
    first_moment: np.ndarray
    """(K, 3) int rho w X dA (X in the body frame), kg m."""
    mass: float
    area: float
    thickness: float
    """Implied vane thickness at the paper's density, m."""
    ei: tuple[float, float]
    gj: tuple[float, float]
    unit: np.ndarray = dataclasses.field(default_factory=lambda: np.ones(0))
    """(K,) largest vertex deflection per unit coordinate, m (1 before any rescaling)."""

    @property
    def stiffness(self) -> np.ndarray:
        return self.mu * self.omega**2

    @property
    def frequency_hz(self) -> np.ndarray:
        return self.omega / (2 * np.pi)

    @property
    def vertices(self) -> np.ndarray:
        """(nv, 3) rest vertices in the body frame."""
        s = self.vert_station * self.length / (self.stations - 1)
        return self.root + s[:, None] * self.shaft + self.vert_x[:, None] * self.chord


def _hermite(xi: float, h: float):
    """Cubic Hermite values, first and second s-derivatives at xi in [0, 1] (DOF v_a, v'_a,
    v_b, v'_b) and linear values/derivatives (theta_a, theta_b)."""
    n = np.array([1 - 3 * xi**2 + 2 * xi**3, h * (xi - 2 * xi**2 + xi**3), 3 * xi**2 - 2 * xi**3,
                  h * (-xi**2 + xi**3)])
    d1 = np.array([-6 * xi + 6 * xi**2, h * (1 - 4 * xi + 3 * xi**2), 6 * xi - 6 * xi**2,
                   h * (-2 * xi + 3 * xi**2)]) / h
    d2 = np.array([-6 + 12 * xi, h * (-4 + 6 * xi), 6 - 12 * xi, h * (-2 + 6 * xi)]) / h**2
    return n, d1, d2


class ShaftBeam:
    """The bending-twisting beam FE of one feather: 3 DOF per node (v, v', theta)."""

    def __init__(self, length: float, ei: tuple[float, float], gj: tuple[float, float],
                 elements: int):
        self.L = float(length)
        self.ne = int(elements)
        self.h = self.L / self.ne
        self.ndof = 3 * (self.ne + 1)
        self.ei, self.gj = ei, gj
        self.K = np.zeros((self.ndof, self.ndof))
        gp, gw = np.polynomial.legendre.leggauss(4)
        for e in range(self.ne):
            dofs = self._dofs(e)
            for xg, wg in zip(gp, gw, strict=True):
                xi = 0.5 * (xg + 1)
                s = (e + xi) * self.h
                EI = ei[0] + (ei[1] - ei[0]) * s / self.L
                GJ = gj[0] + (gj[1] - gj[0]) * s / self.L
                _, _, d2 = _hermite(xi, self.h)
                bv = np.zeros(6)
                bv[[0, 1, 3, 4]] = d2
                bt = np.zeros(6)
                bt[[2, 5]] = (-1 / self.h, 1 / self.h)
                wt = 0.5 * wg * self.h
                self.K[np.ix_(dofs, dofs)] += wt * (EI * np.outer(bv, bv) + GJ * np.outer(bt, bt))

    def _dofs(self, e: int) -> np.ndarray:
        return np.arange(3 * e, 3 * e + 6)

    def row(self, s: float, x: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(w, v', theta) as rows over the DOF at shaft coordinate s, chord offset x."""
        s = min(max(s, 0.0), self.L)
        e = min(int(s / self.h), self.ne - 1)
        xi = s / self.h - e
        n, d1, _ = _hermite(xi, self.h)
        w = np.zeros(self.ndof)
        sl = np.zeros(self.ndof)
        th = np.zeros(self.ndof)
        o = 3 * e
        w[[o, o + 1, o + 3, o + 4]] = n
        sl[[o, o + 1, o + 3, o + 4]] = d1
        th[[o + 2, o + 5]] = (1 - xi, xi)
        return w + x * th, sl, th


def _quadrature(tris: np.ndarray, n: int = 16) -> tuple[np.ndarray, np.ndarray]:
    """Points and area weights covering triangles: each split into n^2 sub-triangles, one
    point at each centroid."""
    pts, wts = [], []
    for a, b, c in tris:
        area = 0.5 * np.linalg.norm(np.cross(b - a, c - a))
        for i in range(n):
            for j in range(n - i):
                # the upright and (where it exists) the inverted sub-triangle
                for u, v in (((i + 1 / 3) / n, (j + 1 / 3) / n), ((i + 2 / 3) / n, (j + 2 / 3) / n)):
                    if u + v <= 1 + 1e-12:
                        pts.append(a + u * (b - a) + v * (c - a))
                        wts.append(area / n**2)
    return np.array(pts), np.array(wts)


def feather_modes(fe: fz.Feather, lead_fraction: float, segments: int, params: ModalParams
                  ) -> FeatherModes:
    """The modes of one feather mesh built by :func:`flapsim.bird.body.feather_geometry.strip`."""
    sub = params.grid_per_segment
    if sub < 2 or sub % 2:
        raise InputError(f"grid_per_segment must be even and >= 2, got {sub}")
    v = np.asarray(fe.vertices, float)
    if len(v) != 2 * (segments + 1):
        raise InputError(f"feather {fe.name}: {len(v)} vertices, expected 2 x {segments + 1}")
    lead_vec = v[0::2] - v[1::2]  # leading minus trailing vertex of each station
    widths = np.linalg.norm(lead_vec, axis=1)
    chord = lead_vec[0] / widths[0]
    centres = v[1::2] + (1 - lead_fraction) * lead_vec
    root = centres[0]
    shaft = centres[-1] - root
    length = float(np.linalg.norm(shaft))
    shaft /= length
    normal = np.cross(shaft, chord)
    tri = v[fe.faces]
    tn = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    if np.sum(tn @ normal) < 0:
        normal = -normal
    rel = v - root
    vert_x = rel @ chord
    vert_station = np.repeat(np.arange(segments + 1), 2)
    ei = params.ei(fe.kind)
    gj = (2 * (1 - params.poisson) * ei[0], 2 * (1 - params.poisson) * ei[1])
    beam = ShaftBeam(length, ei, gj, params.elements)
    pts, wts = _quadrature(tri)
    area = float(wts.sum())
    rho = fe.mass / area
    M = np.zeros((beam.ndof, beam.ndof))
    rows = np.array([beam.row((p - root) @ shaft, (p - root) @ chord)[0] for p in pts])
    M = (rows * (rho * wts)[:, None]).T @ rows
    free = np.arange(3, beam.ndof)  # the root node is clamped
    Kf, Mf = beam.K[np.ix_(free, free)], M[np.ix_(free, free)]
    K = params.modes
    lam, vec = scipy.linalg.eigh(Kf, Mf, subset_by_index=(0, K - 1))
    phi = np.zeros((beam.ndof, K))
    phi[free] = vec
    vrows = np.array([beam.row(vert_station[i] * length / segments, vert_x[i])[0]
                      for i in range(len(v))])
    shape = vrows @ phi
    for k in range(K):  # largest vertex deflection = +1
        i = int(np.argmax(np.abs(shape[:, k])))
        phi[:, k] /= shape[i, k]
    shape = vrows @ phi
    grid = np.linspace(0.0, length, segments * sub + 1)
    slope = np.array([beam.row(s, 0.0)[1] @ phi for s in grid])
    twist = np.array([beam.row(s, 0.0)[2] @ phi for s in grid])
    wq = rows @ phi  # (npts, K)
    mu = np.einsum("ik,ij,jk->k", phi, M, phi)
    gamma = (rho * wts) @ wq
    first = np.einsum("p,pk,pj->kj", rho * wts, wq, pts)
    return FeatherModes(
        fe.name, fe.body, fe.kind, root, shaft, chord, normal, length, segments + 1, sub,
        slope, twist, vert_station, vert_x, np.asarray(fe.faces), shape, np.sqrt(lam), mu,
        gamma, first, float(fe.mass), area, float(fe.mass / area / params.density), ei, gj,
        np.ones(K))


def euler_bernoulli_tip_deflection(force: float, length: float, ei: tuple[float, float]) -> float:
    """Tip deflection of a clamped beam with EI falling linearly from ``ei[0]`` at the root to
    ``ei[1]`` at the tip under a tip load (small deflection): ``int_0^L F (L - s)^2 / EI(s) ds``
    in closed form. With ``EI(s) = a + b s`` and ``u = a + b s``: ``(L - s) = (c - u) / b``,
    ``c = a + b L = ei[1]``, so the integral is ``F / b^3 [c^2 ln(u) - 2 c u + u^2 / 2]``
    from ``u = a`` to ``u = c``."""
    a, c = ei
    L = length
    if abs(c - a) < 1e-15 * abs(a):
        return force * L**3 / (3 * a)
    b = (c - a) / L

    def prim(u: float) -> float:
        return c * c * np.log(u) - 2 * c * u + 0.5 * u * u

    return float(force / b**3 * (prim(c) - prim(a)))
