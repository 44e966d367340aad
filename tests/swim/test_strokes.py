"""Stroke files, the joint conventions, PD tracking, and short swims."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from flapsim.core.errors import DataFileError, InputError
from flapsim.swim.layers import BasicStrokeLayer
from flapsim.swim.model import Swimmer, SwimmerParams
from flapsim.swim.simulate import swim
from flapsim.swim.strokes import STROKES, Stroke, _pairs, _shifted, load_stroke, stroke_tables


@pytest.mark.parametrize("name", STROKES)
def test_bundled_strokes_load(name):
    st = load_stroke(name)
    sw = Swimmer(SwimmerParams(world="bare"))
    tab = stroke_tables(st, sw.joints, 120)
    assert tab.q.shape == (120, sw.model.nq - 7)
    assert tab.v.shape == (120, sw.model.nv - 6)
    assert np.all(np.isfinite(tab.q)) and np.all(np.isfinite(tab.v))
    # human stroke rates (REFERENCE_DATA: crawl 0.6-1.0, breaststroke 0.4-1.1 cycles/s)
    if name == "crawl":
        assert 0.6 <= st.rate_hz <= 1.0
    if name == "breaststroke":
        assert 0.4 <= st.rate_hz <= 1.1


def test_bad_stroke_files(tmp_path):
    bad = tmp_path / "bad.toml"
    bad.write_text('[keys.knee_l]\nflex = [[0.1, 1], [0.1, 2]]\n')
    with pytest.raises(DataFileError, match="same phase"):
        load_stroke(str(bad))
    bad.write_text("period_s = 0.01\n")
    with pytest.raises(DataFileError, match="period_s"):
        load_stroke(str(bad))
    with pytest.raises(InputError, match="unknown stroke"):
        load_stroke("butterfly")


def _pose(**deg) -> Stroke:
    return Stroke("pose", 1.0, "upright", "linear",
                  {k.replace("__", "."): (np.zeros(1), np.array([v])) for k, v in deg.items()})


@pytest.mark.parametrize("dof, expect", [
    ("shoulder_l__flex", (1, 0, 0)),  # arm raised forward (anterior = +x)
    ("shoulder_l__abd", (0, 1, 0)),  # left arm out to the left (+y)
    ("shoulder_r__abd", (0, -1, 0)),  # right arm out to the right
])
def test_anatomical_conventions(dof, expect):
    sw = Swimmer(SwimmerParams(world="bare"))
    layer = BasicStrokeLayer(sw, _pose(**{dof: 90.0}))
    d = sw.data
    sw.reset("upright", height=0.0, qpos_joints=layer.start_pose(0.0))
    side = dof.split("__")[0][-1]
    arm = d.xpos[sw.body[f"forearm_{side}"]] - d.xpos[sw.body[f"upper_arm_{side}"]]
    # exact geometry: the elbow sits one upper-arm length along the commanded direction
    assert np.allclose(arm / np.linalg.norm(arm), expect, atol=1e-9)


def test_pd_tracks_a_pose_in_still_air():
    sw = Swimmer(SwimmerParams(world="bare"))
    m, d = sw.model, sw.data
    m.opt.gravity[:] = 0.0  # only the muscles act: no water, no gravity
    target = _pose(shoulder_l__flex=60.0, elbow_l__flex=45.0, knee_r__flex=30.0, hip_r__abd=20.0)
    layer = BasicStrokeLayer(sw, target)
    sw.reset("upright", height=0.0)
    for _ in range(int(1.5 / m.opt.timestep)):
        layer.apply(d, m.opt.timestep)
        mujoco.mj_step(m, d)
    q = d.qpos
    adr = {n: m.jnt_qposadr[mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, n)]
           for n in ("elbow_flex_l", "knee_r")}
    # 1.5 s is > 10 time constants of these PD loops: within 1 deg of the targets
    assert np.degrees(q[adr["elbow_flex_l"]]) == pytest.approx(45.0, abs=1.0)
    assert np.degrees(q[adr["knee_r"]]) == pytest.approx(30.0, abs=1.0)
    qs = q[m.jnt_qposadr[mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, "shoulder_l")]:][:4]
    ang = np.degrees(2 * np.arccos(min(1.0, abs(qs[0]))))
    assert ang == pytest.approx(60.0, abs=1.5)


def test_faster_stroke_rate_is_honoured():
    r = swim("breaststroke", 4.0, rate_hz=1.0)
    assert r.rate_hz == 1.0
    assert r.cycles == 4  # the phase clock: exactly one cycle per second


def test_whole_turn_keys_are_periodic_up_to_the_turn():
    key = _pairs("t", [[0, 178], [0.25, 95], [0.47, 0], [0.75, -120], [1.0, -182]])
    assert key[2] == -360.0
    st = Stroke("t", 1.0, "prone", "pchip", {"a.b": key, "c.d": _shifted(key, 0.5)})
    x = np.linspace(0, 1, 2001)
    a = st.curve("a.b", x)
    # continuous across the cycle end once the turn is taken off (no 360 deg jump):
    # just before phase 1 the angle is ~ f(0) - 360
    assert abs(a[-2] - (a[0] - 360.0)) < 1.0
    assert np.abs(np.diff(a[:-1])).max() < 1.0
    # the mirrored copy is the same curve half a cycle later, up to whole turns
    c = st.curve("c.d", x)
    d = np.mod(c - st.curve("a.b", x - 0.5) + 180.0, 360.0) - 180.0
    assert np.allclose(d, 0.0, atol=1e-9)


def test_bad_stroke_files_are_one_line_errors(tmp_path):
    bad = tmp_path / "bad.toml"
    bad.write_text("name = 'x'\n[keys.shoulder_l]\nflex = [[0.0, 0], [1.0, 100]]\n")
    with pytest.raises(DataFileError, match="whole turns"):
        load_stroke(str(bad))
    bad.write_text("name = 'x'\n[keys.shoulder_l]\nwiggle = [[0.0, 0]]\n")
    with pytest.raises(DataFileError, match="unknown dof"):
        load_stroke(str(bad))
    bad.write_text("name = [\n")
    with pytest.raises(DataFileError, match="not valid TOML"):
        load_stroke(str(bad))


def test_perturbations_parse_and_blend(tmp_path):
    from flapsim.swim.layers import FeedbackLayer

    f = tmp_path / "p.toml"
    f.write_text(
        'posture = "upright"\n[keys.shoulder_l]\nabd = [[0.0, 40], [0.5, 60]]\n'
        '[perturb.up]\nfeedback = { tilt_x = 2.0, bias = 0.25 }\n'
        '[perturb.up.keys.shoulder_l]\nflex = [[0.0, 20]]\nabd = [[0.0, 10], [0.5, -10]]\n'
        '[mirror]\nshoulder_r = { from = "shoulder_l", shift = 0.5 }\n')
    st = load_stroke(str(f))
    p = st.perturbations["up"]
    assert p.gains == {"tilt_x": 2.0} and p.bias == 0.25
    x = np.linspace(0, 1, 9)
    # offsets add with their weight, and mirror like the keys (half a cycle later)
    assert np.allclose(st.curve("shoulder_l.flex", x, {"up": 0.5}), 10.0)
    assert np.allclose(st.curve("shoulder_r.abd", x, {"up": -1.0}),
                       st.curve("shoulder_l.abd", x - 0.5, {"up": -1.0}))
    sw = Swimmer(SwimmerParams(world="bare"))
    basic = BasicStrokeLayer(sw, st, nsamp=60)
    sw.reset("upright", height=0.0)
    fb = FeedbackLayer(basic)
    # upright and in place: w = bias; the blended tables at w = 1 are the stroke sampled
    # with the offsets (exactly: the blend's end point), at w = 0 the plain stroke
    w = fb.update(sw.data)
    assert w == {"up": 0.25}
    fb.basic.stroke.perturbations["up"] = type(p)("up", p.keys, {}, 1.0)
    fb.update(sw.data)
    full = stroke_tables(st, sw.joints, 60, {"up": 1.0})
    assert np.allclose(basic._tq.reshape(full.q.shape), full.q, atol=1e-12)
    fb.basic.stroke.perturbations["up"] = type(p)("up", p.keys, {}, -3.0)  # clipped to -1
    fb.update(sw.data)
    assert fb.weights["up"] == -1.0
    minus = stroke_tables(st, sw.joints, 60, {"up": -1.0})
    assert np.allclose(basic._tq.reshape(minus.q.shape), minus.q, atol=1e-12)


def test_feedback_signals_measure_lean_and_drift():
    from flapsim.swim.feedback import signals

    sw = Swimmer(SwimmerParams(world="bare"))
    sw.reset("upright", height=0.0)
    d = sw.data
    ref = sw.com()[:2].copy()
    # lean the whole body 10 deg forwards (about +y) and move it 0.2 m along +y
    a = np.radians(10.0)
    d.qpos[3:7] = (np.cos(a / 2), 0.0, np.sin(a / 2), 0.0)
    d.qpos[1] += 0.2
    d.qvel[:] = 0.0
    d.qvel[4] = 0.5  # pitching forwards at 0.5 rad/s (world angular velocity, y)
    mujoco.mj_forward(sw.model, d)
    s = signals(sw.model, d, sw.body["thorax"], sw.body["pelvis"], ref)
    assert s["tilt_x"] == pytest.approx(np.sin(a), abs=1e-9)
    assert s["tilt_y"] == pytest.approx(0.0, abs=1e-9)
    # d(sin lean)/dt = cos(lean) * rate
    assert s["tilt_rate_x"] == pytest.approx(np.cos(a) * 0.5, rel=1e-9)
    assert s["offset_y"] == pytest.approx(0.2, abs=1e-9)


def test_bad_perturbations_are_one_line_errors(tmp_path):
    bad = tmp_path / "bad.toml"
    head = "[keys.knee_l]\nflex = [[0.0, 10]]\n"
    bad.write_text(head + "[perturb.x]\nfeedback = { wobble = 1 }\n"
                   "[perturb.x.keys.knee_l]\nflex = [[0.0, 5]]\n")
    with pytest.raises(DataFileError, match="unknown signals"):
        load_stroke(str(bad))
    bad.write_text(head + "[perturb.x]\nfeedback = { tilt_x = 1 }\n")
    with pytest.raises(DataFileError, match="needs"):
        load_stroke(str(bad))
    bad.write_text(head + "[perturb.x.keys.shoulder_l]\nflex = [[0.0, 0], [1.0, 360]]\n")
    with pytest.raises(DataFileError, match="whole turns"):
        load_stroke(str(bad))
    bad.write_text(head + "[perturb.x]\nfeedback = { tilt_x = 'a' }\n"
                   "[perturb.x.keys.knee_l]\nflex = [[0.0, 5]]\n")
    with pytest.raises(DataFileError, match="numbers"):
        load_stroke(str(bad))


def test_perturbation_mirror_scale_gives_opposite_sides(tmp_path):
    f = tmp_path / "s.toml"
    f.write_text(
        '[keys.elbow_l]\npronation = [[0.0, 10]]\n'
        '[perturb.sway.keys.elbow_l]\npronation = [[0.0, 15], [0.5, -15]]\n'
        '[perturb.sway.mirror]\nelbow_r = { from = "elbow_l", scale = -1.0 }\n'
        '[mirror]\nelbow_r = { from = "elbow_l" }\n')
    st = load_stroke(str(f))
    x = np.linspace(0, 1, 11)
    # the keys mirror as usual, the perturbation's own mirror flips the offsets
    assert np.allclose(st.curve("elbow_r.pronation", x), 10.0)
    left = st.curve("elbow_l.pronation", x, {"sway": 1.0}) - 10.0
    right = st.curve("elbow_r.pronation", x, {"sway": 1.0}) - 10.0
    assert np.allclose(right, -left) and np.abs(left).max() == pytest.approx(15.0)


def test_feedback_smoothing_starts_at_zero_and_survives_a_reset(tmp_path):
    from flapsim.swim.layers import FeedbackLayer

    f = tmp_path / "s.toml"
    f.write_text('[keys.knee_l]\nflex = [[0.0, 10]]\n'
                 '[perturb.p]\nsmooth_s = 0.5\nfeedback = { bias = 1.0 }\n'
                 '[perturb.p.keys.knee_l]\nflex = [[0.0, 5]]\n')
    sw = Swimmer(SwimmerParams(world="bare"))
    basic = BasicStrokeLayer(sw, load_stroke(str(f)), nsamp=24)
    sw.reset("upright", height=0.0)
    fb = FeedbackLayer(basic)
    d = sw.data
    assert fb.update(d)["p"] == 0.0  # the first update moves nothing (dt = 0)
    d.time = 0.25
    assert fb.update(d)["p"] == pytest.approx(0.5)  # half way after half the time constant
    d.time = 0.0  # the simulation was reset: start over, no extrapolation
    assert fb.update(d)["p"] == 0.0
    d.time = 0.1
    assert 0.0 < fb.update(d)["p"] < 1.0
