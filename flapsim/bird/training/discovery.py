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

from flapsim.bird.control.controller import WingbeatController
from flapsim.bird.control.database import ChunkResult, load_database, read_header
from flapsim.bird.control.regression import Regressor
from flapsim.bird.control.targets import SteerTarget, trim_of_base_flight
from flapsim.bird.flight import cycle
from flapsim.bird.training.sampling import (
    SampleWorker,
    SamplingConfig,
    StoredConfig,
    collect_chunk,
    sample_fields,
)
from flapsim.core.errors import InputError, SimulationError
from flapsim.core.io import file_sha256


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
        if not config.db:
            raise InputError("phase 2 needs the phase-1 database (--from DB)")
        self.config = config

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
