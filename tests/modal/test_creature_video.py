"""Creature videos drawn by flapsim's one renderer: the dove's sky and grass, a camera that
follows the creature."""

import imageio.v2 as imageio
import numpy as np

from flapsim.modal.creatures import creature_file, load_creature
from flapsim.modal.video import render_poses
from flapsim.render.world import GRASS_RGB, SKY_RGB

# mp4 (yuv420, x264) moves flat colours by a few units per channel: measured 2-6 here
CODEC_TOL = 12.0


def test_a_creature_video_has_the_sky_above_and_the_grass_below(tmp_path):
    model = load_creature("loop")
    rest = model.qpos0.copy()
    poses = []
    for k in range(6):  # the loop carried 0.5 m along x: the camera goes with it
        q = rest.copy()
        q[0] += 0.1 * k
        poses.append(q)
    out = tmp_path / "loop.mp4"
    assert render_poses(model, poses, out, source=creature_file("loop"), width=160, height=120,
                        progress=False) == 6
    frames = imageio.mimread(out)
    assert len(frames) == 6
    for img in (np.asarray(frames[0], float), np.asarray(frames[-1], float)):
        top = img[:8].reshape(-1, 3)
        # the gradient runs between its two colours: every top pixel inside their box
        lo = 255 * np.minimum(*SKY_RGB) - CODEC_TOL
        hi = 255 * np.maximum(*SKY_RGB) + CODEC_TOL
        assert np.all((top >= lo) & (top <= hi)), (top.min(0), top.max(0))
        bottom = img[-8:].reshape(-1, 3).mean(0)
        # grass, lit: green above red and blue, as both checker colours are
        assert bottom[1] > bottom[0] + 20 and bottom[1] > bottom[2] + 20, bottom
        assert all(g[1] > g[0] for g in GRASS_RGB)
        # the creature (orange) in the middle of the picture, followed
        mid = img[30:90, 40:120].reshape(-1, 3)
        assert np.any((mid[:, 0] > 150) & (mid[:, 2] < 110)), "no creature in the middle"
