"""``flapsim train``'s checks before any work, and its exit status on SIGTERM."""

import os
import shutil
import signal

import pytest

from flapsim.bird.control.controller import bundled_database_path
from flapsim.bird.control.database import load_database
from flapsim.bird.training.fake_worker import FakeConfig, FakeWorker
from flapsim.bird.training.train import train
from flapsim.cli.main import main
from flapsim.core.errors import InputError

CFG = FakeConfig(seed=5)


class _StopAfter:
    """A worker class factory named like FakeWorker whose k-th chunk raises ``exc``."""

    __module__ = FakeWorker.__module__
    __qualname__ = FakeWorker.__qualname__

    def __init__(self, k, exc=KeyboardInterrupt):
        self.k, self.exc = k, exc

    def __call__(self, config):
        w = FakeWorker(config)
        run, count = w.run_chunk, [0]

        def run_chunk(start, stop):
            count[0] += 1
            if count[0] > self.k:
                self.exc()
            return run(start, stop)

        w.run_chunk = run_chunk
        return w


def _raise_interrupt():
    raise KeyboardInterrupt


def test_fewer_samples_than_an_interrupted_run_asked_is_refused(tmp_path):
    """`train --samples 8` on an interrupted 400-sample journal finalized it at 8 and dropped
    the rest."""
    out = tmp_path / "a.db"
    with pytest.raises(KeyboardInterrupt):
        train(CFG, out, 100, _StopAfter(6, _raise_interrupt), chunk_size=4, progress=False)
    held = load_database(out).n
    assert held > 8
    before = out.read_bytes()
    with pytest.raises(InputError) as e:
        train(CFG, out, 8, FakeWorker, chunk_size=4, progress=False)
    msg = str(e.value)
    assert "--samples 100" in msg and f"({held} samples so far)" in msg and "\n" not in msg
    assert out.read_bytes() == before  # untouched
    # the size asked is the journal's alone: the finished database is the one an
    # uninterrupted run writes
    train(CFG, out, 100, FakeWorker, chunk_size=4, progress=False)
    ref = tmp_path / "ref.db"
    train(CFG, ref, 100, FakeWorker, chunk_size=4, progress=False)
    assert out.read_bytes() == ref.read_bytes() and b"samples_asked" not in ref.read_bytes()


def _sigterm():
    os.kill(os.getpid(), signal.SIGTERM)


def test_sigterm_exits_143_and_the_journal_resumes(tmp_path, monkeypatch, capsys):
    """SIGTERM printed "interrupted" and exited 130, while --help promises 143."""
    import flapsim.cli.commands.train as cmd

    out = tmp_path / "a.db"
    monkeypatch.setattr(cmd, "phase1", lambda args: (CFG, _StopAfter(3, _sigterm)))
    assert main(["train", "--samples", "40", "--chunk-size", "4", "--workers", "1",
                 "--no-progress", "--out", str(out)]) == 143
    err = capsys.readouterr().err.strip().splitlines()
    assert err[-1].startswith("flapsim train: terminated (SIGTERM)")
    assert "run the same command again to resume" in err[-1]
    assert [c[0] for c in load_database(out).chunks] == [0, 4, 8]
    monkeypatch.setattr(cmd, "phase1", lambda args: (CFG, FakeWorker))
    assert main(["train", "--samples", "40", "--chunk-size", "4", "--workers", "1",
                 "--no-progress", "--out", str(out)]) == 0
    assert load_database(out, require_finalized=True).n == 40


def test_phase2_checks_its_out_before_discovering(tmp_path, capsys):
    """--out was checked only after a minute of discovery, which then left
    OUT.discovery.db behind."""
    src = tmp_path / "phase1.db"
    shutil.copy(bundled_database_path("rigid"), src)
    out = tmp_path / "K.db"
    train(CFG, out, 12, FakeWorker, chunk_size=4, progress=False)  # another run's database
    before = out.read_bytes()
    assert main(["train", "--phase", "2", "--from", str(src), "--out", str(out), "--samples", "8",
                 "--workers", "1", "--no-progress"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and str(out) in err[0] and "another --out" in err[0], err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["K.db", "phase1.db"]
    assert out.read_bytes() == before
