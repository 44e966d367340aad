"""Phase 2 end to end on a tiny run: discovery tasks, then resampling around them."""

import json

import numpy as np
import pytest

from flapsim.bird.control.database import load_database
from flapsim.bird.training.manifold import Manifold, WingbeatSet
from flapsim.cli.main import main


def test_manifold_fits_a_quadratic_and_continues_along_its_tangent():
    rng = np.random.default_rng(0)
    a = rng.uniform(-0.2, 0.2, 200)
    b = rng.uniform(-0.1, 0.1, 200)
    coef = rng.normal(size=(6, 29))
    X = np.stack([np.ones_like(a), a, b, a * a, a * b, b * b], axis=1)
    m = Manifold.fit(WingbeatSet(X @ coef, a, b))
    # exact quadratic data: the fit is exact (round-off only)
    np.testing.assert_allclose(m.coef, coef, atol=1e-9)
    # beyond the range: value at the edge plus slope x distance (first-order continuation)
    a_hi = m.alpha_range[1]
    edge = m.evaluate(a_hi, 0.0)
    slope = coef[1] + 2 * a_hi * coef[3]
    np.testing.assert_allclose(m.evaluate(a_hi + 0.1, 0.0), edge + 0.1 * slope, atol=1e-9)


@pytest.mark.slow
def test_phase2_from_a_phase1_database(tmp_path, capsys):
    p1 = tmp_path / "p1.db"
    assert main(["train", "--samples", "24", "--workers", "1", "--seed", "3", "--out", str(p1),
                 "--no-progress", "--chunk-size", "8"]) == 0
    p2 = tmp_path / "p2.db"
    js = tmp_path / "p2.json"
    assert main(["train", "--phase", "2", "--from", str(p1), "--samples", "12", "--discovery",
                 "16", "--workers", "1", "--seed", "3", "--out", str(p2), "--json", str(js),
                 "--no-progress", "--chunk-size", "4"]) == 0
    disc = load_database(tmp_path / "p2.db.discovery.db", kind="dove-discovery")
    db = load_database(p2, kind="dove-phase2")
    assert disc.n == 16 and db.n == 12
    # the discovery used the phase-1 controller on this model, and phase 2 sampled around
    # what it discovered (its examples are the discovery's wingbeats)
    assert db.header["provenance"]["examples"] == 16
    assert db.header["config"]["source"].endswith("p2.db.discovery.db")
    s = json.loads(js.read_text())
    assert s["samples"] == 12 and s["discovery"]["samples"] == 16
    # each discovered sample is a real pair: (dS, dP) finite, alpha/beta in radians
    assert np.all(np.isfinite(disc.arrays["dS"])) and np.all(np.abs(disc.arrays["alpha"]) < 1.6)
    # rerunning the same command finds both files complete
    assert main(["train", "--phase", "2", "--from", str(p1), "--samples", "12", "--discovery",
                 "16", "--workers", "1", "--seed", "3", "--out", str(p2), "--no-progress",
                 "--chunk-size", "4"]) == 0
    assert "already complete" in capsys.readouterr().out


@pytest.mark.slow
def test_real_sampler_same_database_for_any_workers_and_backend(tmp_path):
    # the determinism the fake-worker tests check, with the dove itself: sample i depends
    # only on (seed, i), whichever process simulates it (and whatever it simulated before)
    from flapsim.bird.training.sampling import SampleWorker, SamplingConfig
    from flapsim.bird.training.train import train

    cfg = SamplingConfig(seed=21, pitch_deg=10.0, roll_deg=10.0)
    a, b = tmp_path / "one.db", tmp_path / "two.db"
    train(cfg, a, 10, SampleWorker, workers=1, chunk_size=3, progress=False, kind="dove-phase1")
    train(cfg, b, 10, SampleWorker, workers=2, chunk_size=3, progress=False, kind="dove-phase1")
    assert a.read_bytes() == b.read_bytes()
    assert load_database(a).n == 10
    # and on Ray actors (a private local instance)
    pytest.importorskip("ray", reason="Ray is not installed (pip install 'flapsim[cluster]')")
    c = tmp_path / "ray.db"
    train(cfg, c, 10, SampleWorker, workers=2, backend="ray", chunk_size=3, progress=False,
          kind="dove-phase1")
    assert c.read_bytes() == a.read_bytes()
