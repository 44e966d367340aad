"""Experiment (session 27, not kept): the path target's bank kept within BANK_RATE_DEG (env,
default 15) of the roll the reference wingbeat ends at, the turn rate asked to match.

    PYTHONPATH=. python scripts/dove_verdict_spread.py user --seed 1 \
        --patch scripts/experiments/bank_rate_limit.py

Measured: 53 of 100 on the seed-1 draw, against 90 (docs/flight_log.md, "Tried, not kept
(session 27)").
"""

import os

import numpy as np

from flapsim.bird.control import targets
from flapsim.bird.tasks import path_control as path

RATE = np.radians(float(os.environ.get("BANK_RATE_DEG", "15")))
_target_state = path.target_state


def _limited(trim, speed, heading, climb, turn_rate, S_now=None, *args, **kwargs):
    bank = float(np.arctan2(speed * turn_rate, targets.GRAVITY))
    if S_now is not None:
        now = -float(S_now[1])  # the reduced state's roll is minus the target's bank
        bank = float(np.clip(bank, now - RATE, now + RATE))
        turn_rate = targets.GRAVITY * np.tan(bank) / max(speed, 1e-3)
    return _target_state(trim, speed, heading, climb, turn_rate, S_now, *args, **kwargs)


if getattr(path.target_state, "__name__", "") != "_limited":
    path.target_state = _limited
