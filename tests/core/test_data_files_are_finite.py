"""A NaN or an infinity in a data file was taken as a number (a swim table of NaN: the
swimmer never steered; MuJoCo compiled mass="inf"): every file a user passes or flapsim
loads refuses one in one line naming the file and the entry. Each case writes the same
file twice, once with a finite number at that entry (it loads) and once with a NaN or an
infinity there (refused), so only the number can make the difference."""

import json
import math
import os
from pathlib import Path

import numpy as np
import pytest

from flapsim.core.errors import DataFileError, FlapsimError

REPO = Path(__file__).resolve().parents[2]


def _refused(load, bad: Path, *fragments: str, kind=FlapsimError) -> str:
    with pytest.raises(kind) as e:
        load(bad)
    msg = str(e.value)
    assert "\n" not in msg, msg
    assert str(bad) in msg, msg
    assert "non-finite" in msg or "NaN" in msg, msg
    for f in fragments:
        assert f in msg, msg
    return msg


def test_the_walk_finds_the_first_non_finite_number_where_it_is():
    from flapsim.core.validate import nonfinite_entry, require_finite

    # places built by hand: the walk must name the same ones
    doc = {"a": 1, "b": {"c": [0.5, "nan", True, None, [2.0, math.inf]]}, "d": math.nan}
    assert nonfinite_entry(doc) == ("b.c[4][1]", math.inf)
    arr = np.zeros((4, 3))
    arr[2, 1] = -np.inf
    assert nonfinite_entry({"angles": arr}) == ("angles[2, 1]", -math.inf)
    assert nonfinite_entry({"x": np.float32(1.0), "y": np.arange(3)}) is None
    assert nonfinite_entry(["inf", "NaN"]) is None  # text is no number
    with pytest.raises(DataFileError, match=r"^f\.toml: k\[0\] is nan, a non-finite number"):
        require_finite({"k": [math.nan]}, "f.toml")


def _text_case(tmp_path, name, good_text, bad_text):
    good, bad = tmp_path / f"good_{name}", tmp_path / f"bad_{name}"
    good.write_text(good_text)
    bad.write_text(bad_text)
    return good, bad


def test_controller_config(tmp_path):
    from flapsim.bird.control.config import ControllerConfig

    good, bad = _text_case(tmp_path, "c.toml", "[controller]\ncarry = 0.5\n",
                           "[controller]\ncarry = nan\n")
    assert ControllerConfig.from_toml(good).carry == 0.5
    _refused(ControllerConfig.from_toml, bad, "controller.carry is nan")


def test_path_config(tmp_path):
    from flapsim.bird.tasks.config import PathControlConfig

    good, bad = _text_case(tmp_path, "p.toml", "[path]\nmax_bank_deg = 50.0\n",
                           "[path]\nmax_bank_deg = inf\n")
    assert PathControlConfig.from_toml(good).max_bank_deg == 50.0
    _refused(PathControlConfig.from_toml, bad, "path.max_bank_deg is inf")


def test_dove_parameter_file(tmp_path):
    from flapsim.bird.body.params import PARAM_FILE, DoveParams

    text = Path(PARAM_FILE).read_text()
    assert "total_mass = 0.170 " in text
    good, bad = _text_case(tmp_path, "dove.toml", text, text.replace("total_mass = 0.170 ",
                                                                     "total_mass = inf "))
    assert DoveParams.load(good).total_mass == 0.17
    _refused(DoveParams.load, bad, "body.total_mass is inf")


def test_stroke_file(tmp_path):
    from flapsim.swim.strokes import load_stroke, stroke_path

    text = stroke_path("crawl").read_text()
    key = "flex = [[0.00, 0], [0.10, 53],"
    assert key in text
    good, bad = _text_case(tmp_path, "s.toml", text,
                           text.replace(key, "flex = [[0.00, 0], [0.10, nan],"))
    assert load_stroke(str(good)).name == "crawl"
    _refused(lambda p: load_stroke(str(p)), bad, "keys.elbow_l.flex[1][1] is nan")


def test_swim_trajectory_and_path_files(tmp_path):
    from flapsim.swim.goals import load_path, load_trajectory

    good, bad = _text_case(tmp_path, "t.csv", "t,x,y,z\n0,0,0,-1\n5,3,1,-1\n",
                           "t,x,y,z\n0,0,0,-1\n5,3,1,-inf\n")
    assert load_trajectory(str(good)).table.shape == (2, 4)
    _refused(lambda p: load_trajectory(str(p)), bad, "line 3: z is -inf")
    good, bad = _text_case(tmp_path, "p.csv", "x,y\n0,0\n5,1\n", "x,y\n0,0\nnan,1\n")
    assert len(load_path(str(good)).points) == 2
    _refused(lambda p: load_path(str(p)), bad, "line 3: x is nan")


@pytest.mark.parametrize("name, good_text, bad_text, where", [
    ("p.csv", "x,y,z\n0,0,0\n10,0,2\n", "x,y,z\n0,0,0\n10,0,inf\n", "line 3: z is inf"),
    ("p.json", "[[0, 0, 0], [10, 0, 2]]", "[[0, 0, 0], [10, NaN, 2]]", "point 2: y is nan"),
])
def test_flight_path_file(tmp_path, name, good_text, bad_text, where):
    from flapsim.bird.tasks.path_control import load_path

    good, bad = _text_case(tmp_path, name, good_text, bad_text)
    assert load_path(good).points.shape == (2, 3)
    _refused(load_path, bad, where)


def test_capture_files(tmp_path):
    from flapsim.bird.flight.capture import (
        DATA_FILE,
        load_capture,
        reference_capture,
        write_bvh,
        write_csv,
    )

    cap = reference_capture()
    angles = cap.angles[:200]
    # CSV: one angle of frame 7 (file line 9) made NaN
    good = tmp_path / "good.csv"
    write_csv(good, angles, cap.rate_hz)
    lines = good.read_text().splitlines()
    cells = lines[8].split(",")
    cells[3] = "nan"
    bad = tmp_path / "bad.csv"
    bad.write_text("\n".join(lines[:8] + [",".join(cells)] + lines[9:]) + "\n")
    assert load_capture(good).angles.shape == angles.shape
    column = lines[0].split(",")[3]
    _refused(load_capture, bad, f"line 9: {column} is nan")
    # BVH: the frame time made infinite
    good = tmp_path / "good.bvh"
    write_bvh(good, angles, cap.rate_hz)
    bad = tmp_path / "bad.bvh"
    text = good.read_text()
    frame_time = next(ln for ln in text.splitlines() if ln.startswith("Frame Time:"))
    bad.write_text(text.replace(frame_time, "Frame Time: inf"))
    assert load_capture(good).angles.shape == angles.shape
    _refused(load_capture, bad, "Frame Time is inf")
    # flapsim npz: an angle NaN; a steering label NaN is "not labelled", infinite is refused
    with np.load(DATA_FILE) as z:
        arrays = {k: z[k] for k in z.files}
    good = tmp_path / "good.npz"
    np.savez(good, **{**arrays, "steering_deg": np.where(np.arange(len(arrays["steering_deg"]))
                                                         == 4, np.nan, arrays["steering_deg"])})
    assert np.isnan(load_capture(good).steering_deg[4])
    a = arrays["angles"].copy()
    a[5, 2] = np.nan
    bad = tmp_path / "bad.npz"
    np.savez(bad, **{**arrays, "angles": a})
    _refused(load_capture, bad, "angles[5, 2] is nan")
    s = arrays["steering_deg"].copy()
    s[4] = np.inf
    np.savez(bad, **{**arrays, "steering_deg": s})
    _refused(load_capture, bad, "steering_deg[4] is inf")


def test_centre_wingbeat_file(tmp_path):
    from flapsim.cli.commands.train import read_centre_wingbeat

    good, bad = _text_case(tmp_path, "w.json", json.dumps({"wingbeat": [0.5] * 29}),
                           json.dumps({"wingbeat": [0.5] * 28 + [math.inf]}))
    assert len(read_centre_wingbeat(str(good))) == 29
    _refused(lambda p: read_centre_wingbeat(str(p)), bad, "wingbeat[28] is inf")


_GAIT = """[gait]
name = "g"
stride = {stride}
[[modes]]
mode = 6
categories = ["A"]
sign = 1.0
amplitude = 0.3
phase_deg = 0.0
freq_hz = 1.5
beta = 0.0
"""


def test_gait_and_label_files(tmp_path):
    from flapsim.modal.legs import read_label_file
    from flapsim.modal.own import GaitFile

    good, bad = _text_case(tmp_path, "g.toml", _GAIT.format(stride=1.2), _GAIT.format(stride="nan"))
    assert GaitFile.read(good).stride == 1.2
    _refused(GaitFile.read, bad, "gait.stride is nan")
    good, bad = _text_case(tmp_path, "l.toml", "forward = [1.0, 0.0, 0.0]\n",
                           "forward = [1.0, -inf, 0.0]\n")
    assert read_label_file(good)["forward"] == [1.0, 0.0, 0.0]
    _refused(read_label_file, bad, "forward[1] is -inf")


def test_a_database_chunk(tmp_path):
    from flapsim.bird.control.database import load_database, save_database
    from flapsim.bird.training.fake_worker import FakeConfig, FakeWorker

    r = FakeWorker(FakeConfig(seed=3)).run_chunk(0, 10)
    header = {"model_hash": "m", "seed": 3, "config": {"seed": 3}}
    save_database(tmp_path / "good.db", header, r.index, r.arrays, r.rejected)
    y = r.arrays["y"].copy()
    y[2, 1, 0] = np.nan
    bad = tmp_path / "bad.db"
    save_database(bad, header, r.index, {**r.arrays, "y": y}, r.rejected)
    assert load_database(tmp_path / "good.db").n == len(r.index)
    _refused(load_database, bad, "y[2, 1, 0] is nan", "delete it and train again")


def test_training_rejects_a_sample_that_is_not_finite():
    from flapsim.bird.training.sampling import FIELDS, collect_chunk

    def sample(i):
        row = {k: np.full(shape, float(i)) for k, shape in FIELDS.items()}
        if i == 2:
            row["dS"][3] = np.nan
        return row, ""

    chunk = collect_chunk(sample, 0, 4)
    assert list(chunk.index) == [0, 1, 3] and chunk.rejected == {"non_finite": 1}


def test_an_eval_journal_line(tmp_path):
    from flapsim.scenarios.journal import RunJournal, journal_path

    path = journal_path(tmp_path / "r.json")
    result = {"scenario": "b", "family": "flight", "summary": "", "status": "completed",
              "ok": True, "metrics": {"Ep_per_wingbeat": 0.05}, "files": [], "reason": "",
              "wall_s": 1.0}
    j = RunJournal(path, ["k0", "k1"])
    j.open({0: result})
    j.close()
    bad = {**result, "metrics": {"Ep_per_wingbeat": math.nan}}
    with open(path, "a") as f:  # json writes NaN as it is; the journal's writer writes null
        f.write(json.dumps({"i": 1, "run": "k1", "result": bad}) + "\n")
    again = RunJournal(path, ["k0", "k1"])
    assert again.load() == {0: result}
    assert len(again.skipped) == 1 and again.skipped[0].startswith(f"{path} line 3: ")
    assert "result.metrics.Ep_per_wingbeat is nan" in again.skipped[0]


_MJCF = ('<mujoco><worldbody><body name="leg"><joint name="knee" type="hinge"/>'
         '<geom size="0.1" mass="{mass}"/></body></worldbody></mujoco>')


@pytest.mark.parametrize("mass, fragment", [
    ("inf", "body_mass[1] (body 'leg') is inf"),
    ("nan", "a number is NaN"),  # MuJoCo only warns, and puts its default in its place
])
def test_an_mjcf_model(tmp_path, monkeypatch, capsys, mass, fragment):
    from flapsim.cli.main import main
    from flapsim.core.loading import load_model

    good, bad = _text_case(tmp_path, "m.xml", _MJCF.format(mass=2.0), _MJCF.format(mass=mass))
    assert load_model(good).body_mass[1] == 2.0
    _refused(load_model, bad, fragment)
    monkeypatch.chdir(tmp_path)
    assert main(["modes", str(bad)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("flapsim modes: error: ") and fragment in err[0]
    assert sorted(os.listdir(tmp_path)) == ["bad_m.xml", "good_m.xml"]  # no MUJOCO_LOG.TXT


def test_the_bundled_data_files_are_finite():
    """The check refuses none of the files flapsim ships."""
    from flapsim.bird.control.controller import bundled_database_path
    from flapsim.bird.control.database import load_database
    from flapsim.core.loading import load_model

    for feathers in ("rigid", "modal"):
        assert load_database(bundled_database_path(feathers)).n > 0
    for model in sorted([*(REPO / "creatures").glob("*.xml"), *(REPO / "bird_mjcf").glob("*.xml"),
                         *(REPO / "swimmer_mjcf").glob("*.xml")]):
        load_model(model)
