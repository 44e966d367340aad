"""The dove in MuJoCo's viewer under Xvfb: keys steer it, the camera keeps it in view."""

from __future__ import annotations

import json
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from flapsim.cli import main as cli

REPO = Path(__file__).resolve().parents[3]


def test_view_without_a_display_is_a_one_line_error(monkeypatch, capsys):
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    monkeypatch.setenv("MUJOCO_GL", "egl")
    assert cli.main(["view", "--seconds", "1"]) == 2
    err = capsys.readouterr().err
    assert "viewer" in err and len(err.strip().splitlines()) == 1


def test_view_with_modal_feathers_needs_a_modal_database(monkeypatch, capsys):
    # the rigid dove's bundled database is refused by the modal dove (a database is bound to
    # its model's hash), before any window opens
    from flapsim.bird.control.controller import bundled_database_path

    monkeypatch.setenv("DISPLAY", ":0")
    monkeypatch.setenv("MUJOCO_GL", "glfw")
    monkeypatch.setattr("flapsim.render.viewer.display_problem", lambda: None)  # a display
    assert cli.main(["view", "--feathers", "modal", "--seconds", "1", "--db",
                     str(bundled_database_path())]) == 2
    err = capsys.readouterr().err
    assert "built for model" in err and len(err.strip().splitlines()) == 1


def _bird_pixels(rgb: np.ndarray) -> np.ndarray:
    """Pixels that are neither the sky (blue above red) nor the ground (green above red):
    the dove's warm greys. The scene without the bird has none (sky rgb 0.55 0.70 0.90 ->
    0.95 0.97 1, checker 0.42 0.55 0.33 / 0.36 0.48 0.28 in bird_mjcf/dove.xml)."""
    r, g, b = (rgb[..., i].astype(int) for i in range(3))
    return (g <= r + 4) & (b <= r + 4) & (r > 30)


def _open_dove_viewer(xvfb_display, out: Path):
    """``flapsim view`` for 4 s on the virtual display: (the process, its window, its env)."""
    env = xvfb_display.env(PYTHONPATH=str(REPO))  # this display only, GLFW on X11
    app = xvfb_display.spawn([sys.executable, "-m", "flapsim.cli.main", "view", "--seconds", "4",
                              "--json", str(out)], env)
    # the window opens after the first wingbeat is flown: minutes on a loaded machine
    return app, xvfb_display.window(app, env, timeout=180.0), env


def _screenshots(app, xvfb_display, box: tuple[int, int, int, int], n: int = 6) -> list:
    """Up to ``n`` RGB shots of the window, 0.3 s apart, while the app runs (on a loaded
    machine a frame may be mid-redraw, hence several)."""
    from PIL import ImageGrab

    x, y, w, h = box
    shots = []
    for _ in range(n):
        time.sleep(0.3)
        if app.poll() is not None:
            break
        shots.append(np.asarray(ImageGrab.grab(xdisplay=xvfb_display.name).convert("RGB"))
                     [y:y + h, x:x + w])
    return shots


def test_the_dove_turns_the_way_the_keys_ask_and_stays_in_view(tmp_path, xvfb_display):
    pytest.importorskip("PIL.ImageGrab")
    out = tmp_path / "v.json"
    app, window, env = _open_dove_viewer(xvfb_display, out)
    # three Left presses: a left turn of 15 deg/s asked; a second later a push and a gust. Not
    # all at once: a 6 N side push and a 3 m/s gust at the very wingbeat the bank begins (0.7 s
    # in; measured with scripted keys) turn this dove 33 deg the other way, half a second later
    # or more it turns left by 35-55 deg; the heading asserted below is the keys' doing
    subprocess.run(["xdotool", "key", "--window", window, "Left", "Left", "Left"], env=env,
                   check=True, timeout=10)
    time.sleep(1.0)
    subprocess.run(["xdotool", "key", "--window", window, "Insert", "Delete"], env=env, check=True,
                   timeout=10)
    # a few screenshots while it flies
    shots = _screenshots(app, xvfb_display, xvfb_display.geometry(window, env))
    assert shots, "the viewer closed before a screenshot"
    log = app.communicate(timeout=240)[0].decode()
    assert app.returncode == 0, log[-2000:]  # also: no crash while closing the window
    s = json.loads(out.read_text())["viewer"]
    assert s["final_command"]["turn_rate_deg_s"] == pytest.approx(15.0)
    assert [e["key"] for e in s["events"]] == ["Left"] * 3 + ["Insert", "Delete"]
    assert s["pushes"] == 1 and s["gusts"] == 1
    # the gust is a 1-cosine of 3 m/s over 0.5 s, seen at wingbeat ends (~0.11 s apart): at
    # least one falls within 0.054 s of its peak, where it blows > 1.5 (1 + cos(2 pi 0.054 / 0.5))
    # = 2.67 m/s (still air: 0)
    assert s["max_wind_m_s"] > 2.5, s
    # it turned left (+): the keys came ~1-2 s before the end of 3 s; straight flight under the
    # same controller holds its heading within ~2 deg (docs/flight.md), so > 5 deg is the command's doing
    assert s["heading_change_deg"] > 5.0, s
    # the tracking camera keeps the dove in the middle of the window: the central quarter has
    # bird-coloured pixels, the window's lower corners (empty ground) none
    counts = []
    for shot in shots:
        hh, ww = shot.shape[:2]
        centre = _bird_pixels(shot[hh // 4:3 * hh // 4, ww // 4:3 * ww // 4]).sum()
        corners = (_bird_pixels(shot[2 * hh // 3:, :ww // 4]).sum()
                   + _bird_pixels(shot[2 * hh // 3:, 3 * ww // 4:]).sum())
        counts.append((int(centre), int(corners)))
    # the dove at 1.4 m covers ~2,000 pixels of the centre (measured 2,289 at 853x533)
    assert any(c > 300 and k < 20 for c, k in counts), counts


def test_a_double_click_on_the_ground_turns_the_dove_toward_it(tmp_path, xvfb_display):
    pytest.importorskip("PIL.ImageGrab")
    # the chase camera looks at the dove from behind along its heading (+x), 15 deg above,
    # from 1.4 m (flapsim.bird.tasks.interactive): the window's centre ray meets the ground,
    # 10 m below, about 10 / tan 15 deg = 37 m ahead. A double-click a fifth of the width
    # from the left edge is 0.6 of the half-width off centre: with a 45 deg vertical field of
    # view at the window's aspect (1.6) the half-width spans atan(1.6 tan 22.5 deg) = 33.5 deg,
    # so the click lies atan(0.6 tan 33.5 deg) = 22 deg left, and asks a heading of ~22 deg
    # (+ left). Straight flight holds its heading within ~2 deg, so a left turn of over 10 deg
    # by the end is the click's doing.
    out = tmp_path / "v.json"
    app, window, env = _open_dove_viewer(xvfb_display, out)
    box = xvfb_display.geometry(window, env)
    # the window exists before the viewer's loop has put its chase camera behind the dove: a
    # click in between is cast through another camera (its heading came back 180 deg on a
    # machine at load 12); the loop sets the camera every picture, so a second is plenty
    time.sleep(1.0)
    subprocess.run(["xdotool", "mousemove", "--window", window, str(box[2] // 5), str(box[3] // 2),
                    "click", "--repeat", "2", "--delay", "80", "1"], env=env, check=True, timeout=10)
    # the point it was sent to is drawn: a red sphere of 1 m radius ~40 m away, ~3 deg across
    # (~35 px of the window's height); nothing else in the scene is red
    red = [int(((s[..., 0] > 150) & (s[..., 1] < 90) & (s[..., 2] < 90)).sum())
           for s in _screenshots(app, xvfb_display, box)]
    log = app.communicate(timeout=240)[0].decode()
    assert app.returncode == 0, log[-2000:]
    s = json.loads(out.read_text())["viewer"]
    clicks = [e for e in s["events"] if e["key"] == "double-click"]
    assert len(clicks) == 1, s["events"]
    c = clicks[0]
    assert abs(c["click"][2]) < 0.01  # on the ground
    assert 15.0 < c["heading_deg"] < 45.0, c
    assert s["final_command"]["turn_rate_deg_s"] == 0.0
    assert s["heading_change_deg"] > 10.0, s
    assert max(red) > 50, red
