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


def _without_clock(r: dict) -> dict:
    """A run's result less what the wall clock decides."""
    r = dict(r)
    r.pop("wall_s", None)
    r["metrics"] = {k: v for k, v in r.get("metrics", {}).items() if k != "real_time_factor"}
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


def test_torn_stale_and_foreign_journals(tmp_path):
    path = journal_path(tmp_path / "r.json")
    assert path.name == "r.json.partial"
    j = RunJournal(path, "abc", 3)
    j.open({0: {"status": "completed"}})
    j.add(2, {"status": "lost"})
    j.close()
    with open(path, "a") as f:
        f.write('{"i": 1, "result": {"sta')  # torn by a kill mid-line
    assert RunJournal(path, "abc", 3).load() == {0: {"status": "completed"}, 2: {"status": "lost"}}
    other = RunJournal(path, "xyz", 3)
    assert other.load() == {} and other.stale  # other runs: flown afresh, the journal replaced
    path.write_text("my notes, not a journal\n")
    with pytest.raises(InputError, match="not an eval journal"):
        RunJournal(path, "abc", 3).load()
    assert path.read_text() == "my notes, not a journal\n"  # left alone


def test_a_run_written_when_ctrl_c_lands_is_kept(tmp_path, monkeypatch):
    """The race CI met: the Ctrl-C arrives once a run's line is on disk but before ``add``
    returns (here, inside its fsync). The journal's close must keep that run, or the
    interrupted eval throws away a finished run and tells the user nothing can resume."""
    path = journal_path(tmp_path / "r.json")
    j = RunJournal(path, "abc", 2)
    j.open({})
    real_fsync = os.fsync

    def interrupted(fd):
        real_fsync(fd)
        raise KeyboardInterrupt

    monkeypatch.setattr(os, "fsync", interrupted)
    with pytest.raises(KeyboardInterrupt):
        j.add(0, {"status": "completed"})
    monkeypatch.setattr(os, "fsync", real_fsync)
    j.close()
    assert RunJournal(path, "abc", 2).load() == {0: {"status": "completed"}}
    empty = RunJournal(journal_path(tmp_path / "e.json"), "abc", 2)
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
