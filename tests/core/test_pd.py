"""PD servos: the explicit torque and the affine-actuator form give the paper's eq. 6."""

import mujoco
import numpy as np
import pytest

from flapsim.core.errors import ModelError
from flapsim.core.loading import load_model
from flapsim.core.pd import affine_gains, pd_ctrl, pd_torque

XML = """<mujoco><worldbody><body><joint name="a" axis="0 0 1"/><geom size=".1" mass="1"/>
<body pos=".2 0 0"><joint name="b" axis="0 1 0"/><geom size=".05" mass=".2"/></body></body>
</worldbody><actuator>
<general joint="a" gaintype="fixed" biastype="affine" gainprm="1" biasprm="0 -10 -0.002"/>
<general joint="b" gaintype="fixed" biastype="affine" gainprm="1" biasprm="0 -3 -0.5"/>
</actuator></mujoco>"""


def test_pd_torque_formula():
    tau = pd_torque(10.0, 0.002, np.array([1.0, 0.5]), np.array([2.0, 0.0]),
                    np.array([0.5, 0.5]), np.array([1.0, 3.0]))
    assert np.allclose(tau, [10 * 0.5 + 0.002 * 1.0, 0.0 + 0.002 * -3.0])


def test_affine_actuator_equals_pd_torque():
    m = load_model(XML, is_xml=True)
    d = mujoco.MjData(m)
    kp, kv = affine_gains(m)
    assert np.allclose(kp, [10, 3]) and np.allclose(kv, [0.002, 0.5])
    rng = np.random.default_rng(0)
    d.qpos[:] = rng.normal(size=2)
    d.qvel[:] = rng.normal(size=2)
    qd, vd = rng.normal(size=2), rng.normal(size=2)
    d.ctrl[:] = pd_ctrl(kp, kv, qd, vd)
    mujoco.mj_forward(m, d)
    # same number up to float rounding of the two evaluation orders
    assert np.allclose(d.qfrc_actuator, pd_torque(kp, kv, qd, vd, d.qpos, d.qvel), atol=1e-12)


def test_non_pd_actuators_are_refused():
    m = load_model(XML.replace('biastype="affine"', 'biastype="none"', 1), is_xml=True)
    with pytest.raises(ModelError, match="not affine PD"):
        affine_gains(m)
