"""The main job's video shows the task: the path asked is drawn (found by its colour in the
frames), the camera modes, the overlay and the length of fly's default video."""

import imageio.v2 as imageio
import numpy as np
import pytest

from flapsim.bird.body.model import Dove
from flapsim.bird.flight.video import MIN_VIDEO_S, dove_video, video_timing
from flapsim.bird.tasks.flight_tasks import Task, TaskResult
from flapsim.bird.tasks.path_shapes import figure8
from flapsim.core.errors import InputError
from flapsim.render.scene import PATH_SHOWN
from flapsim.scenarios import flight as scen_flight
from flapsim.scenarios.registry import EvalOptions, get

W, H = 128, 96  # small frames: rendering is slow on a CPU; the path is still 3 pixels wide


def _on_path(dove: Dove, path, seconds: float) -> TaskResult:
    """A recorded 'flight' gliding along ``path`` at 7 m/s, trunk level along the tangent:
    each step's qpos (the renderer draws positions only, so no physics is needed to test the
    picture)."""
    dt = float(dove.model.opt.timestep)
    n = int(round(seconds / dt))
    s = 7.0 * dt * np.arange(n)
    q = np.tile(dove.model.qpos0, (n, 1))
    q[:, 0:3] = path.point(s)
    tan = path.tangent(s)
    yaw = np.arctan2(tan[:, 1], tan[:, 0])
    q[:, 3:7] = np.stack([np.cos(yaw / 2), 0 * yaw, 0 * yaw, np.sin(yaw / 2)], 1)
    beats = np.arange(0.0, seconds, 1 / 9.3)
    return TaskResult("completed", "", {}, q[::int(round(0.1075 / dt)), 0:3], np.zeros((0, 4)),
                      [], np.zeros(0), np.zeros(0), q, beats, 1.0)


def _path_pixels(frame: np.ndarray) -> np.ndarray:
    """Pixels of the path's colour (orange: R high, G about half, B low), within the
    compression's and the lighting's spread (+-60 of 255 on each channel)."""
    want = np.asarray(PATH_SHOWN)
    f = frame.astype(int)
    return np.all(np.abs(f - want) < 60, axis=-1)


@pytest.fixture(scope="module")
def dove():
    return Dove.load()


def test_main_jobs_video_shows_the_path(tmp_path, dove):
    sc = get("figure8-level")
    path = figure8(**sc.params["args"])
    r = _on_path(dove, path, 0.25)
    opt = EvalOptions(video_dir=str(tmp_path), fps=20.0, size=(W, H))
    files = scen_flight._outputs(sc, opt, Task(path), r)  # what eval --video writes
    assert files == [str(tmp_path / "figure8-level.mp4")]
    frames = [f for f in imageio.get_reader(files[0])]  # noqa: C416 (len() is inf for mp4)
    stride, slowmo = video_timing(len(r.qpos), float(dove.model.opt.timestep), 20.0, None, 0.0)
    assert slowmo == 1.0 and len(frames) == len(range(0, len(r.qpos), stride))  # real time
    assert abs(len(frames) - 0.25 * 20) <= 1
    for f in frames:
        # the path ahead of the bird: a line of dozens of pixels, in the lower two thirds
        hits = _path_pixels(f)
        assert hits.sum() > 15, hits.sum()
    # the same flight without the path drawn has none of its colour (the dove, the sky, the
    # ground and the trail are other colours): the test can fail
    bare = tmp_path / "bare.mp4"
    dove_video(dove, r.qpos, bare, 20.0, W, H, min_seconds=0.0, progress=False)
    assert all(_path_pixels(f).sum() < 3 for f in imageio.get_reader(str(bare)))


def test_cameras_and_overlay(tmp_path, dove):
    path = figure8(lobe_m=10.0, rise_m=0.0)
    r = _on_path(dove, path, 0.1)
    pictures = {}
    for cam in ("chase", "side", "top", "orbit"):
        out = tmp_path / f"{cam}.mp4"
        dove_video(dove, r.qpos, out, 20.0, W, H, camera=cam, min_seconds=0.0, progress=False,
                   path_points=path.point(np.linspace(0, path.length, 200)))
        pictures[cam] = next(iter(imageio.get_reader(str(out)))).astype(float)
    # four cameras, four different pictures (mean absolute difference > 5 of 255)
    names = list(pictures)
    for i, a in enumerate(names):
        for b in names[i + 1:]:
            assert np.abs(pictures[a] - pictures[b]).mean() > 5, (a, b)
    # the overlay's box darkens the top-left corner against the sky above the horizon
    corner = pictures["chase"][:6, :20].mean()
    right = pictures["chase"][:6, -20:].mean()
    assert corner < right - 30
    with pytest.raises(InputError, match="camera"):
        dove_video(dove, r.qpos, tmp_path / "x.mp4", camera="fisheye")


def test_default_video_lasts_three_seconds():
    # ten wingbeats at 2400 Hz (1.075 s) slowed to at least MIN_VIDEO_S at 60 frames/s
    stride, slowmo = video_timing(2580, 1 / 2400, 60.0, None)
    frames = len(range(0, 2580, stride))
    assert frames / 60.0 >= MIN_VIDEO_S and slowmo == pytest.approx(3.0 / 1.075)
    # asked: as asked (40 steps per frame = 60 frames per flown second at 2400 Hz)
    assert video_timing(2580, 1 / 2400, 60.0, 1.0) == (40, 1.0)
    with pytest.raises(InputError, match="slowmo"):
        video_timing(10, 1 / 2400, 60.0, -1.0)
