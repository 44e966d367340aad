"""LWLR's density-following neighbourhood (``Regressor(k_dense=...)``): k_dense neighbours
where a request lies among densely packed samples, k where they are sparse."""

import numpy as np
import pytest

from flapsim.bird.body.model import Dove
from flapsim.bird.control.controller import load_controller
from flapsim.bird.control.regression import DENSE_QUANTILES, Regressor
from flapsim.bird.flight.dove_flight import DoveFlight
from flapsim.core.errors import InputError


@pytest.fixture(scope="module")
def cloud():
    """A Gaussian cloud of requests (dense at its centre) and a smooth nonlinear map to 29
    wingbeat parameters."""
    rng = np.random.default_rng(3)
    dS = rng.normal(size=(3000, 8)) * np.array([0.1, 0.1, 0.3, 0.2, 0.2, 2.0, 3.0, 2.0])
    M = rng.normal(size=(8, 29))
    dP = np.tanh(dS @ M * 0.2) + 0.1 * (dS[:, :1] ** 2)
    return dS, dP


def test_dense_radii_are_the_brute_force_quantiles(cloud):
    # the samples' own distance to their k_dense-th neighbour (themselves excluded), from all
    # pairwise distances in the regression's weighted units, over the same fixed subset
    dS, dP = cloud
    r = Regressor(dS, dP, k=200, method="lwlr", k_dense=30)
    X = dS * r.sqrt_w
    sub = np.random.default_rng(0).choice(len(dS), min(len(dS), 2000), replace=False)
    A = X[sub]
    d2 = (A * A).sum(1)[:, None] + (X * X).sum(1)[None, :] - 2.0 * A @ X.T
    d = np.sqrt(np.maximum(d2, 0.0))
    kth = np.sort(d, axis=1)[:, 30]  # column 0 is the sample itself
    np.testing.assert_allclose(r.dense_radii, np.quantile(kth, DENSE_QUANTILES), rtol=1e-9)


def test_the_neighbourhood_follows_the_density(cloud):
    dS, dP = cloud
    r = Regressor(dS, dP, k=200, method="lwlr", k_dense=30)
    # the cloud's centre is denser than 90 % of its samples: k_dense; 4 sigma out: k
    assert r.neighbourhood(np.zeros(8)) == 30
    assert r.neighbourhood(4.0 * dS.std(axis=0)) == 200
    # in between, between the two, and growing outwards
    ks = [r.neighbourhood(f * dS.std(axis=0)) for f in np.linspace(0.0, 4.0, 41)]
    assert all(30 <= k <= 200 for k in ks) and any(30 < k < 200 for k in ks)
    assert ks == sorted(ks)


def test_the_fit_is_plain_lwlr_over_that_neighbourhood(cloud):
    # brute force: the same request answered by a fixed-k regression with k = the count chosen
    dS, dP = cloud
    r = Regressor(dS, dP, k=200, method="lwlr", k_dense=30)
    for f in (0.0, 0.8, 1.5, 3.0):
        x = f * dS.std(axis=0) * np.array([1, -1, 1, 1, -1, 1, -1, 1])
        k = r.neighbourhood(x)
        fixed = Regressor(dS, dP, k=k, method="lwlr")
        np.testing.assert_allclose(r.predict(x), fixed.predict(x), rtol=0, atol=1e-12)
    # k_dense = k is the fixed neighbourhood
    same = Regressor(dS, dP, k=200, method="lwlr", k_dense=200)
    plain = Regressor(dS, dP, k=200, method="lwlr")
    x = 0.5 * dS.std(axis=0)
    np.testing.assert_allclose(same.predict(x), plain.predict(x), rtol=0, atol=0)


def test_bad_k_dense_is_a_one_line_error(cloud):
    dS, dP = cloud
    for bad, method in ((300, "lwlr"), (-1, "lwlr"), (10, "knn")):
        with pytest.raises(InputError) as e:
            Regressor(dS, dP, k=200, method=method, k_dense=bad)
        assert "\n" not in str(e.value)


def test_the_default_is_half_a_percent_for_rigid_feathers_and_off_for_modal():
    fl = DoveFlight(Dove.load())
    try:
        ctl = load_controller(fl)
        n = ctl.regressor.n  # the samples and their mirror images
        assert ctl.regressor.k_dense == round(0.005 * n) and ctl.regressor.k == round(0.02 * n)
        lo, hi = ctl.regressor.dense_radii
        assert 0 < lo < hi
        # the paper's fixed k
        assert load_controller(fl, k_dense_share=0.0).regressor.dense_radii is None
        # k-NN has no dense neighbourhood, whatever the share
        assert load_controller(fl, method="knn").regressor.k_dense == 0
        assert load_controller(fl, method="knn", k_dense_share=0.01).regressor.k_dense == 0
        # the share stays within a smaller k
        assert load_controller(fl, k=50).regressor.k_dense == 50
        with pytest.raises(InputError, match="k_dense_share must be a share"):
            load_controller(fl, k_dense_share=-0.1)
    finally:
        fl.close()
    fl = DoveFlight(Dove.load(feathers="modal"))
    try:
        assert load_controller(fl).regressor.dense_radii is None
        ctl = load_controller(fl, k_dense_share=0.005)
        assert ctl.regressor.k_dense == round(0.005 * ctl.regressor.n)
    finally:
        fl.close()


@pytest.mark.parametrize("command", [["eval", "--scenario", "figure8-level"],
                                     ["fly", "--controller", "learned"]])
def test_the_cli_refuses_a_negative_k_dense_share(capsys, tmp_path, command):
    from flapsim.cli.main import main

    config = tmp_path / "dense.toml"
    config.write_text("[controller]\nk_dense_share = -1\n")
    assert main([*command, "--config", str(config)]) == 2
    err = capsys.readouterr().err.strip()
    assert "k_dense_share" in err and "\n" not in err
