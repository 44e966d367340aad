"""A wingbeat-to-wingbeat map x' = A x + B u measured by central differences, and the discrete
LQR on it: what :mod:`flapsim.bird.control.lateral` and :mod:`flapsim.bird.control.longitudinal`
share (each names its own state, its perturbations and its inputs)."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import scipy.linalg

from flapsim.bird.flight import cycle
from flapsim.bird.flight.dove_flight import DoveFlight


def linearise(fl: DoveFlight, P: np.ndarray, start: cycle.Snapshot,
              state: Callable[[DoveFlight], np.ndarray],
              perturb: Callable[[DoveFlight, int, float], None],
              state_step: np.ndarray, directions: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(A, B) of the map flying ``P`` from ``start``: 2 wingbeats per state component (moved by
    ``perturb`` by +-``state_step``) and per input (``P`` +- each row of ``directions``)."""

    def end(p: np.ndarray, j: int | None = None, eps: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
        cycle.restore(fl, start)
        if j is not None:
            perturb(fl, j, eps)
        x0 = state(fl)
        cycle.fly_cycle(fl, None, p, fl.ref)
        return x0, state(fl)

    dX, dY = [], []
    for j, eps in enumerate(state_step):
        (xp, yp), (xm, ym) = end(P, j, eps), end(P, j, -eps)
        dX.append(xp - xm)
        dY.append(yp - ym)
    A = np.array(dY).T @ np.linalg.inv(np.array(dX).T)
    B = np.column_stack([(end(P + e)[1] - end(P - e)[1]) / 2.0 for e in directions])
    return A, B


def lqr(A: np.ndarray, B: np.ndarray, r: float, state_scale: np.ndarray) -> np.ndarray:
    """K of the discrete LQR, u = -K x, the first ``len(state_scale)`` states costing
    1 / state_scale^2 (the rest nothing) and each input ``r``."""
    Q = np.zeros((len(A), len(A)))
    Q[:len(state_scale), :len(state_scale)] = np.diag(1.0 / state_scale ** 2)
    R = r * np.eye(B.shape[1])
    X = scipy.linalg.solve_discrete_are(A, B, Q, R)
    return np.linalg.solve(R + B.T @ X @ B, B.T @ X @ A)
