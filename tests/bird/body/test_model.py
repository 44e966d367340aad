"""The dove MJCF: generated from its parameter file, mass, DOF, feathers, no self-contact."""

import copy

import mujoco
import numpy as np
import pytest

from flapsim.bird.body.model import Dove, build_xml, can_touch_anything, model_path
from flapsim.bird.body.params import DOF_NAMES, DoveParams
from flapsim.bird.flight.dove_flight import fly
from flapsim.core.errors import DataFileError


@pytest.fixture(scope="module")
def dove():
    return Dove.load()


def test_bundled_xml_is_generated_from_the_parameter_file():
    # exact text equality: editing dove.toml without regenerating must fail here
    assert model_path().read_text() == build_xml(DoveParams.load())


def test_mass_and_dof(dove):
    m = dove.model
    # 0.170 kg is the parameter; the generator must distribute exactly that (float rounding
    # of the written inertials is 6 significant digits -> 1e-5 relative)
    assert dove.mass == pytest.approx(0.170, rel=1e-4)
    assert m.nu == 14 and tuple(DOF_NAMES) == tuple(
        mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_ACTUATOR, i) for i in range(m.nu))
    assert m.jnt_type[0] == mujoco.mjtJoint.mjJNT_FREE  # unactuated free root
    assert m.opt.timestep == pytest.approx(1 / 2400, rel=1e-9)


def test_feather_counts_and_twist_joints(dove):
    m = dove.model
    names = [mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_GEOM, g) for g in dove.feather_geoms()]
    for side in "lr":
        assert sum(n.startswith(f"{side}_p") for n in names) == 10
        assert sum(n.startswith(f"{side}_s") for n in names) == 9
    assert sum(n[2] == "r" for n in names) == 12  # l_r*, r_r*: the tail fan
    for side in "lr":
        for k in range(1, 11):
            j = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, f"{side}_p{k}_twist")
            # the stops are the force engine's (flapsim.fluid.hinges), not a MuJoCo limit
            assert not m.jnt_limited[j] and m.jnt_range[j, 0] == 0.0 and m.jnt_range[j, 1] > 0.5
            assert m.jnt_stiffness[j] == pytest.approx(0.6e-4)  # paper value
            assert m.dof_damping[m.jnt_dofadr[j]] == pytest.approx(0.6e-5)


def test_no_self_collision_in_any_pose(dove):
    m = copy.copy(dove.model)
    # the loaded dove skips collision detection (nothing can touch: next test); look anyway
    m.opt.disableflags &= ~int(mujoco.mjtDisableBit.mjDSBL_CONTACT)
    d = mujoco.MjData(m)
    rng = np.random.default_rng(1)
    for _ in range(20):
        d.qpos[7:] = rng.uniform(-1.5, 1.5, m.nq - 7)
        mujoco.mj_forward(m, d)
        assert d.ncon == 0  # folded wings overlap the trunk and tail: still no contact


def test_wings_are_mirror_images(dove):
    b, tris, fwd, names = dove.feather_triangles()
    # same triangles, y negated (order within a feather may differ only by winding)
    lt = np.array([t for n, t in zip(names, tris, strict=True) if n.startswith("l_")])
    rt = np.array([t for n, t in zip(names, tris, strict=True) if n.startswith("r_")])
    assert len(lt) == len(rt) == 132  # 28 left feathers: 10 P x 6, 9 S x 4, 3 T x 4, 6 R x 4
    assert np.allclose(np.sort(lt[:, :, 1].ravel()), np.sort(-rt[:, :, 1].ravel()), atol=1e-9)
    # every polygon's forward direction points toward the leading edge (+x side)
    assert (fwd[:, 0] > 0.0).all()


def test_bad_parameter_file_is_one_line(tmp_path):
    bad = tmp_path / "dove.toml"
    bad.write_text("[body]\ntotal_mass = 0.17\n")
    with pytest.raises(DataFileError, match="lacks key"):
        DoveParams.load(bad)


def test_the_cruise_captures_cycles_sit_inside_the_ranges_with_margin(dove):
    from flapsim.bird.body.params import dof_ranges
    from flapsim.bird.flight.capture import reference_capture
    from flapsim.bird.flight.dove_flight import CRUISE

    lo, hi = dof_ranges(dove.params)
    cap = reference_capture(with_mirror=True, preset="cruise").angles
    biased = cap.copy()
    biased[:, DOF_NAMES.index("tail_bend")] += np.radians(CRUISE.tail_bias_deg)
    # the contract the slow capture keeps (below): 10 deg inside every range, tail as flown
    margin = np.radians(10.0)
    for poses in (cap, biased):
        assert (poses.min(axis=0) >= lo + margin).all()
        assert (poses.max(axis=0) <= hi - margin).all()


def test_ranges_contain_the_reference_and_every_capture_cycle_with_margin(dove):
    from flapsim.bird.body.params import dof_ranges
    from flapsim.bird.flight.capture import reference_capture
    from flapsim.bird.flight.wingbeat import p0, reference_wingbeat, with_tail_bias

    lo, hi = dof_ranges(dove.params)
    assert lo.shape == hi.shape == (14,) and (lo < hi).all()
    ref = reference_wingbeat()
    p = with_tail_bias(p0(), 17.0)  # the flown base wingbeat (paper's +17 deg tail bias)
    q, _ = ref.evaluate(p, np.linspace(0.0, ref.duration(p), 400, endpoint=False))
    cap = reference_capture(with_mirror=True).angles  # every frame of every cycle, both hands
    tail = DOF_NAMES.index("tail_bend")
    biased = cap.copy()
    biased[:, tail] += np.radians(17.0)  # capture cycles as flown with the tail bias
    # a controller samples around these poses: every one must sit 10 deg inside the ranges
    # (the parameter file's ranges were placed with >= 13 deg to spare; 10 deg is the contract)
    margin = np.radians(10.0)
    for poses in (q, cap, biased):
        assert (poses.min(axis=0) >= lo + margin).all()
        assert (poses.max(axis=0) <= hi - margin).all()


def test_mjcf_carries_the_ranges_and_torque_limits(dove):
    from flapsim.bird.body.params import dof_ranges, torque_limits

    m = dove.model
    lo, hi = dof_ranges(dove.params)
    tlo, thi = torque_limits(dove.params)
    for i, name in enumerate(DOF_NAMES):
        if name == "tail_spread":  # a tendon: its range limits the whole fan
            t = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_TENDON, name)
            assert m.tendon_limited[t]
            got = m.tendon_range[t]
        else:
            j = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, name)
            assert m.jnt_limited[j]
            got = m.jnt_range[j]
        # written with 6 significant digits
        assert got == pytest.approx([lo[i], hi[i]], rel=1e-5)
        assert m.actuator_forcelimited[i]
        assert m.actuator_forcerange[i] == pytest.approx([tlo[i], thi[i]], rel=1e-6)
    # the pectoralis figure: Pennycuick 1968, 1.00 N m for a 400 g pigeon x (0.170 / 0.400)
    assert -tlo[DOF_NAMES.index("l_shoulder_flap")] == pytest.approx(1.00 * 0.170 / 0.400, abs=0.01)
    # mirror-symmetric joints: one range and one limit per left/right pair
    assert np.array_equal(lo[:6], lo[6:12]) and np.array_equal(tlo[:6], tlo[6:12])


def test_tail_is_one_fan_that_spreads_with_uniform_spacing():
    from flapsim.bird.body.params import rectrix_joints

    dove = Dove.load()
    m, p = dove.model, dove.params
    m.opt.gravity[:] = 0.0  # only the tail servo acts (the other servos hold zero)
    d = mujoco.MjData(m)
    ts = DOF_NAMES.index("tail_spread")
    s = np.radians(30.0)
    for _ in range(1200):  # 0.5 s: the spread servo settles (torque-limited ramp, then PD)
        d.ctrl[:] = 0.0
        d.ctrl[ts] = p.pd_kp * s  # affine servo: ctrl = kp q_target
        mujoco.mj_step(m, d)
    tendon = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_TENDON, "tail_spread")
    assert d.ten_length[tendon] == pytest.approx(s, abs=1e-6)
    adr = [m.jnt_qposadr[mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, n)]
           for n in rectrix_joints(p)]
    n = p.rectrices_per_side
    closed = (np.arange(n) + 0.5) * p.tail_spacing_deg
    left = closed + np.degrees(d.qpos[adr[:n]])
    right = closed + np.degrees(d.qpos[adr[n:]])
    # one fan: the outermost pair turned by s, every rectrix in proportion, so the spacing is
    # uniform, 4 + 30 / 5.5 = 9.4545 deg, across the centre line too (no gap between halves)
    spacing = p.tail_spacing_deg + 30.0 / (n - 0.5)
    assert left[-1] - closed[-1] == pytest.approx(30.0, abs=1e-4)
    assert np.diff(left) == pytest.approx(np.full(n - 1, spacing), abs=1e-4)
    assert 2 * left[0] == pytest.approx(spacing, abs=1e-4)  # the central pair
    assert right == pytest.approx(left, abs=1e-9)  # mirror-symmetric fan


@pytest.mark.parametrize("edit", ["torque", "range", "timestep"])
def test_model_hash_changes_with_what_a_database_depends_on(edit):
    import dataclasses

    p = DoveParams.load()
    same = Dove.from_params(p).hash()
    assert Dove.from_params(DoveParams.load()).hash() == same  # deterministic
    if edit == "torque":  # a servo's torque limit decides which wingbeats a database holds
        lim = list(p.dof_torque_limit)
        lim[0] = (lim[0][0] * 1.1, lim[0][1])
        q = dataclasses.replace(p, dof_torque_limit=tuple(lim))
    elif edit == "range":
        rng = list(p.dof_range_deg)
        rng[1] = (rng[1][0] - 1.0, rng[1][1])
        q = dataclasses.replace(p, dof_range_deg=tuple(rng))
    else:
        q = dataclasses.replace(p, timestep=p.timestep / 2)
    assert Dove.from_params(q).hash() != same


def test_collision_detection_is_skipped_only_when_nothing_can_touch(dove):
    """The bundled scene has no collider outside the bird (its ground plane: contype 0) and
    its bones collide only with the world, so the loaded dove skips collision detection; the
    same dove over a colliding ground (contype 1, conaffinity 2 against the bones' 2 and 1)
    keeps it. Skipping it changes nothing: two wingbeats with and without are bit-identical."""
    assert dove.model.opt.disableflags & mujoco.mjtDisableBit.mjDSBL_CONTACT
    assert not can_touch_anything(dove.model)
    params = DoveParams.load()
    xml = build_xml(params).replace('<geom name="ground" type="plane" size="2000 2000 0.1" '
                                    'material="grid" contype="0"\n          conaffinity="0"/>',
                                    '<geom name="ground" type="plane" size="2000 2000 0.1" '
                                    'material="grid" contype="1" conaffinity="2"/>')
    grounded = Dove.from_model(mujoco.MjModel.from_xml_string(xml), params)
    assert can_touch_anything(grounded.model)
    assert not grounded.model.opt.disableflags & mujoco.mjtDisableBit.mjDSBL_CONTACT
    m = copy.copy(dove.model)
    m.opt.disableflags &= ~int(mujoco.mjtDisableBit.mjDSBL_CONTACT)
    a = fly(dove, 2)
    b = fly(Dove(m, dove.params, dove.trunk, dove.qadr, dove.dadr), 2)
    assert np.array_equal(a.trunk_pos, b.trunk_pos)
