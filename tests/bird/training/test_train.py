"""train(): the same finished bytes for any worker count, backend or interruption;
resume rules; and the `flapsim train` command's argument checks."""

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from flapsim.bird.control.database import DatabaseWriter, fields_spec, load_database
from flapsim.bird.training.fake_worker import FakeConfig, FakeWorker, expected_samples
from flapsim.bird.training.sampling import SamplingConfig
from flapsim.bird.training.train import run_header, same_entry, train
from flapsim.cli.main import main
from flapsim.core.errors import DataFileError, InputError
from flapsim.scenarios.runner import bundled_seed, is_bundled_run

CFG = FakeConfig(seed=2, sleep_s=0.002)
N = 120
CS = 6


@pytest.fixture(scope="module")
def reference(tmp_path_factory):
    """An uninterrupted in-process run: the bytes every other run must reproduce."""
    path = tmp_path_factory.mktemp("ref") / "ref.db"
    summary = train(CFG, path, N, FakeWorker, workers=1, chunk_size=CS, progress=False)
    return path.read_bytes(), summary


def test_reference_run(reference, tmp_path):
    data, s = reference
    path = tmp_path / "ref.db"
    path.write_bytes(data)
    db = load_database(path, require_finalized=True)
    np.testing.assert_array_equal(db.index, expected_samples(CFG, N))
    assert db.n == s["samples"] == N and db.header["samples"] == N
    examined = s["examined"]
    assert examined % CS == 0 and examined - CS <= expected_samples(CFG, N)[-1] < examined
    assert sum(s["rejected"].values()) == s["rejected_total"] == examined - len(
        [i for i in range(examined) if i % 7 and i % 10 != 3])
    assert s["workers"] == 1 and s["backend"] == "local" and s["samples_per_s"] > 0
    assert db.header["model_hash"] == FakeWorker(CFG).header()["model_hash"]
    assert db.header["config"] == CFG.to_dict() and db.header["chunk_size"] == CS
    # rerunning a finished run does nothing; another size is refused
    again = train(CFG, path, N, FakeWorker, chunk_size=CS, progress=False)
    assert again["already_complete"] and path.read_bytes() == data
    with pytest.raises(InputError, match="finished database of 120 samples"):
        train(CFG, path, N + 1, FakeWorker, progress=False)


def test_two_workers_same_bytes(reference, tmp_path):
    train(CFG, tmp_path / "w2.db", N, FakeWorker, workers=2, chunk_size=CS, progress=False)
    assert (tmp_path / "w2.db").read_bytes() == reference[0]


def test_resume_after_torn_tail(reference, tmp_path):
    path = tmp_path / "a.db"
    w = FakeWorker(CFG)
    res = [w.run_chunk(k * CS, (k + 1) * CS) for k in (0, 1, 3, 4)]  # a gap at chunk 2
    header = {**run_header(CFG, FakeWorker), "model_hash": w.header()["model_hash"],
              "provenance": w.header(), "chunk_size": CS, "fields": fields_spec(res[0].arrays)}
    with DatabaseWriter.create(path, header) as dbw:
        for r in res:
            dbw.append(r)
    path.write_bytes(path.read_bytes()[:-3])  # the last chunk torn
    assert load_database(path).chunks == [(r.start, r.stop, len(r.index)) for r in res[:3]]
    s = train(CFG, path, N, FakeWorker, workers=1, progress=False)  # chunk size from the file
    assert s["resumed_samples"] == len(res[0].index) + len(res[1].index)
    assert path.read_bytes() == reference[0]


def test_resume_refuses_another_run(tmp_path):
    path = tmp_path / "a.db"
    with pytest.raises(KeyboardInterrupt):
        train(CFG, path, N, _InterruptAfter(3), chunk_size=CS, progress=False)
    assert not load_database(path).finalized and load_database(path).n > 0
    for kwargs, fragment in [
        ({"config": FakeConfig(seed=2, sigma=2.0)}, "sigma: 1.0 there, 2.0 now"),
        ({"config": FakeConfig(seed=9, sleep_s=0.002)}, "seed"),
        ({"chunk_size": CS + 1}, f"--chunk-size {CS}"),
        ({"worker_cls": _OtherWorker}, "worker"),
    ]:
        args = {"config": CFG, "out": path, "n_samples": N, "worker_cls": FakeWorker,
                "progress": False, **kwargs}
        with pytest.raises(InputError) as e:
            train(**args)
        assert fragment in str(e.value) and "\n" not in str(e.value)
        assert "another --out" in str(e.value)
    with pytest.raises(InputError, match="another model"):  # the same config, a new model
        train(CFG, path, N, _OtherModel, progress=False, kind="flapsim-samples")
    pic = b"\x89PNG\r\n\x1a\n...."
    (tmp_path / "pic.db").write_bytes(pic)
    with pytest.raises(DataFileError) as e:
        train(CFG, tmp_path / "pic.db", N, FakeWorker, progress=False)
    # the message names the file as foreign and says what to do; the file is untouched
    msg = str(e.value)
    assert "not a flapsim database" in msg and "another --out" in msg and "\n" not in msg
    assert (tmp_path / "pic.db").read_bytes() == pic


class _InterruptAfter:
    """A worker class factory whose worker raises KeyboardInterrupt after k chunks."""

    __module__ = FakeWorker.__module__
    __qualname__ = FakeWorker.__qualname__

    def __init__(self, k):
        self.k = k

    def __call__(self, config):
        w = FakeWorker(config)
        run, count = w.run_chunk, [0]

        def run_chunk(start, stop):
            count[0] += 1
            if count[0] > self.k:
                raise KeyboardInterrupt
            return run(start, stop)

        w.run_chunk = run_chunk
        return w


class _OtherWorker(FakeWorker):
    pass


class _OtherModel(FakeWorker):
    __qualname__ = FakeWorker.__qualname__
    __module__ = FakeWorker.__module__

    def header(self):
        return {**super().header(), "model_hash": "0123456789ab"}


_SCRIPT = """
import sys
from flapsim.bird.training.train import train
from flapsim.bird.training.fake_worker import FakeConfig, FakeWorker
train(FakeConfig(seed=2, sleep_s=0.01), sys.argv[1], {n}, FakeWorker, workers=2,
      chunk_size={cs}, progress=False)
"""


def _children(pid):
    out = []
    for d in Path("/proc").iterdir():
        if d.name.isdigit():
            try:
                stat = (d / "stat").read_text()
            except OSError:
                continue
            if int(stat.rsplit(")", 1)[1].split()[1]) == pid:
                out.append(int(d.name))
    return out


def _alive(pid):
    try:
        return Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0] != "Z"
    except OSError:
        return False


KILL_CFG = FakeConfig(seed=2, sleep_s=0.01)


@pytest.fixture(scope="module")
def kill_reference(tmp_path_factory):
    path = tmp_path_factory.mktemp("kill") / "clean.db"
    train(KILL_CFG, path, N, FakeWorker, workers=2, chunk_size=CS, progress=False)
    return path.read_bytes()


@pytest.mark.parametrize("sig", [signal.SIGKILL, signal.SIGTERM], ids=["SIGKILL", "SIGTERM"])
def test_killed_run_resumes_to_the_same_bytes(kill_reference, tmp_path, sig):
    """A run killed at a random moment (kill -9: maybe mid-append) leaves a file that
    loads, no worker process behind, and resumes to the uninterrupted bytes."""
    path = tmp_path / "k.db"
    proc = subprocess.Popen([sys.executable, "-c", _SCRIPT.format(n=N, cs=CS), str(path)],
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    try:
        deadline = time.monotonic() + 60
        while time.monotonic() < deadline and proc.poll() is None:
            if path.exists() and len(load_database(path).chunks) >= 3:
                break
            time.sleep(0.02)
        assert proc.poll() is None, proc.stderr.read().decode()
        workers = _children(proc.pid)
        assert workers, "no worker processes found"
        os.kill(proc.pid, sig)
        proc.wait(30)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    deadline = time.monotonic() + 10
    while time.monotonic() < deadline and any(_alive(p) for p in workers):
        time.sleep(0.1)
    assert not any(_alive(p) for p in workers), "worker processes outlived the killed run"
    part = load_database(path)  # loads, whatever the moment of the kill
    assert not part.finalized and 0 < part.n < N
    s = train(KILL_CFG, path, N, FakeWorker, workers=2, chunk_size=CS, progress=False)
    assert s["resumed_samples"] > 0
    assert path.read_bytes() == kill_reference


@pytest.mark.slow
def test_ray_backend_same_bytes(reference, tmp_path):
    """One Ray test: a private local Ray instance with two actors (about 10 s to start)."""
    pytest.importorskip("ray", reason="Ray is not installed (pip install 'flapsim[cluster]')")
    s = train(CFG, tmp_path / "ray.db", N, FakeWorker, workers=2, backend="ray", chunk_size=CS,
              progress=False)
    assert s["backend"] == "ray" and s["workers"] == 2
    assert (tmp_path / "ray.db").read_bytes() == reference[0]


# ---------------------------------------------------------------- the command


def _cli(capsys, *args):
    try:
        code = main(["train", *args])
    except SystemExit as exc:  # argparse's own errors
        code = exc.code
    err = capsys.readouterr().err.strip()
    return code, err


@pytest.mark.parametrize("args, fragment", [
    (["--samples", "0"], "--samples must be"),
    (["--samples", "abc"], "invalid int value"),
    (["--workers", "0"], "--workers must be"),
    (["--sigma", "0"], "--sigma must be"),
    (["--sigma", "nan"], "--sigma must be"),
    (["--chunk-size", "0"], "--chunk-size must be"),
    (["--address", "1.2.3.4:6379"], "--address is only for --backend ray"),
    (["--backend", "mpi"], "invalid choice"),
    (["--phase", "3"], "invalid choice"),
    (["--phase", "2"], "--phase 2 needs --from"),
    (["--from", "x.db"], "--from is only for --phase 2"),
    (["--out", "{tmp}"], "is a folder"),
    (["--out", "{tmp}/missing/a.db"], "does not exist"),
    (["--json", "{tmp}/missing/a.json"], "does not exist"),
])
def test_cli_bad_arguments(capsys, tmp_path, args, fragment):
    base = {"--samples": "10", "--out": str(tmp_path / "a.db")}
    args = [a.replace("{tmp}", str(tmp_path)) for a in args]
    for k in list(base):
        if k in args:
            del base[k]
    code, err = _cli(capsys, *[x for kv in base.items() for x in kv], *args)
    assert code == 2 and fragment in err and "\n" not in err, err
    assert not (tmp_path / "a.db").exists()


def test_cli_phase2_refuses_a_bad_phase1_file(capsys, tmp_path):
    (tmp_path / "p1.db").write_bytes(b"")
    code, err = _cli(capsys, "--samples", "5", "--phase", "2", "--from", str(tmp_path / "p1.db"),
                     "--out", str(tmp_path / "p2.db"))
    assert code == 2 and "p1.db" in err and "\n" not in err, err
    assert not (tmp_path / "p2.db").exists()
    assert not (tmp_path / "p2.db.discovery.db").exists()


def test_cli_trains_and_writes_json(capsys, tmp_path, monkeypatch, reference):
    import flapsim.cli.commands.train as cmd

    monkeypatch.setattr(cmd, "phase1", lambda args: (FakeConfig(seed=args.seed, sleep_s=0.002),
                                                      FakeWorker))
    out, js = tmp_path / "cli.db", tmp_path / "s.json"
    code = main(["train", "--samples", str(N), "--seed", "2", "--workers", "1", "--chunk-size",
                 str(CS), "--out", str(out), "--json", str(js), "--no-progress"])
    text = capsys.readouterr().out
    assert code == 0, text
    assert f"{N} samples" in text and "samples/s" in text
    s = json.loads(js.read_text())
    assert s["command"] == "train" and s["samples"] == N and s["phase"] == 1
    assert s["rejected"] and s["workers"] == 1 and s["backend"] == "local"
    assert out.read_bytes() != b""
    db = load_database(out, kind="dove-phase1")
    np.testing.assert_array_equal(db.index, expected_samples(CFG, N))


def test_a_run_is_identified_by_its_classes_not_their_modules():
    # a journal written before its worker moved to another module still resumes; another class
    # of the same module does not
    assert same_entry("worker", "flapsim.bird.sampling.SampleWorker",
                      "flapsim.bird.training.sampling.SampleWorker")
    assert not same_entry("worker", "flapsim.bird.training.sampling.SampleWorker",
                          "flapsim.bird.training.sampling.OtherWorker")
    assert not same_entry("seed", 1, 2)


def test_the_bundled_database_is_recognised_as_its_documented_run():
    # the bundled rigid database is `flapsim train --samples 10000 --pre-pitch-deg 10
    # --pre-roll-deg 10 --seed 2 --float32` (its header records it); Table I reuses it
    # instead of training it again only if its header is recognised as that run
    config = SamplingConfig(seed=bundled_seed(), pitch_deg=10.0, roll_deg=10.0, feathers="rigid")
    assert is_bundled_run(config, 10000)
    assert not is_bundled_run(SamplingConfig(seed=bundled_seed() + 1, pitch_deg=10.0,
                                             roll_deg=10.0, feathers="rigid"), 10000)


def test_the_low_acceptance_warning_says_how_many_draws_the_run_needs():
    from flapsim.bird.training.train import LOW_ACCEPTANCE_AFTER, low_acceptance_warning

    # 10 of 2,000 kept is 0.5 %: 10,000 samples need 10,000 / 0.005 = 2,000,000 draws
    msg = low_acceptance_warning(10, 2000, 10000, {"left_range": 1900, "diverged": 90})
    assert "0.5 %" in msg and "2,000,000 draws" in msg and "left_range (1900)" in msg
    assert "\n" not in msg
    assert low_acceptance_warning(100, 2000, 10000) is None  # 5 %: a slow run, not a stuck one
    assert low_acceptance_warning(0, LOW_ACCEPTANCE_AFTER - 1, 10) is None  # too few to judge
    assert "no end in sight" in low_acceptance_warning(0, LOW_ACCEPTANCE_AFTER, 10)


def test_a_run_that_keeps_no_draw_says_so_once_while_it_runs(tmp_path, caplog):
    import logging

    from flapsim.bird.training.train import LOW_ACCEPTANCE_AFTER

    # every index rejected ("every7" with reject_every 1); the run ends by a failure well after
    # the warning is due, or it would draw for ever
    cfg = FakeConfig(reject_every=1, fail_at=LOW_ACCEPTANCE_AFTER + 200)
    with caplog.at_level(logging.WARNING, logger="flapsim.bird.training.train"), \
            pytest.raises(Exception, match="fake failure"):
        train(cfg, tmp_path / "stuck.db", 10, FakeWorker, workers=1, progress=False)
    warned = [r.getMessage() for r in caplog.records if "draws kept so far" in r.getMessage()]
    assert len(warned) == 1 and "every7" in warned[0] and "no end in sight" in warned[0]
