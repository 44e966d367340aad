"""The controller's regression against brute force (no simulation)."""

import numpy as np
import pytest

from flapsim.bird.control.regression import PAPER_WEIGHTS, Regressor, default_k, idw_average, weight_vector
from flapsim.core.errors import InputError


def brute_force_knn(dS, dP, x, k, w):
    """Eq. 3-4 written out: every weighted squared distance, sort, inverse-distance average."""
    d = np.array([(x - s) @ np.diag(w) @ (x - s) for s in dS])
    order = np.argsort(d, kind="stable")[:k]
    wts = 1.0 / d[order]
    return (wts[:, None] * dP[order]).sum(axis=0) / wts.sum()


def test_knn_equals_brute_force_on_random_data():
    rng = np.random.default_rng(7)
    dS = rng.normal(size=(600, 8)) * np.array([0.1, 0.1, 0.3, 0.3, 0.3, 1.0, 1.0, 1.0])
    dP = rng.normal(size=(600, 29))
    w = weight_vector(PAPER_WEIGHTS)
    for k in (1, 3, 50):
        reg = Regressor(dS, dP, k=k, normalize=False)
        for _ in range(20):
            x = rng.normal(size=8) * 0.5
            # same numbers up to round-off of the kd-tree's distances (1e-12 relative)
            np.testing.assert_allclose(reg.predict(x), brute_force_knn(dS, dP, x, k, w), rtol=1e-9,
                                       atol=1e-12)


def test_normalized_weights_are_the_papers_over_each_spread():
    # normalize=True measures each dimension in units of its spread in the database:
    # the same as brute force with W_i = w_i / std_i^2
    rng = np.random.default_rng(8)
    dS = rng.normal(size=(500, 8)) * np.array([0.1, 0.2, 0.5, 1.0, 0.5, 2.0, 3.0, 4.0])
    dP = rng.normal(size=(500, 29))
    w = weight_vector(PAPER_WEIGHTS) / dS.std(axis=0) ** 2
    reg = Regressor(dS, dP, k=20, normalize=True)
    for _ in range(10):
        x = rng.normal(size=8)
        np.testing.assert_allclose(reg.predict(x), brute_force_knn(dS, dP, x, 20, w), rtol=1e-9,
                                   atol=1e-12)


def test_weights_are_the_papers_and_matter():
    np.testing.assert_array_equal(weight_vector(), [0.2, 0.2, 0.24, 0.24, 0.24, 0.4, 0.4, 0.4])
    # two samples: one off in pitch by 1, one off in angular velocity by 0.8; with w1 = 0.2
    # and w3 = 0.4 the pitch one is nearer (0.2 < 0.4 * 0.64 = 0.256)
    dS = np.zeros((2, 8))
    dS[0, 0] = 1.0
    dS[1, 5] = 0.8
    dP = np.eye(2, 29)
    reg = Regressor(dS, dP, k=1, normalize=False)
    np.testing.assert_array_equal(reg.predict(np.zeros(8)), dP[0])


def test_idw_average_is_eq4_and_exact_match_wins():
    d2 = np.array([1.0, 4.0])
    v = np.array([[1.0], [2.0]])
    # weights 1 and 1/4: (1 + 0.5) / 1.25 = 1.2
    assert idw_average(d2, v)[0] == pytest.approx(1.2)
    assert idw_average(np.array([0.0, 4.0]), v)[0] == 1.0


def test_default_k_is_half_a_percent():
    assert default_k(10000) == 50  # the paper's 50 of 10,000
    assert default_k(100) == 1 and default_k(10) == 1


def test_default_k_per_method():
    # k-NN keeps the paper's 0.5 %; LWLR's 9-coefficient fits take 2 % (the paper's sweep's
    # largest share), 4x as many: 2000 samples -> 10 and 40 neighbours
    rng = np.random.default_rng(0)
    dS, dP = rng.normal(size=(2000, 8)), rng.normal(size=(2000, 29))
    assert Regressor(dS, dP, method="knn").k == 10
    assert Regressor(dS, dP, method="lwlr").k == 40
    assert Regressor(dS, dP, k=7, method="lwlr").k == 7


def test_lwlr_recovers_a_linear_map_exactly():
    # on exactly linear data the weighted affine fit is exact (up to the small ridge):
    # k-NN averaging cannot do this away from the samples' mean
    rng = np.random.default_rng(3)
    A = rng.normal(size=(8, 29))
    dS = rng.normal(size=(400, 8))
    dP = dS @ A + 0.5
    reg = Regressor(dS, dP, k=60, method="lwlr", ridge=1e-9, normalize=False)
    x = rng.normal(size=8) * 0.3
    np.testing.assert_allclose(reg.predict(x), x @ A + 0.5, atol=1e-5)


def test_bad_inputs_are_one_line_errors():
    with pytest.raises(InputError):
        Regressor(np.zeros((3, 7)), np.zeros((3, 29)))
    with pytest.raises(InputError):
        Regressor(np.full((3, 8), np.nan), np.zeros((3, 29)))
    with pytest.raises(InputError):
        Regressor(np.zeros((3, 8)), np.zeros((3, 29)), method="ann")
    reg = Regressor(np.zeros((3, 8)), np.zeros((3, 29)))
    with pytest.raises(InputError):
        reg.predict(np.full(8, np.nan))


def test_mirror_samples_swap_sides_and_make_the_regression_mirror_symmetric():
    from flapsim.bird.control.regression import MIRROR_STATE, mirror_samples
    from flapsim.bird.flight.wingbeat import N_PARAMS, mirror_params, p0

    # one hand-made sample: left shoulder elevation scaled 1.1 (s index 0), right elbow
    # shifted 0.05 rad (DOF 6 + 3 -> t index 2 * 9 + 1), rolled 0.1 rad right wing down,
    # sliding left 0.2 m/s and yawing left 0.3 rad/s; its mirror is the right shoulder at 1.1,
    # the LEFT elbow at 0.05, rolled 0.1 left, sliding right, yawing right
    P0 = p0()
    dP = np.zeros((1, N_PARAMS))
    dP[0, 0], dP[0, 19] = 0.1, 0.05
    dS = np.array([[0.02, 0.1, 0.0, 0.2, 0.0, 0.0, 0.0, 0.3]])
    S2, P2 = mirror_samples(dS, dP, P0)
    np.testing.assert_array_equal(S2[0], dS[0])
    np.testing.assert_array_equal(S2[1], [0.02, -0.1, 0.0, -0.2, 0.0, -0.0, 0.0, -0.3])
    expect = np.zeros(N_PARAMS)
    expect[12], expect[7] = 0.1, 0.05  # right shoulder's scale (DOF 6), left elbow's shift (DOF 3)
    np.testing.assert_allclose(P2[1], expect, atol=1e-15)  # (1 + 0.1) - 1 round-off
    # over random samples, the regression over samples + mirrors answers a mirrored request
    # with the mirrored wingbeat (round-off only: the same neighbours, mirrored)
    rng = np.random.default_rng(3)
    dS = rng.normal(size=(800, 8)) * np.array([0.15, 0.2, 1.0, 2.0, 1.0, 3.0, 1.5, 4.0])
    dP = rng.normal(size=(800, N_PARAMS)) * 0.05
    reg = Regressor(*mirror_samples(dS, dP, P0), k=40, method="lwlr")
    lopsided = Regressor(dS, dP, k=40, method="lwlr")
    worst_lopsided = 0.0
    for _ in range(10):
        x = rng.normal(size=8) * np.array([0.05, 0.1, 0.3, 0.5, 0.3, 1.0, 0.5, 1.0])
        a = reg.predict(x)
        b = mirror_params(P0 + reg.predict(x * MIRROR_STATE)) - P0
        np.testing.assert_allclose(b, a, atol=1e-9)
        a = lopsided.predict(x)
        b = mirror_params(P0 + lopsided.predict(x * MIRROR_STATE)) - P0
        worst_lopsided = max(worst_lopsided, float(np.abs(a - b).max()))
    assert worst_lopsided > 1e-3  # without the mirrors random samples are not symmetric


def test_lwlr_answer_noise_falls_as_one_over_root_k():
    # why LWLR's default k is 2 % rather than 0.5 %: the answer's own noise. With dP pure
    # noise (sd 1) around dS, the local fit's value at the query is a kernel-weighted mean
    # of k samples (the kernel scales with the neighbourhood, so its effective count is a
    # fixed share of k), and its spread across independent databases falls as 1/sqrt(k):
    # 4x the neighbours, half the noise. 40 draws of 20,000 samples; tolerance 0.1 for
    # the ~11 % sampling error of a standard deviation from 40 draws (both k's share draws)
    sd = {100: [], 400: []}
    for seed in range(40):
        rng = np.random.default_rng(seed)
        dS = rng.uniform(-1.0, 1.0, size=(20000, 8))
        dP = rng.normal(size=(20000, 4))
        for k in sd:
            sd[k].append(Regressor(dS, dP, k=k, method="lwlr").predict(np.zeros(8)))
    ratio = np.std(sd[400], axis=0) / np.std(sd[100], axis=0)
    assert np.mean(ratio) == pytest.approx(0.5, abs=0.1)
