"""The reference wingbeat (Fourier average of the capture) and the 29-parameter wingbeat."""

import numpy as np
import pytest

from flapsim.bird.body.params import MIRROR_PERM
from flapsim.bird.flight.capture import reference_capture
from flapsim.bird.flight.wingbeat import (
    N_PARAMS,
    ReferenceWingbeat,
    join,
    mirror_params,
    p0,
    reference_wingbeat,
    split,
    with_tail_bias,
)
from flapsim.core.errors import InputError


@pytest.fixture(scope="module")
def ref():
    return reference_wingbeat()


def test_reference_is_the_phase_aligned_average(ref):
    cap = reference_capture(with_mirror=True)
    mean = cap.cycle_matrix(96).mean(axis=0)
    fit = ref.angles(np.arange(96) / 96)
    # 8 harmonics of a smooth average: residual well under a degree
    assert np.abs(fit - mean).max() < np.radians(0.5)
    assert ref.period == pytest.approx(cap.durations.mean())
    # the average of a set and its mirror is left/right symmetric
    assert np.allclose(ref.coef, ref.coef[MIRROR_PERM], atol=1e-12)


def test_p0_is_the_reference_and_rates_are_derivatives(ref):
    t = np.linspace(0, ref.period, 50, endpoint=False)
    q, qd = ref.evaluate(p0(), t)
    assert np.allclose(q, ref.angles(t / ref.period))
    h = 1e-6
    q2, _ = ref.evaluate(p0(), t + h)
    # central difference error O(h^2 q''') and rounding 1e-10/h: 1e-3 rad/s is ample
    assert np.allclose((q2 - q) / h, qd, atol=1e-3 * np.abs(qd).max())


def test_scale_translate_timewarp_and_fit_roundtrip(ref):
    rng = np.random.default_rng(3)
    s = rng.uniform(0.8, 1.2, 14)
    t = rng.uniform(-0.1, 0.1, 14)
    p = join(s, t, 1.1)
    assert ref.duration(p) == pytest.approx(1.1 * ref.period)
    n = 64
    q, _ = ref.evaluate(p, np.arange(n) / n * ref.duration(p))
    back = ref.fit(q, ref.duration(p))
    assert np.allclose(back, p, atol=1e-9)  # exact model -> exact least-squares fit


def test_mirror_and_bias(ref):
    p = join(np.arange(14) + 1.0, np.arange(14) * 0.01, 1.0)
    m = mirror_params(p)
    s, t, w = split(m)
    assert np.array_equal(s, (np.arange(14) + 1.0)[MIRROR_PERM]) and w == 1.0
    assert np.array_equal(mirror_params(m), p)
    b = with_tail_bias(p0(), 17.0)
    assert split(b)[1][12] == pytest.approx(np.radians(17.0))


def test_bad_parameters_are_refused():
    with pytest.raises(InputError, match="29 parameters"):
        split(np.ones(28))
    bad = p0()
    bad[-1] = 0.0
    with pytest.raises(InputError, match="positive timewarp"):
        split(bad)
    assert N_PARAMS == 29


def test_from_capture_needs_cycles():
    cap = reference_capture()
    from dataclasses import replace

    empty = replace(cap, cycle_start=np.zeros(0), cycle_end=np.zeros(0), steering_deg=np.zeros(0),
                    elevation_deg=np.zeros(0), speed=np.zeros(0), mirrored=np.zeros(0, bool))
    with pytest.raises(InputError, match="no cycles"):
        ReferenceWingbeat.from_capture(empty)
