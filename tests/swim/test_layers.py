"""The per-cycle layer (tables, calibration, steering) and the continuous layer (the
paper's palm-orientation and arm-reach rules), on short horizons."""

from __future__ import annotations

import json
import math
import tomllib
from dataclasses import asdict

import mujoco
import numpy as np
import pytest

from flapsim import __version__
from flapsim.core.errors import DataFileError, InputError
from flapsim.core.io import _jsonable
from flapsim.swim import per_cycle as cyc
from flapsim.swim.goals import Point, Waypoints, load_trajectory
from flapsim.swim.layers import BasicStrokeLayer
from flapsim.swim.model import Swimmer
from flapsim.swim.simulate import swim
from flapsim.swim.strokes import load_stroke, parse_stroke, stroke_path, stroke_tables


def _table(angles_deg: dict, speeds=(0.0, 1.0), weights=(0.5, 1.0)) -> cyc.CycleTable:
    n = len(speeds)
    return cyc.CycleTable("t", np.asarray(speeds, float), np.asarray(weights, float),
                          {k: np.radians(np.asarray(v, float)) for k, v in angles_deg.items()},
                          np.zeros((n, 3)), np.zeros((n, 2)))


def test_weight_for_inverts_the_table():
    # turn per cycle: 10/20 deg at weights 0.5/1 at rest, 20/40 deg at 1 m/s
    t = _table({"yaw_left": [[10, 20], [20, 40]], "yaw_right": [[-5, -10], [-5, -10]],
                "pitch_up": [[10, 5], [10, 5]]})
    r = math.radians
    # at 0.5 m/s the curve is 15/30 deg (linear in speed): 15 deg needs w = 0.5, 7.5 deg
    # w = 0.25 (linear from 0 at w = 0), 60 deg is out of reach: the largest weight
    assert t.weight_for("yaw_left", 0.5, r(15.0)) == pytest.approx(0.5)
    assert t.weight_for("yaw_left", 0.5, r(7.5)) == pytest.approx(0.25)
    assert t.weight_for("yaw_left", 0.5, r(60.0)) == pytest.approx(1.0)
    # a speed beyond the table is clamped to its last row: 30 deg at 2 m/s -> 0.75
    assert t.weight_for("yaw_left", 2.0, r(30.0)) == pytest.approx(0.75)
    # no turn asked, the wrong way, a sequence that turns the wrong way, an unknown one
    assert t.weight_for("yaw_left", 0.5, 0.0) == 0.0
    assert t.weight_for("yaw_left", 0.5, r(-5.0)) == 0.0
    assert t.weight_for("yaw_right", 0.5, r(5.0)) == 0.0
    assert t.weight_for("roll_left", 0.5, r(5.0)) == 0.0
    # a curve that turns back (10 then 5 deg): its monotone envelope, 10 deg at w = 0.5
    assert t.weight_for("pitch_up", 0.5, r(10.0)) == pytest.approx(0.5)
    assert t.weight_for("pitch_up", 0.5, r(30.0)) == pytest.approx(0.5)


def test_table_files_round_trip_and_go_stale(tmp_path):
    st = load_stroke("crawl")
    t = cyc.load_table(st, layers="cycle")
    assert set(t.angles) == set(st.cycle)
    assert t.provenance["stroke_sha256"] == cyc.stroke_hash(st)
    back = cyc.CycleTable.from_dict(json.loads(json.dumps(_jsonable(t.to_dict()))))
    assert np.allclose(back.speeds, t.speeds) and np.allclose(back.angles["yaw_left"],
                                                               t.angles["yaw_left"])
    # an edited stroke file: its (copied) table no longer matches
    edited = tmp_path / "crawl.toml"
    edited.write_text(stroke_path("crawl").read_text() + "\n# edited\n")
    (tmp_path / "crawl.cycle.json").write_text(cyc.table_path(st).read_text())
    with pytest.raises(DataFileError, match="recalibrate"):
        cyc.load_table(load_stroke(str(edited)))
    (tmp_path / "crawl.cycle.json").unlink()
    with pytest.raises(InputError, match="--calibrate"):
        cyc.load_table(load_stroke(str(edited)))


def test_stroke_files_check_cycle_sections():
    raw = tomllib.loads(stroke_path("crawl").read_text())
    raw["cycle"]["spin"] = {"keys": {"neck": {"bend": [[0.0, 10]]}}}
    with pytest.raises(DataFileError, match="unknown per-cycle sequence"):
        parse_stroke(raw, "x.toml")
    raw = tomllib.loads(stroke_path("crawl").read_text())
    raw["cycle"]["yaw_left"]["feedback"] = {"heading_error": 1.0}
    with pytest.raises(DataFileError, match="calibration table"):
        parse_stroke(raw, "x.toml")


def _one_cycle_turn(stroke: str, seq: str | None) -> np.ndarray:
    """Attitude after one cycle from rest with ``seq`` at weight 1, computed here
    directly (not through the calibration worker)."""
    st = load_stroke(stroke)
    sw = Swimmer()
    layer = BasicStrokeLayer(sw, st)
    sw.reset(st.posture, qpos_joints=layer.start_pose(0.0))
    if seq is not None:
        layer.set_tables(stroke_tables(st, sw.joints, 240, {seq: 1.0}))
    m, d = sw.model, sw.data
    with sw:
        while layer.cycles == 0:
            if round(d.time / m.opt.timestep) % 5 == 0:
                sw.update_flow()
            layer.apply(d, m.opt.timestep)
            mujoco.mj_step(m, d)
    return cyc.attitude(d, sw.body["pelvis"], 2, sw.body["head"])


def test_calibration_measures_what_a_direct_swim_does_and_resumes(tmp_path):
    # one snapshot (rest), the crawl's yaw sequences at weight 1, layers "cycle"
    out = tmp_path / "c.cycle.json"
    kw = dict(snapshot_cycles=(0,), weights=(1.0,))
    tables, path = cyc.calibrate("crawl", out, workers=1, **kw)
    t = tables["cycle"]
    ref, left = _one_cycle_turn("crawl", None), _one_cycle_turn("crawl", "yaw_left")
    # the table's turn = the direct swim's yaw difference (same state, same steps)
    assert t.angles["yaw_left"][0, 0] == pytest.approx(cyc.wrap_angle(left[0] - ref[0]), abs=1e-9)
    assert t.angles["yaw_left"][0, 0] > math.radians(1.0)  # bending the neck left turns left
    prov = json.loads(path.read_text())["provenance"]
    assert prov["stroke_sha256"] == cyc.stroke_hash(load_stroke("crawl"))
    assert prov["flapsim_version"] and prov["config"]["weights"] == [1.0]
    # a bundled stroke is named by its place in the package, not this machine's checkout
    assert prov["config"]["stroke"] == "flapsim/swim/data/strokes/crawl.toml"
    # resumable: a journal holding some finished jobs is continued, not redone
    config = cyc.CalibrationConfig(str(stroke_path("crawl").resolve()),
                                   cyc.stroke_hash(load_stroke("crawl")), (0,), (1.0,))
    ident = {"flapsim_version": __version__, "config": asdict(config)}
    worker = cyc.CalibrationWorker(config)
    done = worker.run_chunk(0, 3)
    fake = [dict(r, end=[9.0, 9.0, 9.0]) if r["sequence"] == "yaw_right" else r for r in done]
    out2 = tmp_path / "d.cycle.json"
    journal = out2.with_name(out2.name + ".partial.jsonl")
    journal.write_text(json.dumps({"header": ident}) + "\n" + json.dumps({"results": fake})
                       + "\n{torn")
    tables2, _ = cyc.calibrate("crawl", out2, workers=1, **kw)
    assert not journal.exists()
    # the journalled (doctored) result was used, so it was not recomputed
    assert tables2["cycle"].angles["yaw_right"][0, 0] == pytest.approx(
        -cyc.wrap_angle(9.0 - ref[0]))
    assert tables2["cycle"].angles["yaw_left"][0, 0] == pytest.approx(t.angles["yaw_left"][0, 0])
    # a journal from another run is refused
    journal.write_text(json.dumps({"header": {"other": 1}}) + "\n")
    with pytest.raises(InputError, match="another calibration"):
        cyc.calibrate("crawl", out2, workers=1, **kw)


def test_per_cycle_layer_turns_towards_the_target_side():
    # a target 10 m to the left: after 6 s (5 cycles) the per-cycle layer has turned the
    # crawl left (measured +55 deg); the basic layer alone has not (measured +4 deg)
    def yaw_after(layers):
        r = swim("crawl", 6.0, target=Point(0.0, 10.0), layers=layers)
        return math.degrees(r.body_yaw[-25:].mean())
    assert yaw_after("cycle") > 30.0
    assert abs(yaw_after("basic")) < 15.0


def test_palm_rule_moves_treading_towards_a_target():
    # the paper's Fig. 13: treading water (with its balance rules) towards a target 10 m
    # ahead for 10 s; measured forward displacement 0.03 m without, 0.42 m with the palm
    # rule (the palms then face the water as it flows forwards past them)
    def forward(rules):
        r = swim("treading", 10.0, target=Point(10.0, 0.0), layers="all", rules=rules)
        return r.com[-1, 0] - r.com[0, 0]
    without, palm = forward(()), forward(("palm",))
    assert palm > without + 0.3


def test_palm_and_reach_speed_up_the_crawl():
    # measured over 12 s: 0.96 m/s (basic + per-cycle), 1.01 m/s with both hand rules
    cycle = swim("crawl", 12.0, layers="cycle").summary()
    full = swim("crawl", 12.0, layers="all").summary()
    assert full["speed_m_s"] > cycle["speed_m_s"] + 0.03
    assert full["hand_rules"]["rules"] == ["palm", "reach"]
    with pytest.raises(InputError, match="continuous rules"):
        swim("crawl", 0.1, rules=("wiggle",))


def test_layer_stack_switches_cleanly():
    seen = []

    def hook(sw, layer):
        st = layer.stack
        if not seen:
            st.set_mode("basic", float(sw.data.time))
            # the stroke's own tables are back and no hand offsets act
            assert np.array_equal(layer.tables.q, layer.base_tables.q)
            assert not layer.extra_on and not np.any(layer.extra)
        seen.append(st.mode)
        return True

    r = swim("crawl", 1.0, layers="all", control_hook=hook)
    assert r.layers == "basic" and set(seen) == {"basic"}


def test_targets_in_3d_and_trajectory_files(tmp_path):
    p = Point(3.0, 4.0, z=-2.0)
    assert p.elevation(np.array([0.0, 0.0, 0.0])) == pytest.approx(math.atan2(-2.0, 5.0))
    with pytest.raises(InputError, match="depth"):
        Point(0.0, 0.0, z=3.0)
    w = Waypoints(np.array([[1.0, 0.0, -1.0], [2.0, 0.0, 0.0]]), radius=0.5)
    w.update(np.array([0.9, 0.0, -0.8]), 3.0)  # within 0.5 m of the first
    assert w.current == 1 and w.reached[0] == 3.0 and w.reached[1] is None
    f = tmp_path / "t.csv"
    f.write_text("t, x, y, z\n0, 0, 0, 0\n10, 10, 0, -1\n")
    tr = load_trajectory(str(f))
    assert tr.is_3d and np.allclose(tr.position(5.0), (5.0, 0.0, -0.5))
    assert np.allclose(tr.position(20.0), (10.0, 0.0, -1.0))  # held after the end
    for text, match in (("0,0,0\n0,1,1\n", "increase"), ("0,0\n1,1\n", "expected"),
                        ("0,0,0\n1,1,1,1\n", "same number")):
        f.write_text(text)
        with pytest.raises(DataFileError, match=match):
            load_trajectory(str(f))


def test_calibration_refuses_to_assemble_without_every_cycle(tmp_path, monkeypatch):
    # an executor that brings nothing back: the tables would hold zeros for the missing
    # cycles, so calibrate says so in one line and writes no table
    from flapsim.core.parallel import ChunkExecutor, WorkerError

    monkeypatch.setattr(ChunkExecutor, "map_unordered", lambda self, chunks: iter(()))
    out = tmp_path / "c.cycle.json"
    with pytest.raises(WorkerError, match="no result came back") as e:
        cyc.calibrate("crawl", out, workers=1, snapshot_cycles=(0,), weights=(1.0,))
    assert "\n" not in str(e.value) and not out.exists()


def test_the_per_cycle_layer_holds_a_speed_asked():
    from flapsim.swim.per_cycle import RATE_RANGE

    # the crawl swims 1.02 m/s at its own 0.8 Hz; asked 0.7 m/s it strokes slower. The
    # settled speed (after two cycles) within 0.1 m/s: a cycle's speed lags its rate by
    # about one cycle, and the rate is corrected once per cycle
    s = swim("crawl", 20.0, speed=0.7).summary()
    assert abs(s["speed_m_s"] - 0.7) < 0.1
    assert RATE_RANGE[0] * 0.8 <= s["stroke_rate_hz"] < 0.7
    with pytest.raises(InputError, match="per-cycle layer"):
        swim("crawl", 1.0, speed=0.7, layers="basic")
    with pytest.raises(InputError, match="0.5..1.6"):
        swim("crawl", 1.0, speed=3.0)
    with pytest.raises(InputError, match="swims on the spot"):
        swim("treading", 1.0, speed=0.7)
