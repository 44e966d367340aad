"""Train a sample database: run a sample worker over sample indices 0, 1, 2, ... in
chunks on a pool (:mod:`flapsim.core.parallel`) and append each finished chunk to the
database journal (:mod:`flapsim.bird.control.database`), until the first ``n_samples``
accepted samples are known; then finalize.

Generic over the worker: ``worker_cls(config)`` with ``run_chunk(start, stop)`` and
``header()``, ``config`` a frozen dataclass with ``seed`` and ``to_dict()`` (see
:mod:`flapsim.bird.training.sampling`).

* Chunk k is ``[k * chunk_size, (k + 1) * chunk_size)``. Chunks are dispatched in index
  order (skipping those the file already holds), as many in flight as keep the pool
  busy, but no more than the acceptance rate so far says are needed.
* The run stops when the gap-free prefix of finished chunks holds ``n_samples``
  accepted samples; the finished database keeps exactly the first ``n_samples``
  accepted samples by index and the rejected counts of the chunks in that prefix.
  Since sample i depends only on (seed, i), the file's bytes depend on the config,
  ``n_samples`` and ``chunk_size`` only: not on workers, backend or interruptions.
* Rerunning the same call after a kill resumes the journal (a torn last chunk is cut
  off and run again). A journal from another config, worker, model or flapsim version
  is refused; so is a finished database of another size.
"""

from __future__ import annotations

import contextlib
import json
import logging
import signal
import threading
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

from tqdm import tqdm

from flapsim import __version__
from flapsim.bird.control.database import (
    DEFAULT_KIND,
    DatabaseWriter,
    FinishedDatabase,
    canonical_json,
    fields_spec,
    finalize_database,
    load_database,
)
from flapsim.core import interrupts
from flapsim.core.errors import DataFileError, InputError
from flapsim.core.parallel import BACKENDS, ChunkExecutor

log = logging.getLogger(__name__)

DEFAULT_CHUNK_SIZE = 16

#: Below this share of draws kept, after :data:`LOW_ACCEPTANCE_AFTER` draws of this run, the run
#: says once how long it is set to take and why: a wingbeat drawn around at a joint range keeps
#: only a few draws in a thousand (one sample a second on two cores, ten thousand in hours).
LOW_ACCEPTANCE = 0.02
LOW_ACCEPTANCE_AFTER = 1000

#: journal header entry: the samples the run that started it asked for (a resume that asks
#: for fewer would drop what the journal holds); not kept in the finished database
ASKED = "samples_asked"

#: header entries a resumed journal must share with the run that resumes it
_SAME_RUN = ("kind", "worker", "config_class", "config", "seed", "flapsim_version")


def _qualname(obj: Any) -> str:
    cls = obj if isinstance(obj, type) else type(obj)
    return f"{cls.__module__}.{cls.__qualname__}"


class _Prefix:
    """Accepted samples in the gap-free run of finished chunks 0, 1, 2, ..."""

    def __init__(self, done: dict[int, tuple[int, int]]) -> None:
        self.done = done
        self.k = 0
        self.sum = 0

    def total(self) -> int:
        while self.k in self.done:
            self.sum += self.done[self.k][0]
            self.k += 1
        return self.sum


def run_header(config: Any, worker_cls: type, kind: str = DEFAULT_KIND) -> dict:
    """The header entries that identify a run (before its worker is built)."""
    return json.loads(canonical_json({
        "kind": kind, "worker": _qualname(worker_cls), "config_class": _qualname(config),
        "config": config.to_dict(), "seed": int(config.seed), "flapsim_version": __version__}))


#: header entries that name a class: a run is identified by the class, not by the module that
#: holds it, so that a journal or database outlives a move of its worker to another module
_CLASS_KEYS = ("worker", "config_class")


def same_entry(key: str, old: Any, new: Any) -> bool:
    """Whether two run headers agree on ``key`` (classes compared by their own name)."""
    if key in _CLASS_KEYS and isinstance(old, str) and isinstance(new, str):
        return old.rpartition(".")[2] == new.rpartition(".")[2]
    return canonical_json(old) == canonical_json(new)


def _check_same_run(old: dict, new: dict, out: Path) -> None:
    for key in _SAME_RUN:
        if not same_entry(key, old.get(key), new.get(key)):
            if key == "config":
                a, b = old.get("config") or {}, new.get("config") or {}
                diff = sorted(k for k in set(a) | set(b) if a.get(k) != b.get(k))
                what = "parameters (" + ", ".join(
                    f"{k}: {a.get(k)!r} there, {b.get(k)!r} now" for k in diff[:3]) + ")"
            else:
                what = f"{key} ({old.get(key)!r} there, {new.get(key)!r} now)"
            raise InputError(f"{out} was started with other {what}; rerun with the same settings "
                             "to resume it, or choose another --out")


@contextlib.contextmanager
def _sigterm_as_interrupt() -> Iterator[None]:
    """SIGTERM raises :class:`~flapsim.core.interrupts.Terminated` (so the pool is stopped and
    the journal closed), as the command line's own handler does: not KeyboardInterrupt,
    which made ``flapsim train`` say "interrupted" and exit 130 where its help says 143."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def handler(signum: int, frame: Any) -> None:
        interrupts.signalled(interrupts.Terminated)

    old = signal.signal(signal.SIGTERM, handler)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, old)


def _validate(n_samples: int, workers: int, backend: str, address: str | None,
              chunk_size: int | None, out: Path) -> None:
    if int(n_samples) != n_samples or n_samples < 1:
        raise InputError(f"the number of samples must be an integer >= 1, got {n_samples}")
    if int(workers) != workers or workers < 1:
        raise InputError(f"workers must be an integer >= 1, got {workers}")
    if backend not in BACKENDS:
        raise InputError(f"backend must be one of {', '.join(BACKENDS)}, got {backend!r}")
    if address is not None and backend != "ray":
        raise InputError("an address is only for --backend ray")
    if chunk_size is not None and (int(chunk_size) != chunk_size or chunk_size < 1):
        raise InputError(f"the chunk size must be an integer >= 1, got {chunk_size}")
    if out.is_dir():
        raise InputError(f"--out {out} is a folder; name the database file to write")
    parent = out.parent if str(out.parent) else Path(".")
    if not parent.is_dir():
        raise InputError(f"cannot write {out}: folder {parent} does not exist (create it first)")


def _summary(db: Any, out: Path, *, wall: float, new: int, before: int, startup: float,
             workers: int, backend: str, address: str | None, already: bool) -> dict:
    h = db.header
    rejected = dict(db.rejected)
    examined = int(h.get("examined", db.n + sum(rejected.values())))
    return {
        "out": str(out), "kind": h.get("kind"), "samples": db.n, "examined": examined,
        "rejected": rejected, "rejected_total": sum(rejected.values()),
        "acceptance": (examined - sum(rejected.values())) / examined if examined else None,
        "chunk_size": h.get("chunk_size"), "model_hash": h.get("model_hash"),
        "seed": h.get("seed"), "resumed_samples": before, "new_samples": new,
        "already_complete": already, "wall_s": wall, "startup_s": startup,
        "samples_per_s": new / wall if wall > 0 and new else 0.0,
        "workers": workers, "backend": backend, "address": address,
    }


def check_out(config: Any, out: str | Path, n_samples: int, worker_cls: type, workers: int = 1,
              backend: str = "local", address: str | None = None, chunk_size: int | None = None,
              kind: str = DEFAULT_KIND) -> tuple[Any, int]:
    """Every check :func:`train` makes of its arguments and of the file at ``out`` before any
    work (a caller with work of its own to do first, like phase 2's discovery, calls it
    first too): ``(the database or journal there or None, the chunk size)``."""
    out = Path(out)
    _validate(n_samples, workers, backend, address, chunk_size, out)
    n_samples = int(n_samples)
    ident = run_header(config, worker_cls, kind)
    existing = None
    if out.exists():
        try:
            existing = load_database(out)
        except DataFileError as exc:
            # a foreign or damaged file is never overwritten: say so, and what to do
            raise DataFileError(f"--out cannot be resumed: {exc}. It is left as it is: choose "
                                "another --out, or delete it to start afresh") from None
        _check_same_run(existing.header, ident, out)
        cs = existing.header.get("chunk_size")
        if existing.finalized:
            if existing.n != n_samples:
                raise InputError(f"{out} is a finished database of {existing.n} samples; rerun with "
                                 f"--samples {existing.n}, or choose another --out for "
                                 f"{n_samples}")
            return existing, int(cs or DEFAULT_CHUNK_SIZE)
        if chunk_size is not None and cs != chunk_size:
            raise InputError(f"{out} was started with --chunk-size {cs}; rerun with --chunk-size "
                             f"{cs} to resume it, or choose another --out")
        chunk_size = int(cs)
    chunk_size = int(chunk_size or DEFAULT_CHUNK_SIZE)
    if existing is not None:
        for start, stop, _ in existing.chunks:
            if start % chunk_size or stop - start != chunk_size:
                raise InputError(f"{out} holds chunk {start}..{stop}, not on the --chunk-size "
                                 f"{chunk_size} grid; choose another --out")
        asked = existing.header.get(ASKED)
        if isinstance(asked, int) and n_samples < asked:
            raise InputError(f"{out} is an unfinished run of --samples {asked} ({existing.n} "
                             f"samples so far): finishing it at {n_samples} would drop the rest; "
                             f"rerun with --samples {asked} (or more), or choose another --out")
    return existing, chunk_size


def train(config: Any, out: str | Path, n_samples: int, worker_cls: type, workers: int = 1,
          backend: str = "local", address: str | None = None, chunk_size: int | None = None,
          progress: bool = True, kind: str = DEFAULT_KIND, float32: bool = False) -> dict:
    """Create or resume the database ``out`` until it holds the first ``n_samples``
    accepted samples of ``worker_cls(config)``, then finalize it. Returns a summary:
    samples, examined, rejected (by reason), wall_s, samples_per_s, workers, backend, ...

    ``chunk_size``: samples per chunk (default: the journal's, else
    :data:`DEFAULT_CHUNK_SIZE`). ``progress``: a tqdm bar on stderr. ``float32``: the
    finished file stores its samples in single precision (half the size).
    """
    t0 = time.perf_counter()
    out = Path(out)
    existing, chunk_size = check_out(config, out, n_samples, worker_cls, workers, backend,
                                     address, chunk_size, kind)
    n_samples = int(n_samples)
    ident = run_header(config, worker_cls, kind)
    if existing is not None and existing.finalized:
        return _summary(existing, out, wall=time.perf_counter() - t0, new=0,
                        before=existing.n, startup=0.0, workers=workers, backend=backend,
                        address=address, already=True)
    done: dict[int, tuple[int, int]] = {}  # chunk number -> (accepted, examined)
    if existing is not None:
        for start, stop, acc in existing.chunks:
            done[start // chunk_size] = (acc, stop - start)

    prefix = _Prefix(done)
    before = min(prefix.total(), n_samples)
    startup = 0.0
    if before < n_samples:
        try:
            startup, db = _run(config, out, n_samples, worker_cls, workers, backend, address,
                               chunk_size, progress, ident, existing, done, prefix, float32)
        except FinishedDatabase:
            # another run of this journal finished it while this one started its pool
            fin = load_database(out)
            if fin.n != n_samples:
                raise InputError(f"{out} was finished meanwhile with {fin.n} samples; rerun with "
                                 f"--samples {fin.n}, or choose another --out") from None
            return _summary(fin, out, wall=time.perf_counter() - t0, new=0, before=before,
                            startup=0.0, workers=workers, backend=backend, address=address,
                            already=True)
    else:
        db = finalize_database(out, n_samples, float32=float32)
    summary = _summary(db, out, wall=time.perf_counter() - t0, new=max(0, db.n - before),
                       before=before, startup=startup, workers=workers, backend=backend,
                       address=address, already=False)
    log.info("trained %s: %d samples in %.1f s", out, db.n, summary["wall_s"])
    return summary


def _check_journal(old: dict, header: dict, out: Path) -> None:
    """Refuse to resume a journal of another run (identity, provenance, chunk size)."""
    _check_same_run(old, header, out)
    if canonical_json(old.get("provenance")) != canonical_json(header["provenance"]):
        what = (f"model {old.get('model_hash')}, now {header.get('model_hash')}"
                if old.get("model_hash") != header.get("model_hash")
                else "provenance (reference data)")
        raise InputError(f"{out} was started with another {what}; choose another --out")
    if old.get("chunk_size") != header["chunk_size"]:
        raise InputError(f"{out} was started with --chunk-size {old.get('chunk_size')}; rerun "
                         f"with --chunk-size {old.get('chunk_size')} to resume it, or choose "
                         "another --out")


def low_acceptance_warning(accepted: int, examined: int, n_samples: int,
                           reasons: dict[str, int] | None = None) -> str | None:
    """The one-line warning for a run that keeps under :data:`LOW_ACCEPTANCE` of its draws
    (after at least :data:`LOW_ACCEPTANCE_AFTER`), or None: how many draws ``n_samples``
    then need and the likely fix."""
    if examined < LOW_ACCEPTANCE_AFTER or accepted >= LOW_ACCEPTANCE * examined:
        return None
    share = accepted / examined
    need = f"about {n_samples / share:,.0f} draws" if accepted else "no end in sight"
    why = ""
    if reasons:
        top = max(reasons, key=reasons.get)
        why = f", most rejected as {top} ({reasons[top]})"
    return (f"only {accepted} of {examined} draws kept so far ({100 * share:.1f} %{why}): "
            f"{n_samples} samples need {need}; where the wingbeats drawn leave the joint ranges, "
            "draw around a wingbeat further inside them (--centre-wingbeat, --tail-bias-deg, "
            "--twist-bias-deg) or with a smaller --sigma")


def _run(config: Any, out: Path, n_samples: int, worker_cls: type, workers: int, backend: str,
         address: str | None, chunk_size: int, progress: bool, ident: dict, existing: Any,
         done: dict[int, tuple[int, int]], prefix: _Prefix, float32: bool) -> tuple[float, Any]:
    """Run the pool until the prefix holds ``n_samples``; finalize under the journal's lock.

    What the file holds is read again once its lock is taken (:meth:`DatabaseWriter.resume`):
    another run of the same journal may have added chunks since ``done`` was read (while this
    one started its pool), and they are neither run nor written again."""

    writer: DatabaseWriter | None = None
    buffered: list[Any] = []
    in_flight: set[int] = set()
    next_k = 0
    with contextlib.ExitStack() as stack:
        stack.enter_context(_sigterm_as_interrupt())
        t0 = time.perf_counter()
        ex = stack.enter_context(ChunkExecutor(worker_cls, config, workers, backend, address))
        prov = ex.header()
        startup = time.perf_counter() - t0  # start the pool and build one worker
        header = {**ident, "model_hash": prov.get("model_hash"), "provenance": prov,
                  "chunk_size": chunk_size, ASKED: n_samples}
        accepted = examined = 0

        def attach(new: bool, fields: list | None = None) -> DatabaseWriter:
            """Take the journal's lock (creating the file, or resuming it, also when another
            run created it meanwhile) and learn every chunk it holds."""
            nonlocal accepted, examined
            w = None
            if new:
                try:
                    w = DatabaseWriter.create(out, {**header, "fields": fields})
                except InputError:
                    if not out.exists():
                        raise
            if w is None:
                w, db = DatabaseWriter.resume(out)
            stack.callback(w.close)
            _check_journal(w.header, header, out)
            for start, stop in sorted(w.chunks):
                if start % chunk_size or stop - start != chunk_size:
                    raise InputError(f"{out} holds chunk {start}..{stop}, not on the --chunk-size "
                                     f"{chunk_size} grid; choose another --out")
            if not new or w.chunks:
                db = load_database(out) if new else db
                for start, _, acc in db.chunks:
                    done[start // chunk_size] = (acc, chunk_size)
            accepted = sum(a for a, _ in done.values())
            examined = sum(e for _, e in done.values())
            return w

        if existing is not None:
            writer = attach(False)
        accepted = sum(a for a, _ in done.values())
        examined = sum(e for _, e in done.values())
        bar = stack.enter_context(tqdm(total=n_samples, initial=min(prefix.total(), n_samples),
                                       unit="sample", desc=f"training {out.name}",
                                       disable=not progress, smoothing=0.1))
        shown = bar.n
        # judged on this run's draws only: a resumed run's earlier ones are not re-drawn
        run_accepted, run_examined, reasons, warned = 0, 0, {}, False
        while True:
            if prefix.total() >= n_samples:
                break
            # keep the pool busy, but do not queue more than the acceptance rate needs
            rate = accepted / examined if examined else 1.0
            while ex.pending < ex.capacity and (
                    ex.pending == 0
                    or accepted + len(in_flight) * chunk_size * max(rate, 1e-3) < n_samples):
                while next_k in done or next_k in in_flight:
                    next_k += 1
                ex.submit(next_k * chunk_size, (next_k + 1) * chunk_size)
                in_flight.add(next_k)
            res = ex.next_result()
            k = int(res.start) // chunk_size
            if int(res.start) != k * chunk_size or int(res.stop) != (k + 1) * chunk_size \
                    or k not in in_flight:
                raise RuntimeError(f"worker returned chunk {res.start}..{res.stop}, not one "
                                   "that was asked for")
            in_flight.discard(k)
            if writer is None:
                if not res.arrays:  # no samples and no field shapes: wait for one that has
                    buffered.append(res)
                    done[k] = (0, chunk_size)
                    examined += chunk_size
                    continue
                writer = attach(True, fields_spec(res.arrays))
                for b in buffered:
                    writer.append(b)
                buffered.clear()
            if not writer.append(res):  # another run of this journal wrote it meanwhile
                continue
            m = int(len(res.index))
            done[k] = (m, chunk_size)
            accepted += m
            examined += chunk_size
            run_accepted += m
            run_examined += chunk_size
            for why, n in (res.rejected or {}).items():
                reasons[why] = reasons.get(why, 0) + int(n)
            if not warned:
                message = low_acceptance_warning(run_accepted, run_examined, n_samples, reasons)
                if message is not None:
                    warned = True
                    bar.clear()  # the warning on a line of its own, the bar redrawn below it
                    log.warning("%s", message)
                    bar.refresh()
            total = min(prefix.total(), n_samples)
            if total > shown:
                bar.update(total - shown)
                shown = total
            bar.set_postfix(rejected=examined - accepted, refresh=False)
        db = finalize_database(out, n_samples, float32=float32, writer=writer)
        return startup, db
