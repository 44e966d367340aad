"""Offscreen videos of any MuJoCo model with a chase camera (``mujoco.Renderer``, EGL).

Generic: give a model, a sequence of ``qpos`` frames (e.g. recorded every step and
subsampled to the video rate) and a body to follow. The video is written atomically
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
from dataclasses import dataclass
from pathlib import Path

import mujoco
import numpy as np
from tqdm import tqdm

from flapsim.core.errors import InputError, SimulationError
from flapsim.core.io import atomic_video
from flapsim.core.validate import require_gl

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


@dataclass(frozen=True)
class ChaseCamera:
    """A camera behind and beside a moving body, turning with its heading."""

    body: str
    """Name of the body to follow."""
    distance: float = 1.2
    """Camera distance from the body, m."""
    elevation_deg: float = -15.0
    """Camera elevation (negative: looking down), deg."""
    azimuth_offset_deg: float = 150.0
    """Camera azimuth relative to the body's heading (180 = straight behind), deg."""
    smoothing: float = 0.15
    """Per-frame gain of the look-at tracker and heading filter (1 = rigidly attached;
    small values filter the wingbeat's bobbing). Only the height of the look-at point is
    filtered: horizontally it stays on the body, so a fast body stays centred."""


def _heading_deg(xmat: np.ndarray) -> float:
    fwd = xmat.reshape(3, 3)[:, 0]
    return float(np.degrees(np.arctan2(fwd[1], fwd[0])))


def render_video(model: mujoco.MjModel, qpos_frames: np.ndarray, path: str | os.PathLike,
                 fps: float = 30.0, camera: ChaseCamera | None = None, width: int = 640,
                 height: int = 480, progress: bool = True, before_frame=None) -> int:
    """Render ``qpos_frames`` (n, nq) to a video at ``path`` (.mp4, .gif ...); returns frames.

    Positions only: each frame runs ``mj_forward`` on a private ``MjData`` (no force
    providers are registered on it, so nothing is simulated here). Frames stream to the
    file (memory stays bounded); ``progress`` shows a bar (tqdm, on stderr).
    ``before_frame(data, renderer)``, if given, runs after each frame's ``mj_forward``: e.g. to
    place bent feathers (:class:`flapsim.bird.body.drawing.FeatherDrawing`).
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
    require_gl()
    d = mujoco.MjData(model)
    cam = mujoco.MjvCamera()
    cam.type = mujoco.mjtCamera.mjCAMERA_FREE
    body = -1
    if camera is not None:
        body = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, camera.body)
        if body < 0:
            raise InputError(f"chase camera: no body named {camera.body!r}")
        cam.distance = camera.distance
        cam.elevation = camera.elevation_deg
    try:
        renderer = new_renderer(model, height, width)
    except Exception as exc:  # noqa: BLE001 - GL setup errors come in many types
        raise SimulationError(f"offscreen rendering is unavailable ({type(exc).__name__}: {exc}); "
                              "set MUJOCO_GL=egl or osmesa before starting Python") from None
    n = 0
    try:
        with atomic_video(path, fps=fps, macro_block_size=1) as append:
            look, heading = None, None
            for q in tqdm(frames, desc=f"rendering {Path(path).name}", unit="frame",
                          leave=False, disable=not progress):
                d.qpos[:] = q
                mujoco.mj_forward(model, d)
                if body >= 0:
                    target = d.xpos[body].copy()
                    h = _heading_deg(d.xmat[body])
                    if look is None:
                        look, heading = target, h
                    a = camera.smoothing
                    look = np.array([target[0], target[1],
                                     look[2] + a * (target[2] - look[2])])
                    dh = (h - heading + 180.0) % 360.0 - 180.0
                    heading = heading + a * dh
                    cam.lookat[:] = look
                    cam.azimuth = heading + camera.azimuth_offset_deg
                if before_frame is not None:
                    before_frame(d, renderer)
                renderer.update_scene(d, cam)
                append(renderer.render())
                n += 1
    finally:
        renderer.close()
    log.info("wrote %d frames to %s", n, path)
    return n
