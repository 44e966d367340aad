"""The swimmer in MuJoCo's viewer under Xvfb: keys move the target, change the rate and
switch the control layers."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from flapsim.cli import main as cli

REPO = Path(__file__).resolve().parents[2]


def test_viewer_without_a_display_is_a_one_line_error(monkeypatch, capsys):
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    monkeypatch.setenv("MUJOCO_GL", "egl")
    assert cli.main(["swim", "--viewer", "--seconds", "1"]) == 2
    err = capsys.readouterr().err
    assert "viewer" in err and "MUJOCO_GL" in err and len(err.strip().splitlines()) == 1


def _open_swim_viewer(xvfb_display, out: Path, seconds: float):
    """``flapsim swim --viewer`` (crawl, basic layers, ``seconds`` paced to real time) on the
    virtual display: (the process, its window, the environment it runs in)."""
    env = xvfb_display.env(PYTHONPATH=str(REPO))  # this display only, GLFW on X11
    app = xvfb_display.spawn(
        [sys.executable, "-m", "flapsim.cli.main", "swim", "--viewer", "--stroke", "crawl",
         "--seconds", f"{seconds:g}", "--layers", "basic", "--json", str(out)], env)
    # the window opens at the first control step (after the kernels compile): slow under load
    return app, xvfb_display.window(app, env, timeout=180), env


def test_viewer_steers_with_keys_under_xvfb(tmp_path, xvfb_display):
    out = tmp_path / "v.json"
    app, window, env = _open_swim_viewer(xvfb_display, out, 8)
    subprocess.run(["xdotool", "key", "--window", window, "Up", "Up", "Left", "Page_Up",
                    "End", "End"], env=env, check=True, timeout=10)
    log = app.communicate(timeout=90)[0].decode()
    assert app.returncode == 0, log[-2000:]  # also: no crash while closing the window
    s = json.loads(out.read_text())
    # arrows moved the target from (10, 0) by +2 m in x and +1 m in y; PgUp: rate x1.05
    assert s["viewer"]["final_target"] == [12.0, 1.0], s["viewer"]
    assert s["viewer"]["final_rate_hz"] == pytest.approx(0.8 * 1.05)
    assert s["target"]["x_m"] == 12.0 and s["target"]["y_m"] == 1.0
    # End twice: basic -> basic + per-cycle -> all layers, in that order
    assert [e["layers"] for e in s["viewer"]["events"] if "layers" in e] == ["cycle", "all"]
    assert s["viewer"]["final_layers"] == "all" and s["layers_mode"] == "all"
    assert s["layers"] == ["basic stroke", "per-cycle", "continuous"]
    assert s["cycle_weights"] is not None  # the per-cycle layer ran after the switch
    # paced to real time: 8 simulated seconds took at least ~8 wall seconds
    assert s["seconds"] == pytest.approx(8.0, abs=0.05) and s["wall_s"] > 7.0


def test_viewer_places_the_target_where_it_is_double_clicked_under_xvfb(tmp_path, xvfb_display):
    # the paper's user places the target with the mouse. The chase camera looks from behind
    # the swimmer along its heading (+x at the start), 15 deg above, from 3 m, at a point 0.9 m
    # ahead of its thorax (flapsim.render.viewer), so a double-click at the window's centre
    # lands on the water along the heading: past that point while it is above the surface (at
    # the start the swimmer floats high, ~0.4 m: 0.4 / tan 15 deg = 1.5 m past), short of it
    # once under, or on the swimmer's back on the way. Either way the target leaves 10 m ahead
    # for a point within 3 m of the swimmer on the camera's line, and the swim's target is
    # that point.
    out = tmp_path / "v.json"
    app, window, env = _open_swim_viewer(xvfb_display, out, 6)
    _, _, w, h = xvfb_display.geometry(window, env)
    subprocess.run(["xdotool", "mousemove", "--window", window, str(w // 2), str(h // 2),
                    "click", "--repeat", "2", "--delay", "80", "1"], env=env, check=True, timeout=10)
    log = app.communicate(timeout=90)[0].decode()
    assert app.returncode == 0, log[-2000:]
    s = json.loads(out.read_text())
    clicks = [e for e in s["viewer"]["events"] if "click" in e]
    assert len(clicks) == 1, s["viewer"]["events"]
    c = clicks[0]
    assert c["target"] == pytest.approx(c["click"][:2], abs=0.006)  # placed to the cm
    dx, dy = c["click"][0] - c["swimmer"][0], c["click"][1] - c["swimmer"][1]
    assert np.hypot(dx, dy) < 3.0 and abs(c["click"][2]) < 1.0, c
    # the target left its place 10 m ahead for the point clicked
    assert np.hypot(c["target"][0] - 10.0, c["target"][1]) > 6.0, c
    # a click at the window's centre lies on the camera's line through its look-at point: seen
    # from above, from the look-at point along the camera's azimuth (or back towards the
    # camera, short of it); 10 deg for the chase camera turning in the frame between the
    # click and its reading
    lx, ly = c["camera"]["lookat"][:2]
    ex, ey = c["click"][0] - lx, c["click"][1] - ly
    if np.hypot(ex, ey) > 0.3:
        bearing = np.degrees(np.arctan2(ey, ex))
        az = c["camera"]["azimuth_deg"]
        assert min(abs((bearing - b + 180) % 360 - 180) for b in (az, az + 180.0)) < 10.0, c
    assert s["viewer"]["final_target"] == c["target"]
    assert [s["target"]["x_m"], s["target"]["y_m"]] == c["target"]
