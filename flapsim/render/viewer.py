"""MuJoCo's passive viewer for any animal: one loop for the dove and the swimmer.

:class:`AnimalViewer` opens the viewer on a model (side panels hidden, so the animal fills
the window) with a camera tracking the animal's trunk, receives keys through a queue (the
key callback, which runs in the viewer's thread, only puts the key code there: the
simulation loop reads and applies them, so no lock is shared with the physics), draws
markers and paths as extra geoms, writes a text overlay, and paces the simulation to real
time. The tracking camera is a chase camera (:class:`flapsim.render.video.CameraRig`) that turns
with the animal's heading; ``Home`` switches between it and MuJoCo's free camera (and back,
so the animal can always be found again); ``Escape`` closes the viewer (:attr:`closed_by`).
:meth:`AnimalViewer.flash` draws feedback (an arrow) for :data:`FLASH_S`; the overlay ends
with the achieved real-time factor and :data:`HELP`. A left
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
from collections.abc import Callable, Sequence

import mujoco
import mujoco.viewer
import numpy as np

from flapsim.core.errors import InputError
from flapsim.core.validate import display_problem
from flapsim.render.scene import Arrow, Item, Marker, Polyline, add_items  # noqa: F401 - re-exported for the animals' viewers
from flapsim.render.video import Camera, CameraRig

#: GLFW key codes (what MuJoCo's key callback receives); keys the viewer itself leaves alone
KEY_INSERT, KEY_DELETE, KEY_RIGHT, KEY_LEFT, KEY_DOWN, KEY_UP = 260, 261, 262, 263, 264, 265
KEY_PAGE_UP, KEY_PAGE_DOWN, KEY_HOME, KEY_END = 266, 267, 268, 269
KEY_ESCAPE = 256
"""Closes the viewer (MuJoCo's own viewer also frees its camera on it: the tracking is put
back before the window goes)."""
KEY_NAMES = {KEY_INSERT: "Insert", KEY_DELETE: "Delete", KEY_RIGHT: "Right", KEY_LEFT: "Left",
             KEY_DOWN: "Down", KEY_UP: "Up", KEY_PAGE_UP: "Page_Up", KEY_PAGE_DOWN: "Page_Down",
             KEY_HOME: "Home", KEY_END: "End", KEY_ESCAPE: "Escape"}
HELP = "Esc: close   Home: chase / free camera"
"""The overlay's last line: how to leave, and how to get the animal back in view."""
FLASH_S = 1.0
"""How long feedback (a push's or a gust's arrow) stays drawn, s of simulated time."""
RATE_WINDOW_S = 2.0
"""The overlay's real-time factor is measured over the last this many wall seconds."""
FRAME_S = 1.0 / 30.0
"""How often the view is refreshed, s of simulated time."""
MAX_FRAME_GAP_S = 0.25
"""The longest wall time between two pictures while the simulation runs behind real time:
frames are dropped to catch up (the picture shows the latest state), but not all of them."""
SHADOW_SIZE = 1024
"""The viewer's shadow map side, texels (videos use 4096): MuJoCo redraws the window without
pause, and a software renderer (Xvfb) spent most of each frame on a 4096 x 4096 shadow pass;
:meth:`AnimalViewer.show` waits for the frame being drawn."""

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


def overlay_columns(labels: str, values: str, rate: float | None) -> tuple[str, str]:
    """The overlay's two columns, each row's label beside its value: the caller's rows (a
    value written over two lines has an empty label below its own; either column padded
    to the other's length), then the real-time factor achieved (``rate``) and how to
    leave (:data:`HELP`)."""
    left = labels.split("\n") if labels else []
    right = values.split("\n") if values else []
    n = max(len(left), len(right))
    left += [""] * (n - len(left))
    right += [""] * (n - len(right))
    return ("\n".join([*left, "real time", "leave"]),
            "\n".join([*right, f"{rate:.2f}x" if rate is not None else "-", HELP]))


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
        shadow = int(model.vis.quality.shadowsize)
        model.vis.quality.shadowsize = min(shadow, SHADOW_SIZE)  # read as the window opens
        try:
            self.handle = launch(model, data, key_callback=self.keys.put, show_left_ui=False,
                                 show_right_ui=False)
        finally:
            model.vis.quality.shadowsize = shadow
        # the viewer renders in a daemon thread; close() must wait for it to tear its
        # window down, or the exiting interpreter terminates GLFW under it (seen here:
        # GLXBadDrawable, then a segfault or a hang)
        self._threads = [t for t in threading.enumerate() if t not in before]
        name = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_BODY, self.body)
        self.rig = CameraRig(model, Camera(name, "chase", distance=distance, elevation_deg=-15.0,
                                           lead_m=0.3 * distance))
        self.closed_by: str | None = None
        """``"Escape"`` once Escape was pressed (the window then closes), else None."""
        self._flashes: list[tuple[float, object]] = []
        self._last_sim: float | None = None
        self._rates: list[tuple[float, float]] = []
        self._camera()
        self._take_selection()
        self._t0_wall: float | None = None
        self._t0_sim = 0.0
        self._last_frame_wall = 0.0
        self._last_drawn_sim: float | None = None
        self.next_frame = 0.0
        self.frames = 0
        """Pictures drawn (:meth:`show` calls that reached the window)."""
        self.dropped = 0
        """:meth:`show` calls skipped to catch up with real time."""

    def _camera(self) -> None:
        with self.handle.lock():
            cam = self.handle.cam
            cam.type = mujoco.mjtCamera.mjCAMERA_FREE  # moved by the rig while tracking
            if self.tracking:
                self.rig.heading = None  # pick the heading up again where the animal is

    def pending_keys(self, t: float | None = None) -> list[int]:
        """Keys pressed since the last call (``Home`` is handled here: camera switch)."""
        out = []
        while not self.keys.empty():
            k = self.keys.get()
            if k == KEY_HOME:
                self.tracking = not self.tracking
                self._camera()
            elif k == KEY_ESCAPE:
                self.closed_by = "Escape"
            out.append(k)
        return out

    def flash(self, item: Item | Callable[[], Item], sim_time: float,
              seconds: float = FLASH_S) -> None:
        """Draw ``item`` (e.g. an :class:`~flapsim.render.scene.Arrow`) until ``sim_time +
        seconds``; a callable is asked for the item at every picture (an arrow that stays
        on the moving animal rather than where the animal was)."""
        self._flashes.append((float(sim_time) + seconds, item))

    @property
    def real_time_factor(self) -> float | None:
        """Simulated over wall time since the first frame shown (None before two frames)."""
        if self._t0_wall is None or self._last_sim is None:
            return None
        wall = time.perf_counter() - self._t0_wall
        return (self._last_sim - self._t0_sim) / wall if wall > 0 else None

    def _recent_rate(self, sim_time: float, now: float) -> float | None:
        self._rates.append((now, sim_time))
        while len(self._rates) > 2 and now - self._rates[1][0] > RATE_WINDOW_S:
            self._rates.pop(0)
        (w0, s0) = self._rates[0]
        return (sim_time - s0) / (now - w0) if now > w0 else None

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
        return self.closed_by is None and bool(self.handle.is_running())

    def show(self, sim_time: float, items: Sequence[Item] = (),
             texts: tuple[str, str] | None = None) -> bool:
        """Draw ``data`` with ``items``, the flashes and the overlay (``texts``: its labels and
        values columns; the real-time factor and :data:`HELP` are added), then wait until real
        time catches up with ``sim_time``; False once the window is closed or Escape pressed.
        Behind real time by more than :data:`FRAME_S` the picture is dropped (at most
        :data:`MAX_FRAME_GAP_S` of wall time apart): the window shows fewer pictures rather
        than the animal in slow motion."""
        if not self.running:
            return False
        sim_time = float(sim_time)
        drawn = self._last_drawn_sim
        dt = 0.0 if drawn is None else max(0.0, sim_time - drawn)  # since the last picture
        self._last_sim = sim_time
        self._flashes = [(end, it) for end, it in self._flashes if end >= sim_time]
        now = time.perf_counter()
        if (self._t0_wall is not None
                and (now - self._t0_wall) - (sim_time - self._t0_sim) > FRAME_S
                and now - self._last_frame_wall < MAX_FRAME_GAP_S):
            # behind real time by more than a frame: this picture is dropped (the next one
            # moves the camera's filters on by the time since the last one drawn)
            self.dropped += 1
            return True
        self._last_drawn_sim = sim_time
        rate = self._recent_rate(sim_time, now)
        with self.handle.lock():
            if self.tracking:
                self.rig.update(self.handle.cam, self.data, dt)
            self._draw([*items, *(it() if callable(it) else it for _, it in self._flashes)])
        labels, values = overlay_columns(*(texts if texts is not None else ("", "")), rate)
        self.handle.set_texts((None, mujoco.mjtGridPos.mjGRID_TOPLEFT, labels, values))
        self.handle.sync()
        self.frames += 1
        now = time.perf_counter()
        self._last_frame_wall = now
        if self._t0_wall is None:
            self._t0_wall, self._t0_sim = now, sim_time
        ahead = (sim_time - self._t0_sim) - (now - self._t0_wall)
        if ahead > 0:
            time.sleep(ahead)
        return True

    def _draw(self, items: Sequence[Item]) -> None:
        scn = self.handle.user_scn
        scn.ngeom = 0
        add_items(scn, items)

    def close(self) -> None:
        """Close the window and wait (up to 10 s) until the viewer's thread is done."""
        self.handle.close()
        for t in self._threads:
            t.join(timeout=10.0)
