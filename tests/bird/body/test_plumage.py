"""The dove's looks are display-only: the drawing model's added geoms have no mass, no
contact and no force, the simulated model is not dressed at all."""

import mujoco
import numpy as np

from flapsim.bird.body.model import Dove, build_xml
from flapsim.bird.body.plumage import COLLAR_RGBA, OUTER_RECTRICES, dress
from flapsim.core.loading import load_model


def _names(m, kind=mujoco.mjtObj.mjOBJ_GEOM, n=None):
    return [mujoco.mj_id2name(m, kind, i) for i in range(m.ngeom if n is None else n)]


def test_dressing_adds_display_only_geoms():
    dove = Dove.load()
    plain = load_model(build_xml(dove.params, twist="tree"), is_xml=True)
    shown, _ = dove.drawing()
    added = [g for g in range(shown.ngeom)
             if _names(shown)[g] not in set(_names(plain))]
    names = {_names(shown)[g] for g in added}
    # the collar and a white tip on each side's outer rectrices
    assert names == {"collar"} | {f"{s}_r{k}_tip" for s in "lr" for k in OUTER_RECTRICES}
    for g in added:
        assert shown.geom_contype[g] == 0 and shown.geom_conaffinity[g] == 0
        assert shown.geom_group[g] == 1
        assert shown.geom_type[g] != mujoco.mjtGeom.mjGEOM_MESH  # the force engine's polygons
    g = mujoco.mj_name2id(shown, mujoco.mjtObj.mjOBJ_GEOM, "collar")
    np.testing.assert_allclose(shown.geom_rgba[g], COLLAR_RGBA)
    # no mass, no inertia: every body's the same as undressed, to the bit
    assert np.array_equal(shown.body_mass, plain.body_mass)
    assert np.array_equal(shown.body_inertia, plain.body_inertia)
    assert np.array_equal(shown.body_ipos, plain.body_ipos)
    # no force: the dressed and the plain model step alike, to the bit, from a tumbling
    # state (gravity, joint dampers and springs; a contact or a mass would change it)
    d0, d1 = mujoco.MjData(plain), mujoco.MjData(shown)
    for d in (d0, d1):
        d.qvel[:] = np.linspace(-2.0, 2.0, plain.nv)
        d.qpos[2] = 0.05  # near the ground: a geom that collided would touch it
    for _ in range(200):
        mujoco.mj_step(plain, d0)
        mujoco.mj_step(shown, d1)
    assert d1.ncon == d0.ncon
    assert np.array_equal(d0.qpos, d1.qpos) and np.array_equal(d0.qvel, d1.qvel)


def test_the_simulated_dove_is_not_dressed():
    dove = Dove.load()
    assert "collar" not in _names(dove.model)
    assert dove.model.ngeom == load_model(build_xml(dove.params), is_xml=True).ngeom


def test_dress_is_idempotent_on_colours_only():
    xml = build_xml(Dove.load().params, twist="tree")
    once = load_model(dress(xml), is_xml=True)
    # the sky, the ground's 2 m grid, the sun's shadow
    assert once.light_castshadow[0] == 1
    assert once.mat_texuniform[mujoco.mj_name2id(once, mujoco.mjtObj.mjOBJ_MATERIAL, "grid")] == 1
