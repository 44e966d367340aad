"""A wingbeat-to-wingbeat map x' = A x + B u measured by central differences, and the discrete
LQR on it: what :mod:`flapsim.bird.control.lateral` and :mod:`flapsim.bird.control.longitudinal`
share (each names its own state, its perturbations and its inputs)."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import scipy.linalg

from flapsim.bird.flight import cycle
from flapsim.bird.flight.dove_flight import DoveFlight, FlightConfig
from flapsim.core.errors import InputError, SimulationError


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
    return lqr_q(A, B, Q, r)


def lqr_q(A: np.ndarray, B: np.ndarray, Q: np.ndarray, r: float) -> np.ndarray:
    """K of the discrete LQR, u = -K x, for the state cost ``Q`` and each input costing ``r``."""
    R = r * np.eye(B.shape[1])
    X = scipy.linalg.solve_discrete_are(A, B, Q, R)
    return np.linalg.solve(R + B.T @ X @ B, B.T @ X @ A)


#: The largest input either regulator asks, in steps (10 deg of twist, 20 % of a stroke).
U_MAX = 10.0


@dataclass(frozen=True)
class MapRegulator:
    """A once-a-beat regulator on a measured map: dP = directions^T clip(-K (x - x_target),
    +-:data:`U_MAX`)."""

    K: np.ndarray
    directions: np.ndarray
    A: np.ndarray
    B: np.ndarray

    @property
    def open_loop_radius(self) -> float:
        """The largest |eigenvalue| of A: > 1, a disturbance grows every wingbeat."""
        return float(np.abs(np.linalg.eigvals(self.A)).max())

    @property
    def closed_loop_radius(self) -> float:
        return float(np.abs(np.linalg.eigvals(self.A - self.B @ self.K)).max())

    def offset(self, x: np.ndarray, x_target: np.ndarray) -> np.ndarray:
        """The wingbeat-parameter change (n_params,) for state ``x`` against ``x_target``."""
        u = np.clip(-self.K @ (x - x_target), -U_MAX, U_MAX)
        return u @ self.directions


def settled_twin(fl: DoveFlight, P0: np.ndarray, cfg: FlightConfig, wingbeats: int,
                 name: str, r: float) -> DoveFlight:
    """A twin of ``fl`` (its own state untouched) flown ``wingbeats`` of ``P0`` from ``cfg``'s
    start, where the ``name`` regulator's map is measured; ``r`` (its input cost) checked > 0."""
    if not (np.isfinite(r) and r > 0):
        raise InputError(f"the {name} regulator's input cost must be > 0, got {r!r}")
    tw = fl.twin(None)
    tw.reset(cfg, P0)
    for _ in range(wingbeats):
        cycle.fly_cycle(tw, None, P0, tw.ref)
    return tw


def gain(A: np.ndarray, B: np.ndarray, r: float, state_scale: np.ndarray, name: str) -> np.ndarray:
    """:func:`lqr`, its failure a one-line error naming the ``name`` regulator."""
    try:
        return lqr(A, B, r, state_scale)
    except (np.linalg.LinAlgError, ValueError) as e:
        raise SimulationError(f"no {name} regulator for this dove's map ({e}): fly it with "
                              f"{name} = \"off\"") from None
