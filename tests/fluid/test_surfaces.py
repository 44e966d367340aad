"""Surface forces against analytic cases: a flat plate in uniform flow, moving or spinning, its
torque, a falling plate's terminal velocity, the front-facing rule, the free-surface cut,
friction, a Python flow plugin against the compiled one, and bad polygons refused."""

import mujoco
import numpy as np
import pytest

from flapsim.core.errors import InputError
from flapsim.core.loading import load_model
from flapsim.fluid.coefficients import flat_plate, get_table
from flapsim.fluid.flow import FlowField, PythonField, Uniform
from flapsim.fluid.surfaces import FluidParams, PolygonSet, SurfaceForces

RHO = 1.225
SQUARE = np.array([[[-0.1, -0.1, 0], [0.1, -0.1, 0], [0.1, 0.1, 0], [-0.1, 0.1, 0]]])  # 0.04 m^2


def plate_model(joint: str = "<freejoint/>", gravity: str = "0 0 0", mass: float = 0.1,
                integrator: str = "Euler"):
    xml = f"""<mujoco><option gravity="{gravity}" timestep="0.001" integrator="{integrator}"/>
      <worldbody>
      <body name="plate" pos="0 0 1">{joint}
        <geom type="box" size=".1 .1 .001" mass="{mass}" contype="0" conaffinity="0"/>
      </body></worldbody></mujoco>"""
    m = load_model(xml, is_xml=True)
    return m, mujoco.MjData(m)


@pytest.mark.parametrize("aoa_deg", [0.0, 5.0, 20.0, 45.0, 70.0, 90.0, 110.0, 160.0])
def test_plate_in_uniform_flow_matches_formula(aoa_deg):
    m, d = plate_model()
    a = np.deg2rad(aoa_deg)
    U = 6.0
    # wind in the x-z plane meeting the +x (leading) edge at angle a, from below
    wind = np.array([-U * np.cos(a), 0.0, U * np.sin(a)])
    table = flat_plate()
    ps = PolygonSet.from_polygons(1, SQUARE, forward=(1, 0, 0))
    sf = SurfaceForces(m, ps, [table], FluidParams(RHO), FlowField([Uniform(wind)]))
    mujoco.mj_forward(m, d)
    r = sf.evaluate(d)
    # the analytic flat plate: CL = 2 sin a cos a, CD = 2 sin^2 a + 0.02
    cl = 2 * np.sin(a) * np.cos(a)
    cd = 2 * np.sin(a) ** 2 + 0.02
    q = 0.5 * RHO * U**2 * 0.04
    # the kernel interpolates linearly on a pseudo-angle grid <= 0.64 deg (0.0112 rad)
    # apart: |error| <= h^2/8 max|C''| = 0.0112^2/8 * 4 = 6.3e-5 in each coefficient
    tol = 6.3e-5 * q
    assert np.rad2deg(r.aoa[0]) == pytest.approx(aoa_deg, abs=1e-9)
    assert np.linalg.norm(r.drag[0]) == pytest.approx(q * cd, abs=tol)
    assert np.linalg.norm(r.lift[0]) == pytest.approx(q * abs(cl), abs=tol)
    # drag along the relative wind, lift perpendicular to it and on the side the wind pushes
    assert np.allclose(np.cross(r.drag[0], wind), 0, atol=1e-12)
    assert abs(r.lift[0] @ wind) < 1e-9
    if abs(cl) > 1e-9:
        assert r.lift[0][2] > 0
    # flat plate: the total force is normal to the plate (CN model) up to the CD0 floor
    total = r.force[0]
    tangential = np.hypot(total[0], total[1])
    assert tangential <= q * 0.02 + 2 * tol


def test_moving_plate_in_still_air_equals_still_plate_in_wind():
    m, d = plate_model('<joint type="slide" axis="1 0 0"/><joint type="slide" axis="0 0 1"/>')
    ps = PolygonSet.from_polygons(1, SQUARE, forward=(1, 0, 0))
    table = get_table("dickinson1999")
    moving = SurfaceForces(m, ps, [table], FluidParams(RHO))
    d.qvel[:] = [4.0, -1.5]
    mujoco.mj_forward(m, d)
    r_moving = moving.evaluate(d)
    still = SurfaceForces(m, ps, [table], FluidParams(RHO), FlowField([Uniform((-4.0, 0.0, 1.5))]))
    d.qvel[:] = 0
    mujoco.mj_forward(m, d)
    r_still = still.evaluate(d)
    assert np.allclose(r_moving.force, r_still.force, rtol=1e-12, atol=1e-15)
    assert np.linalg.norm(r_still.force) > 0.1  # a real force, not a trivial zero


def test_spinning_plate_sees_omega_cross_r():
    # plate 0.5 m from a vertical hinge, facing the direction of rotation
    xml = """<mujoco><option gravity="0 0 0"/><worldbody><body name="arm">
      <joint type="hinge" axis="0 0 1"/><geom type="capsule" fromto="0 0 0 .5 0 0" size=".01"/>
      <body name="plate" pos=".5 0 0"><geom type="box" size=".1 .001 .1" mass=".01"/></body>
      </body></worldbody></mujoco>"""
    m = load_model(xml, is_xml=True)
    d = mujoco.MjData(m)
    verts = np.array([[[-0.1, 0, -0.1], [-0.1, 0, 0.1], [0.1, 0, 0.1], [0.1, 0, -0.1]]])
    ps = PolygonSet.from_polygons(2, verts)  # normal +y, no forward vector
    table = flat_plate()
    sf = SurfaceForces(m, ps, [table], FluidParams(RHO))
    omega = 7.0
    d.qvel[0] = omega
    mujoco.mj_forward(m, d)
    r = sf.evaluate(d)
    speed = omega * 0.5  # the centroid moves at omega x r = (0, 3.5, 0)
    q = 0.5 * RHO * speed**2 * 0.04
    assert np.rad2deg(r.aoa[0]) == pytest.approx(90.0, abs=1e-9)
    # 90 deg is a grid point of every table, so the coefficient is exact (CD = 2.02)
    assert np.allclose(r.force[0], [0.0, -q * table.at(90.0)[1], 0.0], rtol=1e-9, atol=1e-12)
    # torque opposes the spin: tau_z = -r * |F|
    tau = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, "plate")
    assert r.body_torque[tau][2] == pytest.approx(-0.5 * q * table.at(90.0)[1], rel=1e-9)


def random_tree(seed=0):
    xml = """<mujoco><option gravity="0 0 0"/><worldbody>
      <body name="a" pos="0.1 0.2 0.3"><freejoint/><geom size=".1" mass="1"/>
        <body name="b" pos="0.3 0 0"><joint type="ball"/><geom size=".05" mass=".3"/>
          <body name="c" pos="0 0.2 0"><joint type="hinge" axis="0 0 1"/>
            <joint type="slide" axis="1 0 0"/><geom size=".05" mass=".2"/></body></body></body>
      <body name="e" pos="1 0 0"><joint type="hinge" axis="0 1 0"/><geom size=".1" mass="1"/></body>
      </worldbody></mujoco>"""
    m = load_model(xml, is_xml=True)
    d = mujoco.MjData(m)
    rng = np.random.default_rng(seed)
    d.qpos[:] = rng.normal(size=m.nq)
    d.qvel[:] = rng.normal(size=m.nv)
    mujoco.mj_normalizeQuat(m, d.qpos)
    return m, d, rng


def random_polygons(m, rng, n=40):
    tri = rng.normal(scale=0.1, size=(n, 3, 3))
    bodies = rng.integers(1, m.nbody, size=n)
    return PolygonSet.from_triangles(bodies, tri, table=rng.integers(0, 2, size=n))


def test_torque_is_sum_of_r_cross_f_and_qfrc_matches_mj_applyFT():
    m, d, rng = random_tree()
    ps = random_polygons(m, rng)
    wind = FlowField([Uniform((3.0, -1.0, 0.5))])
    sf = SurfaceForces(m, ps, ["flat_plate", "dickinson1999"], FluidParams(RHO), wind)
    mujoco.mj_forward(m, d)
    r = sf.evaluate(d)
    for b in range(1, m.nbody):
        sel = ps.body == b
        assert np.allclose(r.body_force[b], r.force[sel].sum(axis=0), atol=1e-14)
        assert np.allclose(r.body_torque[b], np.cross(r.points[sel], r.force[sel]).sum(axis=0),
                           atol=1e-14)
    expected = np.zeros(m.nv)
    for p, f, b in zip(r.points, r.force, ps.body, strict=True):
        mujoco.mj_applyFT(m, d, f, np.zeros(3), p, int(b), expected)
    with sf.register(d):
        mujoco.mj_forward(m, d)
        got = d.qfrc_passive.copy()
    # round-off only: the compiled J^T w and mj_applyFT compute the same products
    assert np.abs(expected).max() > 1e-3
    assert np.allclose(got, expected, rtol=1e-10, atol=1e-13)


@pytest.mark.parametrize("integrator", ["Euler", "RK4", "implicitfast"])
def test_falling_plate_reaches_hand_computed_terminal_velocity(integrator):
    # RK4 calls the passive callback 4x per step: each call must start from a clean slate
    mass = 0.01
    m, d = plate_model('<joint type="slide" axis="0 0 1"/>', gravity="0 0 -9.81", mass=mass,
                       integrator=integrator)
    table = flat_plate(cd0=0.02)
    ps = PolygonSet.from_polygons(1, SQUARE)
    sf = SurfaceForces(m, ps, [table], FluidParams(RHO))
    cd90 = table.at(90.0)[1]  # 2.02 (normal-force model, plate broadside to the flow)
    v_terminal = np.sqrt(2 * mass * 9.81 / (RHO * 0.04 * cd90))  # 1.408 m/s
    with sf.register(d):
        for _ in range(3000):  # 3 s, ~20 time constants v_t/g
            mujoco.mj_step(m, d)
    # each integrator reaches the fixed point to ~1e-6 in 3 s; 1e-4 leaves margin
    assert -d.qvel[0] == pytest.approx(v_terminal, rel=1e-4)


def test_front_facing_rule_and_free_surface_cut():
    m, d = plate_model('<joint type="slide" axis="0 0 1"/>')
    face_up = PolygonSet.from_polygons(1, SQUARE)
    params = FluidParams(1000.0, front_facing_only=True)
    flow_down = FlowField([Uniform((0, 0, -1.0))])
    # flow moving down meets the upward-facing face: it is front facing
    assert np.linalg.norm(SurfaceForces(m, face_up, params=params, flow=flow_down)
                          .evaluate(_fwd(m, d)).force) > 0
    flow_up = FlowField([Uniform((0, 0, 1.0))])
    assert np.linalg.norm(SurfaceForces(m, face_up, params=params, flow=flow_up)
                          .evaluate(_fwd(m, d)).force) == 0
    # vertical plate straddling a free surface at its centre: half submerged -> half force
    vert = PolygonSet.from_polygons(1, np.array([[[0, -.1, -.1], [0, .1, -.1], [0, .1, .1], [0, -.1, .1]]]))
    wind = FlowField([Uniform((-1.0, 0, 0))])
    full = SurfaceForces(m, vert, params=FluidParams(1000.0), flow=wind).evaluate(_fwd(m, d))
    half = SurfaceForces(m, vert, params=FluidParams(1000.0, surface_z=1.0), flow=wind).evaluate(
        _fwd(m, d))
    dry = SurfaceForces(m, vert, params=FluidParams(1000.0, surface_z=0.5), flow=wind).evaluate(
        _fwd(m, d))
    # the polygon spans z = 0.9..1.1 (extent 0.1*sqrt 2 along its diagonal, vertical part 0.141)
    assert half.submerged[0] == pytest.approx(0.5)
    assert np.allclose(half.force, 0.5 * full.force)
    assert np.all(dry.force == 0)


def _fwd(m, d):
    mujoco.mj_forward(m, d)
    return d


def test_friction_along_short_side():
    # flow along N x F (the short side) gives friction only: eta * A * v_t
    m, d = plate_model()
    ps = PolygonSet.from_polygons(1, SQUARE, forward=(1, 0, 0))
    sf = SurfaceForces(m, ps, ["hoerner_plate"], FluidParams(1000.0, friction=2.0),
                       FlowField([Uniform((0, 0.3, 0))]))
    r = sf.evaluate(_fwd(m, d))
    assert np.allclose(r.friction[0], [0, 2.0 * 0.04 * 0.3, 0])
    assert np.all(r.drag == 0) and np.all(r.lift == 0)


def test_python_flow_plugin_equals_compiled_uniform():
    m, d, rng = random_tree(1)
    ps = random_polygons(m, rng, 10)
    tabs = ["flat_plate", "wang2004"]
    a = SurfaceForces(m, ps, tabs, FluidParams(RHO), FlowField([Uniform((1.0, 2.0, 0.0))]))
    b = SurfaceForces(m, ps, tabs, FluidParams(RHO), FlowField(
        [PythonField(lambda pts, t: np.tile([1.0, 2.0, 0.0], (len(pts), 1)))]))
    mujoco.mj_forward(m, d)
    assert np.allclose(a.evaluate(d).force, b.evaluate(d).force, rtol=1e-12, atol=1e-15)
    with b.register(d):
        mujoco.mj_forward(m, d)
        via_python = d.qfrc_passive.copy()
    with a.register(d):
        mujoco.mj_forward(m, d)
        via_cfunc = d.qfrc_passive.copy()
    assert np.allclose(via_python, via_cfunc, rtol=1e-12, atol=1e-15)


def test_bad_polygons_give_clear_errors():
    m, d = plate_model()
    with pytest.raises(InputError, match="shape"):
        PolygonSet.from_triangles(1, np.zeros((3, 3)))
    with pytest.raises(InputError, match="zero area"):
        PolygonSet.from_triangles(1, np.zeros((1, 3, 3)))
    bad = PolygonSet.from_polygons(5, SQUARE)
    with pytest.raises(InputError, match="body ids"):
        SurfaceForces(m, bad)
    with pytest.raises(InputError, match="NaN"):
        PolygonSet(np.array([1]), np.full((1, 3), np.nan), [[0, 0, 1]], [1.0], [[0, 0, 0]], 0, [0.1])
    with pytest.raises(InputError, match="density"):
        FluidParams(density=-1)
