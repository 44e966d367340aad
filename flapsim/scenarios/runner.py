"""Running scenarios in parallel: the runs of one evaluation, their resume journal, the
verdict spread over starts, and the paper's Table I (its databases trained first).

A *run* is a ``(scenario name, options)`` pair. :func:`execute` flies a list of them on
:class:`~flapsim.core.parallel.ChunkExecutor` (local processes or Ray, the training's
executor; chunk i = run i), dearest first, and keeps each finished run in a
:class:`~flapsim.scenarios.journal.RunJournal` when given one, so that an interrupted
evaluation resumes where it stopped. ``flapsim eval`` parses its options into runs, calls
these, and prints the tables.
"""

from __future__ import annotations

import dataclasses
import logging
import math
import shutil
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from tqdm import tqdm

from flapsim import __version__
from flapsim.bird.body.model import Dove
from flapsim.bird.control.config import ControllerConfig
from flapsim.bird.control.controller import bundled_database_path, database_dove
from flapsim.bird.control.database import load_database
from flapsim.bird.tasks.config import PathControlConfig
from flapsim.bird.training.sampling import SampleWorker, SamplingConfig
from flapsim.bird.training.train import run_header, same_entry, train
from flapsim.core import environment
from flapsim.core.errors import InputError
from flapsim.core.parallel import ChunkExecutor, WorkerError, usable_cores
from flapsim.scenarios.journal import RunJournal, fingerprint, journal_path, run_keys
from flapsim.scenarios.registry import (
    EvalOptions,
    completion_interval,
    get,
    run_scenario,
    start_speed_changes,
)

log = logging.getLogger(__name__)

Run = tuple[str, EvalOptions]
"""A scenario's name and the options it is flown with."""


@dataclass
class RunsConfig:
    """What :class:`EvalWorker` runs: ``runs[i] = (scenario name, options)`` for chunk
    ``[i, i + 1)``."""

    runs: list[Run]


class EvalWorker:
    """A :class:`~flapsim.core.parallel.ChunkExecutor` worker running scenarios by index."""

    def __init__(self, config: RunsConfig) -> None:
        self.config = config

    def header(self) -> dict:
        return {"flapsim_version": __version__, "runs": len(self.config.runs)}

    def run_chunk(self, start: int, stop: int) -> list[tuple[int, dict[str, Any]]]:
        return [(i, run_scenario(*self.config.runs[i])) for i in range(start, stop)]


def start_runs(names: list[str], opts: EvalOptions, starts: int = 1, jitter: float = 0.001,
               seed: int = 0) -> list[Run]:
    """A run for each scenario and start: the start as it is, then ``starts - 1`` with its
    forward speed changed by at most ``jitter`` m/s (:func:`~flapsim.scenarios.registry.
    start_speed_changes`); only the first start writes plots and videos (they would
    overwrite each other)."""
    if not 1 <= starts <= 1000:
        raise InputError(f"--starts must be 1..1000, got {starts}")
    if not (math.isfinite(jitter) and 0.0 < jitter <= 0.1):
        raise InputError(f"--start-jitter must be above 0 and at most 0.1 m/s (a perturbation far "
                         f"below the flight's speed), got {jitter}")
    if starts == 1:
        return [(name, opts) for name in names]
    other = [name for name in names if get(name).family != "flight"]
    if other:
        raise InputError(f"--starts perturbs the dove's start: flight scenarios only, not "
                         f"{', '.join(other)} (--scenario flight: the flight part of 'all')")
    runs = []
    for name in names:
        for i, dv in enumerate(start_speed_changes(starts, jitter, seed)):
            o = dataclasses.replace(opts, start_speed_change=dv)
            if i:
                o = dataclasses.replace(o, plots_dir=None, video_dir=None)
            runs.append((name, o))
    return runs


def lookahead_runs(runs: list[Run], workers: int | None, backend: str = "local") -> list[Run]:
    """Each run's controller look-ahead: ``auto`` stays ``auto`` only where the local runs
    leave this machine a second core per worker (one scenario on two cores, say), else it
    becomes ``off``: the suite's runs already fill the cores, and a third thread would slow
    them. ``on`` and ``off`` stand."""
    n = workers or max(1, min(len(runs), usable_cores()))
    n = min(n, len(runs)) if runs else 1
    # "on" would be an error where a run cannot look ahead (no corrections, say): auto is quiet
    spare = backend == "local" and usable_cores() >= 2 * n
    out = []
    for name, o in runs:
        if o.controller is not None and o.controller.lookahead == "auto" and not spare:
            o = dataclasses.replace(o, controller=dataclasses.replace(o.controller, lookahead="off"))
        out.append((name, o))
    return out


def check_database(db: str, feathers: str) -> None:
    """A damaged database (the whole file is read: every chunk's CRC), an unfinished one, or
    one of another dove is a one-line error before any worker starts (each run would fail
    alike)."""
    have = load_database(db, require_finalized=True).header.get("model_hash")
    want = database_dove(db, feathers).hash()
    if have != want:
        other = "modal" if feathers == "rigid" else "rigid"
        hint = (f"fly it with --feathers {other}" if have == Dove.load(feathers=other).hash()
                else f"train one for this dove: flapsim train --feathers {feathers} --out NEW.db")
        raise InputError(f"{db} was built for model {have}, not the {feathers}-feather dove "
                         f"({want}): {hint}")


def open_journal(json_path: str | None, runs: list[Run]) -> RunJournal | None:
    """The journal of the finished runs of an evaluation whose results go to ``json_path``
    (:mod:`flapsim.scenarios.journal`), or None without a file (None, or ``-``: stdout)."""
    if not json_path or json_path == "-":
        return None
    # the packages too: the same runs flown with another numpy may end otherwise (environment)
    tag = environment.tag()
    return RunJournal(journal_path(json_path), run_keys(runs, tag), legacy=fingerprint(runs, tag))


def execute(runs: list[Run], workers: int | None, backend: str = "local",
            address: str | None = None, journal: RunJournal | None = None,
            say: Callable[[str], None] = log.info) -> list[dict]:
    """Run ``(scenario name, options)`` pairs on the training executor; results in order.
    ``journal``: the runs it holds are taken from it, not flown again, and each run flown is
    added to it as it finishes. ``say``: where the journal's news goes (resumed runs, a
    journal of another evaluation)."""
    n = len(runs)
    out: list[dict | None] = [None] * n
    if journal is not None:
        done = journal.load()
        for line in journal.skipped:
            say(line)
        if journal.stale:
            say(f"{journal.path} also holds {len(journal.kept)} runs this eval does not ask for "
                "(other scenarios, options, databases, path files or flapsim version): kept")
        for i, r in done.items():
            if r.get("scenario") != runs[i][0]:  # a line edited to another index
                say(f"{journal.path}: the run kept for {runs[i][0]} is of {r.get('scenario')!r}; "
                    "it is flown again")
                continue
            out[i] = r
        done = {i: r for i, r in done.items() if out[i] is not None}
        journal.resumed = len(done)
        if done:
            say(f"resuming: {len(done)} of {n} runs finished before, read from {journal.path}")
        journal.open(done)
    todo = [i for i in range(n) if out[i] is None]
    # dearest first: the longest run must not be the one that starts last
    order = sorted(todo, key=lambda i: -get(runs[i][0]).cost)
    try:
        if order:
            workers = workers or max(1, min(len(order), usable_cores()))
            workers = min(workers, len(order))
            with ChunkExecutor(EvalWorker, RunsConfig(list(runs)), workers=workers, backend=backend,
                               address=address) as ex, \
                    tqdm(total=n, initial=n - len(order), desc="scenarios", unit="run") as bar:
                for chunk in ex.map_unordered([(i, i + 1) for i in order]):
                    for i, r in chunk:
                        out[i] = r
                        if journal is not None:
                            journal.add(i, r)
                        bar.set_postfix_str(f"{r['scenario']}: {r['status']}")
                        bar.update(1)
            missing = [runs[i][0] for i in order if out[i] is None]
            if missing:  # never a table that silently lacks a run
                raise WorkerError(f"no result came back for {', '.join(missing)}; run the same "
                                  "command again to resume")
    finally:
        if journal is not None:
            journal.close()
    return [r for r in out if r is not None]


def spread(results: list[dict]) -> dict[str, dict]:
    """Completion over the starts of each scenario (:func:`start_runs`), with Wilson's 95 %
    interval and the spread of the largest distance from the path."""
    by: dict[str, list[dict]] = {}
    for r in results:
        by.setdefault(r["scenario"], []).append(r)
    rows = {}
    for name, rs in by.items():
        k = sum(r["status"] == "completed" for r in rs)
        lo, hi = completion_interval(k, len(rs))
        far = [r.get("metrics", {}).get("max_path_distance") for r in rs]
        far = [f for f in far if f is not None]
        rows[name] = {"completed": k, "starts": len(rs), "rate": k / len(rs),
                      "rate_95": [lo, hi],
                      "max_path_distance_range_m": [min(far), max(far)] if far else None}
    return rows


# -- Table I --------------------------------------------------------------------------------

TABLE1_SIZES = (2000, 5000, 10000, 20000)
"""The paper's Table I: database sizes, flown with k = 0.5 %."""
TABLE1_K_PERCENT = (2.0, 1.0, 0.5, 0.3)
"""The paper's Table I: k as a share of 10,000 samples, %."""
TABLE1_SCENARIO = "figure8"
"""The paper's Table I path: a figure of eight with ascending and descending turns."""


def bundled_seed(feathers: str = "rigid") -> int:
    """The sampling seed of the bundled database of the ``feathers`` dove."""
    return int(load_database(bundled_database_path(feathers), require_finalized=True).header["seed"])


def is_bundled_run(config: SamplingConfig, n: int) -> bool:
    """True when the bundled database holds exactly ``n`` samples of this configuration's
    run (:func:`~flapsim.bird.training.train.train` still checks the copy's header before
    accepting it)."""
    db = load_database(bundled_database_path(config.feathers), require_finalized=True)
    ident = run_header(config, SampleWorker, "dove-phase1")
    return db.n == n and all(same_entry(k, db.header.get(k), ident.get(k))
                             for k in ("kind", "worker", "config_class", "config", "seed"))


def table1_databases(sizes: tuple[int, ...], cache: Path, seed: int, feathers: str = "rigid",
                     workers: int = 1, backend: str = "local", address: str | None = None,
                     say: Callable[[str], None] = log.info) -> dict[int, Path]:
    """The phase-1 databases of Table I (the bundled database's sampling: pre-states within
    10 deg), one per size, in ``cache`` as ``phase1_N.db``: trained where missing (resumable),
    copied where the bundled database is that very run."""
    config = SamplingConfig(seed=seed, pitch_deg=10.0, roll_deg=10.0, feathers=feathers)
    dbs = {}
    for n in sorted(set(sizes)):
        out = cache / f"phase1_{n}.db"
        if not out.exists() and is_bundled_run(config, n):
            shutil.copyfile(bundled_database_path(config.feathers), out)
            say(f"database of {n} samples: {out} (the bundled one)")
        else:
            say(f"database of {n} samples: {out}")
        train(config, out, n, SampleWorker, workers=workers, backend=backend, address=address,
              kind="dove-phase1")
        dbs[n] = out
    return dbs


def paper_protocol(o: EvalOptions) -> EvalOptions:
    """``o`` flown as the paper's controller whatever else was asked: S0 simulated at the
    flight's rate, no lateral regulator, the regression's answer flown as it is from P0 every
    wingbeat with the paper's fixed neighbourhood, the bank of the wingbeat's end, the trim's
    angle of attack in turns, the speed asked everywhere, independent speed and height loops,
    and the dove's default bank cap (Table I's figure of eight flies the same at 45 and 60 deg:
    docs/design/flight.md, "A 60 deg bank by default")."""
    dove = PathControlConfig.for_dove(o.feathers)
    controller = o.controller if o.controller is not None else _library_controller(o)
    controller = dataclasses.replace(controller, k_dense_share=0.0, carry=0.0, refine=0,
                                     reference_hz=0.0, lateral="off")
    path = dataclasses.replace(o.path_control or dove, bank_lead_s=0.0, aoa_per_g_deg=0.0,
                               turn_load_factor=0.0, climb_per_speed_deficit=0.0,
                               max_bank_deg=dove.max_bank_deg)
    return dataclasses.replace(o, controller=controller, path_control=path, speed=None)


def _library_controller(o: EvalOptions) -> ControllerConfig:
    """The controller a run without one flies (:func:`~flapsim.bird.control.controller.
    load_controller`'s default)."""
    return dataclasses.replace(ControllerConfig.for_dove(o.feathers, o.predict), lookahead="off")


def table1_runs(name: str, opts: EvalOptions, dbs: dict[int, Path], sizes: tuple[int, ...]
                ) -> tuple[list[Run], list[dict]]:
    """Table I's runs of scenario ``name`` and a label for each (samples, k %, k): every
    size with k = 0.5 %, then the other shares of k on 10,000 samples (or the largest)."""
    runs, labels = [], []
    # k is a share of the samples the regression searches: with the mirror images, twice the
    # database's
    per = 2 if opts.mirror else 1
    for n in sizes:
        k = max(1, round(0.005 * per * n))
        runs.append((name, paper_protocol(dataclasses.replace(opts, db=str(dbs[n]), k=k))))
        labels.append({"samples": n, "k_percent": 0.5, "k": k})
    base = 10000 if 10000 in dbs else max(dbs)
    for kp in TABLE1_K_PERCENT:
        if kp == 0.5:
            continue
        k = max(1, round(kp / 100 * per * base))
        runs.append((name, paper_protocol(dataclasses.replace(opts, db=str(dbs[base]), k=k))))
        labels.append({"samples": base, "k_percent": kp, "k": k})
    return runs, labels
