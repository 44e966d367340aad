"""``flapsim eval --lookahead``: auto turns the second-core look-ahead on only where the runs
leave a core per worker free, and a journal resumes whatever the setting (wall time only)."""

from flapsim import scenarios
from flapsim.bird.control import controller as C
from flapsim.cli.commands.eval import lookahead_runs
from flapsim.scenarios.journal import fingerprint


def _runs(n):
    return [("figure8", scenarios.EvalOptions()) for _ in range(n)]


def test_auto_looks_ahead_only_with_a_free_core_per_worker(monkeypatch):
    monkeypatch.setattr(C, "usable_cores", lambda: 2)
    # one run on two cores: the second core is free
    assert [o.lookahead for _, o in lookahead_runs(_runs(1), "auto", None)] == ["auto"]
    # two runs on two cores: one worker per core, nothing free
    assert {o.lookahead for _, o in lookahead_runs(_runs(2), "auto", None)} == {"off"}
    # asked for one worker: free again; on Ray the cores are not this machine's
    assert {o.lookahead for _, o in lookahead_runs(_runs(3), "auto", 1)} == {"auto"}
    assert {o.lookahead for _, o in lookahead_runs(_runs(1), "auto", 1, "ray")} == {"off"}
    monkeypatch.setattr(C, "usable_cores", lambda: 8)
    # eight runs on eight cores fill them; four leave a core free beside each
    assert {o.lookahead for _, o in lookahead_runs(_runs(8), "auto", None)} == {"off"}
    assert {o.lookahead for _, o in lookahead_runs(_runs(4), "auto", None)} == {"auto"}
    assert {o.lookahead for _, o in lookahead_runs(_runs(8), "auto", 5)} == {"off"}
    # explicit settings are kept as given
    assert {o.lookahead for _, o in lookahead_runs(_runs(2), "on", None)} == {"on"}
    assert {o.lookahead for _, o in lookahead_runs(_runs(1), "off", None)} == {"off"}


def test_the_journal_fingerprint_ignores_the_lookahead():
    on = lookahead_runs(_runs(2), "on", None)
    off = lookahead_runs(_runs(2), "off", None)
    assert fingerprint(on, "v") == fingerprint(off, "v")
    # and still sees an option that changes results
    other = [(n, scenarios.EvalOptions(refine=1)) for n, _ in off]
    assert fingerprint(other, "v") != fingerprint(off, "v")
