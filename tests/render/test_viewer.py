"""The shared viewer's mouse clicks (flapsim.render.viewer), without a window: MuJoCo's selection
(body and the point in its frame) is turned into a world point and consumed."""

from __future__ import annotations

import contextlib
from types import SimpleNamespace

import mujoco
import numpy as np

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
