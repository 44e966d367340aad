"""Steer the swimmer in the MuJoCo viewer: the paper's interactively moved target.

``flapsim swim --viewer`` opens MuJoCo's passive viewer on the swimming simulation,
paced to real time, with a red marker at the target the swimmer steers for (crawl or
breaststroke; treading water stays in place). Keys:

* arrow keys: move the target 1 m (up/down: +x/-x, the start heading; left/right:
  +y/-y);
* Page Up / Page Down: stroke rate x1.05 / /1.05;
* closing the window (or ``--seconds``) ends the swim; the usual results follow.

Needs a display (or Xvfb) and MuJoCo's GLFW backend: ``MUJOCO_GL`` unset or ``glfw``.
"""

from __future__ import annotations

import os
import queue
import threading
import time

import mujoco
import numpy as np

from flapsim.errors import InputError
from flapsim.swim.layers import BasicStrokeLayer
from flapsim.swim.model import Swimmer
from flapsim.swim.targets import Point

#: GLFW key codes (what MuJoCo's key callback receives)
KEY_RIGHT, KEY_LEFT, KEY_DOWN, KEY_UP, KEY_PAGE_UP, KEY_PAGE_DOWN = 262, 263, 264, 265, 266, 267
MOVES = {KEY_UP: (1.0, 0.0), KEY_DOWN: (-1.0, 0.0), KEY_LEFT: (0.0, 1.0), KEY_RIGHT: (0.0, -1.0)}
FRAME_S = 1.0 / 30.0  # how often the view is refreshed [s of simulated time]


def check_display() -> None:
    """One-line error when the viewer cannot open here."""
    gl = os.environ.get("MUJOCO_GL", "glfw").lower()
    if gl not in ("glfw", ""):
        raise InputError(f"the viewer needs MuJoCo's GLFW backend, but MUJOCO_GL={gl}: run with "
                         "MUJOCO_GL=glfw and a display (or under Xvfb)")
    if not os.environ.get("DISPLAY") and not os.environ.get("WAYLAND_DISPLAY"):
        raise InputError("the viewer needs a display: set DISPLAY (e.g. run under Xvfb)")


class SwimViewer:
    """The control hook that runs the viewer (see :func:`flapsim.swim.simulate.swim`)."""

    def __init__(self, swimmer: Swimmer, target: Point, launch=None) -> None:
        import mujoco.viewer

        self.target = target
        self.keys: queue.Queue[int] = queue.Queue()
        self.events: list[dict] = []
        launch = launch or mujoco.viewer.launch_passive
        before = set(threading.enumerate())
        self.handle = launch(swimmer.model, swimmer.data, key_callback=self.keys.put)
        # the viewer renders in a daemon thread; close() must wait for it to tear its
        # window down, or the exiting interpreter terminates GLFW under it (seen here:
        # GLXBadDrawable, then a segfault or a hang)
        self._threads = [t for t in threading.enumerate() if t not in before]
        self._t0_wall: float | None = None
        self._t0_sim = 0.0
        self._next_frame = 0.0

    def __call__(self, swimmer: Swimmer, layer: BasicStrokeLayer) -> bool:
        d = swimmer.data
        while not self.keys.empty():
            self._key(self.keys.get(), layer, float(d.time))
        if d.time + 1e-9 < self._next_frame:
            return True
        self._next_frame = d.time + FRAME_S
        if not self.handle.is_running():
            return False
        with self.handle.lock():
            self._draw()
        self._texts(swimmer, layer)
        self.handle.sync()
        # pace to real time (the simulation itself runs ~100x faster)
        now = time.perf_counter()
        if self._t0_wall is None:
            self._t0_wall, self._t0_sim = now, float(d.time)
        ahead = (d.time - self._t0_sim) - (now - self._t0_wall)
        if ahead > 0:
            time.sleep(ahead)
        return True

    def _key(self, key: int, layer: BasicStrokeLayer, t: float) -> None:
        if key in MOVES:
            dx, dy = MOVES[key]
            self.target.x += dx
            self.target.y += dy
            self.events.append({"t": t, "key": key, "target": [self.target.x, self.target.y]})
        elif key in (KEY_PAGE_UP, KEY_PAGE_DOWN):
            f = 1.05 if key == KEY_PAGE_UP else 1.0 / 1.05
            layer.rate_hz = float(np.clip(layer.rate_hz * f, 0.05, 5.0))
            self.events.append({"t": t, "key": key, "rate_hz": layer.rate_hz})

    def _draw(self) -> None:
        scn = self.handle.user_scn
        scn.ngeom = 0
        if scn.maxgeom < 1:
            return
        mujoco.mjv_initGeom(scn.geoms[0], mujoco.mjtGeom.mjGEOM_SPHERE, np.array([0.15, 0, 0]),
                            np.array([self.target.x, self.target.y, 0.05]), np.eye(3).ravel(),
                            np.array([0.9, 0.15, 0.1, 0.9], dtype=np.float32))
        scn.ngeom = 1

    def _texts(self, swimmer: Swimmer, layer: BasicStrokeLayer) -> None:
        com = swimmer.com()
        dist = float(np.hypot(self.target.x - com[0], self.target.y - com[1]))
        self.handle.set_texts((None, mujoco.mjtGridPos.mjGRID_TOPLEFT,
                               "stroke\nrate\ntarget\ndistance\nkeys",
                               f"{layer.stroke.name}\n{layer.rate_hz:.2f} cycles/s\n"
                               f"({self.target.x:g}, {self.target.y:g}) m\n{dist:.1f} m\n"
                               "arrows: move target, PgUp/PgDn: rate"))

    def close(self) -> None:
        """Close the window and wait (up to 10 s) until the viewer's thread is done."""
        self.handle.close()
        for t in self._threads:
            t.join(timeout=10.0)
