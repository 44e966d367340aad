"""A database whose samples repeat (a merge of overlapping sources made before they were
refused): LWLR's density-following neighbourhood must not divide by a zero radius spread."""

import numpy as np

from flapsim.bird.control.regression import Regressor


def test_lwlr_with_every_sample_tripled_predicts():
    rng = np.random.default_rng(0)
    dS, dP = rng.standard_normal((60, 8)), rng.standard_normal((60, 5))
    # each sample three times: every sample's 2nd neighbour (itself excluded) is at distance
    # 0, so both density radii are 0 (before: ZeroDivisionError on every request)
    reg = Regressor(np.repeat(dS, 3, axis=0), np.repeat(dP, 3, axis=0), k=120, method="lwlr",
                    k_dense=2)
    assert reg.dense_radii == (0.0, 0.0)
    # a request off every sample lies beyond the (zero) dense radius: the whole k, as a
    # request among the sparsest samples gets; one on a sample: the dense end
    assert reg.neighbourhood(dS[0] + 0.01) == 120 and reg.neighbourhood(dS[0]) == 2
    assert np.all(np.isfinite(reg.predict(dS[0] + 0.01)))
    # the same affine fit as the single copies over the same 40 distinct samples: tripling
    # every weight leaves a weighted least-squares solution unchanged (ridge scales with G's
    # trace, so it triples too); to rounding
    single = Regressor(dS, dP, k=40, method="lwlr")
    np.testing.assert_allclose(reg.predict(dS[0] + 0.01), single.predict(dS[0] + 0.01),
                               rtol=1e-9, atol=1e-12)
