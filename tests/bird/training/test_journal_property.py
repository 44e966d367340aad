"""A property of the training journal: whatever the interleaving of two runs of one command
(the second started while the first is starting its pool or running), their interruptions
(Ctrl-C after any chunk) and torn writes (a kill mid-append), no sample a run accepted into
the journal is ever lost, and the finished database is the bytes of one uninterrupted run."""

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from flapsim.bird.control.database import _encode_record, load_database, read_header
from flapsim.bird.training.fake_worker import FakeConfig, FakeWorker, expected_samples
from flapsim.bird.training.train import train
from flapsim.core.errors import InputError

CFG = FakeConfig(seed=7)
N = 40
CS = 4


class _Run:
    """One run of the command, as a worker class factory named like FakeWorker: ``stop``
    chunks, then Ctrl-C (None: to the end); ``during_start``/``during_run``: another run of
    the same command while this one starts its pool / after its first chunk."""

    __module__ = FakeWorker.__module__
    __qualname__ = FakeWorker.__qualname__

    def __init__(self, stop, during_start=None, during_run=None):
        self.stop, self.during_start, self.during_run = stop, during_start, during_run
        self.ran = 0

    def __call__(self, config):
        if self.during_start is not None:
            hook, self.during_start = self.during_start, None
            hook()
        w = FakeWorker(config)
        run = w.run_chunk

        def run_chunk(start, stop):
            if self.stop is not None and self.ran >= self.stop:
                raise KeyboardInterrupt
            self.ran += 1
            if self.during_run is not None and self.ran == 2:
                hook, self.during_run = self.during_run, None
                hook()
            return run(start, stop)

        w.run_chunk = run_chunk
        return w


@pytest.fixture(scope="module")
def reference(tmp_path_factory):
    path = tmp_path_factory.mktemp("ref") / "ref.db"
    train(CFG, path, N, FakeWorker, chunk_size=CS, progress=False)
    return path.read_bytes()


def _accepted(path):
    """Every (chunk start, sample index) the journal (or finished file) holds."""
    if not path.exists():
        return set()
    db = load_database(path)
    if db.finalized:
        return {("final", int(i)) for i in db.index}
    return {(int(s), int(i)) for s, e, _ in db.chunks for i in db.index if s <= i < e}


LAST = int(expected_samples(CFG, N)[-1])


def _sample_set(path):
    """The accepted sample indices the run of N keeps, whether journal or finished."""
    return {i for _, i in _accepted(path) if i <= LAST}


step = st.tuples(
    st.one_of(st.none(), st.integers(0, 6)),           # Ctrl-C after this many chunks
    st.sampled_from(["alone", "during_start", "during_run"]),
    st.one_of(st.none(), st.integers(0, 6)),           # the other run's Ctrl-C
    st.booleans(),                                      # a torn write left after the step
)


@settings(max_examples=30, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(steps=st.lists(step, min_size=1, max_size=4))
def test_two_runs_and_interrupts_never_lose_a_sample(reference, tmp_path_factory, steps):
    out = tmp_path_factory.mktemp("j") / "A.db"
    held: set[int] = set()
    for stop, how, other_stop, torn in steps:
        other_refused = []

        def other(other_stop=other_stop, refused=other_refused):
            try:
                train(CFG, out, N, _Run(other_stop), chunk_size=CS, progress=False)
            except KeyboardInterrupt:
                pass
            except InputError as exc:  # the first run holds the lock: a second writer waits
                assert "being written by another" in str(exc)
                refused.append(exc)

        run = _Run(stop, during_start=other if how == "during_start" else None,
                   during_run=other if how == "during_run" else None)
        try:
            train(CFG, out, N, run, chunk_size=CS, progress=False)
        except KeyboardInterrupt:
            pass
        if how == "during_run" and run.ran >= 2:
            assert other_refused  # never two writers at once
        now = _sample_set(out)
        assert held <= now, f"lost samples {sorted(held - now)}"
        held = now
        if torn and out.exists() and not read_header(out)["finalized"]:
            # a kill in the middle of an append: half a record at the end
            header = read_header(out)
            res = FakeWorker(CFG).run_chunk(400, 400 + CS)
            blob = _encode_record(header, res.start, res.stop, res.index, res.arrays, res.rejected)
            with open(out, "ab") as fh:
                fh.write(blob[: len(blob) // 2])
            assert _sample_set(out) == held
    train(CFG, out, N, FakeWorker, chunk_size=CS, progress=False)
    assert out.read_bytes() == reference
