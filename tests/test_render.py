"""Offscreen video with a chase camera."""

import imageio.v2 as imageio
import mujoco
import numpy as np
import pytest

from flapsim.errors import InputError
from flapsim.render import ChaseCamera, render_video
from flapsim.sim.loading import load_model

XML = """<mujoco><visual><global offwidth="320" offheight="240"/></visual><worldbody>
<geom type="plane" size="5 5 .1"/><body name="ball" pos="0 0 .5"><freejoint/>
<geom size=".1" rgba="1 0 0 1"/></body></worldbody></mujoco>"""


def test_video_follows_the_body(tmp_path):
    m = load_model(XML, is_xml=True)
    frames = np.tile(m.qpos0, (6, 1))
    frames[:, 0] = np.linspace(0, 3, 6)  # the ball flies 3 m: a fixed camera would lose it
    path = tmp_path / "v.mp4"
    n = render_video(m, frames, path, fps=10, camera=ChaseCamera("ball", distance=1.0),
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
