"""Modal analysis against closed forms, rigid-mode counts, constraint ranks and simulation."""

from __future__ import annotations

import math

import mujoco
import numpy as np
import pytest

from flapsim.core.errors import InputError, ModelError
from flapsim.core.loading import load_model
from flapsim.modal import (
    analyze,
    fix_body_orientation,
    fix_joint,
    fix_root,
    ground_contact,
    integrate_displacement,
    parse_constraint,
    pin_site,
    tangent_difference,
)

# Two rigid links on parallel hinges, exact inertials so the closed form is exact.
M1, C1, IY1, L1 = 1.5, 0.3, 0.02, 0.5
M2, C2, IY2 = 0.7, 0.2, 0.005
K1, K2, ARM1, REST2_DEG = 2.0, 1.0, 0.03, 30.0

TWO_LINK = f"""
<mujoco><compiler angle="degree"/><option gravity="0 0 0"/><worldbody>
<body><joint name="j1" axis="0 1 0" stiffness="{K1}" armature="{ARM1}"/>
 <inertial pos="{C1} 0 0" mass="{M1}" diaginertia="0.01 {IY1} 0.03"/>
 <body pos="{L1} 0 0"><joint name="j2" axis="0 1 0" stiffness="{K2}" springref="{REST2_DEG}"/>
  <inertial pos="{C2} 0 0" mass="{M2}" diaginertia="0.004 {IY2} 0.006"/></body></body>
</worldbody></mujoco>"""


def chain_xml(free: bool = True, n: int = 4, damping: float = 0.0, gravity: bool = False) -> str:
    """A free-floating (or welded) chain: a ball joint then hinges on alternating axes."""
    g = "0 0 -9.81" if gravity else "0 0 0"
    xml = [f'<mujoco><option gravity="{g}" integrator="RK4" timestep="0.0002">'
           '<flag contact="disable"/></option>'
           f'<default><joint stiffness="1.5" damping="{damping}"/>'
           '<geom type="capsule" size="0.03" density="800"/></default><worldbody>'
           '<body name="b0" pos="0 0 1">' + ("<freejoint/>" if free else "")
           + '<geom fromto="0 0 0 0.2 0 0"/>']
    for i in range(1, n):
        joint = '<joint type="ball"/>' if i == 1 else (
            f'<joint axis="{"0 1 0" if i % 2 else "0 0 1"}"/>')
        xml.append(f'<body name="b{i}" pos="0.2 0 0">{joint}<geom fromto="0 0 0 0.2 0 0"/>')
    xml.append('<site name="tip" pos="0.2 0 0"/><site name="tip2" pos="0.1 0 0"/>')
    xml.append("</body>" * (n - 1) + "</body></worldbody></mujoco>")
    return "".join(xml)


def closed_form_two_link() -> np.ndarray:
    th = math.radians(REST2_DEG)
    i1 = IY1 + M1 * C1**2 + ARM1
    i2 = IY2 + M2 * C2**2
    a = i1 + i2 + M2 * L1**2 + 2 * M2 * L1 * C2 * math.cos(th)
    b = i2 + M2 * L1 * C2 * math.cos(th)
    d = i2
    det, tr = a * d - b * b, K1 * d + K2 * a
    disc = math.sqrt(tr * tr - 4 * det * K1 * K2)
    w2 = np.array([tr - disc, tr + disc]) / (2 * det)
    return np.sqrt(w2) / (2 * math.pi)


def test_two_link_chain_matches_closed_form():
    res = analyze(load_model(TWO_LINK, is_xml=True))
    # The rest pose is qpos_spring (springref 30 deg) and armature is in M: both enter the
    # closed form. Tolerance: floating-point round-off of a 2x2 eigenproblem.
    assert res.rest_qpos[1] == pytest.approx(math.radians(REST2_DEG))
    np.testing.assert_allclose(res.freqs_hz, closed_form_two_link(), rtol=1e-9)
    assert res.n_rigid == 0


def test_ball_joint_modes_are_principal_axes():
    # A body hung on a ball joint at its centre of mass: K = k I3 in the tangent space,
    # so f_i = sqrt(k / I_i) / 2 pi for each principal moment. Tolerance: round-off.
    k, inertia = 3.0, np.array([0.02, 0.03, 0.04])
    xml = (f'<mujoco><worldbody><body><joint type="ball" stiffness="{k}"/>'
           f'<inertial pos="0 0 0" mass="1" diaginertia="{inertia[0]} {inertia[1]} {inertia[2]}"/>'
           "</body></worldbody></mujoco>")
    res = analyze(load_model(xml, is_xml=True))
    expect = np.sort(np.sqrt(k / inertia) / (2 * math.pi))
    np.testing.assert_allclose(res.freqs_hz, expect, rtol=1e-9)


def test_tendon_stiffness_enters_as_jtkj():
    # One hinge with k plus a fixed tendon 2*theta of stiffness kt: K = k + 4 kt.
    k, kt, iy = 1.0, 0.5, 0.04
    xml = (f'<mujoco><worldbody><body><joint name="h" axis="0 1 0" stiffness="{k}"/>'
           f'<inertial pos="0 0 0" mass="1" diaginertia="0.1 {iy} 0.1"/></body></worldbody>'
           f'<tendon><fixed stiffness="{kt}"><joint joint="h" coef="2"/></fixed></tendon></mujoco>')
    res = analyze(load_model(xml, is_xml=True))
    assert res.freqs_hz[0] == pytest.approx(math.sqrt((k + 4 * kt) / iy) / (2 * math.pi), rel=1e-12)


def test_free_root_has_six_rigid_modes_and_mass_normalised_shapes():
    model = load_model(chain_xml(), is_xml=True)
    res = analyze(model)
    # nv = 6 (free) + 3 (ball) + 2 hinges; a free root adds exactly 6 zero modes.
    assert model.nv == 11
    assert res.n_modes == 11
    assert res.n_rigid == 6
    assert np.all(res.freqs_hz[:6] == 0.0)
    assert res.freqs_hz[6] > 0.1
    # Mass-normalised and K-diagonalising to round-off (generalized eigh).
    gram = res.shapes.T @ res.mass_matrix @ res.shapes
    np.testing.assert_allclose(gram, np.eye(11), atol=1e-9)
    kd = res.shapes.T @ res.stiffness @ res.shapes
    np.testing.assert_allclose(kd, np.diag(res.eigenvalues), atol=1e-8 * res.eigenvalues.max())


def test_fix_root_matches_welded_base():
    free = load_model(chain_xml(free=True), is_xml=True)
    welded = load_model(chain_xml(free=False), is_xml=True)
    a = analyze(free, constraints=fix_root(free))
    b = analyze(welded)
    assert a.n_rigid == 0 and a.n_modes == free.nv - 6
    # Freezing the free joint is the welded model exactly (round-off tolerance).
    np.testing.assert_allclose(a.freqs_hz, b.freqs_hz, rtol=1e-9)


def test_constraints_remove_exactly_their_rank():
    model = load_model(chain_xml(), is_xml=True)
    base = analyze(model).n_modes
    pinned = analyze(model, constraints=[pin_site("tip")])
    assert pinned.n_modes == base - 3 and pinned.constraint_rank == 3
    # Pinned to the world, only the rotations about the pin remain rigid.
    assert pinned.n_rigid == 3
    # A repeated constraint is redundant: still rank 3.
    twice = analyze(model, constraints=[pin_site("tip"), pin_site("tip")])
    assert twice.n_modes == base - 3
    head = analyze(model, constraints=[fix_body_orientation("b0")])
    assert head.n_modes == base - 3 and head.n_rigid == 3
    feet = analyze(model, constraints=[ground_contact(["tip", "tip2"], sliding=True)])
    assert feet.n_modes == base - 2
    both = analyze(model, constraints=[pin_site("tip"), fix_body_orientation("b0")])
    assert both.n_modes == base - 6


def test_loop_closure_rank_and_creature_dof_counts():
    from flapsim.modal.creatures import load_creature

    loop = analyze(load_creature("loop"))
    # Free root + 15 hinges = 21 dofs; the connect closing a planar loop has rank 2
    # (its out-of-plane row is identically zero): 19 dofs, the paper's count.
    assert loop.nv == 21 and loop.constraint_rank == 2 and loop.n_modes == 19
    assert loop.n_rigid == 6
    # The two ovalisation modes of a symmetric ring are degenerate (round-off tolerance).
    assert loop.freqs_hz[7] == pytest.approx(loop.freqs_hz[6], rel=1e-6)
    linear = analyze(load_creature("linear"))
    assert linear.n_modes == 21 and linear.n_rigid == 6


def _measure_period(times: np.ndarray, signal: np.ndarray) -> float:
    s = np.sign(signal)
    idx = np.nonzero(s[:-1] * s[1:] < 0)[0]
    # Linear interpolation of each zero crossing.
    t0 = times[idx] - signal[idx] * (times[idx + 1] - times[idx]) / (signal[idx + 1] - signal[idx])
    assert t0.size >= 5, "too few oscillations to measure a period"
    return 2 * (t0[-1] - t0[0]) / (t0.size - 1)


@pytest.mark.parametrize("mode_offset", [0, 1, 2])
def test_frequencies_match_linear_regime_simulation(mode_offset):
    model = load_model(chain_xml(), is_xml=True)
    res = analyze(model)
    mode = res.n_rigid + mode_offset
    data = mujoco.MjData(model)
    data.qpos[:] = res.displaced_qpos(model, mode, 1e-3)
    data.qvel[:] = 0
    f = res.freqs_hz[mode]
    n_steps = int(6.0 / f / model.opt.timestep)  # six periods
    times, eta = np.empty(n_steps), np.empty(n_steps)
    phi_m = res.shapes[:, mode] @ res.mass_matrix
    for k in range(n_steps):
        mujoco.mj_step(model, data)
        times[k] = data.time
        eta[k] = phi_m @ tangent_difference(model, data.qpos, res.rest_qpos)
    # Undamped, weightless, 1e-3 rad: nonlinear and RK4 errors are << 2% (the accuracy asked of
    # the modal analysis).
    assert 1.0 / _measure_period(times, eta) == pytest.approx(f, rel=0.02)


def test_loop_frequency_matches_simulation_with_closure():
    from flapsim.modal.creatures import load_creature

    model = load_creature("loop")
    model.opt.gravity[:] = 0
    model.opt.disableflags |= mujoco.mjtDisableBit.mjDSBL_CONTACT
    model.dof_damping[:] = 0
    model.tendon_damping[:] = 0
    model.opt.integrator = mujoco.mjtIntegrator.mjINT_RK4
    model.opt.timestep = 2e-4
    res = analyze(model)
    mode = res.n_rigid
    data = mujoco.MjData(model)
    data.qpos[:] = res.displaced_qpos(model, mode, 1e-3)
    n_steps = int(6.0 / res.freqs_hz[mode] / model.opt.timestep)
    times, eta = np.empty(n_steps), np.empty(n_steps)
    phi_m = res.shapes[:, mode] @ res.mass_matrix
    for k in range(n_steps):
        mujoco.mj_step(model, data)
        times[k] = data.time
        eta[k] = phi_m @ tangent_difference(model, data.qpos, res.rest_qpos)
    # The closure is a soft (stiff-solref) constraint in MuJoCo; 2% is the accuracy asked.
    assert 1.0 / _measure_period(times, eta) == pytest.approx(res.freqs_hz[mode], rel=0.02)


def test_tangent_helpers_round_trip():
    model = load_model(chain_xml(), is_xml=True)
    res = analyze(model)
    dq = 1e-2 * res.shape(7)
    q = integrate_displacement(model, res.rest_qpos, dq)
    # Quaternions stay unit; differentiatePos inverts integratePos to round-off.
    assert np.linalg.norm(q[3:7]) == pytest.approx(1.0, abs=1e-12)
    np.testing.assert_allclose(tangent_difference(model, q, res.rest_qpos), dq, atol=1e-12)
    small = integrate_displacement(model, res.rest_qpos, 1e-6 * res.shapes[:, 8])
    eta = res.modal_coordinates(model, small)
    # A small displacement along one mass-normalised mode projects onto that mode only.
    assert eta[8] == pytest.approx(1e-6, rel=1e-4)
    assert np.max(np.abs(np.delete(eta, 8))) < 1e-10


def test_keyframe_and_uniform_stiffness_options():
    key = "</worldbody><keyframe><key name='bent' qpos='0 0.5'/></keyframe>"
    xml = TWO_LINK.replace("</worldbody>", key)
    model = load_model(xml, is_xml=True)
    res = analyze(model, keyframe="bent")
    assert res.rest_qpos[1] == 0.5
    stiff = analyze(model, stiffness=4.0)
    assert np.diag(stiff.stiffness) == pytest.approx([4.0, 4.0])
    scaled = analyze(model, stiffness_scale=4.0)
    # Scaling K by 4 doubles every frequency (exact up to round-off).
    np.testing.assert_allclose(scaled.freqs_hz, 2 * analyze(model).freqs_hz, rtol=1e-12)
    with pytest.raises(ModelError, match="no keyframe"):
        analyze(model, keyframe="missing")


def test_clear_errors():
    no_k = load_model('<mujoco><worldbody><body><joint/><geom size=".1" pos=".2 0 0"/>'
                      "</body></worldbody></mujoco>", is_xml=True)
    with pytest.raises(ModelError, match="no joint or tendon stiffness"):
        analyze(no_k)
    one = load_model('<mujoco><worldbody><body><joint name="h" stiffness="1"/>'
                     '<geom size=".1" pos=".2 0 0"/></body></worldbody></mujoco>', is_xml=True)
    with pytest.raises(ModelError, match="remove every degree of freedom"):
        analyze(one, constraints=[fix_joint("h")])
    # Two coaxial hinges through a point mass with (almost) no inertia: M is singular.
    sing = load_model(
        '<mujoco><worldbody><body><joint name="a" axis="0 0 1" stiffness="1"/>'
        '<inertial pos="0 0 0" mass="1e-9" diaginertia="1e-13 1e-13 1e-13"/>'
        '<body><joint name="b" axis="0 0 1" stiffness="1"/>'
        '<inertial pos="0 0 0" mass="1" diaginertia="1 1 1"/></body></body></worldbody></mujoco>',
        is_xml=True,
    )
    with pytest.raises(ModelError, match="mass matrix is singular"):
        analyze(sing)
    with pytest.raises(InputError, match="KIND:NAME"):
        parse_constraint("head")
    with pytest.raises(ModelError, match="no site named"):
        analyze(load_model(chain_xml(), is_xml=True), constraints=[pin_site("nope")])
