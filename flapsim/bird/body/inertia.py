"""Mass, centre of mass and inertia tensor of a body summed from rigid parts (rods,
ellipsoids, feather plates), for the generated MJCF's inertials."""

from __future__ import annotations

import numpy as np

from flapsim.bird.body import feather_geometry as fz


class _Inertia:
    """Sum of rigid parts: mass, centre of mass and inertia tensor (about the com)."""

    def __init__(self) -> None:
        self.parts: list[tuple[float, np.ndarray, np.ndarray]] = []

    def add(self, mass: float, com, inertia) -> None:
        self.parts.append((float(mass), np.asarray(com, float), np.asarray(inertia, float)))

    def rod(self, mass: float, a, b, radius: float = 0.003) -> None:
        a, b = np.asarray(a, float), np.asarray(b, float)
        L = np.linalg.norm(b - a)
        u = (b - a) / L
        i_perp = mass * (L**2 / 12 + radius**2 / 4)
        i_ax = mass * radius**2 / 2
        self.add(mass, (a + b) / 2, i_perp * np.eye(3) + (i_ax - i_perp) * np.outer(u, u))

    def ellipsoid(self, mass: float, c, semi) -> None:
        a, b, cc = semi
        self.add(mass, c, mass / 5 * np.diag([b * b + cc * cc, a * a + cc * cc, a * a + b * b]))

    def plates(self, feathers: list[fz.Feather]) -> None:
        for fe in feathers:
            com, inertia = fz.plate_inertia(fe.triangles, fe.mass)
            self.add(fe.mass, com, inertia)

    def total(self) -> tuple[float, np.ndarray, np.ndarray]:
        m = sum(p[0] for p in self.parts)
        com = sum(p[0] * p[1] for p in self.parts) / m
        inertia = np.zeros((3, 3))
        for mi, ci, ii in self.parts:
            r = ci - com
            inertia += ii + mi * (r @ r * np.eye(3) - np.outer(r, r))
        return m, com, inertia
