"""Steer the swimmer in the MuJoCo viewer: the paper's interactively moved target.

``flapsim swim --viewer`` opens MuJoCo's passive viewer on the swimming simulation,
paced to real time, with a red marker at the target the swimmer steers for (crawl or
breaststroke; treading water stays in place). Keys:

* double-click (left button) on the water, the pool or the swimmer: put the target
  there (its x and y; a target under water keeps its depth), as the paper's user places it
  with the mouse;
* arrow keys: move the target 1 m (up/down: +x/-x, the start heading; left/right:
  +y/-y);
* Page Up / Page Down: stroke rate x1.05 / /1.05;
* End: switch the control layers, basic -> basic + per-cycle -> all -> basic (the
  paper's Fig. 15 comparison, live; ``--layers`` sets the first);
* Escape or closing the window (or ``--seconds``) ends the swim; the usual results follow.

The window opens at the first control step, on the swimmer in the water; the chase camera
behind it along its heading keeps the target ahead in view.

The window, camera (tracking the thorax; ``Home``: free camera), key queue, overlay and
pacing are the shared :class:`flapsim.render.viewer.AnimalViewer`; this module holds what is the
swimmer's own: its keys and what they change.

Needs a display (or Xvfb) and MuJoCo's GLFW backend: ``MUJOCO_GL`` unset or ``glfw``.
"""

from __future__ import annotations

import sys

import numpy as np

from flapsim.render.viewer import (
    FRAME_S,
    KEY_DOWN,
    KEY_END,
    KEY_LEFT,
    KEY_PAGE_DOWN,
    KEY_PAGE_UP,
    KEY_RIGHT,
    KEY_UP,
    AnimalViewer,
    Marker,
    check_display,
)
from flapsim.swim.goals import Point
from flapsim.swim.layers import BasicStrokeLayer
from flapsim.swim.model import Swimmer

__all__ = ["SwimViewer", "check_display", "MOVES"]

MOVES = {KEY_UP: (1.0, 0.0), KEY_DOWN: (-1.0, 0.0), KEY_LEFT: (0.0, 1.0), KEY_RIGHT: (0.0, -1.0)}
#: the key that switches the control layers, and their order
KEY_LAYERS = KEY_END
LAYER_CYCLE = ("basic", "cycle", "all")


class SwimViewer:
    """The control hook that runs the viewer (see :func:`flapsim.swim.simulate.swim`)."""

    def __init__(self, swimmer: Swimmer, target: Point, launch=None) -> None:
        self.target = target
        self.events: list[dict] = []
        self._launch = launch
        self.view: AnimalViewer | None = None
        """Opened at the first control step, on the swimmer in the water (not on the pose it
        is built in)."""

    def __call__(self, swimmer: Swimmer, layer: BasicStrokeLayer) -> bool:
        d = swimmer.data
        if self.view is None:
            print("flapsim swim: opening the viewer; Esc closes it", file=sys.stderr, flush=True)
            self.view = AnimalViewer(swimmer.model, d, "thorax", distance=3.0, launch=self._launch)
        for key in self.view.pending_keys():
            self._key(key, layer, float(d.time))
        if d.time + 1e-9 < self.view.next_frame:
            return True
        self.view.next_frame = d.time + FRAME_S
        # once a frame: MuJoCo records a click at the viewer's sync, and reading it takes the
        # viewer's lock, which its render thread holds while it draws
        for point in self.view.pending_clicks():
            self._click(point, swimmer, float(d.time))
        return self.view.show(float(d.time), [Marker((self.target.x, self.target.y, 0.05))],
                              self._texts(swimmer, layer))

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
        elif key == KEY_LAYERS and getattr(layer, "stack", None) is not None:
            stack = layer.stack
            nxt = LAYER_CYCLE[(LAYER_CYCLE.index(stack.mode) + 1) % len(LAYER_CYCLE)]
            stack.set_mode(nxt, t)
            self.events.append({"t": t, "key": key, "layers": nxt})

    def _click(self, point: np.ndarray, swimmer: Swimmer, t: float) -> None:
        # x and y only: a point on the swimmer or on the floor steers as the spot above it
        self.target.x, self.target.y = round(float(point[0]), 2), round(float(point[1]), 2)
        com = swimmer.com()
        cam = self.view.handle.cam
        self.events.append({"t": t, "click": [float(point[0]), float(point[1]), float(point[2])],
                            "target": [self.target.x, self.target.y],
                            "swimmer": [float(com[0]), float(com[1])],
                            "camera": {"lookat": [float(v) for v in cam.lookat],
                                       "azimuth_deg": float(cam.azimuth)}})

    def _texts(self, swimmer: Swimmer, layer: BasicStrokeLayer) -> tuple[str, str]:
        com = swimmer.com()
        dist = float(np.hypot(self.target.x - com[0], self.target.y - com[1]))
        stack = getattr(layer, "stack", None)
        mode = stack.mode if stack is not None else "basic"
        return ("stroke\nrate\nlayers\ntarget\ndistance\nkeys\n",
                f"{layer.stroke.name}\n{layer.rate_hz:.2f} cycles/s\n{mode}\n"
                f"({self.target.x:g}, {self.target.y:g}) m\n{dist:.1f} m\n"
                "double-click: place target, arrows: move it,\n"
                "PgUp/PgDn: rate, End: layers")

    def close(self) -> None:
        """Close the window and wait until the viewer's thread is done."""
        if self.view is not None:
            self.view.close()
