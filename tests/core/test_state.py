"""Snapshots: restoring a state replays the run bit for bit."""

import mujoco
import numpy as np
import pytest

from flapsim.core import state
from flapsim.core.errors import InputError
from flapsim.core.loading import load_model

XML = """<mujoco><option timestep="0.002"/><worldbody><body pos="0 0 1"><freejoint/>
<geom type="box" size=".1 .05 .02" mass="1"/><body pos=".1 0 0"><joint axis="0 1 0"/>
<geom type="capsule" fromto="0 0 0 .2 0 0" size=".01" mass=".1"/></body></body></worldbody>
<actuator><motor joint="0" gear="1"/></actuator></mujoco>""".replace('joint="0"', 'joint="j"')


def _model():
    return load_model(XML.replace('<joint axis', '<joint name="j" axis'), is_xml=True)


def test_restore_replays_exactly():
    m = _model()
    d = mujoco.MjData(m)
    d.qvel[:] = np.linspace(-1, 1, m.nv)
    for _ in range(50):
        mujoco.mj_step(m, d)
    snap = state.save(m, d)
    d.ctrl[:] = 0.3
    run1 = []
    for _ in range(100):
        mujoco.mj_step(m, d)
        run1.append(d.qpos.copy())
    state.restore(m, d, snap)
    assert d.ctrl[0] == 0.0 and d.time == snap.time  # controls are part of the snapshot
    d.ctrl[:] = 0.3
    run2 = []
    for _ in range(100):
        mujoco.mj_step(m, d)
        run2.append(d.qpos.copy())
    assert np.array_equal(np.array(run1), np.array(run2))  # bit-identical replay


def test_snapshot_of_another_model_is_refused():
    m = _model()
    other = load_model("<mujoco><worldbody><body><freejoint/><geom size='.1'/></body>"
                       "</worldbody></mujoco>", is_xml=True)
    snap = state.save(other, mujoco.MjData(other))
    with pytest.raises(InputError, match="nq="):
        state.restore(m, mujoco.MjData(m), snap)
