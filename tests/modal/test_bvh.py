"""BVH export re-reads with the same joint angles."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from flapsim.core.errors import DataFileError, ModelError
from flapsim.core.loading import load_model
from flapsim.modal.animate import animate
from flapsim.modal.bvh import bvh_to_qpos, read_bvh, write_bvh
from flapsim.modal.gaits import GAITS, plan_gait, resolve_model


@pytest.mark.parametrize("gait", ["trot", "jump"])
def test_bvh_round_trip(tmp_path, gait):
    g = GAITS[gait]
    model, _ = resolve_model(g.model)
    plan = plan_gait(model, g)
    anim = animate(model, plan.analysis.rest_qpos, plan.components, np.linspace(0, 0.5, 16))
    path = tmp_path / "g.bvh"
    n = write_bvh(path, model, anim.qpos, 1 / 30)
    assert n == model.nv  # one channel per dof: 6 root + one per hinge
    bvh = read_bvh(path)
    assert bvh.motion.shape == (16, model.nv)
    assert bvh.frame_time == pytest.approx(1 / 30, rel=1e-7)
    q = bvh_to_qpos(bvh, model)
    # Angles are written with 6 decimals of a degree: 5e-7 deg = 8.7e-9 rad round-off;
    # positions 6 decimals of a cm = 1e-8 m.
    hinge = np.ones(model.nq, bool)
    hinge[:7] = False
    assert np.abs(q[:, hinge] - anim.qpos[:, hinge]).max() < 1e-8
    assert np.abs(q[:, :3] - anim.qpos[:, :3]).max() < 1e-8
    # Root orientation: angle between the quaternions (sign-free), same round-off.
    dots = np.abs(np.sum(q[:, 3:7] * anim.qpos[:, 3:7], axis=1))
    assert np.all(2 * np.arccos(np.clip(dots, 0, 1)) < 1e-7)
    # The same world poses: every body where it was.
    d1, d2 = mujoco.MjData(model), mujoco.MjData(model)
    d1.qpos[:], d2.qpos[:] = anim.qpos[7], q[7]
    mujoco.mj_kinematics(model, d1)
    mujoco.mj_kinematics(model, d2)
    assert np.abs(d1.xpos - d2.xpos).max() < 1e-7


def test_bvh_offsets_are_the_skeleton(tmp_path):
    model, _ = resolve_model("human")
    path = tmp_path / "h.bvh"
    write_bvh(path, model, model.qpos0[None, :], 0.1)
    bvh = read_bvh(path)
    # OFFSETs in cm: the shank hangs 0.42 m below the thigh.
    np.testing.assert_allclose(bvh.offsets["shank_l"], [0.0, 0.0, -42.0], atol=1e-6)
    assert bvh.joints[0] == "pelvis" and len(bvh.joints) == model.nbody - 1


def test_bvh_refuses_oblique_axes_and_bad_files(tmp_path):
    xml = """<mujoco><worldbody><body><freejoint/><geom size="0.1"/>
      <body pos="0 0 0.2"><joint name="odd" axis="1 1 0"/><geom size="0.05"/></body>
    </body></worldbody></mujoco>"""
    model = load_model(xml, is_xml=True)
    with pytest.raises(ModelError, match="odd"):
        write_bvh(tmp_path / "x.bvh", model, model.qpos0[None, :], 0.1)
    assert not (tmp_path / "x.bvh").exists()  # nothing half-written
    bad = tmp_path / "bad.bvh"
    bad.write_text("HIERARCHY\nROOT a\n{\nOFFSET 0 0 0\nCHANNELS 1 Xrotation\n}\n"
                   "MOTION\nFrames: 2\nFrame Time: 0.1\n1.0\n")
    with pytest.raises(DataFileError, match="expected 2 frames"):
        read_bvh(bad)
