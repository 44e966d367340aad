"""The shared viewer's mouse clicks (flapsim.render.viewer), without a window: MuJoCo's selection
(body and the point in its frame) is turned into a world point and consumed."""

from __future__ import annotations

import contextlib
from types import SimpleNamespace

import mujoco
import numpy as np
import pytest

from flapsim.render.viewer import AnimalViewer

XML = """<mujoco><worldbody>
  <geom type="plane" size="5 5 0.1"/>
  <body name="box" pos="1 2 3" euler="0 0 90"><freejoint/><geom type="box" size="1 0.5 0.2"/></body>
</worldbody></mujoco>"""


class _Handle:
    """What AnimalViewer uses of MuJoCo's passive viewer handle, with a real mjvPerturb."""

    def __init__(self) -> None:
        self.perturb = mujoco.MjvPerturb()
        self.cam = SimpleNamespace()

    def lock(self):
        return contextlib.nullcontext()

    def click(self, body: int, local) -> None:
        # what MuJoCo's viewer does on a left double-click on a geom of ``body``
        self.perturb.select = body
        self.perturb.localpos[:] = local


def test_a_double_click_is_a_world_point_taken_once():
    m = mujoco.MjModel.from_xml_string(XML)
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    h = _Handle()
    v = AnimalViewer(m, d, "box", launch=lambda *a, **kw: h)
    assert v.pending_clicks() == []  # nothing clicked yet (MuJoCo starts at select 0, origin)
    # the box is turned 90 deg about z: its local +x is the world's +y
    h.click(1, [0.5, 0.0, 0.2])
    (p,) = v.pending_clicks()
    np.testing.assert_allclose(p, [1.0, 2.5, 3.2], atol=1e-12)
    assert v.pending_clicks() == [] and h.perturb.select == 0  # consumed; nothing stays selected
    # on the floor (the world body: its frame is the world's)
    h.click(0, [4.0, -1.0, 0.0])
    np.testing.assert_allclose(v.pending_clicks()[0], [4.0, -1.0, 0.0])
    # the same spot again counts again
    h.click(0, [4.0, -1.0, 0.0])
    assert len(v.pending_clicks()) == 1


class _Window(_Handle):
    """A stand-in window that counts the pictures it is handed."""

    def __init__(self, m) -> None:
        super().__init__()
        self.cam = mujoco.MjvCamera()
        self.user_scn = mujoco.MjvScene(m, 100)
        self.synced = 0

    def is_running(self) -> bool:
        return True

    def set_texts(self, texts) -> None:
        self.texts = texts

    def sync(self) -> None:
        self.synced += 1


def test_pictures_behind_real_time_are_dropped_not_slowed(monkeypatch):
    from flapsim.render import viewer as V

    clock = [100.0]  # a wall clock the test moves (the machine's load must not decide)
    monkeypatch.setattr(V.time, "perf_counter", lambda: clock[0])
    monkeypatch.setattr(V.time, "sleep", lambda s: clock.__setitem__(0, clock[0] + s))
    m = mujoco.MjModel.from_xml_string(XML)
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    w = _Window(m)
    v = AnimalViewer(m, d, "box", launch=lambda *a, **kw: w)
    frame = V.FRAME_S
    assert v.show(0.0) and w.synced == 1  # the first picture starts the clock
    # the simulation took 3 frames of wall time for one frame of flight: behind, dropped
    clock[0] += 3 * frame
    assert v.show(frame) and (w.synced, v.dropped) == (1, 1)
    # ... but never for longer than MAX_FRAME_GAP_S: then one is drawn however late
    clock[0] += V.MAX_FRAME_GAP_S
    assert v.show(2 * frame) and (w.synced, v.dropped) == (2, 1)
    # on time again (the simulation ahead of the clock): drawn, and the show waits for real time
    late = clock[0] - 100.0
    assert v.show(late + 0.5 * frame) and (w.synced, v.dropped) == (3, 1)
    assert clock[0] - 100.0 == pytest.approx(late + 0.5 * frame)
    assert (v.frames, v.dropped) == (3, 1)


def test_the_overlay_keeps_each_label_beside_its_value():
    from flapsim.render.viewer import HELP, overlay_columns

    # the dove's overlay: the keys' help runs over two lines, its label has an empty row below
    labels, values = overlay_columns("steering\nelevation\nkeys\n",
                                     "+10 deg/s\n+0 deg\narrows: steer,\nInsert: push", 0.99)
    left, right = labels.split("\n"), values.split("\n")
    assert len(left) == len(right) == 6
    row = dict(zip(left, right, strict=True))
    assert row["elevation"] == "+0 deg" and row["keys"] == "arrows: steer,"
    assert row["real time"] == "0.99x" and row["leave"] == HELP
    # no rows of the caller's, or a value longer than its labels: padded, never shifted
    assert overlay_columns("", "", None) == ("real time\nleave", f"-\n{HELP}")
    labels, values = overlay_columns("a", "1\n2\n3", 1.0)
    assert labels.split("\n").index("real time") == values.split("\n").index("1.00x") == 3


def test_a_flash_given_as_a_callable_follows_the_animal(monkeypatch):
    from flapsim.render import viewer as V

    clock = [0.0]
    monkeypatch.setattr(V.time, "perf_counter", lambda: clock[0])
    monkeypatch.setattr(V.time, "sleep", lambda s: clock.__setitem__(0, clock[0] + s))
    m = mujoco.MjModel.from_xml_string(XML)
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    w = _Window(m)
    v = AnimalViewer(m, d, "box", launch=lambda *a, **kw: w)
    v.tracking = False  # the stand-in camera has no rig to move
    # a push arrow ending at the box, and one left where the box was
    v.flash(lambda: V.Arrow(d.xpos[1] - [0.8, 0, 0], [0.7, 0, 0]), 0.0)
    v.flash(V.Arrow(d.xpos[1] - [0.8, 0, 0], [0.7, 0, 0], rgba=(0, 0, 1, 1)), 0.0)
    centres = []
    for x in (0.0, 3.5):  # the box flies on 3.5 m (half a second of a dove's flight)
        d.qpos[0] = x
        mujoco.mj_forward(m, d)
        assert v.show(0.1 + x / 7.0)
        g = [w.user_scn.geoms[i] for i in range(w.user_scn.ngeom)]
        red = [gg for gg in g if gg.rgba[0] > 0.5]
        centres.append(np.mean([gg.pos[0] for gg in red]))
        blue = [gg for gg in g if gg.rgba[2] > 0.5 and gg.rgba[0] < 0.5]
        assert np.mean([gg.pos[0] for gg in blue]) < 1.0  # the fixed one stayed behind
    # the callable's arrow moved with the box, by the box's 3.5 m
    assert centres[1] - centres[0] == pytest.approx(3.5, abs=1e-6)
