"""A chase-camera video of a dove flight from its recorded steps (rigid or modal feathers)."""

from __future__ import annotations

import os

import numpy as np

from flapsim.bird.body.drawing import video_model
from flapsim.render.video import ChaseCamera, render_video


def dove_video(dove, qpos_steps: np.ndarray, path: str | os.PathLike, fps: float = 30.0,
               width: int = 640, height: int = 480) -> int:
    """Render every simulation step's frame (n, width) of ``dove`` (its ``qpos``, then any
    engine-integrated modal coordinates: :meth:`~flapsim.bird.flight.dove_flight.DoveFlight.frame`),
    subsampled to ``fps``, to ``path``; modal feathers are drawn bent. Returns the number of
    frames."""

    model, hook = dove.model, None
    frames = np.asarray(qpos_steps)
    if dove.modal is not None:
        model, hook, ix = video_model(dove)
        frames = frames[:, ix]
    else:  # the primaries drawn twisted (their hinges are outside the skeleton)
        model, ix = dove.drawing()
        frames = frames[:, ix]
    dt = float(model.opt.timestep)
    stride = max(1, int(round(1.0 / (fps * dt))))
    return render_video(model, frames[::stride], path, fps=1.0 / (stride * dt),
                        camera=ChaseCamera("trunk"), width=width, height=height,
                        before_frame=hook)
