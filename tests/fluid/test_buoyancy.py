"""Ellipsoid buoyancy: exact cap geometry, the compiled kernel, and floating bodies."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest
from scipy.integrate import quad
from scipy.optimize import brentq
from scipy.spatial.transform import Rotation

from flapsim.core.callbacks import DISPATCHER
from flapsim.core.errors import InputError, ModelError
from flapsim.core.loading import load_model
from flapsim.fluid.buoyancy import (
    Buoyancy,
    BuoyancyParams,
    cap_fraction,
    geom_volume,
    submerged,
)


def _slice_reference(center, R, semi, level):
    """Submerged volume and centroid by integrating horizontal slices (independent of the
    unit-sphere map): the ellipsoid is (x-c)^T M (x-c) <= 1 with M = R S^-2 R^T; the slice
    at height offset z is an ellipse centred at -M_xy^-1 M_xz z with area
    pi (1 - z^2 (M_zz - M_xz^T M_xy^-1 M_xz)) / sqrt(det M_xy)."""
    M = R @ np.diag(1.0 / np.asarray(semi) ** 2) @ R.T
    Mxy, Mxz, Mzz = M[:2, :2], M[:2, 2], M[2, 2]
    inv = np.linalg.inv(Mxy)
    k = Mzz - Mxz @ inv @ Mxz
    zmax = 1.0 / np.sqrt(k)
    det = np.linalg.det(Mxy)
    shift = -inv @ Mxz

    def area(z):
        return max(0.0, np.pi * (1.0 - z * z * k) / np.sqrt(det))

    top = min(zmax, level - center[2])
    if top <= -zmax:
        return 0.0, np.asarray(center, dtype=float)
    opts = dict(epsabs=1e-14, epsrel=1e-11, limit=200)
    vol = quad(area, -zmax, top, **opts)[0]
    mz = quad(lambda z: z * area(z), -zmax, top, **opts)[0]
    # slice centres move linearly with z, so the xy moment is shift * mz
    centroid = np.asarray(center, dtype=float) + np.array([shift[0] * mz, shift[1] * mz, mz]) / vol
    return vol, centroid


def test_sphere_cap_volume_and_centroid_match_closed_form():
    r, c = 0.3, np.array([0.2, -0.1, 0.5])
    for level in np.linspace(c[2] - 0.9999 * r, c[2] + 0.9999 * r, 41):
        h = level - (c[2] - r)  # height of the submerged cap
        v_ref = np.pi * h * h * (3 * r - h) / 3.0
        # centroid of a cap of height h lies 3 (2r - h)^2 / (4 (3r - h)) from the centre
        z_ref = c[2] - 3.0 * (2 * r - h) ** 2 / (4.0 * (3 * r - h))
        vol, cb = submerged(c, np.eye(3), (r, r, r), level)
        # 1e-6 relative: the acceptance tolerance; the formulas agree to rounding
        assert abs(vol - v_ref) <= 1e-6 * v_ref
        assert abs(cb[2] - z_ref) <= 1e-6 * r
        assert np.allclose(cb[:2], c[:2], atol=1e-12)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_tilted_ellipsoid_matches_slice_integration(seed):
    rng = np.random.default_rng(seed)
    semi = rng.uniform(0.05, 0.4, 3)
    R = Rotation.from_quat(rng.normal(size=4)).as_matrix()
    c = rng.uniform(-1, 1, 3)
    half_height = np.linalg.norm(semi * R[2, :])
    for frac in np.linspace(-0.98, 0.98, 15):
        level = c[2] + frac * half_height
        vol, cb = submerged(c, R, semi, level)
        v_ref, cb_ref = _slice_reference(c, R, semi, level)
        # 1e-6 relative (acceptance); quad reaches ~1e-12 on these smooth integrands
        assert abs(vol - v_ref) <= 1e-6 * v_ref
        assert np.linalg.norm(cb - cb_ref) <= 1e-6 * max(semi)


def test_fully_dry_and_fully_wet():
    vol, _ = submerged((0, 0, 2.0), np.eye(3), (0.1, 0.2, 0.3), 0.0)
    assert vol == 0.0  # above the surface: nothing displaced (exact)
    vol, cb = submerged((0, 0, -2.0), np.eye(3), (0.1, 0.2, 0.3), 0.0)
    assert vol == pytest.approx(4 / 3 * np.pi * 0.006, rel=1e-12)  # full volume, rounding only
    assert np.allclose(cb, (0, 0, -2.0), atol=1e-12)


def test_linear_method_is_the_papers_fraction():
    d = np.linspace(-1, 1, 9)
    assert np.allclose(cap_fraction(d, "linear"), (1 + d) / 2, atol=1e-15)
    # the linear rule agrees with the exact cap at the ends and the middle (exact values)
    for x in (-1.0, 0.0, 1.0):
        assert cap_fraction(x, "linear") == pytest.approx(cap_fraction(x), abs=1e-15)
    # exact - linear = d (1 - d^2) / 4: largest, 1/(6 sqrt 3) = 0.0962, at d = 1/sqrt(3)
    x = 1 / np.sqrt(3)
    assert cap_fraction(x) - cap_fraction(x, "linear") == pytest.approx(1 / (6 * np.sqrt(3)), abs=1e-12)


_FREE = """
<mujoco><option gravity="0 0 -9.81"/>
  <worldbody><body name="b" pos="0.1 0.2 0.05" quat="0.9 0.3 0.2 0.1"><freejoint/>
    <geom type="ellipsoid" size="0.1 0.2 0.3" pos="0.05 0 0" density="600"/></body>
  </worldbody></mujoco>"""


def test_kernel_applies_force_at_centre_of_buoyancy():
    m = load_model(_FREE, is_xml=True)
    d = mujoco.MjData(m)
    buoy = Buoyancy.for_bodies(m, ["b"], water_level=0.0, fluid_density=1000.0)
    mujoco.mj_forward(m, d)
    base = d.qfrc_passive.copy()
    with buoy.register(d):
        mujoco.mj_forward(m, d)
        got = d.qfrc_passive - base
    DISPATCHER.check(d)
    # reference: numpy geometry + mj_applyFT of the force at the centre of buoyancy
    R = d.xmat[1].reshape(3, 3)
    c = d.xpos[1] + R @ np.array([0.05, 0, 0])
    vol, cb = submerged(c, R, (0.1, 0.2, 0.3), 0.0)
    assert 0.05 < vol / (4 / 3 * np.pi * 0.006) < 0.95  # really straddles the surface
    f = np.array([0, 0, 1000.0 * 9.81 * vol])
    ref = np.zeros(m.nv)
    mujoco.mj_applyFT(m, d, f, np.zeros(3), cb, 1, ref)
    # 1e-9 relative: the same arithmetic in a different order
    assert np.allclose(got, ref, rtol=1e-9, atol=1e-9 * np.abs(ref).max())
    vol_k, cb_k = buoy.report
    assert vol_k[0] == pytest.approx(vol, rel=1e-12)
    assert np.allclose(cb_k[0], cb, atol=1e-12)


def _box_on_slide(density: float) -> str:
    # a slide joint with viscous damping stands in for water drag so the box settles
    # (the test is about the buoyant equilibrium, not about how fast it gets there)
    return f"""
<mujoco><option timestep="0.002"/>
  <worldbody><body name="box" pos="0 0 0.3"><joint type="slide" axis="0 0 1" damping="60"/>
    <geom type="box" size="0.2 0.15 0.1" density="{density}"/></body>
  </worldbody></mujoco>"""


@pytest.mark.parametrize("density", [500.0, 300.0, 800.0])
def test_floating_box_settles_at_analytic_draft(density):
    m = load_model(_box_on_slide(density), is_xml=True)
    d = mujoco.MjData(m)
    buoy = Buoyancy.for_bodies(m, ["box"], water_level=0.0, fluid_density=1000.0)
    semi_z = buoy.ellipsoids.semi_axes[0, 2]
    assert buoy.total_volume == pytest.approx(8 * 0.2 * 0.15 * 0.1, rel=1e-12)
    with buoy.register(d):
        for _ in range(5000):
            mujoco.mj_step(m, d)
        DISPATCHER.check(d)
    # equilibrium: submerged fraction = density ratio; the volume-matched ellipsoid's
    # cap fraction (1+dd)^2 (2-dd)/4 = ratio gives dd = (level - z) / semi_z
    ratio = density / 1000.0
    dd = brentq(lambda x: (1 + x) ** 2 * (2 - x) / 4 - ratio, -1, 1)
    z_ref = -dd * semi_z
    # 1e-5 m: settled after 10 s at damping ratio ~1 (residual motion << 1e-6 m)
    assert d.qpos[0] + 0.3 == pytest.approx(z_ref, abs=1e-5)
    if density == 500.0:
        # half density: the box floats with its centre at the surface, exactly as a box would
        assert abs(d.qpos[0] + 0.3) < 1e-5


def test_geom_volumes_and_errors():
    xml = """
<mujoco><asset><mesh name="cube" vertex="-.1 -.1 -.1 .1 -.1 -.1 .1 .1 -.1 -.1 .1 -.1
      -.1 -.1 .1 .1 -.1 .1 .1 .1 .1 -.1 .1 .1"/></asset>
  <worldbody>
    <body name="a"><freejoint/><geom type="capsule" size="0.05 0.2"/></body>
    <body name="m" pos="1 0 0"><freejoint/><geom type="mesh" mesh="cube"/></body>
    <body name="empty" pos="2 0 0"><freejoint/><inertial pos="0 0 0" mass="1" diaginertia="1 1 1"/></body>
  </worldbody></mujoco>"""
    m = load_model(xml, is_xml=True)
    cap = np.pi * 0.05**2 * 0.4 + 4 / 3 * np.pi * 0.05**3
    assert geom_volume(m, 0) == pytest.approx(cap, rel=1e-12)
    # 0.2 m cube from its triangles; MuJoCo stores mesh vertices as float32 (~1e-7 relative)
    assert geom_volume(m, 1) == pytest.approx(0.008, rel=1e-6)
    b = Buoyancy.for_bodies(m, ["a", "m"])
    assert b.volumes == pytest.approx([cap, 0.008], rel=1e-6)
    with pytest.raises(ModelError, match="no body named"):
        Buoyancy.for_bodies(m, ["nope"])
    with pytest.raises(ModelError, match="no geoms"):
        Buoyancy.for_bodies(m, ["empty"])
    e = Buoyancy.for_bodies(m, ["empty"], ellipsoids={"empty": ((0, 0, 0), (0.1, 0.1, 0.1))})
    assert e.total_volume == pytest.approx(4 / 3 * np.pi * 1e-3, rel=1e-12)
    with pytest.raises(InputError, match="method"):
        BuoyancyParams(method="cubic")
