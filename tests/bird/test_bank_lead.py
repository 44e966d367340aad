"""The rigid dove's bank lead: how far ahead the path target asks the bank."""

import numpy as np
import pytest

from flapsim.bird import tasks
from flapsim.bird.path import FlightPath
from flapsim.bird.paths import START_HEIGHT
from flapsim.bird.tasks import DEFAULT_BANK_LEAD_S, Task, build_flight, fly_task


def _s_curve(r: float = 3.5) -> np.ndarray:
    """A half circle of radius ``r`` to the left, then one to the right, 6 m straight ends:
    a roll reversal from a steep bank (1.74 g at 7 m/s), which the dove meets slowed to 5 m/s."""
    t = np.linspace(0.0, np.pi, 25)
    left = np.stack([r * np.sin(t), r * (1 - np.cos(t))], 1)
    right = np.stack([-r * np.sin(t), 2 * r + r * (1 - np.cos(t))], 1)
    xy = np.vstack([[[-6.0, 0.0], [-3.0, 0.0]], left, right[1:], [[3.0, 4 * r], [6.0, 4 * r]]])
    return np.c_[xy, np.full(len(xy), START_HEIGHT)]


def test_the_default_lead_follows_an_s_of_3_5_m_half_circles(monkeypatch):
    """Over starts under 1 mm/s apart (a flight this tight is chaotic: one run's verdict
    says little), the S is followed with the rigid dove's default lead and lost with the 0.3 s
    of sessions 10-17. Measured with scripts/dove_verdict_spread.py over 10 starts: largest
    distance 1.8-3.0 m in 8, 3.3 and 6.5 m in the other two, against 3.8-6.8 m, all lost. The
    median of five starts against 3.5 m (half a metre past the 3 m tube): a start past it has
    come 1 in 10 with the default, and none has come under it with 0.3 s."""
    assert DEFAULT_BANK_LEAD_S == {"rigid": 0.2, "modal": 0.3}
    dv = {"v": 0.0}
    real = tasks.start_on_path

    def jittered(fl, *args, **kwargs):
        real(fl, *args, **kwargs)
        v = fl.data.qvel[0:3]
        v += dv["v"] * v / np.linalg.norm(v)

    monkeypatch.setattr(tasks, "start_on_path", jittered)
    path = FlightPath(_s_curve())
    fl, ctl = build_flight(Task(path))
    largest = {}
    try:
        for lead in (None, 0.3):
            worst = []
            for dv["v"] in (0.0, 3e-4, -3e-4, 6e-4, -6e-4):
                r = fly_task(Task(path, bank_lead_s=lead), controller=ctl)
                worst.append(r.metrics["max_path_distance"])
            largest[lead] = float(np.median(worst))
    finally:
        fl.close()
    assert largest[None] < 3.5 < largest[0.3], largest


@pytest.mark.parametrize("feathers, lead", [("rigid", 0.2), ("modal", 0.3)])
def test_the_task_asks_the_doves_own_lead_unless_given(feathers, lead, monkeypatch):
    seen = []

    class Spy(tasks.PathTarget):
        def __init__(self, *args, **kwargs):
            seen.append(kwargs["bank_lead_s"])
            raise RuntimeError("seen")

    monkeypatch.setattr(tasks, "PathTarget", Spy)
    path = FlightPath(_s_curve())
    for given in (None, 0.05):
        with pytest.raises(RuntimeError, match="seen"):
            tasks.fly_task(Task(path, feathers=feathers, bank_lead_s=given))
    assert seen == [lead, 0.05]
