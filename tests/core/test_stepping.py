"""Divergence is reported with a one-line error instead of MuJoCo's silent reset."""

import mujoco
import numpy as np
import pytest

from flapsim.core.callbacks import register
from flapsim.core.errors import SimulationError
from flapsim.core.loading import load_model
from flapsim.core.stepping import step

XML = """<mujoco><option timestep="0.01"/><worldbody><body><joint type="hinge"/>
  <geom size=".1" mass="1"/></body></worldbody></mujoco>"""


def test_healthy_steps_pass_and_advance_time():
    m = load_model(XML, is_xml=True)
    d = mujoco.MjData(m)
    step(m, d, 10)
    assert d.time == pytest.approx(0.1)


def test_exploding_force_is_reported():
    m = load_model(XML, is_xml=True)
    d = mujoco.MjData(m)

    def huge(model, data):
        data.qfrc_passive[0] += 1e300 * (1 + data.qvel[0] ** 2)

    with register(m, d, huge):
        with pytest.raises(SimulationError, match="diverged at t=.*lower the timestep"):
            step(m, d, 50, what="test pendulum")


def test_nan_state_is_reported():
    m = load_model(XML, is_xml=True)
    d = mujoco.MjData(m)
    d.qvel[0] = np.nan
    with pytest.raises(SimulationError, match="diverged"):
        step(m, d)
