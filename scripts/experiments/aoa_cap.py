"""Experiment (session 27): the nose-up asked in a turn (``aoa_per_g (n - 1)``) capped at
AOA_CAP_DEG (env; default 16.57 deg, what 40 deg per g asks at a 45 deg bank). Since session
26 the rigid dove's bank cap is 60 deg, where 40 deg per g asks 40 deg more nose-up.

    AOA_CAP_DEG=16.57 PYTHONPATH=. python scripts/dove_verdict_spread.py user --seed 1 \
        --patch scripts/experiments/aoa_cap.py

Measured on the seed-1 draw: 74 of 100 against 90 (docs/flight_log.md, "Tried, not kept
(session 27)"). Not kept.
"""

import os

import numpy as np

from flapsim.bird.control import targets
from flapsim.bird.tasks import path_control as path

CAP = np.radians(float(os.environ.get("AOA_CAP_DEG", "16.57")))
_target_state = path.target_state


def _capped(trim, speed, heading, climb, turn_rate, S_now=None, settle_s=0.2, wind=None,
            aoa_per_g=0.0):
    bank = float(np.arctan2(speed * turn_rate, targets.GRAVITY))
    extra = aoa_per_g * (1.0 / max(float(np.cos(bank)), 0.2) - 1.0)
    if extra > CAP:
        aoa_per_g = aoa_per_g * CAP / extra  # the same formula, asking CAP
    return _target_state(trim, speed, heading, climb, turn_rate, S_now, settle_s, wind, aoa_per_g)


if getattr(path.target_state, "__name__", "") != "_capped":
    path.target_state = _capped
