"""A fake sample worker for tests of the training machinery (database, executor,
``train``). It follows the sample-worker contract of :mod:`flapsim.bird.training.sampling`
without simulating anything. It lives in the package, not under tests/, because
worker processes (spawned, or Ray actors) must import it by name.
"""

from __future__ import annotations

import hashlib
import os
import time
from dataclasses import asdict, dataclass

import numpy as np

from flapsim.bird.control.database import ChunkResult


@dataclass(frozen=True)
class FakeConfig:
    """Parameters of the fake sampler."""

    seed: int = 0
    """random seed: sample i depends only on (seed, i)"""
    sigma: float = 1.0
    """scale of the fake samples"""
    reject_every: int = 7
    """indices divisible by this are rejected ('every7'), those ending in 3 too ('ends3')"""
    sleep_s: float = 0.0
    """seconds of pretend work per sample"""
    model: str = "fake-dove"
    """stands in for the model file: its hash is the model hash"""
    fail_at: int = -1
    """raise ValueError when this sample index is run (-1: never)"""

    def to_dict(self) -> dict:
        return asdict(self)

    @classmethod
    def from_dict(cls, d: dict) -> FakeConfig:
        return cls(**d)


class FakeWorker:
    """Deterministic fake samples: ``x`` (3,) and ``y`` (2, 2) from
    ``default_rng([seed, i])``."""

    builds = 0

    def __init__(self, config: FakeConfig) -> None:
        self.config = config
        FakeWorker.builds += 1
        self.serial = (os.getpid(), FakeWorker.builds)
        self.calls = 0

    def run_chunk(self, start: int, stop: int) -> ChunkResult:
        c = self.config
        self.calls += 1
        keep, xs, ys, rejected = [], [], [], {}
        for i in range(start, stop):
            if i == c.fail_at:
                raise ValueError(f"fake failure at sample {i}")
            if c.sleep_s:
                time.sleep(c.sleep_s)
            rng = np.random.default_rng([c.seed, i])
            x, y = c.sigma * rng.standard_normal(3), rng.standard_normal((2, 2))
            if i % c.reject_every == 0:
                rejected["every7"] = rejected.get("every7", 0) + 1
            elif i % 10 == 3:
                rejected["ends3"] = rejected.get("ends3", 0) + 1
            else:
                keep.append(i)
                xs.append(x)
                ys.append(y)
        res = ChunkResult(start=start, stop=stop, index=np.array(keep, np.int64),
                          arrays={"x": np.array(xs).reshape(-1, 3), "y": np.array(ys).reshape(-1, 2, 2)},
                          rejected=rejected)
        res.worker = (*self.serial, self.calls)  # which worker object ran it (tests)
        return res

    def header(self) -> dict:
        return {"model_hash": hashlib.sha256(self.config.model.encode()).hexdigest()[:12],
                "reference": [0.1, 0.25, 1.0 / 3.0]}


def expected_samples(config: FakeConfig, n: int) -> np.ndarray:
    """The indices of the first ``n`` accepted fake samples."""
    out, i = [], 0
    while len(out) < n:
        if i % config.reject_every and i % 10 != 3:
            out.append(i)
        i += 1
    return np.array(out, np.int64)
