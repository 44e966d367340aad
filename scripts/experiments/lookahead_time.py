"""Experiment (session 27): the path target's look-ahead time set by env LOOKAHEAD_S (s; the
paper's and the default's is 1 s).

    LOOKAHEAD_S=0.7 PYTHONPATH=. python scripts/dove_verdict_spread.py user --seed 1 \
        --patch scripts/experiments/lookahead_time.py

Measured on the seed-1 draw: 0.5 s 0 of 100, 0.7 s 90, 1 s (the default) 90, 1.3 s 78
(docs/flight_log.md, "Tried, not kept (session 27)").
"""

import os

from flapsim.bird.tasks import path_control as path

VALUE = float(os.environ.get("LOOKAHEAD_S", "1.0"))
_post_init = path.PathTarget.__post_init__


def _with_lookahead(self) -> None:
    self.lookahead_s = VALUE  # a dataclass default is baked into __init__: set it here
    _post_init(self)


if path.PathTarget.__post_init__ is _post_init:
    path.PathTarget.__post_init__ = _with_lookahead
