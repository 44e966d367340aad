"""Modal (deformable) feathers: statics against Euler-Bernoulli, frequency against a
finite-difference linearization, energy, warping, the primaries' twist, rest equivalence with
the rigid feathers, snapshots, and the base controller's flight."""

import mujoco
import numpy as np
import pytest

from flapsim.bird.body.feather_dynamics import ModalFeathers, clamped_feather_xml, dove_feather_modes
from flapsim.bird.body.feather_modes import ModalParams, ShaftBeam, euler_bernoulli_tip_deflection
from flapsim.bird.body.inertia import _Inertia
from flapsim.bird.body.model import Dove, _inertial_xml
from flapsim.bird.body.params import DoveParams
from flapsim.bird.flight.dove_flight import DoveFlight, FlightConfig, flight_metrics, fly
from flapsim.fluid.coefficients import get_table

RIGID_HASH = "78496ea82ee6"  # the bundled controller database is bound to it
TREE_HASH = "ff4b126f5b0b"  # the same dove with the twist hinges in the skeleton (before 2026-11-29)
FOUR = ModalParams(modes=4)  # the paper's reduction: the dove flies 1 mode (see ModalParams.modes)
MECHANISMS = ("engine", "joints")  # who integrates the modes (ModalParams.integration)


@pytest.fixture(scope="module")
def params():
    return DoveParams.load()


@pytest.fixture(scope="module")
def modal_dove():
    return Dove.load(feathers="modal")


def _feather(params, name, mp=None):
    mp = mp or ModalParams()
    return next(fm for fm in dove_feather_modes(params, mp) if fm.name == name)


def _clamped(params, name, mp=None, density=1.225, **kw):
    mp = mp or ModalParams()
    fm = _feather(params, name, mp)
    m = mujoco.MjModel.from_xml_string(clamped_feather_xml(fm, mp, params.timestep, **kw))
    prov = ModalFeathers(m, [fm], get_table("dickinson1999_profile"), density, params=mp)
    return fm, m, prov


def test_rigid_dove_is_unchanged():
    assert Dove.load().hash() == RIGID_HASH
    # the drawing model (and the modal dove's base) is the earlier dove, hinges in the skeleton
    assert Dove.from_model(Dove.load().drawing()[0], DoveParams.load()).hash() == TREE_HASH


@pytest.mark.parametrize("integration", MECHANISMS)
@pytest.mark.parametrize("modes", [1, 4])
def test_static_tip_load_matches_euler_bernoulli(params, modes, integration):
    """A primary (tapering EI and vane) clamped at its root under a 5 mN load at the shaft tip,
    settled by simulation, against int F (L - s)^2 / EI(s) ds (the dove's one mode, and the
    paper's four)."""
    # settle fast; statics do not depend on it
    mp = ModalParams(damping_ratio=1.0, modes=modes, integration=integration)
    fm, m, prov = _clamped(params, "l_p6", mp)
    d = mujoco.MjData(m)
    F = 5e-3
    lf = params.primary_lead_fraction
    tip = np.flatnonzero(fm.vert_station == fm.stations - 1)
    lead, trail = (tip[0], tip[1]) if fm.vert_x[tip[0]] > 0 else (tip[1], tip[0])
    # split so the load acts on the shaft: no twisting moment about it
    prov.ext[3 * lead:3 * lead + 3] = (1 - lf) * F * fm.normal
    prov.ext[3 * trail:3 * trail + 3] = lf * F * fm.normal
    with prov.register(d):
        mujoco.mj_step(m, d, nstep=600)
    q = prov.coordinates(d)[0]
    v = prov.body_vertices(q, 0)
    shaft_tip = (1 - lf) * v[lead] + lf * v[trail]  # the shaft point between them
    rest_tip = fm.root + fm.length * fm.shaft
    deflection = (shaft_tip - rest_tip) @ fm.normal
    eb = euler_bernoulli_tip_deflection(F, fm.length, fm.ei)
    assert deflection == pytest.approx(eb, rel=0.10)
    assert 0 < deflection < 0.05 * fm.length  # small-deflection regime


def test_euler_bernoulli_closed_form_against_quadrature():
    L, ei = 0.12, (0.018, 0.0019)
    s = np.linspace(0, L, 200001)
    f = (L - s) ** 2 / (ei[0] + (ei[1] - ei[0]) * s / L)
    assert euler_bernoulli_tip_deflection(1.0, L, ei) == pytest.approx(np.trapezoid(f, s), rel=1e-6)


def test_first_frequency_of_the_engine_matches_finite_difference_linearization(params):
    """The engine-integrated modes: a finite-difference linearization of one simulation step
    (``mj_step`` with the kernel's forces, the mode's state perturbed in ``userdata``) of a
    clamped secondary in still air, against the shell reduction's first eigenfrequency: the
    step is the oscillator's exact exponential, so its eigenvalues are exp(+-i w dt) (and
    |lambda| = 1 without damping)."""
    mp = ModalParams(damping_ratio=0.0)
    fm, m, prov = _clamped(params, "l_s5", mp)
    d = mujoco.MjData(m)
    h = (1e-7, 1e-7 * fm.omega[0])  # a coordinate (m-ish) and a rate of the same energy
    A = np.zeros((2, 2))
    with prov.register(d):
        for j in range(2):
            cols = []
            for sgn in (1, -1):
                mujoco.mj_resetData(m, d)
                x = np.zeros(2)
                x[j] = sgn * h[j]
                prov.set_coordinates(d, x[:1], x[1:])
                mujoco.mj_step(m, d)
                cols.append(np.concatenate([a.ravel() for a in prov.state(d)]))
            A[:, j] = (cols[0] - cols[1]) / (2 * h[j])
    lam = np.linalg.eigvals(A)
    dt = m.opt.timestep
    assert np.abs(np.angle(lam)).max() / dt == pytest.approx(fm.omega[0], rel=1e-4)
    np.testing.assert_allclose(np.abs(lam), 1.0, atol=1e-6)


def test_first_frequency_matches_finite_difference_linearization(params):
    """MuJoCo's finite-difference linearization of the clamped feather's step (all of the
    point masses, springs and the kernel's forces assembled) against the shell reduction's
    first eigenfrequency; the step's symplectic Euler shifts it by asin(w dt/2) 2/dt (modes
    on joints)."""
    mp = ModalParams(damping_ratio=0.0, integration="joints")
    fm, m, prov = _clamped(params, "l_s5", mp)
    d = mujoco.MjData(m)
    with prov.register(d):
        mujoco.mj_forward(m, d)
        n = 2 * m.nv
        A = np.zeros((n, n))
        mujoco.mjd_transitionFD(m, d, 1e-7, True, A, None, None, None)
    lam = np.linalg.eigvals(A)
    dt = m.opt.timestep
    w_discrete = np.sort(np.abs(np.angle(lam)))[::2] / dt  # conjugate pairs
    w1 = fm.omega[0]
    assert w_discrete[0] == pytest.approx(2 / dt * np.arcsin(w1 * dt / 2), rel=0.01)
    assert w_discrete[0] == pytest.approx(w1, rel=0.02)


def test_first_frequency_matches_a_finite_difference_beam(params):
    """Independent check of the shell reduction: a secondary (symmetric vane, so it bends
    without twisting) against a 400-cell finite-difference Euler-Bernoulli beam with the same
    EI(s) and the strip's mass per length, clamped at the root, free at the tip."""
    fm = _feather(params, "l_s5")
    N = 400
    L = fm.length
    h = L / N
    s = np.arange(N + 1) * h
    st = np.arange(fm.stations) * L / (fm.stations - 1)
    widths = np.array([np.ptp(fm.vert_x[fm.vert_station == j]) for j in range(fm.stations)])
    width = np.interp(s, st, widths)
    mpl = fm.mass / np.trapezoid(width, s) * width  # uniform mass per area
    EI = fm.ei[0] + (fm.ei[1] - fm.ei[0]) * s / L
    # unknowns w_1..w_N (w_0 = 0); curvature at 0..N-1 with the clamp's ghost w_-1 = w_1;
    # moment EI w'' zero at the tip; shear zero there (ghost M_N+1 = M_N-1)
    curv = np.zeros((N + 1, N))
    curv[0, 0] = 2 / h**2
    for i in range(1, N):
        if i - 2 >= 0:
            curv[i, i - 2] = 1 / h**2
        curv[i, i - 1] = -2 / h**2
        if i < N:
            curv[i, i] = 1 / h**2
    moment = EI[:, None] * curv
    moment[N] = 0.0
    load = np.zeros((N, N))
    for i in range(1, N):
        load[i - 1] = (moment[i - 1] - 2 * moment[i] + moment[i + 1]) / h**2
    load[N - 1] = (2 * moment[N - 1] - 2 * moment[N]) / h**2
    ev = np.linalg.eigvals(load / mpl[1:, None])
    ev = np.sort(ev.real[ev.real > 1.0])
    assert np.sqrt(ev[0]) == pytest.approx(fm.omega[0], rel=0.03)


def test_undamped_engine_feather_energy_does_not_grow(params):
    """1,000 unforced steps of a clamped primary in vacuum with every engine-integrated mode
    displaced, no structural damping: the resolved first mode's energy 1/2 (mu v^2 + k q^2)
    stays what it was (an exact step: to round-off), the unresolvable ones (their k dt of
    numerical damping) only lose energy."""
    mp = ModalParams(damping_ratio=0.0, modes=4)
    fm, m, prov = _clamped(params, "l_p3", mp, density=0.0)
    d = mujoco.MjData(m)
    k, mu = fm.stiffness, fm.mu
    e = []
    with prov.register(d):
        mujoco.mj_forward(m, d)
        prov.set_coordinates(d, 0.005 / fm.unit)  # 5 mm of each mode's largest deflection
        for _ in range(1000):
            mujoco.mj_step(m, d)
            q, v = (a[0] for a in prov.state(d))
            e.append(0.5 * (mu * v**2 + k * q**2))
    e = np.array(e)
    assert np.abs(e[:, 0] / e[0, 0] - 1).max() < 1e-9
    resolved = fm.omega * m.opt.timestep <= mp.implicit_above
    assert resolved[0] and not resolved[1:].any()  # what the two checks are about
    assert np.all(np.diff(e[:, 1:], axis=0) <= 1e-12 * e[0, 1:])
    assert e[-1, 1:].max() < 0.01 * e[0, 1:].min()


def test_undamped_feather_energy_does_not_grow(params):
    """1,000 unforced steps of a clamped primary with every mode displaced, no structural
    damping: the energy at the end is at most what it was at the start (the resolved mode is
    stepped symplectically, the unresolvable ones by backward Euler, which only dissipates;
    modes on joints)."""
    mp = ModalParams(damping_ratio=0.0, modes=4, integration="joints")
    fm, m, _ = _clamped(params, "l_p3", mp)
    d = mujoco.MjData(m)
    K = fm.omega.size
    d.qpos[:K] = 0.005 / fm.unit  # 5 mm of each mode's largest deflection
    k = m.jnt_stiffness[:K]

    def energy():
        M = np.zeros((m.nv, m.nv))
        mujoco.mj_forward(m, d)
        mujoco.mj_fullM(m, d, M)
        return 0.5 * d.qvel @ M @ d.qvel + 0.5 * np.sum(k * d.qpos[:K] ** 2)

    e = []
    for _ in range(1000):
        mujoco.mj_step(m, d)
        e.append(energy())
    e = np.array(e)
    assert e[-100:].max() <= e[:100].max() * (1 + 1e-9)
    # the resolved first mode alone: symplectic, its energy oscillates but neither grows nor
    # decays
    d.qpos[:] = 0
    d.qvel[:] = 0
    d.qpos[0] = 0.005 / fm.unit[0]
    e1 = []
    for _ in range(1000):
        mujoco.mj_step(m, d)
        e1.append(energy())
    e1 = np.array(e1)
    assert e1[-50:].max() <= e1[:50].max() * (1 + 1e-9)
    assert e1[-50:].max() >= 0.98 * e1[:50].max()


def test_warping_jacobian_and_length(params):
    """The vertex Jacobians are the derivatives of the warped positions, and a strongly bent
    feather keeps its length (modal warping) where linear modes would stretch it."""
    fm, m, prov = _clamped(params, "l_p8", FOUR)
    K = fm.omega.size
    q = np.array([0.3, -0.2, 0.1, 0.05]) / fm.unit * 0.05
    J = prov.warped(q, 0)[1]
    for k in range(K):
        dq = np.zeros(K)
        dq[k] = 1e-6 / abs(fm.unit[k])
        fd = (prov.warped(q + dq, 0)[0] - prov.warped(q - dq, 0)[0]) / (2 * dq[k])
        np.testing.assert_allclose(J[:, k], fd, rtol=1e-4, atol=1e-6 * np.abs(fd).max())
    # bend the first mode until the tip moves 40 % of the length
    qb = np.zeros(K)
    qb[0] = 0.4 * fm.length / fm.unit[0]
    v = prov.body_vertices(qb, 0)
    lf = params.primary_lead_fraction
    centres = [(1 - lf) * v[2 * j] + lf * v[2 * j + 1] for j in range(fm.stations)]
    arc = sum(np.linalg.norm(np.diff(centres, axis=0), axis=1))
    assert arc == pytest.approx(fm.length, rel=0.01)
    linear_tip = fm.root + fm.length * fm.shaft + fm.normal * (qb[0] * fm.unit[0])
    assert np.linalg.norm(linear_tip - fm.root) > 1.07 * fm.length  # what warping avoids


def _primary_on_twist_hinge(params, k: int = 4):
    """A primary on its twist hinge (the dove's spring, damper and one-sided range), the hinge
    fixed in space, gravity off."""
    from flapsim.bird.body.params import left_feathers

    fe = next(f for f in left_feathers(params) if f.name == f"l_p{k + 1}")
    inert = _Inertia()
    inert.plates([fe])
    tw = np.radians(params.twist_max_deg)
    ax = " ".join(f"{x:.9g}" for x in -fe.shaft)
    xml = f"""<mujoco><compiler angle="radian"/>
      <option timestep="{params.timestep:.10g}" integrator="implicitfast" gravity="0 0 0"/>
      <worldbody><body name="p">{_inertial_xml(inert)}
      <joint name="twist" axis="{ax}" range="0 {tw:.6g}" stiffness="{params.twist_stiffness:.6g}"
       damping="{params.twist_damping:.6g}" solreflimit="0.001 1" solimplimit="0.95 0.99 0.001"/>
      </body></worldbody></mujoco>"""
    return fe, mujoco.MjModel.from_xml_string(xml)


def test_twist_relaxes_with_the_spring_time_constant(params):
    """H th'' + c th' + k th = 0 with c = 0.6e-5 N m s/rad, k = 0.6e-4 N m/rad and the
    primary's inertia about its shaft H: overdamped (c^2 >> 4 k H), the slow root is
    s = (-c + sqrt(c^2 - 4 k H)) / (2 H) ~ -k/c, tau = 1/|s| ~ c/k = 0.1 s."""
    fe, m = _primary_on_twist_hinge(params)
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    M = np.zeros((1, 1))
    mujoco.mj_fullM(m, d, M)
    H = M[0, 0]
    c, k = params.twist_damping, params.twist_stiffness
    assert c * c > 40 * k * H  # strongly overdamped
    s_slow = (-c + np.sqrt(c * c - 4 * k * H)) / (2 * H)
    tau = -1 / s_slow
    assert tau == pytest.approx(c / k, rel=0.01)
    d.qpos[0] = 0.5
    t, th = [], []
    for _ in range(int(0.3 / m.opt.timestep)):
        mujoco.mj_step(m, d)
        t.append(d.time)
        th.append(d.qpos[0])
    t, th = np.array(t), np.array(th)
    sel = (t > 0.02) & (t < 0.25)  # after the fast root has died out
    slope = np.polyfit(t[sel], np.log(th[sel]), 1)[0]
    assert -1 / slope == pytest.approx(tau, rel=0.03)


@pytest.mark.parametrize("torque", [-3e-4, 3e-4])
def test_twist_stays_within_its_one_sided_limit(params, torque):
    """Pushed either way by 3e-4 N m (about the largest aerodynamic twisting torque on a
    primary, 5x the spring's torque at 1 rad), the twist settles on its stop (0, or
    twist_max) within 0.5 deg, and overshoots it by less than 3 deg when it strikes it
    (MuJoCo's soft limit, solref 1 ms)."""
    fe, m = _primary_on_twist_hinge(params)
    d = mujoco.MjData(m)
    d.qpos[0] = 0.3
    d.qfrc_applied[0] = torque
    lo = hi = d.qpos[0]
    for _ in range(2000):
        mujoco.mj_step(m, d)
        lo, hi = min(lo, d.qpos[0]), max(hi, d.qpos[0])
    top = np.radians(params.twist_max_deg)
    assert lo > -np.radians(3.0) and hi < top + np.radians(3.0)
    stop = 0.0 if torque < 0 else top
    assert d.qpos[0] == pytest.approx(stop, abs=np.radians(0.5))


@pytest.mark.parametrize("integration", MECHANISMS)
def test_modal_primaries_twist_only_one_way(integration):
    """In flight (two wingbeats of the base controller) the modal dove's primaries twist open
    at the upstroke and stay shut at the downstroke, as the rigid dove's
    (``test_flight.test_primaries_twist_only_one_way``): on the engine's hinges exactly
    within the stops, on the joints within MuJoCo's soft limit (3 deg)."""
    dove = Dove.load(feathers="modal", modal=ModalParams(integration=integration))
    f = fly(dove, 2)
    m = dove.model
    adr = [m.jnt_qposadr[mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, f"l_p{k}_twist")]
           for k in range(1, 11)]
    tw = f.qpos[:, adr]
    soft = 0.0 if integration == "engine" else np.radians(3.0)
    top = np.radians(DoveParams.load().twist_max_deg)
    assert tw.min() >= -soft - 1e-12
    assert np.radians(20.0) < tw.max() <= top + soft + 1e-12


def test_undeformed_modal_feathers_feel_the_rigid_forces(modal_dove):
    """At rest deformation the deformed-triangle kernel gives the rigid engine's forces
    (same triangles, same formula), moving through the same air."""
    rig = Dove.load()
    out = []
    for dv in (rig, modal_dove):
        fl = DoveFlight(dv, use_rollout=False)
        try:
            fl.reset(FlightConfig())
            F, P, feather = fl.aero_forces()
            out.append((F[feather].sum(0), np.cross(P[feather], F[feather]).sum(0)))
        finally:
            fl.close()
    np.testing.assert_allclose(out[1][0], out[0][0], rtol=1e-5, atol=1e-7)
    np.testing.assert_allclose(out[1][1], out[0][1], rtol=1e-5, atol=1e-7)
    assert modal_dove.mass == pytest.approx(rig.mass, rel=1e-9)


def test_modal_state_is_in_the_snapshot(modal_dove):
    """The engine keeps the modes in ``userdata``: restoring a snapshot (the full-physics
    state, the warm start and ``userdata``) repeats the continuation bit for bit, also
    through ``mujoco.rollout`` and after extra ``mj_forward`` calls (what the controller's
    snapshots and P0 predictions rely on); without ``userdata`` it does not."""
    from flapsim.bird.flight import cycle
    from flapsim.bird.flight.wingbeat import p0, with_tail_bias

    fl = DoveFlight(modal_dove, use_rollout=False)
    try:
        fl.reset(FlightConfig())
        m, d = fl.model, fl.data
        d.ctrl[:] = 0.01
        mujoco.mj_step(m, d, nstep=100)
        snap = cycle.snapshot(fl)
        assert np.abs(fl.modal.coordinates(d)).max() > 0
        mujoco.mj_step(m, d, nstep=100)
        a, qa = d.qpos.copy(), fl.modal.coordinates(d)
        cycle.restore(fl, snap)
        mujoco.mj_forward(m, d)  # a repeated forward changes nothing
        d.ctrl[:] = 0.01  # restore zeroes the controls
        mujoco.mj_step(m, d, nstep=100)
        np.testing.assert_array_equal(d.qpos, a)
        np.testing.assert_array_equal(fl.modal.coordinates(d), qa)
        p = with_tail_bias(p0(), FlightConfig.tail_bias_deg)
        ends = [cycle.fly_cycle(fl, snap, p, record=rec) for rec in (False, True)]  # rollout, steps
        np.testing.assert_array_equal(ends[0].snapshot.physics, ends[1].snapshot.physics)
        np.testing.assert_array_equal(ends[0].snapshot.userdata, ends[1].snapshot.userdata)
        cycle.restore(fl, cycle.Snapshot(snap.physics, snap.warmstart, None))  # userdata kept
        assert not np.array_equal(cycle.fly_cycle(fl, None, p).snapshot.physics,
                                  ends[0].snapshot.physics)
    finally:
        fl.close()


def test_modal_base_controller_flies_ten_wingbeats_along_the_line(modal_dove):
    f = fly(modal_dove, 10)
    met = flight_metrics(f)
    assert met["finite"]
    assert met["max_vertical_deviation"] < 0.3 and met["max_lateral_deviation"] < 0.3
    # the feathers did deform: the frames' modal coordinates (after qpos), up to millimetres
    q = f.qpos[:, modal_dove.model.nq:]
    assert q.shape[1] == 56 and 1e-4 < np.abs(q).max() < 0.05


def test_engine_modes_follow_the_coupled_joints_in_flight(modal_dove):
    """The engine-integrated modes (the feathers' reaction on the bones: their aerodynamic
    forces, eq. 9) against the fully coupled MuJoCo joints (the deforming mass pushes back
    too) over 3 wingbeats of the base flight: P8's tip deflection follows the same curve,
    within 10 % of its range (the joints' soft twist limit and the left-out modal inertia on
    the bone differ: measured 2-4 %)."""
    out = []
    for dove in (modal_dove, Dove.load(feathers="modal", modal=ModalParams(integration="joints"))):
        fl = DoveFlight(dove, use_rollout=False)
        try:
            cfg = FlightConfig()
            from flapsim.bird.flight.wingbeat import p0, with_tail_bias

            p = with_tail_bias(p0(), cfg.tail_bias_deg)
            fl.reset(cfg, p)
            i = fl.modal.feather_index("l_p8")
            tips = []
            for _ in range(3):
                rec = fl.run_cycle(p)
                tips.append(rec.qpos[:, dove.model.nq + i] if fl.modes_in_userdata else
                            rec.qpos[:, fl.modal.qadr[i]])
            out.append(np.concatenate(tips) * fl.modal.modes[i].unit[0])
        finally:
            fl.close()
    eng, jnt = out
    assert np.ptp(eng) > 3e-3  # millimetres of bending
    assert np.abs(eng - jnt).max() < 0.10 * np.ptp(jnt)


def test_shaft_beam_static_matches_closed_form():
    """The beam elements alone (before the modal truncation) under a tip load."""
    L, ei = 0.11, (0.018, 0.0019)
    beam = ShaftBeam(L, ei, (1.0, 1.0), 16)
    f = np.zeros(beam.ndof)
    f[3 * 16] = 1e-3
    free = np.arange(3, beam.ndof)
    u = np.linalg.solve(beam.K[np.ix_(free, free)], f[free])
    assert u[3 * 16 - 3] == pytest.approx(euler_bernoulli_tip_deflection(1e-3, L, ei), rel=1e-3)


@pytest.mark.parametrize("integration", MECHANISMS)
def test_own_weight_sag_matches_the_beam(params, integration):
    """Gravity acts on the modes (the D'Alembert load of a bone accelerating at g): a clamped
    secondary, flat and horizontal, in vacuum, sags under its own weight as the full beam
    (all its elements, no modal truncation) does under the same distributed load."""
    from flapsim.bird.body.feather_modes import _quadrature
    from flapsim.bird.body.params import left_feathers

    mp = ModalParams(damping_ratio=1.0, integration=integration)
    fm, m, prov = _clamped(params, "l_s5", mp, density=0.0, gravity=True)
    d = mujoco.MjData(m)
    with prov.register(d):
        mujoco.mj_step(m, d, nstep=600)
    v = prov.body_vertices(prov.coordinates(d)[0], 0)
    tip = np.flatnonzero(fm.vert_station == fm.stations - 1)
    sag = float(np.mean((v[tip] - fm.vertices[tip]) @ fm.normal))
    # the beam: load rho g over the vane, integrated over the triangles
    fe = next(f for f in left_feathers(params) if f.name == "l_s5")
    beam = ShaftBeam(fm.length, fm.ei, fm.gj, 32)
    pts, wts = _quadrature(fe.triangles)
    rho = fe.mass / wts.sum()
    f = np.zeros(beam.ndof)
    for pt, wt in zip(pts, wts, strict=True):
        f += -9.81 * rho * wt * beam.row((pt - fm.root) @ fm.shaft, (pt - fm.root) @ fm.chord)[0]
    free = np.arange(3, beam.ndof)
    u = np.zeros(beam.ndof)
    u[free] = np.linalg.solve(beam.K[np.ix_(free, free)], f[free])
    expected = beam.row(fm.length, 0.0)[0] @ u
    assert sag < 0
    assert sag == pytest.approx(expected, rel=0.05)


@pytest.mark.parametrize("integration", MECHANISMS)
def test_an_angular_acceleration_of_the_bone_loads_the_modes(params, integration):
    """The D'Alembert load of the bone's rotation: a clamped primary in vacuum on a heavy
    bone spun up at a constant angular acceleration alpha about an axis in the feather's plane
    settles (critically damped mode) at q = -Gamma n.(alpha x c) / k, c = S / Gamma the mode's
    centre (Q = -(Gamma n.a_o + n.(alpha x S)); a_o = 0 at the bone's origin on the axis).
    After 40 ms the spin (alpha t = 2 rad/s) adds w^2 |c| / (alpha |c|) = 8 % of centrifugal
    load at most: within the 10 % tolerance."""
    mp = ModalParams(damping_ratio=1.0, integration=integration)
    fm = _feather(params, "l_p6", mp)
    import xml.etree.ElementTree as ET

    root = ET.fromstring(clamped_feather_xml(fm, mp, params.timestep))
    ET.SubElement(root.find("worldbody/body"), "joint", name="spin", type="hinge",
                  axis=" ".join(map(str, fm.chord)))
    m = mujoco.MjModel.from_xml_string(ET.tostring(root, encoding="unicode"))
    prov = ModalFeathers(m, [fm], get_table("dickinson1999_profile"), 0.0, params=mp)
    d = mujoco.MjData(m)
    alpha = 50.0
    j = m.jnt_dofadr[mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, "spin")]
    with prov.register(d):
        mujoco.mj_forward(m, d)
        M = np.zeros((m.nv, m.nv))
        mujoco.mj_fullM(m, d, M)
        d.qfrc_applied[j] = alpha * M[j, j]
        mujoco.mj_step(m, d, nstep=int(round(0.04 / m.opt.timestep)))
    assert d.qvel[j] == pytest.approx(alpha * 0.04, rel=0.02)  # the bone spun up as asked
    c = fm.first_moment[0] / fm.gamma[0]
    expected = -fm.gamma[0] * fm.normal @ np.cross(alpha * fm.chord, c) / fm.stiffness[0]
    assert abs(expected) * fm.unit[0] > 1e-5  # a load that bends it measurably
    assert prov.coordinates(d)[0, 0] == pytest.approx(expected, rel=0.10)


def test_modes_couple_to_the_bone_by_their_participation(params):
    """The bone's acceleration loads mode k by Gamma_k (translation along the normal) and
    S_k x n (rotation): MuJoCo's mass matrix of a feather on a free bone has exactly these
    off-diagonal terms (the D'Alembert load and, by symmetry, its reaction on the bone)."""
    mp = ModalParams(modes=4, integration="joints")
    fm = _feather(params, "l_p6", mp)
    m = mujoco.MjModel.from_xml_string(clamped_feather_xml(fm, mp, params.timestep,
                                                           free_bone=True))
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    M = np.zeros((m.nv, m.nv))
    mujoco.mj_fullM(m, d, M)
    K = fm.omega.size
    for k in range(K):
        np.testing.assert_allclose(M[6 + k, 0:3], fm.gamma[k] * fm.normal, atol=1e-9 * fm.mass)
        np.testing.assert_allclose(M[6 + k, 3:6], np.cross(fm.first_moment[k], fm.normal),
                                   atol=1e-9 * fm.mass)
        assert M[6 + k, 6 + k] == pytest.approx(fm.mu[k], rel=1e-6)


@pytest.mark.parametrize("integration", MECHANISMS)
def test_aerodynamic_load_bends_the_feather_its_way(params, integration):
    """A clamped, flat primary in a 6 m/s updraft (no gravity): the air pushes it up and it
    bends up, and settles where its modal stiffness balances the generalized aerodynamic
    force (k q = Q to 0.1 %)."""
    from flapsim.fluid.flow import FlowField, Uniform

    mp = ModalParams(damping_ratio=1.0, integration=integration)
    fm = _feather(params, "l_p6", mp)
    m = mujoco.MjModel.from_xml_string(clamped_feather_xml(fm, mp, params.timestep))
    prov = ModalFeathers(m, [fm], get_table("dickinson1999_profile"), 1.225,
                         FlowField([Uniform((0.0, 0.0, 6.0))]), params=mp)
    d = mujoco.MjData(m)
    with prov.register(d):
        mujoco.mj_step(m, d, nstep=600)
        mujoco.mj_forward(m, d)
        rep = prov.evaluate(d)
        q = prov.coordinates(d)[0]
    assert rep.force.sum(0) @ fm.normal > 0
    v = prov.body_vertices(q, 0)
    tip = np.flatnonzero(fm.vert_station == fm.stations - 1)
    assert np.mean((v[tip] - fm.vertices[tip]) @ fm.normal) > 1e-4
    np.testing.assert_allclose(fm.stiffness * q, rep.generalized[0], rtol=1e-3)


def test_fly_command_takes_feathers_modal(tmp_path, modal_dove):
    import json

    from flapsim.cli.main import main

    out = tmp_path / "fly.json"
    assert main(["fly", "--feathers", "modal", "--wingbeats", "1", "--json", str(out)]) == 0
    res = json.loads(out.read_text())
    assert res["feathers"] == "modal" and res["model_hash"] != RIGID_HASH and res["finite"]


def test_calibration_scene_bends_at_the_downstroke_and_twists_at_the_upstroke():
    """The paper's Fig. 3/12 in the calibration scene (trunk fixed at 5 deg in a 7 m/s
    headwind, the reference wingbeat, engine-integrated modes): the outer primary's tip bends
    up (dorsally) under the downstroke's lift, and less (or down) in the upstroke; its vanes
    twist open at the upstroke (tens of degrees: the hinge's stop is at the twist limit) and
    stay nearly shut at the downstroke (a few degrees at most). The secondary, with no hinge,
    does not twist beyond its elastic twist (below 0.1 deg)."""
    from flapsim.bird.flight.calibration import record, summary

    res = summary(record(7.0, 5.0))
    p8, s5 = res["l_p8"], res["l_s5"]
    assert p8["downstroke_mean_deflection_mm"] > 1.0
    assert p8["downstroke_mean_deflection_mm"] > p8["upstroke_mean_deflection_mm"] + 2.0
    assert p8["upstroke_mean_twist_deg"] > 20.0 > 5.0 > p8["downstroke_mean_twist_deg"]
    assert max(abs(s5["upstroke_mean_twist_deg"]), abs(s5["downstroke_mean_twist_deg"])) < 0.1
