"""The passive-force dispatcher: isolation between models, errors, unregistering."""

import mujoco
import numpy as np
import pytest

from flapsim.core.callbacks import DISPATCHER, register
from flapsim.core.errors import ProviderError
from flapsim.core.loading import load_model
from flapsim.fluid.flow import FlowField, Uniform
from flapsim.fluid.surfaces import FluidParams, PolygonSet, SurfaceForces

XML = """<mujoco><option gravity="0 0 -9.81" timestep="0.002"/><worldbody>
  <body name="p" pos="0 0 1"><freejoint/><geom type="box" size="{s} {s} .002" mass="{m}"/>
  </body></worldbody></mujoco>"""


def make(size, mass, wind):
    m = load_model(XML.format(s=size, m=mass), is_xml=True)
    d = mujoco.MjData(m)
    d.qvel[3:] = [1.0, 2.0, 0.5]  # tumbling, so forces vary every step
    verts = np.array([[[-size, -size, 0], [size, -size, 0], [size, size, 0], [-size, size, 0]]])
    sf = SurfaceForces(m, PolygonSet.from_polygons(1, verts), ["flat_plate"], FluidParams(1.225),
                       FlowField([Uniform(wind)]))
    return m, d, sf


def run(m, d, n):
    out = []
    for _ in range(n):
        mujoco.mj_step(m, d)
        out.append(d.qpos.copy())
    return np.array(out)


def test_two_models_stepped_alternately_get_only_their_own_forces():
    ma, da, sa = make(0.1, 0.05, (2.0, 0, 0))
    mb, db, sb = make(0.2, 0.2, (0, -3.0, 1.0))
    with sa.register(da):
        alone_a = run(ma, da, 200)
    with sb.register(db):
        alone_b = run(mb, db, 200)
    ma2, da2, sa2 = make(0.1, 0.05, (2.0, 0, 0))
    mb2, db2, sb2 = make(0.2, 0.2, (0, -3.0, 1.0))
    with sa2.register(da2), sb2.register(db2):
        inter_a, inter_b = [], []
        for _ in range(200):
            mujoco.mj_step(ma2, da2)
            inter_a.append(da2.qpos.copy())
            mujoco.mj_step(mb2, db2)
            inter_b.append(db2.qpos.copy())
    # bit-identical: each data's callback reads and writes only its own arrays
    assert np.array_equal(np.array(inter_a), alone_a)
    assert np.array_equal(np.array(inter_b), alone_b)
    # and the forces matter (the runs differ from free fall)
    m0, d0, _ = make(0.1, 0.05, (2.0, 0, 0))
    assert np.abs(run(m0, d0, 200)[-1] - alone_a[-1]).max() > 1e-3


def test_provider_exception_names_the_provider():
    m, d, _ = make(0.1, 0.05, (0, 0, 0))

    def exploding(model, data):
        raise ValueError("bad coefficient")

    with register(m, d, exploding, name="my wind"):
        with pytest.raises(ProviderError, match="my wind.*bad coefficient"):
            mujoco.mj_step(m, d)


def test_python_and_compiled_providers_add_up_and_unregister():
    m, d, sf = make(0.1, 0.05, (2.0, 0, 0))
    mujoco.mj_forward(m, d)
    reg = sf.register(d)
    mujoco.mj_forward(m, d)
    fluid_only = d.qfrc_passive.copy()

    def push(model, data):
        data.qfrc_passive[2] += 1.5

    with register(m, d, push):
        mujoco.mj_forward(m, d)
        both = d.qfrc_passive.copy()
    assert both[2] - fluid_only[2] == pytest.approx(1.5)
    assert np.allclose(np.delete(both, 2), np.delete(fluid_only, 2))
    assert DISPATCHER.providers(d) == ["surface forces"]
    reg.remove()
    mujoco.mj_forward(m, d)
    assert np.all(d.qfrc_passive == 0)
    assert DISPATCHER.providers(d) == []


def test_nonfinite_force_is_reported_not_applied():
    m, d, sf = make(0.1, 0.05, (2.0, 0, 0))
    with sf.register(d):
        d.qvel[0] = np.nan
        mujoco.mj_forward(m, d)
        with pytest.raises(ProviderError, match="non-finite"):
            DISPATCHER.check(d)


def test_loading_a_model_while_a_python_provider_is_installed_works():
    m, d, _ = make(0.1, 0.05, (0, 0, 0))
    with register(m, d, lambda model, data: None):
        other = load_model(XML.format(s=0.3, m=1.0), is_xml=True)
        assert other.nbody == 2
        mujoco.mj_step(m, d)  # the callback is back in place
