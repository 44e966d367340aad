"""The per-joint power record of a budgeted swim (``swim(budget=True)``), checked against what
is known without it: the joints' work adds up to the energy balance that MuJoCo's own
bookkeeping closes, the kinetic energy is MuJoCo's, a rigid translation has no internal
kinetic energy (Koenig's theorem), and the joint groups hold the swimmer's 33 joint dofs as
its anatomy counts them."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from flapsim.swim.budget import JOINT_GROUPS, dof_groups, fold_segments, water_work_rates
from flapsim.swim.model import Swimmer, SwimmerParams
from flapsim.swim.simulate import SAMPLE_HZ, kinetic_energies, swim
from flapsim.swim.strokes import load_stroke, stroke_for_body

from .test_power import SECONDS, _work_of_everything_else


def test_the_joints_work_closes_the_energy_balance_and_records_mujocos_kinetic_energy() -> None:
    sw = Swimmer(SwimmerParams(body_shape="rounded"))
    st = load_stroke(stroke_for_body("crawl", "rounded"))
    r = swim(st, SECONDS, swimmer=sw, layers="basic", budget=True)
    jp = r.joint_power
    assert jp.shape == (len(r.times), sw.model.nv - 6, 4)
    # each sample after the first is the mean power since the previous one
    work = float(jp[1:, :, 0].sum()) / SAMPLE_HZ
    d_energy, other, _ = _work_of_everything_else(sw, st)
    # 1 %: the balance's own integration is first order in the step (0.3-0.4 % at 4 ms)
    assert work == pytest.approx(d_energy - other, rel=0.01)
    # a dof's positive part is never below its net, and the sum over dofs of the positive
    # parts is what the swim's positive count adds
    assert np.all(jp[:, :, 1] >= jp[:, :, 0] - 1e-12)
    assert float(jp[1:, :, 1].sum()) == pytest.approx(float(r.power_positive[1:].sum()), rel=1e-9)
    # the last recorded kinetic energy is MuJoCo's own (energy bookkeeping on) at that state
    m, d = sw.model, sw.data
    m.opt.enableflags |= mujoco.mjtEnableBit.mjENBL_ENERGY
    try:
        # _work_of_everything_else left the very same swim's end state in d
        mujoco.mj_forward(m, d)
        ke_mujoco = float(d.energy[1])
        ke, _ = kinetic_energies(m, d, mujoco.MjData(m), sw.body["pelvis"])
    finally:
        m.opt.enableflags &= ~int(mujoco.mjtEnableBit.mjENBL_ENERGY)
    assert ke == pytest.approx(ke_mujoco, rel=1e-9)
    # the summary's joint budget is the settled swim's, as its muscle power is
    jb = r.summary()["joint_budget"]
    assert jb["net_w"] == pytest.approx(r.summary()["muscle_power_mean_w"], rel=1e-9)
    assert jb["negative_w"] == pytest.approx(jb["positive_w"] - jb["net_w"], rel=1e-12)
    # per-segment water rates fold into the groups the budget reports
    assert np.allclose(fold_segments(r.water_rates_segments), r.water_rates, atol=1e-9)
    s = Swimmer(SwimmerParams(body_shape="rounded"))
    s.reset("prone")
    s.data.qvel[:] = 0.0
    s.data.qvel[3:6] = (0.2, -0.4, 0.9)
    mujoco.mj_forward(s.model, s.data)
    assert np.allclose(water_work_rates(s, per_segment=True).sum(axis=0),
                       water_work_rates(s).sum(axis=0), rtol=1e-12, atol=1e-12)


def test_a_rigid_translation_has_no_internal_kinetic_energy() -> None:
    sw = Swimmer(SwimmerParams())
    sw.reset("prone")
    m, d = sw.model, sw.data
    V = np.array([1.1, -0.3, 0.2])
    d.qvel[:] = 0.0
    d.qvel[0:3] = V
    total, internal = kinetic_energies(m, d, mujoco.MjData(m), sw.body["pelvis"])
    assert total == pytest.approx(0.5 * sw.mass * float(V @ V), rel=1e-9)
    assert abs(internal) < 1e-9 * total


def test_the_joint_groups_hold_the_swimmers_33_joint_dofs_by_anatomy() -> None:
    sw = Swimmer(SwimmerParams())
    g = dof_groups(sw.model)
    counts = dict(zip(JOINT_GROUPS, np.bincount(g, minlength=len(JOINT_GROUPS)), strict=True))
    # balls 3 dofs, hinges 1 (swimmer.xml): two shoulders; two elbows of flexion and
    # pronation; two wrists; lumbar, thoracic and neck balls; two hips; two knees; two
    # ankles of flexion and inversion
    assert counts == {"shoulders": 6, "elbows": 4, "wrists": 2, "trunk_neck": 9, "hips": 6,
                      "knees": 2, "ankles": 4}
