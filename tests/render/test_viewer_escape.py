"""The dove's viewer under Xvfb closes cleanly on Escape, with its JSON written, exit 0 and
the achieved real-time factor in it."""

from __future__ import annotations

import json
import subprocess
import sys
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]


def test_escape_closes_the_viewer_with_the_json_written(tmp_path, xvfb_display):
    out = tmp_path / "view.json"
    env = xvfb_display.env(PYTHONPATH=str(REPO))
    app = xvfb_display.spawn([sys.executable, "-m", "flapsim.cli.main", "view", "--seconds", "20",
                              "--json", str(out)], env)
    window = xvfb_display.window(app, env, timeout=180.0)
    t_open = time.monotonic()
    subprocess.run(["xdotool", "key", "--window", window, "Escape"], env=env, check=True,
                   timeout=10)
    log = app.communicate(timeout=240)[0].decode()
    closed_in = time.monotonic() - t_open
    assert app.returncode == 0, log[-2000:]
    s = json.loads(out.read_text())["viewer"]
    assert s["status"] == "closed by Escape", s["status"]
    # it stopped at the key, not at the 20 s asked: the window was open ~1-2 s of wall time, and
    # the viewer never runs ahead of real time (it sleeps to hold it), so it flew no longer than
    # that plus the wingbeat in flight (0.11 s) when the key came
    assert s["simulated_s"] < min(20.0, closed_in + 1.0), (s["simulated_s"], closed_in)
    # the real-time factor achieved is reported: simulated over wall time, at most 1 (paced)
    # plus a frame's scheduling slack
    assert 0.0 < s["real_time_factor"] <= 1.1, s["real_time_factor"]
    # the terminal had progress lines instead of a loading screen
    assert "opening the viewer" in log and "Esc closes it" in log
