"""MuJoCo's passive viewer for any animal: one loop for the dove and the swimmer.

:class:`AnimalViewer` opens the viewer on a model (side panels hidden, so the animal fills
the window) with a camera tracking the animal's trunk, receives keys through a queue (the
key callback, which runs in the viewer's thread, only puts the key code there: the
simulation loop reads and applies them, so no lock is shared with the physics), draws
markers and paths as extra geoms, writes a text overlay, and paces the simulation to real
time. ``Home`` switches between the tracking camera and MuJoCo's free camera. A left
double-click in the scene is MuJoCo's selection; :meth:`AnimalViewer.pending_clicks` hands
the point clicked to the caller (the swimmer's viewer puts its target there, as the paper's
user places it with the mouse; the dove's turns toward it). Reading it takes the viewer's
lock, so callers read it once a frame, not every physics step.

Needs a display (or Xvfb) and MuJoCo's GLFW backend: ``MUJOCO_GL`` unset or ``glfw``.
Close it with :meth:`AnimalViewer.close` (leaving it to interpreter shutdown segfaulted).
"""

from __future__ import annotations

import os
import queue
import threading
import time
from collections.abc import Sequence
from dataclasses import dataclass

import mujoco
import mujoco.viewer
import numpy as np

from flapsim.core.errors import InputError
from flapsim.core.validate import display_problem

#: GLFW key codes (what MuJoCo's key callback receives); keys the viewer itself leaves alone
KEY_INSERT, KEY_DELETE, KEY_RIGHT, KEY_LEFT, KEY_DOWN, KEY_UP = 260, 261, 262, 263, 264, 265
KEY_PAGE_UP, KEY_PAGE_DOWN, KEY_HOME, KEY_END = 266, 267, 268, 269
KEY_NAMES = {KEY_INSERT: "Insert", KEY_DELETE: "Delete", KEY_RIGHT: "Right", KEY_LEFT: "Left",
             KEY_DOWN: "Down", KEY_UP: "Up", KEY_PAGE_UP: "Page_Up", KEY_PAGE_DOWN: "Page_Down",
             KEY_HOME: "Home", KEY_END: "End"}
FRAME_S = 1.0 / 30.0
"""How often the view is refreshed, s of simulated time."""

#: What the selection's local point is set to once a click is taken: MuJoCo writes a real
#: point there on the next double-click on a geom (and leaves it on a click into the void)
_NO_CLICK = np.full(3, 1e30)


def check_display() -> None:
    """One-line error when the viewer cannot open here."""
    gl = os.environ.get("MUJOCO_GL", "glfw").lower()
    if gl not in ("glfw", ""):
        raise InputError(f"the viewer needs MuJoCo's GLFW backend, but MUJOCO_GL={gl}: run with "
                         "MUJOCO_GL=glfw and a display (or under Xvfb)")
    if not os.environ.get("DISPLAY") and not os.environ.get("WAYLAND_DISPLAY"):
        raise InputError("the viewer needs a display: set DISPLAY (e.g. run under Xvfb)")
    problem = None if os.environ.get("WAYLAND_DISPLAY") else display_problem()
    if problem:
        raise InputError(problem)


@dataclass(frozen=True)
class Marker:
    """A sphere drawn in the scene (a target), m."""

    pos: Sequence[float]
    radius: float = 0.15
    rgba: Sequence[float] = (0.9, 0.15, 0.1, 0.9)


@dataclass(frozen=True)
class Polyline:
    """A path drawn as thin capsules through ``points`` (n, 3), m."""

    points: np.ndarray
    width: float = 0.03
    rgba: Sequence[float] = (0.95, 0.55, 0.1, 0.8)


class AnimalViewer:
    """The passive viewer on ``model``/``data`` tracking body ``track_body``.

    ``data`` is what is drawn: the caller writes the state to show into it (and runs
    ``mj_forward``) before :meth:`show`; simulate on another ``MjData`` if the physics
    jumps around (the dove's controller restores snapshots).
    """

    def __init__(self, model: mujoco.MjModel, data: mujoco.MjData, track_body: int | str,
                 distance: float = 1.5, launch=None) -> None:

        if isinstance(track_body, str):
            bid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, track_body)
            if bid < 0:
                raise InputError(f"no body {track_body!r} to track in the model")
            track_body = bid
        self.model, self.data, self.body = model, data, int(track_body)
        self.keys: queue.Queue[int] = queue.Queue()
        self.tracking = True
        self.distance = distance
        launch = launch or mujoco.viewer.launch_passive
        before = set(threading.enumerate())
        self.handle = launch(model, data, key_callback=self.keys.put, show_left_ui=False,
                             show_right_ui=False)
        # the viewer renders in a daemon thread; close() must wait for it to tear its
        # window down, or the exiting interpreter terminates GLFW under it (seen here:
        # GLXBadDrawable, then a segfault or a hang)
        self._threads = [t for t in threading.enumerate() if t not in before]
        self._camera()
        self._take_selection()
        self._t0_wall: float | None = None
        self._t0_sim = 0.0
        self.next_frame = 0.0

    def _camera(self) -> None:
        with self.handle.lock():
            cam = self.handle.cam
            if self.tracking:
                cam.type = mujoco.mjtCamera.mjCAMERA_TRACKING
                cam.trackbodyid = self.body
                cam.distance = self.distance
                cam.elevation = -15.0
                cam.azimuth = 30.0  # behind and beside an animal heading +x (both start so)
            else:
                cam.type = mujoco.mjtCamera.mjCAMERA_FREE

    def pending_keys(self, t: float | None = None) -> list[int]:
        """Keys pressed since the last call (``Home`` is handled here: camera switch)."""
        out = []
        while not self.keys.empty():
            k = self.keys.get()
            if k == KEY_HOME:
                self.tracking = not self.tracking
                self._camera()
            out.append(k)
        return out

    def pending_clicks(self) -> list[np.ndarray]:
        """World points (m) double-clicked in the scene since the last call, at most one per
        viewer sync. MuJoCo's viewer records a left double-click as a selection: the body
        under the mouse and the point on it in the body's frame (the world's, for the pool's
        surface or floor); the point is moved into the world with ``data``'s pose of that
        body, and the selection is cleared, so the same spot clicked again counts again and
        no body stays selected (nothing can be dragged by the mouse: a selected body is what
        MuJoCo's Ctrl-drag would push)."""
        point = self._take_selection()
        return [] if point is None else [point]

    def _take_selection(self) -> np.ndarray | None:
        with self.handle.lock():
            pert = self.handle.perturb
            local = np.array(pert.localpos, float)
            body = int(pert.select)
            pert.select = 0
            pert.localpos[:] = _NO_CLICK
        if np.array_equal(local, _NO_CLICK) or not np.all(np.isfinite(local)):
            return None
        if not 0 <= body < self.model.nbody:
            return None
        rot = self.data.xmat[body].reshape(3, 3)
        return self.data.xpos[body] + rot @ local

    @property
    def running(self) -> bool:
        return bool(self.handle.is_running())

    def show(self, sim_time: float, items: Sequence[Marker | Polyline] = (),
             texts: tuple[str, str] | None = None) -> bool:
        """Draw ``data`` with ``items`` and the overlay, then wait until real time catches up
        with ``sim_time``; False once the window is closed."""
        if not self.handle.is_running():
            return False
        with self.handle.lock():
            self._draw(items)
        if texts is not None:
            self.handle.set_texts((None, mujoco.mjtGridPos.mjGRID_TOPLEFT, texts[0], texts[1]))
        self.handle.sync()
        now = time.perf_counter()
        if self._t0_wall is None:
            self._t0_wall, self._t0_sim = now, float(sim_time)
        ahead = (sim_time - self._t0_sim) - (now - self._t0_wall)
        if ahead > 0:
            time.sleep(ahead)
        return True

    def _draw(self, items: Sequence[Marker | Polyline]) -> None:
        scn = self.handle.user_scn
        scn.ngeom = 0
        for it in items:
            if isinstance(it, Marker):
                if scn.ngeom >= scn.maxgeom:
                    return
                mujoco.mjv_initGeom(scn.geoms[scn.ngeom], mujoco.mjtGeom.mjGEOM_SPHERE,
                                    np.array([it.radius, 0, 0]), np.asarray(it.pos, float),
                                    np.eye(3).ravel(), np.asarray(it.rgba, np.float32))
                scn.ngeom += 1
            else:
                pts = np.asarray(it.points, float)
                step = max(1, int(np.ceil(len(pts) / max(1, scn.maxgeom - scn.ngeom - 8))))
                pts = pts[::step]
                for a, b in zip(pts[:-1], pts[1:], strict=True):
                    if scn.ngeom >= scn.maxgeom:
                        return
                    g = scn.geoms[scn.ngeom]
                    mujoco.mjv_initGeom(g, mujoco.mjtGeom.mjGEOM_CAPSULE, np.zeros(3), np.zeros(3),
                                        np.eye(3).ravel(), np.asarray(it.rgba, np.float32))
                    mujoco.mjv_connector(g, mujoco.mjtGeom.mjGEOM_CAPSULE, it.width, a, b)
                    scn.ngeom += 1

    def close(self) -> None:
        """Close the window and wait (up to 10 s) until the viewer's thread is done."""
        self.handle.close()
        for t in self._threads:
            t.join(timeout=10.0)
