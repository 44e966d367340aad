"""Experiment (session 27, not kept): a state-conditioned regression (``--set state_weight=1``)
that compares start states by pitch and roll only (the rest of S zeroed on both sides).

    flapsim train --samples 5000 --pre-pitch-deg 10 --pre-roll-deg 70 --seed 7 --float32 \
        --out bank70.db
    flapsim train --merge flapsim/bird/control/data/dove_controller.db bank70.db --out merged70.db
    PYTHONPATH=. python scripts/dove_verdict_spread.py user --seed 1 --set db=merged70.db \
        --set state_weight=1 --patch scripts/experiments/attitude_context.py

Measured: 0 of 100 on the seed-1 draw, against 90 for the bundled database alone; the merge
without this patch 10 (20 with ``state_weight=1``) (docs/flight_log.md, "Tried, not kept
(session 27)").
"""

import numpy as np

from flapsim.bird.control import regression

_init = regression.Regressor.__init__
_query = regression.Regressor._query_point


def _init_attitude(self, dS, dP, *args, context=None, **kwargs):
    if context is not None:
        context = np.asarray(context, float).copy()
        context[:, 2:] = 0.0
    _init(self, dS, dP, *args, context=context, **kwargs)


def _query_attitude(self, x, s):
    if s is not None:
        s = np.asarray(s, float).copy()
        s[2:] = 0.0
    return _query(self, x, s)


if regression.Regressor.__init__ is _init and regression.Regressor._query_point is _query:
    regression.Regressor.__init__ = _init_attitude
    regression.Regressor._query_point = _query_attitude
