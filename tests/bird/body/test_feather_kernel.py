"""The optimised modal-feather kernel against a straightforward NumPy computation of the same
physics on a bent, moving dove: modal warping written out (Simpson's rule along the shaft,
the sections rotated by the bend and twist angles), the vertex Jacobians and deformation
velocities by complex-step differentiation of that warp (no hand-written derivative), and the
forces on each deformed triangle from the shared plate formula
(:func:`flapsim.fluid.surfaces.plate_force`), spread to the bone and to the modes by virtual work;
for the engine-integrated modes the primaries ride their twist hinges (the plate's frame turned
by the hinge angle about its axis, its points moving with the twist rate too)."""

import mujoco
import numpy as np
import pytest

from flapsim.bird.body.feather_dynamics import REC, ModalFeathers, modal_engine, modal_kernel
from flapsim.bird.body.feather_modes import ModalParams
from flapsim.bird.body.model import Dove
from flapsim.bird.flight.dove_flight import DoveFlight, FlightConfig
from flapsim.bird.flight.wingbeat import p0, with_tail_bias
from flapsim.fluid.coefficients import get_table
from flapsim.fluid.flow import FlowField, Uniform
from flapsim.fluid.surfaces import plate_force

WIND = np.array([1.5, -0.7, 0.4])


def _warp(fm, q):
    """Body-frame vertices of feather ``fm`` at (possibly complex) coordinates ``q``."""
    ng = fm.slope.shape[0]
    h = fm.length / (ng - 1)
    beta = fm.slope @ q
    tau = fm.twist @ q
    t = np.cos(beta)[:, None] * fm.shaft + np.sin(beta)[:, None] * fm.normal  # shaft tangent
    pair = h / 3 * (t[0:-2:2] + 4 * t[1:-1:2] + t[2::2])  # Simpson over each pair of intervals
    C = np.concatenate([np.zeros((1, 3)), np.cumsum(pair, axis=0)])[::fm.sub // 2]
    g = np.arange(fm.stations) * fm.sub
    nb = -np.sin(beta[g])[:, None] * fm.shaft + np.cos(beta[g])[:, None] * fm.normal
    chord = np.cos(tau[g])[:, None] * fm.chord + np.sin(tau[g])[:, None] * nb
    j = fm.vert_station
    return fm.root + C[j] + fm.vert_x[:, None] * chord[j]


def _rot(u, th):
    """Rotation by ``th`` about unit axis ``u`` (Rodrigues)."""
    ux = np.array([[0, -u[2], u[1]], [u[2], 0, -u[0]], [-u[1], u[0], 0]])
    return np.eye(3) + np.sin(th) * ux + (1 - np.cos(th)) * ux @ ux


def _reference(prov, m, d, density, cl, cd, hinges=None):
    """(per-triangle world force, body wrenches about the origin (nbody, 6) as torque|force,
    generalized forces of the modes (nfeathers, K), aerodynamic torque about each hinge)."""
    K = prov.K
    eps = 1e-30
    forces, wrench, Q = [], np.zeros((m.nbody, 6)), np.zeros((len(prov.modes), K))
    labels = list(hinges.label) if hinges is not None else []
    hinge_torque = np.zeros(len(labels))
    coords, rates = prov.state(d)
    for f, fm in enumerate(prov.modes):
        b = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, fm.body)
        q, qd = coords[f], rates[f]
        X = _warp(fm, q.astype(complex)).real
        J = np.stack([_warp(fm, q + 1j * eps * np.eye(K)[k]).imag / eps for k in range(K)], 1)
        U = _warp(fm, q + 1j * eps * qd).imag / eps  # deformation velocity, body frame
        Rb = d.xmat[b].reshape(3, 3)
        R, origin, spin, h = Rb, d.xpos[b], np.zeros(3), -1
        if fm.name in labels:  # on its twist hinge: the body frame turned about the axis
            h = labels.index(fm.name)
            jt = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, hinges.joint[h])
            th, thd = d.qpos[m.jnt_qposadr[jt]], d.qvel[m.jnt_dofadr[jt]]
            R = Rb @ _rot(hinges.axis[h], th)
            hinge_o = d.xpos[b] + Rb @ hinges.origin[h]
            origin = hinge_o - R @ hinges.origin[h]
            spin = thd * (Rb @ hinges.axis[h])
        P = origin + X @ R.T
        c = d.subtree_com[m.body_rootid[b]]
        om, lin = d.cvel[b, :3], d.cvel[b, 3:]
        for a, bb, cc in fm.faces:
            p = (P[a] + P[bb] + P[cc]) / 3
            av = np.cross(P[bb] - P[a], P[cc] - P[a])
            area = 0.5 * np.linalg.norm(av)
            n = av / np.linalg.norm(av)
            fwd = R[:, 0] - (R[:, 0] @ n) * n
            fwd /= np.linalg.norm(fwd)
            v = lin + np.cross(om, p - c) + R @ (U[a] + U[bb] + U[cc]) / 3
            if h >= 0:
                v = v + np.cross(spin, p - hinge_o)
            V = WIND - v
            s = np.cross(n, fwd)
            vs = V @ s
            out = plate_force(density, 0.0, area, *n, *V, V @ n, *(vs * s), -(V @ fwd), True, 0,
                              cl, cd)
            F = np.array(out[0:3]) + np.array(out[3:6]) + np.array(out[6:9])
            forces.append(F)
            wrench[b, :3] += np.cross(p, F)
            wrench[b, 3:] += F
            Jw = np.einsum("ij,vkj->vki", R, J[[a, bb, cc]])  # (3 vertices, K, 3) world
            Q[f] += Jw.sum(axis=0) @ F / 3
            if h >= 0:
                hinge_torque[h] += (Rb @ hinges.axis[h]) @ np.cross(p - hinge_o, F)
    return np.array(forces), wrench, Q, hinge_torque


@pytest.fixture(scope="module", params=[(1, "engine"), (4, "engine"), (1, "joints"), (4, "joints")],
                ids=["one mode", "four modes", "one mode on joints", "four modes on joints"])
def bent_state(request):
    """A modal dove (the default one mode per feather, and the paper's four: the kernel is
    compiled for each; the engine's modes and the joints') one wingbeat into the base flight,
    its modes then scaled (positions and rates) until the largest bend angle is 1.2 rad: both
    branches of the kernel's cos/sin."""
    modes, integration = request.param
    dove = Dove.load(feathers="modal", modal=ModalParams(modes=modes, integration=integration))
    fl = DoveFlight(dove)
    try:
        cfg = FlightConfig()
        p = with_tail_bias(p0(), cfg.tail_bias_deg)
        fl.reset(cfg, p)
        fl.run_cycle(p, record=False)
        for _ in range(60):  # into the downstroke
            mujoco.mj_step(fl.model, fl.data)
    finally:
        fl.close()
    m, d = fl.model, fl.data
    hinges = dove.twist_hinges() if integration == "engine" else None
    prov = ModalFeathers(m, fl.modal.modes, get_table(fl.table), 1.225,
                         FlowField([Uniform(tuple(WIND))]), hinges=hinges, params=dove.modal)
    q, qd = prov.state(d)
    top = max(np.abs(fm.slope @ q[f]).max() for f, fm in enumerate(prov.modes))
    mujoco.mj_forward(m, d)
    prov.set_coordinates(d, q * 1.2 / top, qd * 1.2 / top)
    if hinges is not None:  # the primaries twisted well open and turning
        for h in range(len(hinges)):
            jt = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, hinges.joint[h])
            d.qpos[m.jnt_qposadr[jt]] = 0.3 + 0.05 * h
            d.qvel[m.jnt_dofadr[jt]] = 20.0 - 2.0 * h
        mujoco.mj_forward(m, d)
    return m, d, prov, hinges


def test_kernel_equals_the_reference_on_a_bent_moving_dove(bent_state):
    m, d, prov, hinges = bent_state
    q = prov.coordinates(d)
    angles = np.concatenate([np.abs(fm.slope @ q[f]) for f, fm in enumerate(prov.modes)])
    assert angles.max() > 0.5 and np.median(angles) < 0.5  # the polynomial and libm both used
    rec = np.zeros(REC * prov.ntri + 3 * prov.nvert)
    w = np.zeros(6 * m.nbody)
    arrays = prov.arrays(m, d, record=rec)
    if prov.engine:
        arrays[prov.QFRC_ARG_ENGINE] = np.zeros(m.nv)
        arrays[-1] = d.userdata.copy()
        assert modal_engine(w, *arrays) == 0
        got_Q = arrays[21].reshape(len(prov.modes), prov.K)
        got_tau = arrays[25].reshape(len(hinges), -1)[:, 16]  # the hinges' aerodynamic torque
    else:
        qfrc = np.zeros(m.nv)
        arrays[7] = qfrc
        assert modal_kernel(w, *arrays) == 0
        got_Q = np.array([qfrc[a:a + prov.K] for a in prov.dadr])
    F, W, Q, tau = _reference(prov, m, d, 1.225, prov._cl, prov._cd, hinges)
    got_F = rec[:REC * prov.ntri].reshape(-1, REC)[:, 0:3]
    assert np.abs(F).max() > 1e-3  # a real load
    np.testing.assert_allclose(got_F, F, rtol=0, atol=1e-9 * np.abs(F).max())
    np.testing.assert_allclose(w.reshape(-1, 6), W, rtol=0, atol=1e-9 * np.abs(W).max())
    np.testing.assert_allclose(got_Q, Q, rtol=0, atol=1e-9 * np.abs(Q).max())
    if prov.engine:
        assert np.abs(tau).max() > 1e-6
        np.testing.assert_allclose(got_tau, tau, rtol=0, atol=1e-9 * np.abs(tau).max())


def test_kernel_cos_sin_is_libm_to_the_last_bits():
    """The warp's cos/sin (a polynomial below 1/2 rad) against libm across both branches."""
    from flapsim.bird.body.feather_dynamics import _cos_sin

    a = np.concatenate([np.linspace(-3.0, 3.0, 2001), np.geomspace(1e-12, 0.4999999, 500),
                        -np.geomspace(1e-12, 0.4999999, 500)])
    c, s = np.array([_cos_sin(x) for x in a]).T
    np.testing.assert_allclose(c, np.cos(a), rtol=4e-16, atol=0)
    np.testing.assert_allclose(s, np.sin(a), rtol=4e-16, atol=0)
