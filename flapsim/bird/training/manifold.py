"""The control manifold of phase 2 (the flight paper, sec. 5.2): the wingbeat change dP as a
quadratic function of the steering alpha and elevation beta asked, fitted to discovered
wingbeats, so that phase 2 can draw wingbeats beyond the examples' extremes."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from flapsim.core.errors import InputError


def _features(alpha: np.ndarray, beta: np.ndarray) -> np.ndarray:
    a, b = np.atleast_1d(alpha), np.atleast_1d(beta)
    return np.stack([np.ones_like(a), a, b, a * a, a * b, b * b], axis=1)


@dataclass(frozen=True)
class Manifold:
    """dP as a quadratic function of (alpha, beta), fitted to discovered wingbeats."""

    coef: np.ndarray
    """(6, 29) coefficients of (1, a, b, a^2, ab, b^2)."""
    alpha_range: tuple[float, float]
    """(min, max) alpha of the examples (2nd and 98th percentiles), rad."""
    beta_range: tuple[float, float]
    """(min, max) beta of the examples, rad."""
    residual: np.ndarray
    """(n, 29) residuals of the fit (noise added to drawn wingbeats)."""

    @classmethod
    def fit(cls, ws: WingbeatSet) -> Manifold:
        if len(ws.dP) < 12:
            raise InputError(f"the manifold fit needs >= 12 examples, got {len(ws.dP)}")
        A = _features(ws.alpha, ws.beta)
        coef, *_ = np.linalg.lstsq(A, ws.dP, rcond=None)
        res = ws.dP - A @ coef
        return cls(coef, (float(np.quantile(ws.alpha, 0.02)), float(np.quantile(ws.alpha, 0.98))),
                   (float(np.quantile(ws.beta, 0.02)), float(np.quantile(ws.beta, 0.98))), res)

    def evaluate(self, alpha: float, beta: float) -> np.ndarray:
        """dP on the manifold; beyond the fitted range, continued along its tangent."""
        a0 = float(np.clip(alpha, *self.alpha_range))
        b0 = float(np.clip(beta, *self.beta_range))
        f0 = _features(a0, b0)[0] @ self.coef
        # gradient of the quadratic at the clipped point
        da = self.coef[1] + 2 * a0 * self.coef[3] + b0 * self.coef[4]
        db = self.coef[2] + a0 * self.coef[4] + 2 * b0 * self.coef[5]
        return f0 + (alpha - a0) * da + (beta - b0) * db

    def draw_beyond(self, rng: np.random.Generator, scale: float) -> np.ndarray:
        """A wingbeat past the examples' steering or elevation extremes (up to ``scale``
        times the largest one), with a residual of the fit as natural variation."""
        amax = max(abs(self.alpha_range[0]), abs(self.alpha_range[1]))
        bmax = max(abs(self.beta_range[0]), abs(self.beta_range[1]))
        if rng.random() < 0.5:
            a = rng.choice([-1.0, 1.0]) * amax * (1 + (scale - 1) * rng.random())
            b = rng.uniform(*self.beta_range)
        else:
            a = rng.uniform(*self.alpha_range)
            b = rng.choice([-1.0, 1.0]) * bmax * (1 + (scale - 1) * rng.random())
        return self.evaluate(a, b) + self.residual[rng.integers(len(self.residual))]


@dataclass(frozen=True)
class WingbeatSet:
    """Example wingbeats with their steering and elevation (the capture, or discovered ones)."""

    dP: np.ndarray
    """(n, 29) wingbeat minus P0."""
    alpha: np.ndarray
    """(n,) steering per wingbeat, rad (+ left)."""
    beta: np.ndarray
    """(n,) elevation per wingbeat, rad (+ up)."""
