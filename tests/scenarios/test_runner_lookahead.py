"""The controller configuration's ``lookahead`` in ``flapsim eval``: auto turns the
second-core look-ahead on only where the runs leave a core per worker free, and a journal
resumes whatever the setting (wall time only)."""

import dataclasses

from flapsim import scenarios
from flapsim.bird.control.config import ControllerConfig
from flapsim.scenarios import runner
from flapsim.scenarios.journal import fingerprint
from flapsim.scenarios.runner import lookahead_runs


def _runs(n, mode="auto"):
    opts = scenarios.EvalOptions(controller=ControllerConfig(lookahead=mode))
    return [("figure8", opts) for _ in range(n)]


def _modes(runs):
    return {o.controller.lookahead for _, o in runs}


def test_auto_looks_ahead_only_with_a_free_core_per_worker(monkeypatch):
    monkeypatch.setattr(runner, "usable_cores", lambda: 2)
    # one run on two cores: the second core is free
    assert [o.controller.lookahead for _, o in lookahead_runs(_runs(1), None)] == ["auto"]
    # two runs on two cores: one worker per core, nothing free
    assert _modes(lookahead_runs(_runs(2), None)) == {"off"}
    # asked for one worker: free again; on Ray the cores are not this machine's
    assert _modes(lookahead_runs(_runs(3), 1)) == {"auto"}
    assert _modes(lookahead_runs(_runs(1), 1, "ray")) == {"off"}
    monkeypatch.setattr(runner, "usable_cores", lambda: 8)
    # eight runs on eight cores fill them; four leave a core free beside each
    assert _modes(lookahead_runs(_runs(8), None)) == {"off"}
    assert _modes(lookahead_runs(_runs(4), None)) == {"auto"}
    assert _modes(lookahead_runs(_runs(8), 5)) == {"off"}
    # explicit settings are kept as given
    assert _modes(lookahead_runs(_runs(2, "on"), None)) == {"on"}
    assert _modes(lookahead_runs(_runs(1, "off"), None)) == {"off"}
    # a run without a configuration flies the library's default (no look-ahead): kept
    plain = [("figure8", scenarios.EvalOptions())]
    assert lookahead_runs(plain, None) == plain


def test_the_journal_fingerprint_ignores_the_lookahead():
    on, off = _runs(2, "on"), _runs(2, "off")
    assert fingerprint(on, "v") == fingerprint(off, "v")
    # and still sees a setting that changes results
    other = [(n, dataclasses.replace(o, controller=dataclasses.replace(o.controller, refine=1)))
             for n, o in off]
    assert fingerprint(other, "v") != fingerprint(off, "v")
