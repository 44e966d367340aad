"""The finished runs of an evaluation, kept as each finishes, so that an interrupted
``flapsim eval --json PATH`` resumes where it stopped when the same command is run again.

The journal is ``PATH.partial``: JSON lines, a header naming what was asked (a fingerprint
of every run's scenario and options, the versions of flapsim and the packages whose numerics
decide a flight (:func:`flapsim.core.environment.tag`), and the bytes of each database and path
file the runs read), then one line per finished run, appended and synced as it arrives.
A run is deterministic given what the fingerprint covers, so a run read back is the run that
would be flown again. A line torn by ``kill -9`` is flown again; a journal of other runs (the
options, a database or the code changed) is replaced by the new one; a file there that is no
journal is left alone and refused in one line. The command removes the journal once PATH
itself is written.
"""

from __future__ import annotations

import hashlib
import json
import os
from pathlib import Path
from typing import Any

from flapsim.bird.control.controller import bundled_database_path
from flapsim.core.errors import InputError
from flapsim.core.io import _jsonable, atomic_path
from flapsim.scenarios.registry import get

KIND = "flapsim-eval-journal"
VERSION = 1
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


class RunJournal:
    """Finished runs by index, on disk at ``path`` for runs of ``fingerprint``."""

    def __init__(self, path: str | os.PathLike, fingerprint: str, n_runs: int) -> None:
        self.path = Path(path)
        self.fingerprint = fingerprint
        self.n_runs = int(n_runs)
        self.stale = False
        """True when :meth:`load` found a journal of other runs (it is replaced)."""
        self.resumed = 0
        """Runs :meth:`load` read back."""
        self._f = None
        self._bare = -1

    def _header(self) -> dict:
        return {"kind": KIND, "version": VERSION, "fingerprint": self.fingerprint,
                "runs": self.n_runs}

    def load(self) -> dict[int, dict]:
        """The runs already finished (none when there is no journal, or one of other runs);
        a file there that is no eval journal is a one-line error."""
        if not self.path.exists():
            return {}
        try:
            lines = self.path.read_bytes().split(b"\n")
            head = json.loads(lines[0])
        except (OSError, ValueError, IndexError):
            head = None
        if not isinstance(head, dict) or head.get("kind") != KIND:
            raise InputError(f"{self.path} exists and is not an eval journal (flapsim eval keeps "
                             "its finished runs there): move it away or choose another --json")
        if head.get("version") != VERSION or head.get("fingerprint") != self.fingerprint:
            self.stale = True
            return {}
        done: dict[int, dict] = {}
        for line in lines[1:]:
            try:
                rec = json.loads(line)
                i, result = int(rec["i"]), rec["result"]
            except (ValueError, KeyError, TypeError):
                continue  # torn by a kill mid-write, or empty: that run is flown again
            if 0 <= i < self.n_runs and isinstance(result, dict):
                done[i] = result
        self.resumed = len(done)
        return done

    def open(self, done: dict[int, dict]) -> None:
        """Start the journal afresh with ``done`` in it (written whole, then renamed), and
        keep it open for :meth:`add`."""
        with atomic_path(self.path, suffix=SUFFIX) as tmp:
            with open(tmp, "w") as f:
                f.write(json.dumps(self._header()) + "\n")
                for i in sorted(done):
                    f.write(json.dumps(_jsonable({"i": i, "result": done[i]})) + "\n")
                f.flush()
                os.fsync(f.fileno())
        self._f = open(self.path, "a")
        self._bare = self.path.stat().st_size if not done else -1

    def add(self, i: int, result: dict) -> None:
        """Append run ``i``'s result and sync it to disk."""
        self._f.write(json.dumps(_jsonable({"i": int(i), "result": result})) + "\n")
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

    def remove(self) -> None:
        """The results are written: the journal is no longer needed."""
        self.close()
        self.path.unlink(missing_ok=True)
