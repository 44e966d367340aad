"""The chunk executor: same results in process and in spawned processes, one worker
object per process, early stop and errors leave no process behind."""

import multiprocessing as mp
import sys

import numpy as np
import pytest

from flapsim.bird.training.fake_worker import FakeConfig, FakeWorker
from flapsim.core.errors import InputError
from flapsim.core.parallel import ChunkExecutor

CHUNKS = [(k * 5, (k + 1) * 5) for k in range(12)]


def _by_start(results):
    return {r.start: r for r in results}


def test_processes_match_in_process_and_build_the_worker_once():
    cfg = FakeConfig(seed=5, sleep_s=0.002)
    with ChunkExecutor(FakeWorker, cfg, workers=1) as ex:
        ref = _by_start(ex.map_unordered(CHUNKS))
        head = ex.header()
    with ChunkExecutor(FakeWorker, cfg, workers=2) as ex:
        assert ex.capacity == 4
        got = _by_start(ex.map_unordered(iter(CHUNKS)))
        assert ex.header() == head
    assert sorted(got) == sorted(ref) == [s for s, _ in CHUNKS]
    for s, r in ref.items():
        np.testing.assert_array_equal(got[s].index, r.index)
        for k in r.arrays:
            np.testing.assert_array_equal(got[s].arrays[k], r.arrays[k])
        assert got[s].rejected == r.rejected
    # one worker object per process, reused for every chunk it ran
    pids = {r.worker[0] for r in got.values()}
    assert all(r.worker[1] == 1 for r in got.values())
    assert sum(max(r.worker[2] for r in got.values() if r.worker[0] == p) for p in pids) >= 12
    assert not mp.active_children()


def test_early_stop_and_worker_errors_stop_every_process():
    with ChunkExecutor(FakeWorker, FakeConfig(sleep_s=0.01), workers=2) as ex:
        for _ in ex.map_unordered(CHUNKS):
            break
    assert not mp.active_children()
    with pytest.raises(ValueError, match="fake failure at sample 23"):
        with ChunkExecutor(FakeWorker, FakeConfig(fail_at=23), workers=2) as ex:
            list(ex.map_unordered(CHUNKS))
    assert not mp.active_children()
    with pytest.raises(ValueError, match="fake failure"):  # the same in process
        with ChunkExecutor(FakeWorker, FakeConfig(fail_at=23), workers=1) as ex:
            list(ex.map_unordered(CHUNKS))


def test_chunks_that_finish_together_are_all_returned():
    # two chunks finished before the first result is asked for: one wait sees both. The
    # first is returned and the second must still count as pending, or map_unordered stops
    # with it unreturned (14 of 40 suites of 12 quick chunks lost or leaked results so)
    import time

    with ChunkExecutor(FakeWorker, FakeConfig(), workers=2) as ex:
        ex.submit(0, 5)
        ex.submit(5, 10)
        deadline = time.monotonic() + 60.0
        while not all(f.done() for f in ex._impl.futures) and time.monotonic() < deadline:
            time.sleep(0.01)
        got = sorted(r.start for r in ex.map_unordered([]))
        assert got == [0, 5]
        # and nothing is left over for the next map
        assert sorted(r.start for r in ex.map_unordered(CHUNKS)) == [s for s, _ in CHUNKS]
    assert not mp.active_children()


def test_bad_arguments_and_missing_ray(monkeypatch):
    with pytest.raises(InputError, match="workers"):
        ChunkExecutor(FakeWorker, FakeConfig(), workers=0)
    with pytest.raises(InputError, match="backend"):
        ChunkExecutor(FakeWorker, FakeConfig(), backend="mpi")
    with pytest.raises(InputError, match="only for the ray backend"):
        ChunkExecutor(FakeWorker, FakeConfig(), address="10.0.0.1:6379")
    monkeypatch.setitem(sys.modules, "ray", None)  # import ray -> ImportError
    with pytest.raises(InputError) as e:
        ChunkExecutor(FakeWorker, FakeConfig(), workers=2, backend="ray")
    assert "pip install 'flapsim[cluster]'" in str(e.value) and "\n" not in str(e.value)


def test_a_signal_python_dropped_is_raised_while_a_chunk_runs():
    # a KeyboardInterrupt Python printed and dropped (flapsim.core.interrupts) is raised while the
    # pool waits, not when the running chunk (20 s here, minutes for a suite's flight) ends
    import threading
    import time

    from flapsim.core import interrupts
    timer = threading.Timer(0.5, interrupts.record, (KeyboardInterrupt,))
    t0 = time.monotonic()
    with pytest.raises(KeyboardInterrupt):
        with ChunkExecutor(FakeWorker, FakeConfig(sleep_s=4.0), workers=2) as ex:
            timer.start()
            list(ex.map_unordered([(0, 5)]))
    # the chunk's 20 s not waited for: 10 s leaves room for the spawned worker's start-up
    assert time.monotonic() - t0 < 10.0
    assert not mp.active_children()
    interrupts.clear()
