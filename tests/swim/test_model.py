"""The swimmer model: body numbers from the paper, polygons, floating and sinking."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from flapsim.swim.model import SEGMENTS, Swimmer, SwimmerParams, swimmer_polygons


def test_body_matches_the_paper():
    sw = Swimmer(SwimmerParams(lung_volume_l=0.0))
    m = sw.model
    assert m.nv == 39  # the paper: 39 DOF
    assert len(SEGMENTS) == 16 and m.nbody == 17  # 16 segments + world
    # 16 anatomical joints: the free root, 7 balls, and elbows/wrists/knees/ankles
    assert sum(1 for j in range(m.njnt) if m.jnt_type[j] == mujoco.mjtJoint.mjJNT_BALL) == 7
    assert sw.mass == pytest.approx(89.57, abs=1e-3)  # paper; masses written to 7 digits
    # cadaveric density 1.044 g/mL: volume = mass / density (rounding of box sizes ~1e-4)
    assert sw.volume == pytest.approx(89.57 / 1044.0, rel=1e-4)
    assert m.nu == 33  # a PD muscle (motor) on every non-root dof


def test_lungs_add_volume_only():
    a = Swimmer(SwimmerParams(lung_volume_l=0.0))
    b = Swimmer(SwimmerParams(lung_volume_l=3.0))
    assert b.volume - a.volume == pytest.approx(3e-3, rel=1e-6)  # exactly the lung volume
    assert b.mass == pytest.approx(a.mass, abs=1e-9)
    # the paper's "buoyancy of 91 kg" at 3 L is reproduced with sea water (1025 kg/m^3)
    assert b.volume * 1025.0 == pytest.approx(91.0, abs=0.1)


def test_polygons_cover_the_boxes():
    sw = Swimmer(SwimmerParams(lung_volume_l=0.0, body_shape="box"))
    m = sw.model
    full = swimmer_polygons(m, patch_length=0.12, hide_joint_faces=False)
    boxes = sum(8 * (h[0] * h[1] + h[1] * h[2] + h[0] * h[2])
                for h in (m.geom_size[mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, s)]
                          for s in SEGMENTS))
    assert full.area.sum() == pytest.approx(boxes, rel=1e-12)  # patches tile each face
    hidden = sw.polygons.area.sum()
    # joints hide end faces: the hidden part is 5-25% of the box surface (plausible range
    # for end-to-end segments; the exact value depends on cross sections)
    assert 0.05 < 1 - hidden / boxes < 0.25
    # forward vectors lie in each polygon's plane, and along the longer side of its face
    assert np.abs(np.einsum("ij,ij->i", full.normal, full.forward)).max() < 1e-9
