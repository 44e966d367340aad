"""The finished runs of an evaluation, kept as each finishes, so that an interrupted
``flapsim eval --json PATH`` resumes where it stopped when the same command is run again.

The journal is ``PATH.partial``: JSON lines, a header, then one line per finished run,
appended and synced as it arrives, under the run's own fingerprint: its scenario and
options, the versions of flapsim and the packages whose numerics decide a flight
(:func:`flapsim.core.environment.tag`), and the bytes of the database and path file it reads.
A run is deterministic given what its fingerprint covers, so a run read back is the run that
would be flown again, whichever eval asks for it: an eval of a subset of an interrupted one
reuses the runs it shares with it. Runs an eval does not ask for stay in the journal (they
are never deleted unasked). A line that is no finished run (torn by ``kill -9``, or edited)
is skipped with a warning naming the file and line, and that run is flown again; a file
there that is no journal is left alone and refused in one line. The command removes the
journal once PATH itself is written, unless it holds runs of other evals.
"""

from __future__ import annotations

import hashlib
import json
import os
from pathlib import Path
from typing import Any

from flapsim.bird.control.controller import bundled_database_path
from flapsim.core.errors import DataFileError, InputError
from flapsim.core.io import _jsonable, atomic_path, read_regular
from flapsim.core.validate import nonfinite_entry
from flapsim.scenarios.registry import get

KIND = "flapsim-eval-journal"
VERSION = 2
SUFFIX = ".partial"


def journal_path(json_path: str | os.PathLike) -> Path:
    """Where ``flapsim eval --json json_path`` keeps its finished runs."""
    return Path(str(json_path) + SUFFIX)


def _file_digest(path: str | os.PathLike) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


#: Options that change how fast a run goes, never what it gives: not in the fingerprint
#: (``(table, key)``: a key of the options' table, None: of the options themselves).
WALL_TIME_ONLY = (("controller", "lookahead"),)


def fingerprint(runs: list[tuple[str, Any]], version: str) -> str:
    """sha256 over what decides the runs' results: each run's scenario name and options
    (``to_dict()``), ``version`` (the software's: :func:`flapsim.core.environment.tag`), and the
    content of the database and path file each reads (the bundled database stands for
    ``db=None`` on a flight)."""
    files: dict[str, str] = {}

    def digest(p: str | os.PathLike | None) -> str | None:
        if p is None:
            return None
        key = str(p)
        if key not in files:
            files[key] = _file_digest(p) if Path(p).is_file() else "missing"
        return files[key]

    items = []
    for name, opts in runs:
        d = opts.to_dict() if hasattr(opts, "to_dict") else dict(opts)
        for table, k in WALL_TIME_ONLY:
            where = d if table is None else d.get(table)
            if isinstance(where, dict):
                where.pop(k, None)
        db = d.get("db")
        if db is None and get(name).family == "flight":
            db = bundled_database_path(d.get("feathers", "rigid"))
        items.append({"scenario": name, "options": d, "db_sha256": digest(db),
                      "path_sha256": digest(d.get("path_file"))})
    text = json.dumps(_jsonable({"version": version, "runs": items}), sort_keys=True)
    return hashlib.sha256(text.encode()).hexdigest()


def run_keys(runs: list[tuple[str, Any]], version: str) -> list[str]:
    """Each run's own fingerprint (:func:`fingerprint` of that run alone): a finished run is
    reused by any eval that asks for the same run, whatever else it asks for."""
    return [fingerprint([run], version) for run in runs]


#: Entries a run's result must have, with their types, to be read back from a journal.
_RESULT_ENTRIES = {"scenario": str, "family": str, "status": str, "ok": bool, "metrics": dict}


def _record_problem(rec: Any, version: int) -> str | None:
    """Why a journal line cannot be a finished run, or None."""
    if not isinstance(rec, dict):
        return "not a JSON object"
    i = rec.get("i")
    if type(i) is not int or i < 0:
        return f"its run index {i!r} is not a whole number >= 0"
    if version >= 2 and not isinstance(rec.get("run"), str):
        return "it names no run"
    result = rec.get("result")
    if not isinstance(result, dict):
        return "it has no result"
    for key, kind in _RESULT_ENTRIES.items():
        if not isinstance(result.get(key), kind):
            return f"its result's {key!r} is {type(result.get(key)).__name__}, not {kind.__name__}"
    found = nonfinite_entry(result, "result")
    if found is not None:  # results are written with null for a number that is not finite
        return f"its {found[0]} is {found[1]!r}, a non-finite number"
    return None


class RunJournal:
    """Finished runs, each under its own fingerprint (:func:`run_keys`), on disk at ``path``.

    A journal holds the runs of every eval that used it: an eval of a subset, or of other
    runs, reuses those it asks for and keeps the others (it never deletes runs it was not
    asked to discard); it is removed once it holds nothing that the written results lack."""

    def __init__(self, path: str | os.PathLike, keys: list[str], legacy: str | None = None) -> None:
        self.path = Path(path)
        self.keys = list(keys)
        self.n_runs = len(self.keys)
        self.legacy = legacy
        """The whole eval's :func:`fingerprint`: reads a journal of the first format."""
        self.kept: list[dict] = []
        """Records of runs this eval does not ask for (kept in the journal)."""
        self.skipped: list[str] = []
        """One line per journal line that could not be read (that run is flown again)."""
        self.resumed = 0
        """Runs :meth:`load` read back."""
        self._f = None
        self._bare = -1

    @property
    def stale(self) -> bool:
        """Whether the journal holds runs of another eval (kept, not flown)."""
        return bool(self.kept)

    def _header(self) -> dict:
        return {"kind": KIND, "version": VERSION, "runs": self.n_runs}

    def load(self) -> dict[int, dict]:
        """The runs already finished, by index in this eval; a file there that is no eval
        journal is a one-line error. A line that is no finished run (torn by a kill, or
        edited) is skipped and named in :attr:`skipped`: that run is flown again."""
        if not self.path.exists():
            return {}
        try:
            lines = read_regular(self.path, "eval journal").split(b"\n")
            head = json.loads(lines[0])
        except DataFileError as exc:
            raise InputError(f"{exc}; move it away or choose another --json") from None
        except (ValueError, IndexError):
            head = None
        if not isinstance(head, dict) or head.get("kind") != KIND:
            raise InputError(f"{self.path} exists and is not an eval journal (flapsim eval keeps "
                             "its finished runs there): move it away or choose another --json")
        version = head.get("version")
        if version not in (1, VERSION):
            raise InputError(f"{self.path} is an eval journal of another flapsim (format "
                             f"{version!r}); move it away or choose another --json")
        same_eval = version == 1 and head.get("fingerprint") == self.legacy
        by_key: dict[str, dict] = {}
        for n, line in enumerate(lines[1:], start=2):
            if not line.strip():
                continue
            try:
                rec = json.loads(line)
            except ValueError:
                rec = None
                problem = "not JSON (torn by an interrupted write?)"
            else:
                problem = _record_problem(rec, version)
            if problem is not None:
                self.skipped.append(f"{self.path} line {n}: {problem}; that run is flown again")
                continue
            if version == 1:
                if not (same_eval and rec["i"] < self.n_runs):
                    self.kept.append({**rec, "run": None, "eval": head.get("fingerprint")})
                    continue
                rec = {**rec, "run": self.keys[rec["i"]]}
            by_key.setdefault(rec["run"], rec)
        wanted = set(self.keys)
        done: dict[int, dict] = {}
        for i, key in enumerate(self.keys):
            rec = by_key.get(key)
            if rec is not None:
                done[i] = rec["result"]
        self.kept += [rec for key, rec in by_key.items() if key not in wanted]
        self.resumed = len(done)
        return done

    def open(self, done: dict[int, dict]) -> None:
        """Write the journal afresh with ``done`` and the runs of other evals in it (whole,
        then renamed), and keep it open for :meth:`add`."""
        with atomic_path(self.path, suffix=SUFFIX) as tmp:
            with open(tmp, "w") as f:
                f.write(json.dumps(self._header()) + "\n")
                for i in sorted(done):
                    f.write(json.dumps(_jsonable(self._record(i, done[i]))) + "\n")
                for rec in self.kept:
                    f.write(json.dumps(_jsonable(rec)) + "\n")
                f.flush()
                os.fsync(f.fileno())
        self._f = open(self.path, "a")
        self._bare = self.path.stat().st_size if not (done or self.kept) else -1

    def _record(self, i: int, result: dict) -> dict:
        return {"i": int(i), "run": self.keys[i], "result": result}

    def add(self, i: int, result: dict) -> None:
        """Append run ``i``'s result and sync it to disk."""
        self._f.write(json.dumps(_jsonable(self._record(i, result))) + "\n")
        self._f.flush()
        os.fsync(self._f.fileno())

    def close(self) -> None:
        """Stop adding; a journal that holds no run is removed (nothing to resume from).
        Judged by the file's size, not by a count kept in :meth:`add`: a Ctrl-C that lands
        after a run's line is written but before ``add`` returns must not remove that run."""
        if self._f is not None:
            self._f.close()
            self._f = None
            try:
                bare = self.path.stat().st_size == self._bare
            except FileNotFoundError:
                return
            if bare:
                self.path.unlink(missing_ok=True)

    def finish(self) -> bool:
        """The results are written: the journal goes, unless it holds runs of other evals
        (then it stays, and True is returned)."""
        self.close()
        if self.kept:
            return True
        self.path.unlink(missing_ok=True)
        return False

    remove = finish
