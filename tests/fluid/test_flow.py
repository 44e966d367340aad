"""Flow primitives against their closed forms."""

import numpy as np
import pytest

from flapsim.core.errors import InputError
from flapsim.fluid.flow import Breeze, FlowField, Gust, PythonField, Source, Uniform, Vortex


def test_uniform_and_set_uniform():
    f = FlowField([Uniform((1.0, 2.0, 3.0))])
    assert np.allclose(f.velocity(np.zeros((2, 3))), [[1, 2, 3], [1, 2, 3]])
    f.set_uniform((0, 0, -1))
    assert np.allclose(f.velocity(np.ones((1, 3))), [[0, 0, -1]])


def test_one_minus_cosine_gust_profile():
    f = FlowField([Gust(direction=(0, 2, 0), amplitude=3.0, start=1.0, duration=0.5)])
    p = np.zeros((1, 3))
    assert np.allclose(f.velocity(p, 0.99), 0)
    assert np.allclose(f.velocity(p, 1.25), [[0, 3.0, 0]])  # peak at mid-gust
    assert f.velocity(p, 1.125)[0, 1] == pytest.approx(1.5)  # 0.5 (1 - cos(pi/2)) * 3
    assert np.allclose(f.velocity(p, 1.51), 0)


def test_breeze_is_sinusoidal():
    f = FlowField([Breeze(direction=(1, 0, 0), amplitude=0.5, frequency=0.25)])
    assert f.velocity(np.zeros((1, 3)), 1.0)[0, 0] == pytest.approx(0.5)  # sin(pi/2)


def test_point_source_carries_its_volume_rate_through_a_sphere():
    q = 0.7
    f = FlowField([Source(position=(1, 1, 1), strength=q, core=1e-6)])
    rng = np.random.default_rng(0)
    d = rng.normal(size=(20000, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    r = 0.5
    v = f.velocity(np.array([1, 1, 1]) + r * d)
    # flux = mean radial speed * sphere area = Q (Monte Carlo over an isotropic field: exact)
    flux = np.mean(np.einsum("ij,ij->i", v, d)) * 4 * np.pi * r**2
    assert flux == pytest.approx(q, rel=1e-6)


def test_line_vortex_circulation_and_direction():
    gamma = 2.0
    f = FlowField([Vortex(position=(0, 0, 0), axis=(0, 0, 1), circulation=gamma, core=1e-6)])
    th = np.linspace(0, 2 * np.pi, 400, endpoint=False)
    r = 0.3
    pts = np.stack([r * np.cos(th), r * np.sin(th), np.full_like(th, 5.0)], axis=1)
    v = f.velocity(pts)
    tangent = np.stack([-np.sin(th), np.cos(th), np.zeros_like(th)], axis=1)
    circulation = np.mean(np.einsum("ij,ij->i", v, tangent)) * 2 * np.pi * r
    assert circulation == pytest.approx(gamma, rel=1e-9)  # counter-clockwise about +z
    assert np.allclose(v[:, 2], 0)


def test_python_field_is_added_and_checked():
    f = FlowField([Uniform((1, 0, 0)), PythonField(lambda p, t: np.tile([0, t, 0], (len(p), 1)))])
    assert np.allclose(f.velocity(np.zeros((3, 3)), 2.0), [[1, 2, 0]] * 3)
    bad = FlowField([PythonField(lambda p, t: np.zeros(2))])
    with pytest.raises(InputError, match="3x3"):
        bad.velocity(np.zeros((3, 3)))
    with pytest.raises(InputError, match="non-zero"):
        Gust(direction=(0, 0, 0)).pack()


def test_still_stops_every_primitive_in_place_and_restores_them():
    """Inside ``still()`` every primitive (compiled rows and Python fields) gives zero, in
    the same array a force kernel holds; after it, even when the block raises, the flow is
    what it was, to the bit."""
    f = FlowField([Uniform((1.0, 2.0, 0.5)), Gust((0, 1, 0), 3.0, 0.0, 1.0),
                   Breeze((1, 0, 0), 0.7, 0.3), Vortex((0, 0, 0), (0, 0, 1), 2.0),
                   PythonField(lambda p, t: np.tile([0.0, 0.0, 4.0], (len(p), 1)))])
    held = f.params  # what a compiled kernel was handed
    pts = np.array([[0.3, -0.2, 1.0], [2.0, 1.0, 0.0]])
    before = f.velocity(pts, 0.4)
    assert np.abs(before).max() > 1.0
    with f.still():
        assert f.params is held
        np.testing.assert_array_equal(f.velocity(pts, 0.4), np.zeros_like(pts))
    np.testing.assert_array_equal(f.velocity(pts, 0.4), before)
    with pytest.raises(RuntimeError):
        with f.still():
            raise RuntimeError("inside")
    np.testing.assert_array_equal(f.velocity(pts, 0.4), before)
