"""An interrupted ``flapsim eval --json PATH`` keeps its finished runs and resumes."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from flapsim.bird.control.config import ControllerConfig
from flapsim.core.errors import InputError
from flapsim.scenarios import EvalOptions
from flapsim.scenarios.journal import RunJournal, fingerprint, journal_path

ROOT = Path(__file__).resolve().parents[2]
RUNS = "wind-steady,wind-gusts,push-up"  # quick variants: a few seconds each on one worker


def _eval(tmp_path, out, *extra):
    cmd = [sys.executable, "-m", "flapsim.cli.main", "eval", "--scenario", RUNS, "--quick",
           "--workers", "1", "--json", out, *extra]
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    return subprocess.Popen(cmd, cwd=tmp_path, env=env, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)


#: What the wall clock decides in a run's metrics: its speed, and how many references the
#: look-ahead thread had simulated before the flight asked for them (one it had not started
#: is simulated on the spot, the same bits either way)
CLOCK_METRICS = ("real_time_factor", "lookahead_hits", "lookahead_misses")


def _without_clock(r: dict) -> dict:
    """A run's result less what the wall clock decides."""
    r = dict(r)
    r.pop("wall_s", None)
    r["metrics"] = {k: v for k, v in r.get("metrics", {}).items() if k not in CLOCK_METRICS}
    return r


def test_an_interrupted_eval_resumes_without_flying_its_finished_runs_again(tmp_path):
    proc = _eval(tmp_path, "q.json")
    journal = tmp_path / "q.json.partial"
    try:
        t_end = time.monotonic() + 120
        # the header, then one finished run
        while not (journal.exists() and journal.read_text().count("\n") >= 2):
            assert proc.poll() is None, proc.communicate()
            assert time.monotonic() < t_end, "no run finished"
            time.sleep(0.05)
        proc.send_signal(signal.SIGINT)
        _, err = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 130, err
    assert "run the same command again to resume" in err.strip().splitlines()[-1]
    assert not (tmp_path / "q.json").exists()
    kept = [json.loads(line) for line in journal.read_text().splitlines()[1:]]
    assert 1 <= len(kept) < 3  # the signal came before the last run finished

    again = _eval(tmp_path, "q.json")
    out, err = again.communicate(timeout=300)
    assert again.returncode in (0, 1), err  # 1: a quick push run may be lost; it is still written
    assert f"resuming: {len(kept)} of 3 runs finished before" in out
    resumed = json.loads((tmp_path / "q.json").read_text())
    assert resumed["resumed_runs"] == len(kept)
    assert not journal.exists()  # removed once the results are written
    # the kept runs are read back to the bit, wall clock included: not flown again (a run
    # flown again would have its own wall time)
    for rec in kept:
        assert resumed["scenarios"][rec["i"]] == rec["result"]
    # and the whole is what an uninterrupted eval gives (the runs are deterministic)
    fresh = _eval(tmp_path, "fresh.json")
    fresh.communicate(timeout=300)
    clean = json.loads((tmp_path / "fresh.json").read_text())
    assert clean["resumed_runs"] == 0
    assert ([_without_clock(r) for r in resumed["scenarios"]]
            == [_without_clock(r) for r in clean["scenarios"]])


def test_a_journal_is_of_the_runs_asked_and_their_files(tmp_path):
    db = tmp_path / "a.db"
    db.write_bytes(b"one")
    runs = [("wind-steady", EvalOptions(db=str(db), quick=True))]
    f = fingerprint(runs, "1.0")
    assert fingerprint(runs, "1.0") == f
    assert fingerprint(runs, "1.1") != f  # another flapsim
    assert fingerprint([("wind-gusts", runs[0][1])], "1.0") != f  # another scenario
    refine0 = EvalOptions(db=str(db), quick=True, controller=ControllerConfig(refine=0))
    assert fingerprint([("wind-steady", refine0)], "1.0") != f
    db.write_bytes(b"two")  # the same database path, other samples
    assert fingerprint(runs, "1.0") != f


def _result(name, status="completed"):
    """A run's result as :func:`flapsim.scenarios.registry.run_scenario` returns it."""
    return {"scenario": name, "family": "flight", "summary": "", "status": status,
            "ok": status == "completed", "metrics": {"Ep_per_wingbeat": 0.05}, "files": [],
            "reason": "", "wall_s": 1.5}


def test_torn_stale_and_foreign_journals(tmp_path):
    path = journal_path(tmp_path / "r.json")
    assert path.name == "r.json.partial"
    j = RunJournal(path, ["k0", "k1", "k2"])
    j.open({0: _result("a")})
    j.add(2, _result("c", "lost"))
    j.close()
    with open(path, "a") as f:
        f.write('{"i": 1, "run": "k1", "result": {"sta')  # torn by a kill mid-line
    again = RunJournal(path, ["k0", "k1", "k2"])
    assert again.load() == {0: _result("a"), 2: _result("c", "lost")}
    assert len(again.skipped) == 1 and "line 4" in again.skipped[0]
    # other runs: none resumed, and the journal's runs are kept (never deleted unasked)
    other = RunJournal(path, ["x0", "x1", "x2"])
    assert other.load() == {} and other.stale and len(other.kept) == 2
    other.open({})
    other.close()
    assert RunJournal(path, ["k0", "k1", "k2"]).load() == {0: _result("a"), 2: _result("c", "lost")}
    path.write_text("my notes, not a journal\n")
    with pytest.raises(InputError, match="not an eval journal"):
        RunJournal(path, ["k0"]).load()
    assert path.read_text() == "my notes, not a journal\n"  # left alone


@pytest.mark.parametrize("line, problem", [
    ('{"i": 1, "run": "k1", "result": {}}', "'scenario'"),
    ('{"i": 1, "run": "k1", "result": {"scenario": "b", "family": "flight", "status": "completed", '
     '"ok": true, "metrics": "fast"}}', "'metrics' is str"),
    ('{"i": "0", "run": "k0", "result": {}}', "run index '0'"),
    ('[1, 2]', "not a JSON object"),
    ('{"i": 1, "result": {"scenario": "b"}}', "names no run"),
])
def test_a_bad_journal_line_is_named_and_its_run_flown_again(tmp_path, line, problem):
    """A corrupted line made every rerun fly the other runs, then die with KeyError or
    AttributeError; now it is skipped before any work, with its file and line named."""
    path = journal_path(tmp_path / "r.json")
    j = RunJournal(path, ["k0", "k1"])
    j.open({0: _result("a")})
    j.close()
    with open(path, "a") as f:
        f.write(line + "\n")
    again = RunJournal(path, ["k0", "k1"])
    assert again.load() == {0: _result("a")}
    assert len(again.skipped) == 1 and again.skipped[0].startswith(f"{path} line 3: ")
    assert problem in again.skipped[0] and "flown again" in again.skipped[0]


def test_an_eval_of_a_subset_reuses_its_runs_and_keeps_the_others(tmp_path, monkeypatch):
    """Four runs asked, three finished, then the same --json with two of them: both are read
    back (none flown: the executor is never built), and the journal keeps the third finished
    run, which a rerun of the four reads back too (before: 'starting afresh', all deleted)."""
    from flapsim.core.parallel import ChunkExecutor
    from flapsim.scenarios.runner import execute, open_journal

    def no_flying(*a, **k):
        raise AssertionError("a finished run was flown again")

    monkeypatch.setattr(ChunkExecutor, "__init__", no_flying)
    names = ["figure8-level", "wind-steady", "push-up", "figure8"]
    four = [(n, EvalOptions(quick=True)) for n in names]
    out = tmp_path / "q.json"
    j = open_journal(str(out), four)
    j.load()
    j.open({})
    for i in (0, 1, 2):
        j.add(i, _result(names[i]))
    j.close()
    said = []
    sub = open_journal(str(out), [four[1], four[0]])
    results = execute([four[1], four[0]], 1, journal=sub, say=said.append)
    assert results == [_result("wind-steady"), _result("figure8-level")]
    assert sub.resumed == 2 and len(sub.kept) == 1
    assert sub.finish() and journal_path(out).exists()  # push-up's run is kept
    again = open_journal(str(out), four)
    assert again.load() == {i: _result(names[i]) for i in (0, 1, 2)}


def test_a_run_written_when_ctrl_c_lands_is_kept(tmp_path, monkeypatch):
    """The race CI met: the Ctrl-C arrives once a run's line is on disk but before ``add``
    returns (here, inside its fsync). The journal's close must keep that run, or the
    interrupted eval throws away a finished run and tells the user nothing can resume."""
    path = journal_path(tmp_path / "r.json")
    j = RunJournal(path, ["k0", "k1"])
    j.open({})
    real_fsync = os.fsync

    def interrupted(fd):
        real_fsync(fd)
        raise KeyboardInterrupt

    monkeypatch.setattr(os, "fsync", interrupted)
    with pytest.raises(KeyboardInterrupt):
        j.add(0, _result("a"))
    monkeypatch.setattr(os, "fsync", real_fsync)
    j.close()
    assert RunJournal(path, ["k0", "k1"]).load() == {0: _result("a")}
    empty = RunJournal(journal_path(tmp_path / "e.json"), ["k0", "k1"])
    empty.open({})
    empty.close()
    assert not empty.path.exists()  # no run finished: nothing to resume from, no file left


def test_a_run_whose_result_never_came_back_is_an_error_not_a_shorter_table(monkeypatch):
    # an executor that returns fewer results than runs (as one did when two chunks finished
    # in the same wait): eval must say so in one line, not print a table without the run
    from flapsim.core.parallel import ChunkExecutor, WorkerError
    from flapsim.scenarios import EvalOptions
    from flapsim.scenarios.runner import execute

    monkeypatch.setattr(ChunkExecutor, "map_unordered", lambda self, chunks: iter(()))
    with pytest.raises(WorkerError, match="no result came back for figure8") as e:
        execute([("figure8", EvalOptions(quick=True))], workers=1)
    assert "\n" not in str(e.value)
