"""Videos of modes and creature runs, drawn by flapsim's one renderer
(:mod:`flapsim.render.video`) under the sky and over the grass of the dove's and swimmer's
(:mod:`flapsim.render.world`), written as mp4 or a looping gif (imageio), atomically (never
half-written). MuJoCo needs an offscreen GL backend (``MUJOCO_GL=egl`` without a display).
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
from flapsim.render.video import Camera, render_frames
from flapsim.render.world import drawing_model

log = logging.getLogger(__name__)

VIDEO_SUFFIXES = (".mp4", ".gif")

GRID_M = 0.5
"""Side of the ground's squares under a creature, m: the dove's grass and grid, at a step
that a creature of 0.3-1.5 m is seen to cover (the dove's 2 m squares pass under it slowly)."""


def check_video_path(path: str | os.PathLike) -> Path:
    """Refuse an output path whose extension we cannot write, before any work is done."""
    p = Path(path)
    if p.suffix.lower() not in VIDEO_SUFFIXES:
        raise InputError(f"video file {p} must end in .mp4 or .gif")
    if not (p.parent if str(p.parent) else Path(".")).is_dir():
        raise InputError(f"cannot write {p}: folder {p.parent} does not exist (create it first)")
    return p


def followed_body(model: mujoco.MjModel) -> str:
    """The body a creature's camera follows: of the world's children, the heaviest subtree
    (the creature, not a cart or a prop beside it): its name (:func:`~flapsim.render.world.
    drawing_model` names every one)."""
    roots = [b for b in range(1, model.nbody) if model.body_parentid[b] == 0]
    if not roots:
        raise ModelError("the model has no body to film")
    b = max(roots, key=lambda i: float(model.body_subtreemass[i]))
    return mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_BODY, b) or ""


def camera_for(model: mujoco.MjModel, rest_qpos: np.ndarray) -> Camera:
    """A side camera on the creature's centre of mass, looking along +y (creatures move in the
    x-z plane), far enough to frame it at ``rest_qpos`` (2.8 times its radius: moving
    bodies only, a ground plane would inflate the extent)."""
    body = followed_body(model)
    data = mujoco.MjData(model)
    data.qpos[:] = rest_qpos
    mujoco.mj_forward(model, data)
    b = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, body)
    inside = [i for i in range(1, model.nbody) if model.body_rootid[i] == model.body_rootid[b]]
    pts = data.xpos[inside]
    radius = float(np.max(np.linalg.norm(pts - data.subtree_com[b], axis=1)))
    geoms = [g for g in range(model.ngeom) if model.geom_bodyid[g] in inside]
    if geoms:
        radius += float(np.max(model.geom_rbound[geoms]))
    return Camera(body, "side", distance=max(2.8 * radius, 0.05), elevation_deg=-15.0,
                  azimuth_deg=90.0, com=True, lead_m=0.0)


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
    source: str | os.PathLike,
    fps: float = 30.0,
    width: int = 480,
    height: int = 360,
    progress: bool = True,
) -> int:
    """Render a sequence of poses (nq each) of ``model`` to a video with flapsim's one
    renderer (:func:`flapsim.render.video.render_frames`): its sky, grass with a
    :data:`GRID_M` grid and sun (``source``, the model's MJCF file, compiled for the picture:
    :func:`flapsim.render.world.drawing_model`), a side camera following the creature's centre of
    mass (:func:`camera_for`)."""

    if len(poses) == 0:
        raise InputError("no frames to render")
    check_video_path(path)
    require_gl()
    drawn = drawing_model(source, nq=model.nq, grid_m=GRID_M, width=width, height=height)
    frames = render_frames(drawn, np.asarray(poses, dtype=float), fps,
                           camera_for(drawn, poses[0]), width, height)
    try:
        return write_frames(path, frames, fps, total=len(poses), progress=progress)
    finally:
        frames.close()


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
