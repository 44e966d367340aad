"""The gliding dove with its induced flow, against momentum theory."""

import numpy as np
import pytest

from flapsim.bird.body.model import wingspan
from flapsim.bird.body.params import DoveParams
from flapsim.bird.flight.dove_flight import AIR_DENSITY
from flapsim.bird.flight.glide import glide_tunnel
from flapsim.core.errors import InputError

SPEED = 10.0


def test_each_sides_downwash_is_the_momentum_value_of_its_force():
    # Glauert's actuator disk per side (half the span's disk, pi b^2 / 8): at steady state
    # the downwash is -F_perp / (2 rho A |V + w|); 25 time constants settle it to 1e-10, so
    # 1 % is the tolerance of the averaging window, not of the physics
    r = glide_tunnel(-2.0, SPEED, induced=True)
    area = np.pi * wingspan(DoveParams.load()) ** 2 / 8
    v = np.array([-SPEED, 0.0, 0.0])
    for g in range(2):
        f, w = r.wing_force_N[g], r.downwash_m_s[g]
        f_perp = f - (f @ v) / (v @ v) * v
        expected = -f_perp / (2 * AIR_DENSITY * area * np.linalg.norm(v + w))
        assert np.allclose(w, expected, rtol=0.01, atol=1e-4)
        assert w[2] < -0.1  # lift up, air down
    # the two sides mirror each other (y flips)
    assert np.allclose(r.downwash_m_s[0] * [1, -1, 1], r.downwash_m_s[1], atol=1e-9)


def _drag_at_weight(induced: bool) -> tuple[float, float]:
    pts = [glide_tunnel(p, SPEED, induced=induced) for p in (-2.0, 0.0, 2.0, 4.0)]
    lift = np.array([x.lift_N for x in pts])
    drag = np.array([x.drag_N for x in pts])
    assert np.all(np.diff(lift) > 0)  # below the stall: interpolation is safe
    weight = pts[0].weight_N
    assert lift[0] < weight < lift[-1]
    return float(np.interp(weight, lift, drag)), weight


def test_a_glide_at_10_m_s_pays_the_induced_drag_of_its_span():
    # induced drag k W^2 / (q pi b^2) with k ~ 1.2 for a bird wing (span efficiency ~0.83):
    # the drag at lift = weight with the downwash minus without it, within 30 %
    d_with, weight = _drag_at_weight(True)
    d_without, _ = _drag_at_weight(False)
    q = 0.5 * AIR_DENSITY * SPEED**2
    b = wingspan(DoveParams.load())
    expected = 1.2 * weight**2 / (q * np.pi * b**2)
    assert abs((d_with - d_without) - expected) <= 0.3 * expected


def test_a_dove_without_the_downwash_sees_none():
    r = glide_tunnel(0.0, SPEED, induced=False)
    assert np.all(r.downwash_m_s == 0.0)
    with pytest.raises(InputError, match="speed"):
        glide_tunnel(0.0, 0.0)
