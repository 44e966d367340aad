"""Hinged polygons (flapsim.fluid.hinges): the paper's feather twist integrated by the engine.

The reference for the D'Alembert load is independent of the engine: the same plate on a hinge
inside the skeleton, which MuJoCo integrates as a coupled multibody system.
"""

import mujoco
import numpy as np
import pytest

from flapsim.core.errors import InputError, ModelError
from flapsim.fluid.hinges import PolygonHinges
from flapsim.fluid.surfaces import FluidParams, PolygonSet, SurfaceForces

DT = 1 / 2400
M, A, B, X0, Y0 = 1e-3, 0.04, 0.2, -0.03, 0.05  # plate mass, chord, span, its x and y start
K, C = 1e-2, 2e-5  # spring N m/rad, damper N m s/rad


def _plate():
    """Mass, com and inertia about the com of a uniform rectangle (x: chord, y: span)."""
    com = np.array([X0 + A / 2, Y0 + B / 2, 0.0])
    i = M / 12 * np.diag([B * B, A * A, A * A + B * B])
    return com, i


def _tri():
    return np.array([[[X0, Y0, 0], [X0 + A, Y0, 0], [X0 + A, Y0 + B, 0]]])


def _flapper(tree: bool, lo: float, hi: float, amp: float = 0.8, grav: bool = True, k: float = K,
             c: float = C) -> str:
    """A heavy bone flapped about world x by a stiff servo, a plate on it twisting about the
    bone's y axis: in the bone's body (``tree``, MuJoCo's limit) or on its own hinge."""
    com, i = _plate()
    plate_inertial = (f'<inertial pos="{com[0]} {com[1]} {com[2]}" mass="{M}" '
                      f'fullinertia="{i[0, 0]} {i[1, 1]} {i[2, 2]} 0 0 0"/>')
    joint = (f'type="hinge" stiffness="{k}" damping="{c}" range="{lo} {hi}"')
    if tree:
        plate = (f'<body name="plate">{plate_inertial}<joint name="twist" axis="0 1 0" {joint} '
                 'limited="true" solreflimit="0.001 1"/></body>')
        extra = ""
    else:
        plate = '<site name="axis" zaxis="0 1 0"/>'
        h = i[1, 1] + M * (com[0] ** 2 + com[2] ** 2)
        extra = ('<body name="hinge"><inertial pos="0 0 0" mass="1e-9" diaginertia="1e-15 1e-15 1e-15"/>'
                 f'<joint name="twist" axis="1 0 0" {joint} limited="false" armature="{h}"/></body>')
    g = "0 0 -9.81" if grav else "0 0 0"
    return f"""<mujoco><compiler angle="radian"/><size nuserdata="14"/>
      <option timestep="{DT}" integrator="implicitfast" gravity="{g}"/>
      <worldbody>
        <body name="bone" pos="0 0 1">
          <inertial pos="0 0.1 0" mass="0.5" diaginertia="0.01 0.01 0.01"/>
          <joint name="flap" axis="1 0 0" damping="0"/>
          {plate}
        </body>
        {extra}
      </worldbody>
      <actuator><position name="servo" joint="flap" kp="300" kv="5"/></actuator>
      <!-- amp {amp} -->
    </mujoco>"""


def _hinges(model):
    com, i = _plate()
    io = i + M * (com @ com * np.eye(3) - np.outer(com, com))
    return PolygonHinges(("plate",), ("bone",), ("twist",), np.array([[0, 1.0, 0]]), np.zeros((1, 3)),
                         np.array([M]), com[None], np.array([[io[0, 0], io[1, 1], io[2, 2], io[0, 1],
                                                               io[0, 2], io[1, 2]]]))


def _forces(model, density=1e-12):
    bone = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, "bone")
    polys = PolygonSet.from_triangles(bone, _tri(), labels=("plate",))
    return SurfaceForces(model, polys, params=FluidParams(density), hinges=_hinges(model))


def _run(tree: bool, lo=-1.5, hi=1.5, seconds=0.4, hz=8.0, amp=0.8, torque=0.0, grav=True,
         theta0=0.0, k=K, c=C):
    m = mujoco.MjModel.from_xml_string(_flapper(tree, lo, hi, amp, grav, k, c))
    d = mujoco.MjData(m)
    reg = None if tree else _forces(m).register(d)
    tw = m.joint("twist")
    d.qpos[tw.qposadr[0]] = theta0
    out = []
    try:
        for _ in range(int(round(seconds / DT))):
            d.ctrl[0] = amp * np.sin(2 * np.pi * hz * d.time)
            d.qfrc_applied[tw.dofadr[0]] = torque
            mujoco.mj_step(m, d)
            out.append((d.qpos[tw.qposadr[0]], d.qpos[m.joint("flap").qposadr[0]]))
    finally:
        if reg is not None:
            reg.remove()
    return np.array(out)


def test_dalembert_twist_matches_the_coupled_multibody_hinge():
    """Flapped at 8 Hz by +-0.5 rad, the plate (chord offset 1 cm behind its axis) twists by
    inertia and weight alone (no air); the separate hinge, driven by the D'Alembert load of
    its bone's last-step acceleration, follows MuJoCo's coupled hinge. Tolerances: the swing
    within 1 %; the angle within 5 % of the swing at every step: half a step of lag on a
    twist that rings at its 33 Hz natural frequency (2 pi 33 Hz dt / 2 = 4 % of a radian).
    The explicit ``qacc`` of the servo-damped bone as the acceleration misses the swing by
    13 % (the first version of this mechanism)."""
    a = _run(True, amp=0.5)
    b = _run(False, amp=0.5)
    assert np.ptp(a[:, 0]) > 0.3  # the inertial load really twists it
    assert np.allclose(a[:, 1], b[:, 1], atol=0.01)  # the same bone motion
    assert np.ptp(b[:, 0]) == pytest.approx(np.ptp(a[:, 0]), rel=0.01)
    assert np.abs(a[:, 0] - b[:, 0]).max() < 0.05 * np.ptp(a[:, 0])


def test_gravity_alone_twists_a_still_plate_to_the_spring_balance():
    """Bone held level, no air: the plate's weight about its axis (m g x_c, x_c = -1 cm) is
    balanced by the spring at theta = m g x_c / k (k theta = m g x_c cos theta: 1e-4 here)."""
    a = _run(False, seconds=1.0, amp=0.0)
    com, _ = _plate()
    # the weight -m g z at x_c has the moment x_c m g about +y
    theta = M * 9.81 * com[0] / K
    assert a[-1, 0] == pytest.approx(theta, rel=0.001)


def test_the_stop_holds_the_angle_exactly():
    """A torque driving the plate shut is held on the one-sided stop at exactly 0 (the clamp
    lands the integrator's next angle on it: rounding only), and one driving it open beyond
    the range on the upper stop; MuJoCo's soft limit in the skeleton yields (solref 1 ms)."""
    shut = _run(False, lo=0.0, hi=1.2, seconds=0.1, amp=0.0, torque=-2e-2, grav=False)
    assert np.abs(shut[:, 0]).max() < 1e-12
    opened = _run(False, lo=0.0, hi=1.2, seconds=0.1, amp=0.0, torque=+2e-2, grav=False)  # k 1.2 < 2e-2
    assert opened[:, 0].max() < 1.2 + 1e-12 and opened[-1, 0] == pytest.approx(1.2, abs=1e-12)
    soft = _run(True, lo=0.0, hi=1.2, seconds=0.1, amp=0.0, torque=-2e-2, grav=False)
    assert soft[:, 0].min() < -1e-4  # the coupled hinge's stop is soft: the clamp is not it


def test_twist_relaxes_with_the_spring_time_constant():
    """Released from 0.5 rad with nothing else acting: H th'' + c th' + k th = 0, overdamped
    like the paper's primaries (damping ratio 8 here, 7 there), so it creeps back with the
    slow root ~ -k/c; the closed form (both roots) against the simulation at 20-200 ms.
    Tolerance 1 %: the implicit-damper Euler step errs by ~ lambda dt / 2 on the fast root
    (c/H = 257/s: 5 % of a decay that is over within 20 ms) and far less on the slow one."""
    k, c = 6e-5, 6e-5
    a = _run(False, seconds=0.2, amp=0.0, grav=False, theta0=0.5, k=k, c=c)
    com, i = _plate()
    h = i[1, 1] + M * com[0] ** 2
    r1, r2 = np.roots([h, c, k])
    # th(0) = 0.5, th'(0) = 0
    c1 = 0.5 * r2 / (r2 - r1)
    c2 = 0.5 - c1
    t = DT * np.arange(1, len(a) + 1)
    exact = np.real(c1 * np.exp(r1 * t) + c2 * np.exp(r2 * t))
    for ms in (20, 50, 100, 200):
        k = int(round(ms / 1000 / DT)) - 1
        assert a[k, 0] == pytest.approx(exact[k], rel=0.01, abs=1e-4)


def test_hinges_are_refused_on_a_joint_that_is_not_separate():
    m = mujoco.MjModel.from_xml_string(_flapper(True, -1, 1))
    with pytest.raises(ModelError, match="only, unlimited hinge of a body hung from the world"):
        _forces(m)


def test_hinged_polygons_must_ride_the_hinge_body():
    m = mujoco.MjModel.from_xml_string(_flapper(False, -1, 1))
    polys = PolygonSet.from_triangles(2, _tri(), labels=("plate",))  # the hinge's own body
    with pytest.raises(InputError, match="must all ride body 'bone'"):
        SurfaceForces(m, polys, hinges=_hinges(m))


def test_rk4_is_refused():
    m = mujoco.MjModel.from_xml_string(_flapper(False, -1, 1).replace("implicitfast", "RK4"))
    with pytest.raises(ModelError, match="not RK4"):
        _forces(m)
