"""Stroke files, the joint conventions, PD tracking, and short swims."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from flapsim.errors import DataFileError, InputError
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
