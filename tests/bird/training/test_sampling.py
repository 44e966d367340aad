"""One-cycle API and phase-1 sampling."""

import mujoco
import numpy as np
import pytest

from flapsim.bird.flight import cycle
from flapsim.bird.flight.dove_flight import pitch_roll, pose_quat
from flapsim.bird.flight.wingbeat import (
    N_PARAMS,
    join,
    p0,
    project_to_ranges,
    reference_wingbeat,
    split,
)
from flapsim.bird.training.manifold import WingbeatSet
from flapsim.bird.training.sampling import (
    Ellipses,
    SampleWorker,
    SamplingConfig,
    in_ranges,
    trajectory_bounds,
)

#: this module's flight keeps its feather forces registered from test to test (conftest)
SHARED_FLIGHT = True


@pytest.fixture(scope="module")
def worker():
    w = SampleWorker(SamplingConfig(seed=11))
    yield w
    w.close()


def test_one_cycle_is_repeatable_from_a_snapshot(worker):
    fl = worker.flight
    rng = np.random.default_rng(0)
    snap = worker.pre_state(rng)
    a = cycle.fly_cycle(fl, snap, worker.P0)
    # a different wingbeat in between must not leak into the next run (warm start restored)
    dP = worker.draw_wingbeat(np.random.default_rng(5))
    cycle.fly_cycle(fl, snap, worker.P0 + dP)
    b = cycle.fly_cycle(fl, snap, worker.P0)
    np.testing.assert_array_equal(a.snapshot.physics, b.snapshot.physics)
    np.testing.assert_array_equal(a.S, b.S)


def test_reduced_state_is_position_and_heading_invariant(worker):
    # gravity is along z: moving the bird or turning it about z changes nothing physical
    fl = worker.flight
    snap = worker.pre_state(np.random.default_rng(1))
    a = cycle.fly_cycle(fl, snap, worker.P0)
    cycle.restore(fl, snap)
    d = fl.data
    psi = 1.1
    qz = np.array([np.cos(psi / 2), 0, 0, np.sin(psi / 2)])
    q = np.empty(4)
    mujoco.mju_mulQuat(q, qz, d.qpos[3:7].copy())
    Rz = np.array([[np.cos(psi), -np.sin(psi), 0], [np.sin(psi), np.cos(psi), 0], [0, 0, 1]])
    d.qpos[0:3] = (3.0, -7.0, 25.0)
    d.qpos[3:7] = q
    d.qvel[0:3] = Rz @ d.qvel[0:3]  # world-frame linear velocity turns with the bird
    mujoco.mj_forward(fl.model, d)
    b = cycle.fly_cycle(fl, None, worker.P0)
    # 250 steps of round-off (1e-16) amplified by the flapping dynamics stay far below 1e-7
    np.testing.assert_allclose(b.S, a.S, atol=1e-7)
    h_a, c_a = cycle.heading_and_climb(a.com_vel)
    h_b, c_b = cycle.heading_and_climb(b.com_vel)
    assert cycle.wrap(h_b - h_a) == pytest.approx(psi, abs=1e-7)
    assert c_b == pytest.approx(c_a, abs=1e-7)


def test_fit_recovers_a_known_wingbeat():
    ref = reference_wingbeat()
    rng = np.random.default_rng(2)
    s = 1 + 0.1 * rng.normal(size=14)
    t = 0.05 * rng.normal(size=14)
    P = join(s, t, 1.07)
    n = 96
    q, _ = ref.evaluate(P, np.arange(n) / n * ref.duration(P))
    # the fit is linear least squares on a model the data follow exactly: round-off only
    np.testing.assert_allclose(ref.fit(q, ref.duration(P)), P, atol=1e-9)


def test_ellipse_draws_stay_inside_and_have_the_uniform_disk_covariance():
    rng = np.random.default_rng(4)
    n = 400
    # one bin (bins=1): examples with a known covariance per joint
    C = np.array([[0.04, 0.01], [0.01, 0.01]])
    L = np.linalg.cholesky(C)
    dP = np.zeros((n, N_PARAMS))
    for j in range(14):
        dP[:, 2 * j:2 * j + 2] = rng.normal(size=(n, 2)) @ L.T
    dP[:, -1] = 0.02 * rng.normal(size=n)
    ws = WingbeatSet(dP, rng.normal(size=n), rng.normal(size=n))
    E = Ellipses.fit(ws, bins=1)
    sigma = 3.0
    draws = np.array([E.draw(rng, sigma)[0] for _ in range(4000)])
    Cfit = np.cov(dP[:, 0:2].T)
    x = draws[:, 0:2] - dP[:, 0:2].mean(axis=0)
    maha = np.einsum("ni,ij,nj->n", x, np.linalg.inv(Cfit), x)
    assert maha.max() <= sigma**2 * (1 + 1e-9)  # inside the sigma-scaled 1-std ellipse
    # a uniform unit disk has covariance I/4: the draws' covariance is sigma^2 C / 4
    # (4000 draws: ~3 % sampling error on a variance, 10 % allowed)
    np.testing.assert_allclose(np.cov(x.T), sigma**2 * Cfit / 4, rtol=0.1, atol=2e-3)
    w = draws[:, -1] - dP[:, -1].mean()
    assert np.abs(w).max() <= sigma * dP[:, -1].std() + 1e-12


def test_projection_keeps_every_commanded_angle_inside_the_ranges():
    ref = reference_wingbeat()
    lo = np.full(14, -0.3) + ref.mean
    hi = np.full(14, 0.3) + ref.mean
    P = p0()
    P[0:-1:2] = 1.8  # scales that swing past the ranges
    P[1:-1:2] = 0.4  # and shifts that leave them
    assert not in_ranges(ref, P, lo, hi)
    Pp = project_to_ranges(ref, P, lo, hi, margin=0.01)
    qmin, qmax = trajectory_bounds(ref, Pp)
    assert np.all(qmin >= lo + 0.01 - 1e-9) and np.all(qmax <= hi - 0.01 + 1e-9)
    # a wingbeat already inside is left alone
    P_in = p0()
    P_in[0:-1:2] = 0.5
    lo2, hi2 = trajectory_bounds(ref, P_in)
    np.testing.assert_array_equal(project_to_ranges(ref, P_in, lo2 - 0.1, hi2 + 0.1), P_in)
    assert split(Pp)[2] == split(P)[2]


def test_pose_quat_pitch_and_roll_follow_pitch_roll():
    for pitch, roll in ((0.3, 0.0), (0.0, 0.4), (-0.2, -0.5)):
        R = np.zeros(9)
        mujoco.mju_quat2Mat(R, pose_quat(pitch, roll, heading=0.7))
        p, r = pitch_roll(R.reshape(3, 3))
        assert p == pytest.approx(pitch, abs=1e-12) and r == pytest.approx(roll, abs=1e-12)


def test_samples_depend_only_on_seed_and_index(worker):
    a, why_a = worker.sample(3)
    worker.sample(8)
    b, why_b = worker.sample(3)
    assert why_a == why_b
    if a is not None:
        for k in a:
            np.testing.assert_array_equal(a[k], b[k])


def test_pre_state_is_drawn_in_the_papers_ranges(worker):
    for i in range(20):
        snap = worker.pre_state(np.random.default_rng([11, i]))
        cycle.restore(worker.flight, snap)
        S = worker.flight.reduced_state()
        assert abs(S[0]) <= np.radians(45) + 1e-12 and abs(S[1]) <= np.radians(45) + 1e-12
        assert np.all(np.abs(S[2:5] - [7.0, 0, 0]) <= 0.3 + 1e-12)
        assert np.all(np.abs(S[5:8]) <= np.radians(4) + 1e-12)


def test_a_chunk_holds_samples_and_counts_rejections(worker):
    res = worker.run_chunk(0, 6)
    assert len(res.index) + sum(res.rejected.values()) == 6
    assert res.arrays["dP"].shape == (len(res.index), N_PARAMS)
    # dS is measured against P0 from the same state: S0 + dS is where P0 + dP ended
    assert np.all(np.isfinite(res.arrays["dS"]))
    for i, idx in enumerate(res.index):
        P = worker.P0 + res.arrays["dP"][i]
        assert in_ranges(worker.ref, P, worker.lo, worker.hi)
        del idx


def test_snapshots_carry_the_solver_warm_start(worker):
    # a wingbeat that presses the elbows into their joint limit keeps a limit constraint
    # active across the wingbeat boundary: the constraint solver then starts from
    # qacc_warmstart, so a snapshot without it would not repeat bit for bit
    from flapsim.bird.body.params import DOF_NAMES

    fl = worker.flight
    press = worker.P0.copy()
    for side in "lr":
        press[2 * DOF_NAMES.index(f"{side}_elbow_flex") + 1] += 0.8  # past the 110 deg limit
    snap = cycle.fly_cycle(fl, worker.pre_state(np.random.default_rng(3)), press).snapshot
    assert fl.data.nefc > 0  # a limit is active at the boundary
    a = cycle.fly_cycle(fl, snap, press)
    cycle.fly_cycle(fl, snap, worker.P0)  # leaves another warm start behind
    b = cycle.fly_cycle(fl, snap, press)
    np.testing.assert_array_equal(a.snapshot.physics, b.snapshot.physics)


def test_wingbeats_leaving_a_joint_range_are_never_drawn():
    # with wide ellipses (sigma 8) many draws cross a range: each is refused (None), and
    # every wingbeat returned keeps its whole commanded trajectory inside every range
    w = SampleWorker(SamplingConfig(seed=5, sigma=8.0))
    try:
        rng = np.random.default_rng(0)
        draws = [w.draw_wingbeat(rng) for _ in range(300)]
        kept = [d for d in draws if d is not None]
        assert 0 < len(kept) < len(draws)
        for dP in kept:
            qmin, qmax = trajectory_bounds(w.ref, w.P0 + dP)
            assert np.all(qmin >= w.lo) and np.all(qmax <= w.hi)
    finally:
        w.close()


def test_a_flight_without_its_feather_forces_refuses_to_fly():
    from flapsim.bird.body.model import Dove
    from flapsim.bird.flight.dove_flight import DoveFlight
    from flapsim.core.errors import SimulationError

    fl = DoveFlight(Dove.load())
    fl.reset()
    fl.close()  # unregisters the feather forces
    with pytest.raises(SimulationError, match="not registered"):
        cycle.fly_cycle(fl, None, p0())


def test_pre_states_centred_on_a_pitched_trim_fly_level():
    # a trunk pitched th nose up in level flight at v sees (v cos th, 0, -v sin th) in its own
    # frame: drawn with no spread, the pre-state is exactly that attitude and a level velocity
    c = SamplingConfig(seed=3, pitch_deg=0.0, roll_deg=0.0, linvel=0.0, angvel_deg_s=0.0,
                       pitch_centre_deg=18.0, cruise_speed=8.5)
    w = SampleWorker(c)
    try:
        cycle.restore(w.flight, w.pre_state(np.random.default_rng(0)))
        S = w.flight.reduced_state()
        th = np.radians(18.0)
        assert S[0] == pytest.approx(th, abs=1e-12)  # round-off of the quaternion only
        np.testing.assert_allclose(w.flight.data.qvel[0:3], [8.5, 0.0, 0.0], atol=1e-12)
        np.testing.assert_allclose(S[2:5], [8.5 * np.cos(th), 0.0, -8.5 * np.sin(th)], atol=1e-12)
        # spread around the centre: the pitch stays within centre +- range
        w2 = SampleWorker(SamplingConfig(seed=3, pitch_deg=10.0, pitch_centre_deg=18.0))
        try:
            for i in range(10):
                cycle.restore(w2.flight, w2.pre_state(np.random.default_rng([3, i])))
                assert abs(w2.flight.reduced_state()[0] - th) <= np.radians(10.0) + 1e-12
        finally:
            w2.close()
    finally:
        w.close()
    # the paper's level centre is not written, so older databases' headers are unchanged
    assert "pitch_centre_deg" not in SamplingConfig().to_dict()
    assert SamplingConfig(pitch_centre_deg=18.0).to_dict()["pitch_centre_deg"] == 18.0
