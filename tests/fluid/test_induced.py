"""Induced flow's momentum theory and its inputs (flapsim.fluid.induced)."""

import numpy as np
import pytest

from flapsim.core.errors import InputError, ModelError
from flapsim.fluid.induced import MIN_SPEED, InducedFlow, induced_xml, momentum_downwash


def test_the_downwash_of_a_disk_lifting_in_forward_flight():
    # 2 N up through a 0.1 m^2 disk in a 10 m/s stream at sea level: w = F / (2 rho A V)
    # = 2 / (2 * 1.225 * 0.1 * 10) = 0.816 m/s down (V + w taken as 10 m/s: w is 0 here)
    w = momentum_downwash(0.0, 0.0, 2.0, -10.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.225, 0.1)
    assert np.allclose(w, (0.0, 0.0, -2.0 / (2 * 1.225 * 0.1 * 10.0)))
    # the force along the stream (drag) pushes no downwash
    assert np.allclose(momentum_downwash(0.5, 0.0, 0.0, -10.0, 0, 0, 0, 0, 0, 1.225, 0.1), 0.0)
    # hover: the speed through the disk is the downwash itself (floored at MIN_SPEED)
    w_h = np.sqrt(2.0 / (2 * 1.225 * 0.1))  # the hover value, w = sqrt(T / (2 rho A))
    w = momentum_downwash(0.0, 0.0, 2.0, 0.0, 0.0, 0.0, 0.0, 0.0, -w_h, 1.225, 0.1)
    assert w[2] == pytest.approx(-w_h)
    assert momentum_downwash(0.0, 0.0, 2.0, 0, 0, 0, 0, 0, 0, 1.225, 0.1)[2] == pytest.approx(
        -2.0 / (2 * 1.225 * 0.1 * MIN_SPEED))


def test_bad_induced_flow_inputs_are_refused():
    with pytest.raises(ModelError, match="tau"):
        induced_xml(("a",), tau_s=0.0)
    with pytest.raises(InputError, match="disk area"):
        InducedFlow(("a",), np.array([0, -1]), (0.0,), "trunk")
    with pytest.raises(InputError, match="polygon_group"):
        InducedFlow(("a",), np.array([0, 1]), (0.1,), "trunk")
    assert 'damping="0.1"' in induced_xml(("a",), tau_s=0.01, mass_kg=1e-3)
