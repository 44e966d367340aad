"""Offscreen videos of any MuJoCo model (``mujoco.Renderer``, EGL): the one renderer of the
dove's, the swimmer's and the creatures' videos.

Generic: give a model, a sequence of ``qpos`` frames (e.g. recorded every step and
subsampled to the video rate), a body to follow and a camera mode (:data:`CAMERAS`), the
things to draw besides the model (a path, targets, trees: :mod:`flapsim.render.scene`), a
fading trail and a text overlay. The video is written atomically
(a temporary file renamed on success) with imageio's bundled ffmpeg.

``MUJOCO_GL`` must be chosen before mujoco is first imported; ``import flapsim`` sets
``egl`` when there is no display.

Known pitfall (measured here, mujoco 3.17 + VTK via pyvista): closing a pyvista
offscreen window after a MuJoCo EGL renderer has run terminates the EGL display that
MuJoCo shares, and every later ``mujoco.Renderer`` in that process failed (EGLError
EGL_NOT_INITIALIZED). :func:`new_renderer` initializes MuJoCo's display again first
(``eglInitialize`` on a live display changes nothing), so every renderer flapsim opens
works after a pyvista picture; flapsim's plots use matplotlib all the same.
"""

from __future__ import annotations

import logging
import os
import sys
from collections.abc import Callable, Generator, Sequence
from dataclasses import dataclass
from pathlib import Path

import mujoco
import numpy as np
from PIL import Image, ImageDraw, ImageFont
from tqdm import tqdm

from flapsim.core.errors import InputError, SimulationError
from flapsim.core.io import atomic_video
from flapsim.core.validate import require_gl
from flapsim.render.scene import Item, Trail, add_items

log = logging.getLogger(__name__)


def new_renderer(model: mujoco.MjModel, height: int, width: int) -> mujoco.Renderer:
    """``mujoco.Renderer(model, height, width)``, after bringing MuJoCo's shared EGL display
    back if something in this process terminated it (a closed VTK window does: see the module
    doc). Errors are mujoco's own."""
    egl = sys.modules.get("mujoco.egl")
    display = getattr(egl, "EGL_DISPLAY", None)
    if display is not None:
        try:
            egl.EGL.eglInitialize(display, None, None)
        except Exception:  # noqa: BLE001 - PyOpenGL raises its own types; the renderer reports
            log.debug("eglInitialize on MuJoCo's display failed", exc_info=True)
    return mujoco.Renderer(model, height, width)


CAMERAS = ("chase", "side", "top", "orbit")
"""Camera modes: ``chase`` behind the body along its heading and above it, looking ahead;
``side`` beside it; ``top`` straight down (the heading up the picture); ``orbit`` circling it."""

_DEFAULTS = {  # distance m, elevation deg, azimuth from the heading deg
    "chase": (2.6, -17.0, 0.0), "side": (2.4, -6.0, 90.0), "top": (7.0, -89.0, 0.0),
    "orbit": (2.6, -15.0, 0.0)}


@dataclass(frozen=True)
class Camera:
    """A camera following a moving body, turning with the heading of its motion."""

    body: str
    """Name of the body to follow."""
    mode: str = "chase"
    """One of :data:`CAMERAS`."""
    distance: float | None = None
    """Camera distance from the point looked at, m (None: the mode's)."""
    elevation_deg: float | None = None
    """Camera elevation (negative: looking down), deg (None: the mode's)."""
    lead_m: float = 0.8
    """How far ahead of the body along its heading the camera looks (chase), m: the body sits
    below the picture's centre and the path ahead of it is in view."""
    tau_s: float = 0.25
    """Time constant of the heading and height filters, s of the recording: they follow
    turns and climbs, not the wingbeat's bobbing."""
    orbit_deg_s: float = 30.0
    """``orbit``: how fast the camera circles, deg/s of the recording."""
    azimuth_deg: float | None = None
    """A fixed world azimuth, deg (MuJoCo's: 90 looks along +y), instead of turning with the
    heading: for an animal that moves along one axis, oscillating back and forth."""
    com: bool = False
    """Follow the centre of mass of the body and all below it rather than the body's origin
    (a creature whose root goes round as it rolls: the loop)."""

    def __post_init__(self) -> None:
        if self.mode not in CAMERAS:
            raise InputError(f"camera {self.mode!r} is not one of {', '.join(CAMERAS)}")


def ChaseCamera(body: str, distance: float | None = None, **kw) -> Camera:  # noqa: N802
    """The chase :class:`Camera` on ``body``."""
    return Camera(body, "chase", distance=distance, **kw)


class CameraRig:
    """Moves a free ``MjvCamera`` after a :class:`Camera` frame by frame. The heading is the
    direction of the body's horizontal motion between frames (the body's own x axis while it
    barely moves), filtered with ``tau_s``."""

    def __init__(self, model: mujoco.MjModel, camera: Camera) -> None:
        self.spec = camera
        self.body = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, camera.body)
        if self.body < 0:
            raise InputError(f"camera: no body named {camera.body!r}")
        dist, elev, self.azimuth_offset = _DEFAULTS[camera.mode]
        self.distance = camera.distance if camera.distance is not None else dist
        self.elevation = camera.elevation_deg if camera.elevation_deg is not None else elev
        self.heading: float | None = None
        self.height = 0.0
        self.last: np.ndarray | None = None
        self.t = 0.0

    def followed(self, data: mujoco.MjData) -> np.ndarray:
        """The point followed, world, m (a copy)."""
        return (data.subtree_com if self.spec.com else data.xpos)[self.body].copy()

    def update(self, cam: mujoco.MjvCamera, data: mujoco.MjData, dt: float) -> None:
        """Place ``cam`` for ``data`` (``dt``: the recording's time since the last frame, s)."""
        pos = self.followed(data)
        moved = None if self.last is None else pos[:2] - self.last[:2]
        if moved is not None and np.linalg.norm(moved) > 0.1 * dt:  # moving faster than 0.1 m/s
            h = float(np.arctan2(moved[1], moved[0]))
        elif self.heading is None:
            h = float(np.arctan2(*data.xmat[self.body].reshape(3, 3)[[1, 0], 0]))
        else:
            h = self.heading
        if self.heading is None:
            self.heading, self.height = h, float(pos[2])
        else:
            a = 1.0 - np.exp(-dt / self.spec.tau_s) if dt > 0 else 1.0
            self.heading += a * float((h - self.heading + np.pi) % (2 * np.pi) - np.pi)
            self.height += a * (float(pos[2]) - self.height)
        self.last, self.t = pos, self.t + dt
        fwd = np.array([np.cos(self.heading), np.sin(self.heading), 0.0])
        lead = self.spec.lead_m if self.spec.mode == "chase" else 0.0
        cam.type = mujoco.mjtCamera.mjCAMERA_FREE
        cam.lookat[:] = (pos[0] + lead * fwd[0], pos[1] + lead * fwd[1], self.height)
        az = np.degrees(self.heading) + self.azimuth_offset
        if self.spec.azimuth_deg is not None:
            az = float(self.spec.azimuth_deg)
        if self.spec.mode == "orbit":
            az += self.spec.orbit_deg_s * self.t
        cam.azimuth = float(az)
        cam.elevation = float(self.elevation)
        cam.distance = float(self.distance)


def draw_text(frame: np.ndarray, text: str) -> np.ndarray:
    """``text`` (lines) in the top-left corner of an RGB ``frame`` on a translucent box."""
    h = frame.shape[0]
    size = max(8, h // 34)
    img = Image.fromarray(frame).convert("RGBA")
    layer = Image.new("RGBA", img.size, (0, 0, 0, 0))
    draw = ImageDraw.Draw(layer)
    try:
        font = ImageFont.load_default(size=size)
    except (TypeError, OSError):  # Pillow without FreeType: the fixed bitmap font
        font = ImageFont.load_default()
    box = draw.multiline_textbbox((0, 0), text, font=font, spacing=2)
    pad = max(2, size // 3)
    draw.rectangle((0, 0, box[2] + 2 * pad, box[3] + 2 * pad), fill=(0, 0, 0, 120))
    draw.multiline_text((pad, pad), text, font=font, fill=(255, 255, 255, 255), spacing=2)
    return np.asarray(Image.alpha_composite(img, layer).convert("RGB"))


@dataclass(frozen=True)
class TrailSpec:
    """The fading trail of the followed body's positions over the last ``seconds``."""

    seconds: float = 3.0
    width: float = 0.02
    line_px: float | None = 4.0


def render_video(model: mujoco.MjModel, qpos_frames: np.ndarray, path: str | os.PathLike,
                 fps: float = 60.0, camera: Camera | None = None, width: int = 640,
                 height: int = 480, progress: bool = True, before_frame=None,
                 items: Sequence[Item] = (), trail: TrailSpec | None = None,
                 overlay: Callable[[int, mujoco.MjData], str] | None = None,
                 frame_dt: float | None = None,
                 frame_items: Callable[[int], Sequence[Item]] | None = None) -> int:
    """Render ``qpos_frames`` (n, nq) to a video at ``path`` (.mp4, .gif ...); returns frames.
    The pictures are :func:`render_frames`' (see there for the arguments); they stream to the
    file (memory stays bounded), with a progress bar (tqdm, on stderr) when ``progress``."""
    frames = render_frames(model, qpos_frames, fps, camera, width, height, before_frame, items,
                           trail, overlay, frame_dt, frame_items)
    n = 0
    try:
        with atomic_video(path, fps=fps, macro_block_size=1) as append:
            for img in tqdm(frames, total=len(qpos_frames), desc=f"rendering {Path(path).name}",
                            unit="frame", leave=False, disable=not progress):
                append(img)
                n += 1
    finally:
        frames.close()
    log.info("wrote %d frames to %s", n, path)
    return n


def render_frames(model: mujoco.MjModel, qpos_frames: np.ndarray, fps: float = 60.0,
                  camera: Camera | None = None, width: int = 640, height: int = 480,
                  before_frame=None, items: Sequence[Item] = (), trail: TrailSpec | None = None,
                  overlay: Callable[[int, mujoco.MjData], str] | None = None,
                  frame_dt: float | None = None,
                  frame_items: Callable[[int], Sequence[Item]] | None = None
                  ) -> Generator[np.ndarray, None, None]:
    """The RGB pictures (height, width, 3) of ``qpos_frames`` (n, nq), one at a time: the
    arguments are checked and the renderer opened at once (a one-line error before any file
    is made), the renderer closed when the generator ends or is closed.

    Positions only: each frame runs ``mj_forward`` on a private ``MjData`` (no force
    providers are registered on it, so nothing is simulated here).
    ``before_frame(data, renderer)``, if given, runs after each frame's ``mj_forward``: e.g. to
    place bent feathers (:class:`flapsim.bird.body.drawing.FeatherDrawing`). ``items`` are
    drawn in every frame (a path, targets, trees: :mod:`flapsim.render.scene`), and
    ``frame_items(i)`` in frame ``i`` only (things that move: flock mates); ``trail``
    draws the camera body's recent positions; ``overlay(i, data)`` gives the text of frame
    ``i``. ``frame_dt``: the recording's time between frames, s (default ``1 / fps``; less in
    slow motion): the camera's filters and the trail run on it. The sky, ground and light are
    the model's own (:func:`flapsim.render.world.drawing_model` gives any MJCF flapsim's).
    """
    frames = np.asarray(qpos_frames, dtype=float)
    if frames.ndim != 2 or frames.shape[1] != model.nq:
        raise InputError(f"qpos frames must be (n, {model.nq}), got {frames.shape}")
    if len(frames) == 0:
        raise InputError("no frames to render")
    if width > model.vis.global_.offwidth or height > model.vis.global_.offheight:
        raise InputError(f"video {width}x{height} exceeds the model's offscreen buffer "
                         f"{model.vis.global_.offwidth}x{model.vis.global_.offheight}")

    if not 0 < fps <= 1000 or not np.isfinite(fps):
        raise InputError(f"video frame rate must be > 0 and <= 1000 frames/s, got {fps}")
    dt = float(frame_dt) if frame_dt is not None else 1.0 / fps
    if not (np.isfinite(dt) and dt > 0):
        raise InputError(f"time between frames must be > 0 s, got {frame_dt}")
    require_gl()
    rig = CameraRig(model, camera) if camera is not None else None
    try:
        renderer = new_renderer(model, height, width)
    except Exception as exc:  # noqa: BLE001 - GL setup errors come in many types
        raise SimulationError(f"offscreen rendering is unavailable ({type(exc).__name__}: {exc}); "
                              "set MUJOCO_GL=egl or osmesa before starting Python") from None
    return _frames(model, frames, renderer, rig, dt, before_frame, items, trail, overlay,
                   frame_items)


def _frames(model, frames, renderer, rig, dt, before_frame, items, trail, overlay, frame_items):
    d = mujoco.MjData(model)
    cam = mujoco.MjvCamera()
    cam.type = mujoco.mjtCamera.mjCAMERA_FREE
    keep = max(2, int(round(trail.seconds / dt)) + 1) if trail is not None else 0
    history: list[np.ndarray] = []
    try:
        for i, q in enumerate(frames):
            d.qpos[:] = q
            mujoco.mj_forward(model, d)
            if rig is not None:
                rig.update(cam, d, dt if i else 0.0)
            if before_frame is not None:
                before_frame(d, renderer)
            renderer.update_scene(d, cam)
            extra = list(items) + (list(frame_items(i)) if frame_items is not None else [])
            if trail is not None and rig is not None:
                history.append(rig.followed(d))
                del history[:-keep]
                if len(history) > 1:
                    extra.append(Trail(np.array(history), width=trail.width, line_px=trail.line_px))
            add_items(renderer.scene, extra)
            img = renderer.render()
            if overlay is not None:
                img = draw_text(img, overlay(i, d))
            yield img
    finally:
        renderer.close()
