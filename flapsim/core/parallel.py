"""Run chunks of independent samples on a pool of workers: local processes, or Ray.

A *sample worker* class is built once per worker (``worker_cls(config)``: it compiles
its model once) and then runs many chunks (``worker.run_chunk(start, stop)``); its
``header()`` is the run's provenance. Results come back as they complete::
    with ChunkExecutor(SampleWorker, config, workers=4) as ex:
        for result in ex.map_unordered([(0, 32), (32, 64), ...]):
            ...

or, to decide what to run next from what came back, :meth:`ChunkExecutor.submit` /
:meth:`ChunkExecutor.next_result` with :attr:`ChunkExecutor.capacity` in flight.

Backends:

* ``local``, ``workers == 1``: in this process (same results, no start-up cost).
* ``local``: ``workers`` processes started with ``spawn``. Not ``fork``: the parent may
  hold threads (tqdm's monitor, MuJoCo's rollout pool, Ray's), an EGL context or
  numba's threading layer, none of which survives a fork safely; spawn costs one
  import of the worker module per process, once. Workers ignore SIGINT (the parent
  stops them) and exit by themselves when the parent dies, even by SIGKILL.
* ``ray``: one actor per worker holding the worker object. ``address=None`` starts a
  private local Ray instance with ``workers`` CPUs (``address="local"``: never joins a
  cluster someone else started on this machine), else connects to ``address`` (every
  node needs flapsim installed). Ray is optional: ``pip install 'flapsim[cluster]'``.

On any exit from the ``with`` block other than a normal one (an error, Ctrl-C, SIGTERM
turned into KeyboardInterrupt by the caller) work in flight is dropped and every
worker process is stopped.
"""

from __future__ import annotations

import logging
import multiprocessing as mp
import os
import signal
import threading
import time
from collections import deque
from collections.abc import Iterable, Iterator
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from concurrent.futures.process import BrokenProcessPool
from typing import Any

from flapsim.core import interrupts
from flapsim.core.errors import FlapsimError, InputError

log = logging.getLogger(__name__)

BACKENDS = ("local", "ray")


class WorkerError(FlapsimError):
    """A worker process died or could not be reached."""


def usable_cores() -> int:
    """CPU cores this process may run on (its affinity mask where the system has one)."""
    try:
        return len(os.sched_getaffinity(0))
    except (AttributeError, OSError):  # not on Linux
        return os.cpu_count() or 1


# ------------------------------------------------------------------ in the worker process

_WORKER: Any = None


def _watch_parent(parent: int) -> None:
    while True:
        time.sleep(0.5)
        if os.getppid() != parent:
            os._exit(1)


def _init_process(worker_cls: type, config: Any, parent: int) -> None:
    global _WORKER
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    threading.Thread(target=_watch_parent, args=(parent,), daemon=True).start()
    _WORKER = worker_cls(config)


def _run_chunk(start: int, stop: int) -> Any:
    return _WORKER.run_chunk(start, stop)


def _header() -> dict:
    return _WORKER.header()


class _RayActor:
    """A Ray actor holding one sample worker."""

    def __init__(self, worker_cls: type, config: Any) -> None:
        self.worker = worker_cls(config)

    def run_chunk(self, start: int, stop: int) -> Any:
        return self.worker.run_chunk(start, stop)

    def header(self) -> dict:
        return self.worker.header()


# ------------------------------------------------------------------ backends

class _InProcess:
    capacity_per_worker = 1

    def __init__(self, worker_cls: type, config: Any, workers: int, address: str | None) -> None:
        self.worker = worker_cls(config)
        self.queue: deque[tuple[int, int]] = deque()

    def header(self) -> dict:
        return self.worker.header()

    def submit(self, start: int, stop: int) -> None:
        self.queue.append((start, stop))

    @property
    def pending(self) -> int:
        return len(self.queue)

    def next_result(self) -> Any:
        return self.worker.run_chunk(*self.queue.popleft())

    def close(self, abort: bool) -> None:
        self.queue.clear()
        if callable(getattr(self.worker, "close", None)):
            self.worker.close()


#: Seconds a pool waits for a chunk before it looks for a signal Python dropped
#: (:mod:`flapsim.core.interrupts`).
POLL_S = 0.25


class _LocalPool:
    capacity_per_worker = 2

    def __init__(self, worker_cls: type, config: Any, workers: int, address: str | None) -> None:
        self._before = set(mp.active_children())
        self.pool = ProcessPoolExecutor(workers, mp_context=mp.get_context("spawn"),
                                        initializer=_init_process,
                                        initargs=(worker_cls, config, os.getpid()))
        self.futures: set[Future] = set()
        self.done: deque[Future] = deque()
        # every process the pool ever started (it starts them lazily, and replaces broken
        # ones): close() must stop all of them, not only those alive at that moment
        self.procs: dict[int, Any] = {}

    def _track(self) -> None:
        self.procs.update(getattr(self.pool, "_processes", None) or {})

    def header(self) -> dict:
        return self._result(self.pool.submit(_header))

    @staticmethod
    def _result(fut: Future) -> Any:
        try:
            return fut.result()
        except BrokenProcessPool:
            raise WorkerError("a worker process died (killed, out of memory or crashed); run the "
                              "same command again to resume") from None

    def submit(self, start: int, stop: int) -> None:
        try:
            self.futures.add(self.pool.submit(_run_chunk, start, stop))
            self._track()
        except BrokenProcessPool:
            raise WorkerError("a worker process died (killed, out of memory or crashed); run the "
                              "same command again to resume") from None

    @property
    def pending(self) -> int:
        # finished but not yet returned counts: one wait can finish several chunks, and a
        # caller that stops at zero pending would drop them (14 of 40 quick maps lost or
        # leaked a result before this)
        return len(self.futures) + len(self.done)

    def next_result(self) -> Any:
        while not self.done:
            # in short waits, so that a signal Python dropped is raised within one (a flight
            # of the evaluation suite runs for minutes in its worker)
            finished, _ = wait(self.futures, timeout=POLL_S, return_when=FIRST_COMPLETED)
            self.futures -= finished
            self.done.extend(finished)
            interrupts.check()
        return self._result(self.done.popleft())

    def close(self, abort: bool) -> None:
        self._track()
        procs = list(self.procs.values())
        busy = any(not f.done() for f in self.futures)
        if abort or busy:
            for f in self.futures:
                f.cancel()
            self.pool.shutdown(wait=False, cancel_futures=True)
            for p in procs:
                if p.is_alive():
                    p.terminate()
            for p in procs:
                p.join(10)
                if p.is_alive():
                    p.kill()
                    p.join(5)
        self.pool.shutdown(wait=True, cancel_futures=True)
        # a process the pool was starting while it shut down is in neither list yet: every
        # child this process gained since the pool was made is the pool's
        procs += [p for p in mp.active_children() if p not in self._before and p not in procs]
        for p in procs:
            if p.is_alive() and (abort or busy):
                p.terminate()
            p.join(10)
            if p.is_alive():
                p.kill()
                p.join(5)
        # the pool's own manager thread may reap a process concurrently (os.waitpid in two
        # threads): our join then returns before the exit status is stored; wait for it
        deadline = time.monotonic() + 10.0
        while any(p.exitcode is None for p in procs) and time.monotonic() < deadline:
            time.sleep(0.01)
        self.futures.clear()
        self.done.clear()


class _RayPool:
    capacity_per_worker = 2

    def __init__(self, worker_cls: type, config: Any, workers: int, address: str | None) -> None:
        try:
            import ray
        except ImportError:
            raise InputError("--backend ray needs Ray: pip install 'flapsim[cluster]'") from None
        self.ray = ray
        self.owns = False
        if not ray.is_initialized():
            kwargs = dict(include_dashboard=False, logging_level=logging.WARNING,
                          configure_logging=True)
            try:
                if address is None:
                    ray.init(address="local", num_cpus=workers, **kwargs)
                else:
                    ray.init(address=address, **kwargs)
            except (ConnectionError, ValueError, RuntimeError) as exc:
                msg = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
                raise WorkerError(f"cannot start/connect to Ray at {address or 'a local instance'}: "
                                  f"{msg}") from None
            self.owns = True
        actor = ray.remote(num_cpus=1, max_restarts=0)(_RayActor)
        self.actors = [actor.remote(worker_cls, config) for _ in range(workers)]
        self.load = [0] * workers
        self.refs: dict[Any, int] = {}  # object ref -> actor number

    def _get(self, ref: Any) -> Any:
        ray = self.ray
        try:
            return ray.get(ref)
        except ray.exceptions.RayTaskError as exc:
            cause = getattr(exc, "cause", None)
            if isinstance(cause, BaseException):
                raise cause from None
            raise
        except ray.exceptions.RayActorError as exc:
            raise WorkerError(f"a Ray worker died ({type(exc).__name__}); run the same command "
                              "again to resume") from None

    def header(self) -> dict:
        return self._get(self.actors[0].header.remote())

    def submit(self, start: int, stop: int) -> None:
        k = min(range(len(self.actors)), key=self.load.__getitem__)
        self.refs[self.actors[k].run_chunk.remote(start, stop)] = k
        self.load[k] += 1

    @property
    def pending(self) -> int:
        return len(self.refs)

    def next_result(self) -> Any:
        ready: list = []
        while not ready:  # in short waits, as _LocalPool's
            ready, _ = self.ray.wait(list(self.refs), num_returns=1, timeout=POLL_S)
            interrupts.check()
        k = self.refs.pop(ready[0])
        self.load[k] -= 1
        return self._get(ready[0])

    def close(self, abort: bool) -> None:
        ray = self.ray
        for ref in self.refs:
            try:
                ray.cancel(ref, force=False)
            except Exception:  # noqa: BLE001 - best effort while shutting down
                pass
        self.refs.clear()
        for a in self.actors:
            try:
                ray.kill(a)
            except Exception:  # noqa: BLE001
                pass
        if self.owns:
            ray.shutdown()


# ------------------------------------------------------------------ the executor

class ChunkExecutor:
    """Runs ``worker_cls(config).run_chunk(start, stop)`` for many chunks on a pool
    (see the module docstring). Use as a context manager."""

    def __init__(self, worker_cls: type, config: Any, workers: int = 1, backend: str = "local",
                 address: str | None = None, in_process: bool | None = None) -> None:
        if backend not in BACKENDS:
            raise InputError(f"backend must be one of {', '.join(BACKENDS)}, got {backend!r}")
        if int(workers) != workers or workers < 1:
            raise InputError(f"workers must be an integer >= 1, got {workers}")
        if address is not None and backend != "ray":
            raise InputError("an address is only for the ray backend (--backend ray)")
        self.workers = int(workers)
        self.backend = backend
        self.address = address
        if in_process is None:
            in_process = backend == "local" and workers == 1
        kind = _InProcess if in_process else _LocalPool if backend == "local" else _RayPool
        t0 = time.perf_counter()
        self._impl = kind(worker_cls, config, self.workers, address)
        self.startup_s = time.perf_counter() - t0
        self.capacity = self.workers * kind.capacity_per_worker
        self._closed = False

    def header(self) -> dict:
        """The worker's provenance (from one worker; all are built alike)."""
        return self._impl.header()

    def submit(self, start: int, stop: int) -> None:
        """Queue the chunk ``[start, stop)``."""
        self._impl.submit(int(start), int(stop))

    @property
    def pending(self) -> int:
        """Chunks submitted whose result has not been returned yet."""
        return self._impl.pending

    def next_result(self) -> Any:
        """Wait for any submitted chunk and return its result (a worker's exception is
        raised here)."""
        if not self.pending:
            raise RuntimeError("next_result() with nothing submitted")
        return self._impl.next_result()

    def map_unordered(self, chunks: Iterable[tuple[int, int]]) -> Iterator[Any]:
        """Run every chunk, keeping :attr:`capacity` in flight (``chunks`` is consumed
        lazily); yield results as they complete."""
        it = iter(chunks)
        exhausted = False
        while True:
            while not exhausted and self.pending < self.capacity:
                nxt = next(it, None)
                if nxt is None:
                    exhausted = True
                else:
                    self.submit(*nxt)
            if not self.pending:
                return
            interrupts.check()  # a signal Python dropped (the pools also check while waiting)
            yield self.next_result()

    def close(self, abort: bool = False) -> None:
        """Stop the workers (``abort``: drop work in flight at once)."""
        if not self._closed:
            self._closed = True
            self._impl.close(abort)

    def __enter__(self) -> ChunkExecutor:
        return self

    def __exit__(self, exc_type: type | None, *exc: object) -> None:
        self.close(abort=exc_type is not None)
