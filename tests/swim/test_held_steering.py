"""The per-cycle layer's steering settings of a stroke file: ``cycle_hold`` (a calibration
that holds each yaw sequence for several cycles), ``cycle_gain`` and ``cycle_lead``."""

from __future__ import annotations

import dataclasses
import math

import mujoco
import numpy as np
import pytest

from flapsim.core.errors import DataFileError, InputError
from flapsim.swim import per_cycle as cyc
from flapsim.swim.goals import Heading
from flapsim.swim.layers import BasicStrokeLayer
from flapsim.swim.model import Swimmer, SwimmerParams
from flapsim.swim.strokes import STROKE_DIR, STROKES, load_stroke, parse_stroke, stroke_path, stroke_tables

ROUNDED_CRAWL = str(STROKE_DIR / "rounded" / "crawl.toml")


@pytest.mark.parametrize("name", STROKES)
def test_the_bundled_box_strokes_keep_the_one_cycle_calibration(name):
    st = load_stroke(name)
    assert (st.cycle_hold, st.cycle_gain, st.cycle_lead) == (1, 1.0, 0.0)
    config = cyc.CalibrationConfig(str(stroke_path(name)), "", hold=st.cycle_hold)
    # every job swims the one cycle of the paper's calibration
    assert {config.cycles_of(s) for _, _, s, _ in config.jobs()} == {1}


def test_the_rounded_crawl_holds_its_yaw_sequences_only():
    st = load_stroke(ROUNDED_CRAWL)
    assert (st.cycle_hold, st.cycle_gain, st.cycle_lead) == (3, 0.5, 1.0)
    config = cyc.CalibrationConfig(ROUNDED_CRAWL, "", hold=st.cycle_hold)
    assert config.cycles_of(None) == 3  # the reference, to subtract its own drift
    assert [config.cycles_of(s) for s in ("yaw_left", "yaw_right")] == [3, 3]
    assert [config.cycles_of(s) for s in ("pitch_up", "pitch_down", "roll_left",
                                           "roll_right")] == [1, 1, 1, 1]
    # its bundled table was made from this very file on the rounded body
    cyc.load_table(st, layers="all", body_shape="rounded")


def _results(config: cyc.CalibrationConfig, ends: dict) -> dict[int, dict]:
    """Synthetic job results: ``ends[seq]`` = attitudes at each cycle's end."""
    out = {}
    for i, (mode, k, seq, w) in enumerate(config.jobs()):
        e = ends.get(seq, ends[None][:1])
        r = {"i": i, "layers": mode, "snapshot": k, "sequence": seq, "weight": w, "speed": 0.5,
             "start": [0.0, 0.0, 0.0], "end": e[0], "mean": [0.0, 0.0, 0.0]}
        if config.cycles_of(seq) > 1:
            r["ends"] = e
        out[i] = r
    return out


def test_a_held_turn_is_the_mean_per_cycle_after_the_first():
    config = cyc.CalibrationConfig(ROUNDED_CRAWL, "", (0,), (1.0,), layers=("cycle",), hold=3)
    # (yaw, pitch, roll) [rad] at the end of cycles 1..3; the reference drifts 0.1 rad left
    # a cycle; yaw_left's first cycle is the bent neck swinging the body line (0.3 rad)
    ends = {None: [[0.1, 0.01, 0.0], [0.2, 0.01, 0.0], [0.3, 0.01, 0.0]],
            "yaw_left": [[0.4, 0.0, 0.0], [0.6, 0.0, 0.0], [0.85, 0.0, 0.0]],
            "yaw_right": [[0.05, 0.0, 0.0], [-0.05, 0.0, 0.0], [-0.2, 0.0, 0.0]],
            "pitch_up": [[0.0, 0.05, 0.0]], "roll_left": [[0.0, 0.0, -0.05]]}
    t = cyc._assemble(config, _results(config, ends), {}, "cycle")
    # by hand: ((0.85 - 0.4) - (0.3 - 0.1)) / 2 = 0.125; right: -((-0.2 - 0.05) - 0.2) / 2
    assert t.angles["yaw_left"][0, 0] == pytest.approx(0.125, abs=1e-12)
    assert t.angles["yaw_right"][0, 0] == pytest.approx(0.225, abs=1e-12)
    # one-cycle sequences: end minus the reference's first cycle (roll_left: sign -1)
    assert t.angles["roll_left"][0, 0] == pytest.approx(0.05, abs=1e-12)
    assert t.angles["pitch_up"][0, 0] == pytest.approx(0.04, abs=1e-12)
    # across +-pi: 3.0 -> 3.1 -> -3.1 (3.1832) rad
    across = {**ends, "yaw_left": [[3.0, 0, 0], [3.1, 0, 0], [-3.1, 0, 0]]}
    t2 = cyc._assemble(config, _results(config, across), {}, "cycle")
    turn = ((-3.1 + 2 * math.pi - 3.0) - 0.2) / 2  # unwrapped by hand
    assert t2.angles["yaw_left"][0, 0] == pytest.approx(turn, abs=1e-12)
    # held once (the default), the same ends give the paper's one-cycle turn: 0.4 - 0.1
    one = dataclasses.replace(config, hold=1)
    t1 = cyc._assemble(one, _results(one, ends), {}, "cycle")
    assert t1.angles["yaw_left"][0, 0] == pytest.approx(0.3, abs=1e-12)


def test_a_held_calibration_measures_what_a_direct_swim_does():
    # the rounded crawl from rest, yaw_left at weight 1 for 3 cycles, swum here directly
    st = load_stroke(ROUNDED_CRAWL)
    config = cyc.CalibrationConfig(ROUNDED_CRAWL, "", (0,), (1.0,), {"body_shape": "rounded"},
                                   layers=("cycle",), hold=3)
    jobs = config.jobs()
    idx = {s: i for i, (_, _, s, _) in enumerate(jobs) if s in (None, "yaw_left")}
    worker = cyc.CalibrationWorker(config)
    res = {i: worker.run_job(i) for i in idx.values()}

    def direct(seq: str | None) -> list[np.ndarray]:
        sw = Swimmer(SwimmerParams(body_shape="rounded"))
        layer = BasicStrokeLayer(sw, st)
        sw.reset(st.posture, qpos_joints=layer.start_pose(0.0))
        if seq is not None:
            layer.set_tables(stroke_tables(st, sw.joints, 240, {seq: 1.0}))
        m, d = sw.model, sw.data
        out = []
        with sw:
            for c in range(3):
                i = 0
                while layer.cycles == c:
                    if i % 5 == 0:  # the flow at 50 Hz, counted from each cycle's start
                        sw.update_flow()
                    layer.apply(d, m.opt.timestep)
                    mujoco.mj_step(m, d)
                    i += 1
                out.append(cyc.attitude(d, sw.body["pelvis"], 2, sw.body["head"]))
        return out

    ref, left = direct(None), direct("yaw_left")
    want = (cyc.wrap_angle(left[2][0] - left[0][0]) - cyc.wrap_angle(ref[2][0] - ref[0][0])) / 2
    t = cyc._assemble(config, res, {}, "cycle")
    assert t.angles["yaw_left"][0, 0] == pytest.approx(want, abs=1e-9)  # same steps, same state
    assert want > math.radians(2.0)  # bending the neck left (and the back right) turns left


def _layer(gain: float = 1.0, lead: float = 0.0, turn: float = 0.2):
    """A CycleLayer on the rounded crawl (its settings replaced) over a table whose yaw
    sequences turn ``turn`` rad per cycle at weight 1, linearly in the weight."""
    st = dataclasses.replace(load_stroke(ROUNDED_CRAWL), cycle_gain=gain, cycle_lead=lead)
    sw = Swimmer(SwimmerParams(body_shape="rounded"))
    basic = BasicStrokeLayer(sw, st)
    sw.reset(st.posture, qpos_joints=basic.start_pose(0.0))
    w = np.array(cyc.WEIGHTS)
    row = np.tile(w * turn, (2, 1))
    table = cyc.CycleTable("crawl", np.array([0.0, 2.0]), w,
                           {n: row if n.startswith("yaw") else 0 * row for n in st.cycle},
                           np.zeros((2, 3)), np.zeros((2, 2)))
    yaw0 = cyc.attitude(sw.data, sw.body["pelvis"], 2, sw.body["head"])[0]
    return sw, basic, table, float(yaw0)


@pytest.mark.parametrize("gain, weight", [(1.0, 0.75), (0.5, 0.375)])
def test_cycle_gain_scales_the_turn_asked(gain, weight):
    sw, basic, table, yaw0 = _layer(gain=gain)
    layer = cyc.CycleLayer(basic, table, target=Heading(yaw0 + 0.15))
    w = layer.update(sw.data)
    # asked: gain x 0.15 rad of a table turning 0.2 rad per unit weight
    assert w["yaw_left"] == pytest.approx(weight, abs=1e-9) and w["yaw_right"] == 0.0


@pytest.mark.parametrize("lead, weight", [(0.0, 0.65), (1.0, 0.4), (2.0, 0.15)])
def test_cycle_lead_aims_from_where_the_last_turn_carries_the_swimmer(lead, weight):
    sw, basic, table, yaw0 = _layer(lead=lead)
    layer = cyc.CycleLayer(basic, table, target=Heading(yaw0 + 0.18))
    assert layer.update(sw.data)["yaw_left"] == pytest.approx(0.9, abs=1e-9)
    # the whole swimmer turned 0.05 rad left by the next cycle's start
    q = sw.data.qpos[3:7].copy()
    turn = np.array([math.cos(0.025), 0.0, 0.0, math.sin(0.025)])
    mujoco.mju_mulQuat(sw.data.qpos[3:7], turn, q)
    mujoco.mj_forward(sw.model, sw.data)
    basic.cycles += 1
    # error 0.18 - 0.05 - lead x 0.05 rad at 0.2 rad per unit weight
    assert layer.update(sw.data)["yaw_left"] == pytest.approx(weight, abs=1e-6)


@pytest.mark.parametrize("key, bad", [("cycle_hold", 0), ("cycle_hold", 1.5), ("cycle_hold", True),
                                      ("cycle_hold", 11), ("cycle_gain", 0.0),
                                      ("cycle_gain", float("inf")), ("cycle_gain", "x"),
                                      ("cycle_lead", -1.0), ("cycle_lead", 6)])
def test_bad_settings_are_refused_in_one_line(key, bad):
    raw = {"keys": {"neck": {"bend": [[0.0, 0.0]]}}, key: bad}
    with pytest.raises(DataFileError, match=key) as exc:
        parse_stroke(raw, "x.toml")
    assert "\n" not in str(exc.value)


def test_a_layer_refuses_a_stroke_given_a_non_finite_gain():
    sw, basic, table, _ = _layer()
    basic.stroke = dataclasses.replace(basic.stroke, cycle_gain=float("nan"))
    with pytest.raises(InputError, match="cycle_gain") as exc:
        cyc.CycleLayer(basic, table)
    assert "\n" not in str(exc.value)
