"""Offscreen videos of modes and creature runs (mujoco.Renderer, imageio for mp4/gif).

MuJoCo needs an offscreen GL backend: ``flapsim/__init__.py`` sets ``MUJOCO_GL=egl``
when there is no display. Files are written atomically (never half-written).
"""

from __future__ import annotations

import logging
import math
import os
from collections.abc import Iterable, Sequence
from pathlib import Path

import mujoco
import numpy as np
from tqdm import tqdm

from flapsim.core.errors import InputError, ModelError
from flapsim.core.io import atomic_video
from flapsim.core.validate import require_gl
from flapsim.modal.analysis import ModalAnalysis, integrate_displacement
from flapsim.render.video import new_renderer

log = logging.getLogger(__name__)

VIDEO_SUFFIXES = (".mp4", ".gif")


def check_video_path(path: str | os.PathLike) -> Path:
    """Refuse an output path whose extension we cannot write, before any work is done."""
    p = Path(path)
    if p.suffix.lower() not in VIDEO_SUFFIXES:
        raise InputError(f"video file {p} must end in .mp4 or .gif")
    if not (p.parent if str(p.parent) else Path(".")).is_dir():
        raise InputError(f"cannot write {p}: folder {p.parent} does not exist (create it first)")
    return p


def _camera(model: mujoco.MjModel, data: mujoco.MjData) -> mujoco.MjvCamera:
    """A free camera framing the moving bodies (ground planes would inflate the extent)."""
    bodies = [b for b in range(1, model.nbody)]
    cam = mujoco.MjvCamera()
    cam.type = mujoco.mjtCamera.mjCAMERA_FREE
    if bodies:
        pts = data.xpos[bodies]
        center = data.subtree_com[0] if model.body_mass.sum() > 0 else pts.mean(axis=0)
        radius = float(np.max(np.linalg.norm(pts - center, axis=1)))
        geoms = [g for g in range(model.ngeom) if model.geom_bodyid[g] != 0]
        if geoms:
            radius += float(np.max(model.geom_rbound[geoms]))
    else:
        center, radius = model.stat.center, model.stat.extent
    cam.lookat[:] = center
    cam.distance = max(2.8 * radius, 1e-3)
    cam.azimuth = 90.0  # look along +y: creatures move in the x-z plane
    cam.elevation = -15.0
    return cam


def _renderer(model: mujoco.MjModel, width: int, height: int) -> mujoco.Renderer:
    width = min(width, int(model.vis.global_.offwidth))
    height = min(height, int(model.vis.global_.offheight))
    try:
        return new_renderer(model, height, width)
    except Exception as exc:  # GL backends raise assorted types
        raise ModelError(
            f"cannot open an offscreen renderer ({exc}); set MUJOCO_GL=egl or osmesa "
            "and install the matching GL library"
        ) from None


def write_frames(path: str | os.PathLike, frames: Iterable[np.ndarray], fps: float,
                 total: int | None = None, progress: bool = True) -> int:
    """Write RGB frames to an mp4 (ffmpeg from imageio-ffmpeg) or a looping gif, streaming
    (memory stays bounded), with a progress bar of ``total`` frames on stderr."""

    p = check_video_path(path)
    if not (math.isfinite(fps) and 0 < fps <= 1000):
        raise InputError(f"video frame rate must be > 0 and <= 1000 frames/s, got {fps}")
    count = 0
    kw = (dict(mode="I", duration=1000.0 / fps, loop=0) if p.suffix.lower() == ".gif"
          else dict(fps=fps, codec="libx264", macro_block_size=8))
    with atomic_video(p, **kw) as append:
        for frame in tqdm(frames, total=total, desc=f"rendering {p.name}", unit="frame",
                          leave=False, disable=not progress):
            append(frame)
            count += 1
        if count == 0:
            raise InputError("no frames to write")
    return count


def render_poses(
    model: mujoco.MjModel,
    poses: Sequence[np.ndarray],
    path: str | os.PathLike,
    *,
    fps: float = 30.0,
    width: int = 480,
    height: int = 360,
    track: bool = False,
) -> int:
    """Render a sequence of poses (nq each) to a video; ``track`` follows the centre of mass."""

    if len(poses) == 0:
        raise InputError("no frames to render")
    require_gl()
    data = mujoco.MjData(model)
    data.qpos[:] = poses[0]
    mujoco.mj_forward(model, data)
    cam = _camera(model, data)
    renderer = _renderer(model, width, height)

    def frames() -> Iterable[np.ndarray]:
        for q in poses:
            data.qpos[:] = q
            mujoco.mj_forward(model, data)
            if track:
                cam.lookat[:2] = data.subtree_com[0][:2]
            renderer.update_scene(data, camera=cam)
            yield renderer.render().copy()

    try:
        return write_frames(path, frames(), fps, total=len(poses))
    finally:
        renderer.close()


def mode_poses(
    model: mujoco.MjModel,
    analysis: ModalAnalysis,
    modes: Sequence[int],
    *,
    amplitude_rad: float = 0.35,
    cycles: float = 2.0,
    frames_per_cycle: int = 30,
) -> list[np.ndarray]:
    """Poses showing each mode oscillating about the rest pose, one mode after another.

    Every mode is shown at the same display period (``frames_per_cycle`` frames per
    cycle) whatever its frequency, so high modes stay visible; ``amplitude_rad`` is the
    excursion of the most-moving joint.
    """
    poses = []
    n = max(int(round(cycles * frames_per_cycle)), 1)
    for i in modes:
        shape = analysis.shape(i, "max") * amplitude_rad
        for k in range(n):
            s = math.sin(2 * math.pi * k / frames_per_cycle)
            poses.append(integrate_displacement(model, analysis.rest_qpos, shape, s))
    return poses
