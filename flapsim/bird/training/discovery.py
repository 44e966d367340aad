"""Phase 2 of the flight paper's resampling (sec. 5.2): control strategy discovery.

1. **Discovery.** The phase-1 controller flies many random steering/elevation tasks: from a
   random state (drawn as in phase 1, with its pre-simulation wingbeat) it is asked to steer
   by alpha and climb by beta in one wingbeat (:class:`~flapsim.bird.control.targets.SteerTarget`)
   with (alpha, beta) uniform over a range wider than the phase-1 data reach. Each task
   gives a sample (S, dS, dP, alpha, beta) measured, like phase 1, against the reference
   wingbeat from the same state: these are wingbeats the controller actually uses.
2. **Resampling.** The discovered samples replace the capture as phase 1's examples: the
   4 x 4 (alpha, beta) bins and per-joint PCA ellipses are fitted to them, and a smaller,
   well-spread database is sampled from them (:class:`~flapsim.bird.training.sampling.SampleWorker`
   with ``source`` = the discovery database).
3. **Extrapolation.** :class:`Manifold` fits the discovered wingbeats as a smooth function
   of (alpha, beta) (quadratic, least squares) and draws a share of the new samples along
   it beyond the discovered extremes (continued linearly past them); every such sample is
   simulated like any other, so the database holds only what the bird really did.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from flapsim.bird.control.database import ChunkResult
from flapsim.bird.flight import cycle
from flapsim.bird.training.sampling import (
    SampleWorker,
    SamplingConfig,
    StoredConfig,
    WingbeatSet,
    collect_chunk,
    file_sha256,
    sample_fields,
)
from flapsim.core.errors import InputError, SimulationError


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
class DiscoveryConfig(StoredConfig):
    """Every parameter of a discovery run (phase 2, step 1)."""

    kind = "discovery configuration"

    seed: int = 0
    """Base seed: task i draws from ``default_rng([seed, i])``."""
    db: str = ""
    """The phase-1 database the controller regresses over."""
    method: str = "knn"
    """Regression: ``knn`` (paper) or ``lwlr``."""
    k: int = 0
    """Neighbours (0: the method's default share of the database,
    :data:`~flapsim.bird.control.regression.DEFAULT_K_SHARE`)."""
    alpha_max_deg: float = 30.0
    """Steering asked within +-this per wingbeat, deg."""
    beta_max_deg: float = 15.0
    """Elevation asked within +-this per wingbeat, deg."""
    sampling: dict | None = None
    """The phase-1 sampling parameters (pre-states, tail bias, table); default: the database's."""


class DiscoveryWorker:
    """Runs the phase-1 controller on random steering tasks (one task = one sample)."""

    def __init__(self, config: DiscoveryConfig) -> None:
        from flapsim.bird.control.controller import WingbeatController
        from flapsim.bird.control.database import load_database
        from flapsim.bird.control.regression import Regressor
        from flapsim.bird.control.targets import trim_of_base_flight

        if not config.db:
            raise InputError("phase 2 needs the phase-1 database (--from DB)")
        self.config = config
        from flapsim.bird.control.database import read_header

        scfg = config.sampling or read_header(config.db).get("config") or {}
        self.sampler = SampleWorker(SamplingConfig.from_dict(scfg) if scfg else SamplingConfig())
        db = load_database(config.db, model_hash=self.sampler.dove.hash(), require_finalized=True)
        self.db_header = db.header
        reg = Regressor(db.arrays["dS"], db.arrays["dP"], k=config.k or None, method=config.method)
        self.controller = WingbeatController(self.sampler.flight, reg, self.sampler.P0,
                                             self.sampler.lo, self.sampler.hi)
        self.trim = trim_of_base_flight(self.sampler.flight, self.sampler.P0)

    def header(self) -> dict:
        h = self.sampler.header()
        h["kind"] = "discovery"
        h["phase1_model_hash"] = self.db_header.get("model_hash")
        h["phase1_sha256"] = file_sha256(self.config.db)
        return h

    def close(self) -> None:
        self.sampler.close()

    def sample(self, index: int) -> tuple[dict[str, np.ndarray] | None, str]:
        from flapsim.bird.control.targets import SteerTarget

        c = self.config
        rng = np.random.default_rng([c.seed, index])
        sp = self.sampler
        pre = sp.pre_state(rng)
        dP_pre = sp.draw_wingbeat(rng)
        if dP_pre is None:
            return None, "out_of_range"
        alpha = np.radians(c.alpha_max_deg) * (2 * rng.random() - 1)
        beta = np.radians(c.beta_max_deg) * (2 * rng.random() - 1)
        fl = sp.flight
        try:
            start = cycle.fly_cycle(fl, pre, sp.P0 + dP_pre, sp.ref).snapshot
            S = fl.reduced_state()
            step = self.controller.choose(SteerTarget(self.trim, alpha, beta), start)
        except SimulationError:
            return None, "diverged"
        return sample_fields(S, step.P - sp.P0, step.reference, step.end)

    def run_chunk(self, start: int, stop: int) -> ChunkResult:
        return collect_chunk(self.sample, start, stop)
