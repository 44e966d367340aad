"""The swimmer in MuJoCo's viewer under Xvfb: keys move the target, change the rate and
switch the control layers."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from flapsim import cli

REPO = Path(__file__).resolve().parents[2]


def test_viewer_without_a_display_is_a_one_line_error(monkeypatch, capsys):
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    monkeypatch.setenv("MUJOCO_GL", "egl")
    assert cli.main(["swim", "--viewer", "--seconds", "1"]) == 2
    err = capsys.readouterr().err
    assert "viewer" in err and "MUJOCO_GL" in err and len(err.strip().splitlines()) == 1


def test_viewer_steers_with_keys_under_xvfb(tmp_path, xvfb_display):
    env = dict(os.environ, DISPLAY=xvfb_display.name, MUJOCO_GL="glfw", PYTHONPATH=str(REPO))
    out = tmp_path / "v.json"
    app = xvfb_display.spawn(
        [sys.executable, "-m", "flapsim.cli", "swim", "--viewer", "--stroke", "crawl",
         "--seconds", "8", "--layers", "basic", "--json", str(out)], env)
    window = xvfb_display.window(app, env, timeout=40)
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
