"""Mode browser: offscreen contact sheet, live slider updates, and the window under Xvfb."""

from __future__ import annotations

import subprocess
import sys
import time
from pathlib import Path

import imageio.v2 as imageio
import numpy as np
import pytest

from flapsim.modal.browser import WINDOW_TITLE, ModeBrowser, contact_sheet
from flapsim.modal.gaits import GAITS, plan_gait, resolve_model

REPO = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def walk():
    model, _ = resolve_model("human")
    return model, plan_gait(model, GAITS["walk"])


def test_contact_sheet_shows_the_motion(tmp_path, walk):
    model, plan = walk
    path = tmp_path / "walk.png"
    info = contact_sheet(plan, model, path, frames=4, cols=2, tile=(160, 120))
    img = imageio.imread(path)
    assert img.shape[:2] == (240, 320) and info["frames"] == 4
    tiles = [img[r * 120:(r + 1) * 120, c * 160:(c + 1) * 160, :3].astype(int)
             for r in range(2) for c in range(2)]
    # Something is drawn (not a blank white tile) and the pose changes between frames:
    # a quarter cycle apart the legs swing by ~0.5 rad, moving hundreds of pixels.
    assert all((t < 200).any(axis=2).sum() > 200 for t in tiles)
    assert (np.abs(tiles[0] - tiles[2]).sum(axis=2) > 60).sum() > 100


def test_sliders_update_the_pose_at_once(walk):
    model, plan = walk
    b = ModeBrowser(plan, model, off_screen=True, window_size=(160, 120))
    try:
        b.set_time(0.125)  # a quarter of the 2 Hz cycle: the swing at its peak
        moving = b.data.geom_xpos.copy()
        for k in range(len(b.components)):
            b.set_param(k, "amplitude", 0.0)
        still = b.data.geom_xpos.copy()
        b.set_time(0.3)
        # With every amplitude at 0 the creature stands in its rest pose at any time.
        np.testing.assert_allclose(b.data.geom_xpos, still, atol=1e-12)
        assert np.abs(moving - still).max() > 0.05  # the feet had moved > 5 cm
        b.set_param(0, "beta", 0.3)  # a posture offset moves it without time
        assert np.abs(b.data.geom_xpos - still).max() > 0.01
    finally:
        b.plotter.close()


def test_cli_sheet(tmp_path):
    from flapsim.cli.main import main

    path = tmp_path / "trot.png"
    assert main(["animate", "--gait", "trot", "--seconds", "0.1", "--sheet", str(path)]) == 0
    img = imageio.imread(path)
    assert img.shape[:2] == (480, 1280)  # 8 tiles of 320 x 240 in 2 rows of 4
    assert main(["animate", "--gait", "trot", "--sheet", str(tmp_path / "x.jpg")]) == 2


def test_window_opens_under_xvfb(tmp_path, xvfb_display):
    # this display only, and VTK on an X window there (not its EGL fallback, which opens none)
    env = xvfb_display.env(PYTHONPATH=str(REPO))
    env.pop("MUJOCO_GL")  # the browser draws with VTK alone
    marker = tmp_path / "opened"
    app = xvfb_display.spawn(
        [sys.executable, "-m", "flapsim.modal.browser", "--gait", "walk", "--seconds", "4",
         "--marker", str(marker)], env)
    deadline = time.monotonic() + 40
    while not marker.exists() and time.monotonic() < deadline and app.poll() is None:
        time.sleep(0.1)
    assert marker.exists(), app.communicate(timeout=10)[0].decode()[-2000:]
    windows = []
    for _ in range(20):  # the title may be set a moment after the window maps
        found = subprocess.run(["xdotool", "search", "--name", WINDOW_TITLE], env=env,
                               capture_output=True, text=True, timeout=10)
        windows = found.stdout.split()
        if windows:
            break
        time.sleep(0.1)
    out = app.communicate(timeout=60)[0].decode()
    assert windows, f"no window titled {WINDOW_TITLE!r} on the display; log: {out[-1500:]}"
    assert app.returncode == 0, out[-2000:]
    pid, frames, closed = marker.read_text().split()
    # It animated while open: the timer redraws at up to 30 frames/s for 4 s; under
    # software GL on a loaded 2-core box a redraw may take ~0.3 s, so demand only 3.
    assert closed == "closed" and int(frames) >= 3, marker.read_text()
