"""Offscreen video with a chase camera."""

import os
import subprocess
import sys
from pathlib import Path

import imageio.v2 as imageio
import mujoco
import numpy as np
import pytest

from flapsim.core.errors import InputError
from flapsim.core.loading import load_model
from flapsim.render.video import ChaseCamera, render_video

XML = """<mujoco><visual><global offwidth="320" offheight="240"/></visual><worldbody>
<geom type="plane" size="5 5 .1"/><body name="ball" pos="0 0 .5"><freejoint/>
<geom size=".1" rgba="1 0 0 1"/></body></worldbody></mujoco>"""


def test_video_follows_the_body(tmp_path):
    m = load_model(XML, is_xml=True)
    frames = np.tile(m.qpos0, (6, 1))
    frames[:, 0] = np.linspace(0, 3, 6)  # the ball flies 3 m: a fixed camera would lose it
    path = tmp_path / "v.mp4"
    n = render_video(m, frames, path, fps=10, camera=ChaseCamera("ball", distance=1.0, lead_m=0.0),
                     width=160, height=120)
    assert n == 6 and path.exists()
    imgs = [f for f in imageio.get_reader(str(path))]  # noqa: C416 (len() is inf for mp4)
    assert len(imgs) == 6
    # the red ball stays near the image centre in the last frame (chase camera)
    last = imgs[-1].astype(int)
    red = (last[:, :, 0] > last[:, :, 1] + 40) & (last[:, :, 0] > last[:, :, 2] + 40)
    ys, xs = np.nonzero(red)
    assert red.sum() > 20 and abs(xs.mean() - 80) < 40 and abs(ys.mean() - 60) < 40


def test_bad_inputs(tmp_path):
    m = load_model(XML, is_xml=True)
    with pytest.raises(InputError, match="no body named"):
        render_video(m, m.qpos0[None], tmp_path / "a.mp4", camera=ChaseCamera("nope"),
                     width=160, height=120)
    with pytest.raises(InputError, match="qpos frames"):
        render_video(m, np.zeros((2, 3)), tmp_path / "a.mp4")
    assert not (tmp_path / "a.mp4").exists()
    _ = mujoco  # imported for MUJOCO_GL side effects through flapsim


AFTER_PYVISTA = """
import numpy as np
from flapsim.modal.browser import contact_sheet
from flapsim.modal.gaits import GAITS, plan_gait, resolve_model
from flapsim.render.video import render_video
from flapsim.core.loading import load_model
m = load_model(XML, is_xml=True)
frames = np.tile(m.qpos0, (3, 1))
render_video(m, frames, OUT + "/a.mp4", fps=10, width=160, height=120, progress=False)
model, _ = resolve_model("human")
contact_sheet(plan_gait(model, GAITS["walk"]), model, OUT + "/walk.png", frames=2, cols=2,
              tile=(160, 120))  # closes a VTK offscreen window: it terminated MuJoCo's EGL display
print(render_video(m, frames, OUT + "/b.mp4", fps=10, width=160, height=120, progress=False))
"""


def test_a_video_renders_after_a_pyvista_picture_in_the_same_process(tmp_path):
    """A MuJoCo video, a pyvista contact sheet, and a video again, in one fresh process (the
    order a pytest worker met: every later renderer failed with EGL_NOT_INITIALIZED). Only
    meaningful with EGL, the headless default."""
    if os.environ.get("MUJOCO_GL", "egl") != "egl":
        pytest.skip("the terminated display is EGL's; this process renders with "
                    f"MUJOCO_GL={os.environ['MUJOCO_GL']}")
    code = f"XML = {XML!r}\nOUT = {str(tmp_path)!r}\n" + AFTER_PYVISTA
    env = dict(os.environ, MUJOCO_GL="egl", PYTHONPATH=str(Path(__file__).resolve().parents[2]))
    env.pop("DISPLAY", None)
    done = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True,
                          timeout=300)
    assert done.returncode == 0, done.stderr[-1500:]
    assert done.stdout.split()[-1] == "3"  # the second video's frames
    assert (tmp_path / "b.mp4").stat().st_size > 0
