"""``flapsim modes`` on a model from an arbitrary folder (with a mesh), and ``flapsim creature``."""

from __future__ import annotations

import json

import imageio.v2 as imageio
import numpy as np
import pytest

from flapsim.cli.main import main
from flapsim.core.loading import load_model
from flapsim.modal import analyze

OBJ = """v 0 0 0
v 0.1 0 0
v 0 0.1 0
v 0 0 0.1
f 1 3 2
f 1 2 4
f 1 4 3
f 2 3 4
"""

MODEL = """<mujoco model="foreign">
  <compiler meshdir="parts"/>
  <asset><mesh name="tet" file="tet.obj"/></asset>
  <worldbody><light pos="0 0 2"/>
    <body name="base" pos="0 0 1"><freejoint/><geom type="mesh" mesh="tet" density="500"/>
      <body name="arm" pos="0.1 0 0"><joint name="shoulder" axis="0 1 0" stiffness="2"/>
        <geom type="capsule" fromto="0 0 0 0.2 0 0" size="0.02"/>
        <site name="hand" pos="0.2 0 0"/>
        <body name="fore" pos="0.2 0 0"><joint name="elbow" type="ball" stiffness="1"/>
          <geom type="capsule" fromto="0 0 0 0.15 0 0" size="0.015"/></body>
      </body>
    </body>
  </worldbody>
</mujoco>
"""


@pytest.fixture()
def foreign_model(tmp_path, monkeypatch):
    folder = tmp_path / "elsewhere"
    (folder / "parts").mkdir(parents=True)
    (folder / "parts" / "tet.obj").write_text(OBJ)
    path = folder / "robot.xml"
    path.write_text(MODEL)
    work = tmp_path / "cwd"
    work.mkdir()
    monkeypatch.chdir(work)  # meshes must resolve relative to the model, not the cwd
    return path


def test_modes_command_writes_every_frequency_and_a_gif(foreign_model, tmp_path, capsys):
    out, gif = tmp_path / "modes.json", tmp_path / "modes.gif"
    rc = main(["modes", str(foreign_model), "--count", "2", "--json", str(out),
               "--video", str(gif), "--cycles", "0.5", "--constrain", "pin:hand"])
    assert rc == 0
    data = json.loads(out.read_text())
    expect = analyze(load_model(foreign_model), constraints=[])
    # nv = 6 + 1 + 3 = 10; pinning the hand removes exactly 3 (rank of a site pin).
    assert data["nv"] == 10 and data["n_modes"] == 7 and len(data["freqs_hz"]) == 7
    assert data["constraint_rank"] == 3
    assert expect.n_modes == 10
    frames = imageio.mimread(gif)
    # Two modes x half a cycle at 30 frames per cycle (the GIF encoder may merge
    # near-identical frames, so only the written count is exact).
    assert data["video"]["frames"] == 2 * 15 and data["video"]["modes"] == [3, 4]
    assert len(frames) > 10 and np.asarray(frames[5]).std() > 1.0
    assert "dominant joints" in capsys.readouterr().out


def test_modes_command_errors_are_one_line(foreign_model, tmp_path, capsys):
    bad = foreign_model.with_name("soft.xml")
    bad.write_text(MODEL.replace('stiffness="2"', "").replace('stiffness="1"', ""))
    assert main(["modes", str(bad)]) == 2
    err = capsys.readouterr().err.strip()
    assert "no joint or tendon stiffness" in err and "\n" not in err
    assert main(["modes", str(foreign_model), "--video", str(tmp_path / "x.avi")]) == 2
    assert not (tmp_path / "x.avi").exists()


def test_creature_command_json(tmp_path):
    out = tmp_path / "run.json"
    assert main(["creature", "--model", "loop", "--seconds", "1", "--no-progress",
                 "--json", str(out)]) == 0
    data = json.loads(out.read_text())
    assert data["creature"] == "loop" and data["simulated_s"] == pytest.approx(1.0)
    for key in ("distance_x_m", "distance_x_body_lengths", "mean_speed_m_s"):
        assert np.isfinite(data[key])
    assert main(["creature", "--model", "worm"]) == 2
