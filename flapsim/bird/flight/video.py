"""A video of a dove flight from its recorded steps (rigid or modal feathers): the path asked
drawn as a line, the flight as a fading trail, trees and targets in view, a camera mode
(:data:`flapsim.render.video.CAMERAS`) and an overlay (time, speed, wingbeat, a metric)."""

from __future__ import annotations

import os
from collections.abc import Callable, Sequence

import numpy as np

from flapsim.bird.body.drawing import video_model
from flapsim.core.errors import InputError
from flapsim.render.scene import Item, Marker, Polyline, tree_items
from flapsim.render.video import Camera, TrailSpec, render_video

MIN_VIDEO_S = 3.0
"""The shortest video :func:`dove_video` makes by default (``min_seconds``), s: a ten-wingbeat
flight (1.1 s) is slowed to last this long, which also shows the wingbeat."""

MATE_RADIUS_M = 0.12
"""A flock mate is drawn as a sphere of about the dove's trunk and folded wings, m."""
MATE_RGBA = (0.55, 0.50, 0.47, 1.0)


def video_timing(n_steps: int, dt: float, fps: float, slowmo: float | None,
                 min_seconds: float = MIN_VIDEO_S) -> tuple[int, float]:
    """(steps per frame, slow motion factor) for ``n_steps`` recorded steps of ``dt`` s at
    ``fps``: ``slowmo`` as asked, or (None) the least factor >= 1 that makes the video last
    ``min_seconds``."""
    if not (np.isfinite(fps) and 0 < fps <= 1000):
        raise InputError(f"video frame rate must be > 0 and <= 1000 frames/s, got {fps}")
    if slowmo is None:
        slowmo = max(1.0, min_seconds / max(n_steps * dt, 1e-9))
    if not (np.isfinite(slowmo) and 0.01 <= slowmo <= 1000):
        raise InputError(f"--slowmo must be within 0.01..1000, got {slowmo}")
    stride = max(1, int(1.0 / (fps * slowmo * dt) + 1e-9))  # floor: never shorter than asked
    return stride, float(slowmo)


def dove_video(dove, qpos_steps: np.ndarray, path: str | os.PathLike, fps: float = 60.0,
               width: int = 640, height: int = 480, *, slowmo: float | None = None,
               camera: str = "chase", path_points: np.ndarray | None = None, forest=None,
               targets: Sequence[Item] = (), wingbeat_times: np.ndarray | None = None,
               metric: tuple[str, Callable[[np.ndarray], float]] | None = None,
               mates: Sequence[tuple[np.ndarray, np.ndarray]] = (),
               min_seconds: float = MIN_VIDEO_S, progress: bool = True) -> int:
    """Render the recorded steps (n, width) of ``dove`` (its ``qpos``, then any
    engine-integrated modal coordinates: :meth:`~flapsim.bird.flight.dove_flight.DoveFlight.frame`),
    one frame per ``1 / (fps * slowmo)`` s of flight, to ``path``; modal feathers are drawn
    bent. ``path_points``: the path asked (n, 3), drawn; ``forest``: its trees; ``targets``:
    more scene items; ``wingbeat_times``: each wingbeat's start, s (the overlay counts them);
    ``metric``: (label, f(trunk position) -> value) shown as it goes; ``mates``: other birds'
    (times s, positions (n, 3) m) tracks, drawn where they are at each frame's time (the
    recording starting at ``wingbeat_times[0]``, else 0). Returns the frames."""

    model, hook = dove.model, None
    frames = np.asarray(qpos_steps)
    if dove.modal is not None:
        model, hook, ix = video_model(dove)
        frames = frames[:, ix]
    else:  # the primaries drawn twisted (their hinges are outside the skeleton)
        model, ix = dove.drawing()
        frames = frames[:, ix]
    dt = float(model.opt.timestep)
    stride, slowmo = video_timing(len(frames), dt, fps, slowmo, min_seconds)
    shown = frames[::stride]
    step_s = stride * dt  # flight time between frames
    items: list[Item] = list(targets) + tree_items(forest)
    if path_points is not None and len(path_points) > 1:
        items.insert(0, Polyline(np.asarray(path_points, float), line_px=max(3.0, height / 160)))
    beats = np.asarray(wingbeat_times, float) if wingbeat_times is not None else None
    pos = shown[:, 0:3]
    speed = np.zeros(len(shown))
    if len(shown) > 1:
        v = np.linalg.norm(np.diff(pos, axis=0), axis=1) / step_s
        speed[1:], speed[0] = v, v[0]
    total: list[float] = [0.0]

    def overlay(i: int, data) -> str:
        t = i * step_s
        lines = [f"t {t:6.2f} s" + (f"   slow motion x{slowmo:.1f}" if slowmo > 1.01 else ""),
                 f"speed {speed[i]:5.2f} m/s"]
        if beats is not None and len(beats):
            lines.append(f"wingbeat {int(np.searchsorted(beats, t + beats[0], 'right'))}")
        if metric is not None:
            value = float(metric[1](pos[i]))
            total[0] = value if i == 0 else total[0] + value
            lines.append(f"{metric[0]} {value:.2f} m (mean {total[0] / (i + 1):.2f} m)")
        return "\n".join(lines)

    t0 = float(beats[0]) if beats is not None and len(beats) else 0.0

    def mates_at(i: int) -> list[Item]:
        t = t0 + i * step_s
        out: list[Item] = []
        for times, p in mates:
            if len(times) and times[0] <= t <= times[-1]:
                at = [float(np.interp(t, times, p[:, c])) for c in range(3)]
                out.append(Marker(at, MATE_RADIUS_M, MATE_RGBA))
        return out

    return render_video(model, shown, path, fps=fps, camera=Camera("trunk", camera),
                        width=width, height=height, before_frame=hook, items=items,
                        trail=TrailSpec(seconds=2.0, line_px=max(2.0, height / 120)),
                        overlay=overlay, frame_dt=step_s,
                        progress=progress, frame_items=mates_at if len(mates) else None)
