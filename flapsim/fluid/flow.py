"""Wind and current fields: the fluid's own velocity at a world point and time.

A :class:`FlowField` is a sum of primitives. The compiled ones (uniform, 1-cosine gust,
oscillating breeze, point source, line vortex) are packed into one float64 array that
the force kernel evaluates per polygon inside the passive callback; a
:class:`PythonField` is any user function ``fn(points (n,3), t) -> (n,3)``, evaluated
once per callback for all polygons (slower: it runs Python every step).
"""

from __future__ import annotations

from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass

import numpy as np
from numba import njit

from flapsim.core.errors import InputError

ROW = 12  # floats per packed primitive: kind + 11 parameters
UNIFORM, GUST, BREEZE, SOURCE, VORTEX = 0, 1, 2, 3, 4


def _vec3(name: str, v: Sequence[float]) -> np.ndarray:
    a = np.asarray(v, dtype=float)
    if a.shape != (3,) or not np.all(np.isfinite(a)):
        raise InputError(f"{name} must be 3 finite numbers, got {v!r}")
    return a


def _unit(name: str, v: Sequence[float]) -> np.ndarray:
    a = _vec3(name, v)
    n = np.linalg.norm(a)
    if n < 1e-12:
        raise InputError(f"{name} must be a non-zero direction")
    return a / n


@dataclass(frozen=True)
class Uniform:
    """Uniform flow (steady wind or current) of ``velocity`` [m/s]."""

    velocity: Sequence[float] = (0.0, 0.0, 0.0)

    def pack(self) -> np.ndarray:
        row = np.zeros(ROW)
        row[0] = UNIFORM
        row[1:4] = _vec3("Uniform.velocity", self.velocity)
        return row


@dataclass(frozen=True)
class Gust:
    """A '1-cosine' gust: speed ``amplitude`` [m/s] along ``direction``, rising and falling
    smoothly over ``duration`` [s] from ``start`` [s] (the standard discrete-gust shape)."""

    direction: Sequence[float] = (0.0, 1.0, 0.0)
    amplitude: float = 1.0
    start: float = 0.0
    duration: float = 0.5

    def pack(self) -> np.ndarray:
        if self.duration <= 0:
            raise InputError("Gust.duration must be > 0 s")
        row = np.zeros(ROW)
        row[0] = GUST
        row[1:4] = _unit("Gust.direction", self.direction) * float(self.amplitude)
        row[4], row[5] = self.start, self.duration
        return row


@dataclass(frozen=True)
class Breeze:
    """Oscillating wind: ``amplitude`` [m/s] * sin(2 pi ``frequency`` t + ``phase``) along
    ``direction`` (add a :class:`Uniform` for its mean)."""

    direction: Sequence[float] = (1.0, 0.0, 0.0)
    amplitude: float = 0.5
    frequency: float = 0.2
    phase: float = 0.0

    def pack(self) -> np.ndarray:
        row = np.zeros(ROW)
        row[0] = BREEZE
        row[1:4] = _unit("Breeze.direction", self.direction) * float(self.amplitude)
        row[4], row[5] = self.frequency, self.phase
        return row


@dataclass(frozen=True)
class Source:
    """Point source (sink if ``strength`` < 0) of volume rate ``strength`` [m^3/s] at
    ``position``: v = Q r / (4 pi (|r|^2 + rc^2)^(3/2)), core radius ``core`` [m] keeps it finite."""

    position: Sequence[float] = (0.0, 0.0, 0.0)
    strength: float = 1.0
    core: float = 0.05

    def pack(self) -> np.ndarray:
        if self.core <= 0:
            raise InputError("Source.core must be > 0 m")
        row = np.zeros(ROW)
        row[0] = SOURCE
        row[1:4] = _vec3("Source.position", self.position)
        row[4], row[5] = self.strength, self.core
        return row


@dataclass(frozen=True)
class Vortex:
    """Straight line vortex through ``position`` along ``axis`` with circulation
    ``circulation`` [m^2/s]: v = Gamma/(2 pi) (axis x r_perp) / (|r_perp|^2 + rc^2)."""

    position: Sequence[float] = (0.0, 0.0, 0.0)
    axis: Sequence[float] = (0.0, 0.0, 1.0)
    circulation: float = 1.0
    core: float = 0.05

    def pack(self) -> np.ndarray:
        if self.core <= 0:
            raise InputError("Vortex.core must be > 0 m")
        row = np.zeros(ROW)
        row[0] = VORTEX
        row[1:4] = _vec3("Vortex.position", self.position)
        row[4:7] = _unit("Vortex.axis", self.axis)
        row[7], row[8] = self.circulation, self.core
        return row


@dataclass(frozen=True)
class PythonField:
    """User plug-in: ``fn(points (n,3) world [m], t [s]) -> velocities (n,3) [m/s]``."""

    fn: Callable[[np.ndarray, float], np.ndarray]


class FlowField:
    """Sum of flow primitives. Row 0 is always a :class:`Uniform` (zero if none given),
    so :meth:`set_uniform` can retarget it cheaply, e.g. once per control step."""

    def __init__(self, primitives: Sequence[object] = ()) -> None:
        compiled = [p for p in primitives if not isinstance(p, PythonField)]
        self.python_fields = [p for p in primitives if isinstance(p, PythonField)]
        bad = [p for p in compiled if not hasattr(p, "pack")]
        if bad:
            raise InputError(f"not a flow primitive: {bad[0]!r}")
        if not compiled or not isinstance(compiled[0], Uniform):
            compiled = [Uniform(), *compiled]
        self.params = np.concatenate([p.pack() for p in compiled])

    @property
    def has_python(self) -> bool:
        return bool(self.python_fields)

    def set_uniform(self, velocity: Sequence[float]) -> None:
        """Replace the uniform component in place (the compiled kernel sees it at once)."""
        self.params[1:4] = _vec3("uniform velocity", velocity)

    @contextmanager
    def still(self) -> Iterator[None]:
        """Within the block the fluid is at rest everywhere (every packed row a zero
        :class:`Uniform`, no Python fields); afterwards the flow is as it was. In place, so a
        compiled force kernel holding :attr:`params` sees it too: what a bird does in still
        air (its trim), measured on the flight that will fly in the wind."""
        saved, fields = self.params.copy(), self.python_fields
        self.params[:] = 0.0  # kind 0 is UNIFORM: zero velocity
        self.python_fields = []
        try:
            yield
        finally:
            self.params[:] = saved
            self.python_fields = fields

    def velocity(self, points: np.ndarray, t: float = 0.0) -> np.ndarray:
        """Fluid velocity at world ``points`` (n,3) at time ``t``."""
        pts = np.asarray(points, dtype=float)
        if pts.ndim != 2 or pts.shape[1] != 3:
            raise InputError(f"points must have shape (n, 3), got {pts.shape}")
        out = np.empty_like(pts)
        for i in range(pts.shape[0]):
            out[i] = flow_at(self.params, pts[i, 0], pts[i, 1], pts[i, 2], t)
        for f in self.python_fields:
            out += _checked(f.fn(pts, t), pts.shape[0])
        return out


def _checked(v: np.ndarray, n: int) -> np.ndarray:
    a = np.asarray(v, dtype=float)
    if a.shape != (n, 3) or not np.all(np.isfinite(a)):
        raise InputError(f"a PythonField must return {n}x3 finite velocities, got {a.shape}")
    return a


@njit(cache=True, inline="always")
def flow_at(params, x, y, z, t):
    """Sum of the packed primitives at (x, y, z, t) -> (vx, vy, vz)."""
    vx = 0.0
    vy = 0.0
    vz = 0.0
    for k in range(params.size // ROW):
        o = k * ROW
        kind = int(params[o])
        if kind == UNIFORM:
            vx += params[o + 1]
            vy += params[o + 2]
            vz += params[o + 3]
        elif kind == GUST:
            s = (t - params[o + 4]) / params[o + 5]
            if 0.0 <= s <= 1.0:
                g = 0.5 * (1.0 - np.cos(2.0 * np.pi * s))
                vx += g * params[o + 1]
                vy += g * params[o + 2]
                vz += g * params[o + 3]
        elif kind == BREEZE:
            g = np.sin(2.0 * np.pi * params[o + 4] * t + params[o + 5])
            vx += g * params[o + 1]
            vy += g * params[o + 2]
            vz += g * params[o + 3]
        elif kind == SOURCE:
            rx = x - params[o + 1]
            ry = y - params[o + 2]
            rz = z - params[o + 3]
            d2 = rx * rx + ry * ry + rz * rz + params[o + 5] ** 2
            c = params[o + 4] / (4.0 * np.pi * d2 * np.sqrt(d2))
            vx += c * rx
            vy += c * ry
            vz += c * rz
        elif kind == VORTEX:
            rx = x - params[o + 1]
            ry = y - params[o + 2]
            rz = z - params[o + 3]
            ax = params[o + 4]
            ay = params[o + 5]
            az = params[o + 6]
            along = rx * ax + ry * ay + rz * az
            rx -= along * ax
            ry -= along * ay
            rz -= along * az
            c = params[o + 7] / (2.0 * np.pi * (rx * rx + ry * ry + rz * rz + params[o + 8] ** 2))
            vx += c * (ay * rz - az * ry)
            vy += c * (az * rx - ax * rz)
            vz += c * (ax * ry - ay * rx)
    return vx, vy, vz
