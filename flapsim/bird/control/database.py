"""Sample databases: accepted samples of a training run, with their provenance, in one
versioned binary file that survives being killed at any moment.

Layout (little-endian throughout)::
    preamble   8 s   magic b"\\x93FLAPDB\\n"
               u32   schema version (SCHEMA_VERSION)
               u32   header length H
               u32   CRC-32 of the header bytes
    header     H     JSON (UTF-8, sorted keys, no spaces): kind, schema_version,
                     flapsim_version, model_hash, seed, config (every sampling
                     parameter), config_class, worker, provenance (the worker's
                     header()), chunk_size, fields [{name, dtype, shape}] sorted by
                     name, finalized; a finalized file adds samples and examined
    records    repeated until the end of the file, one per chunk:
               4 s   b"CHNK"
               u32   CRC-32 of the payload
               u64   payload length L
               L     payload: u32 descriptor length D, descriptor JSON
                     {start, stop, n, rejected}, then index (n x int64), then each
                     field in header order (n x shape, the field's dtype), C order

While training, the file is a journal: the header is written once (atomically), then
each finished chunk is appended as one record with one write and an fsync. A process
killed mid-append leaves a torn last record, which the length and CRC expose; loading
ignores it and :meth:`DatabaseWriter.resume` cuts it off, so no sample is lost (its
chunk is simply run again) or duplicated. A record that is damaged but not last is
corruption, not a torn write, and is an error.

:func:`finalize_database` rewrites the journal in sample-index order, as one record,
to a temporary file renamed over it. Nothing in the file depends on the worker count,
the backend, the completion order or interruptions (no times, no hosts), so a finished
database's bytes depend only on the run's parameters. Finalized files (and those
written by :func:`save_database`) must be intact: any damage is an error.

numpy only: no pickles, no HDF5 (one file, append-only, and a torn-write rule we
control; HDF5 would need h5py and gives no guarantee for a process killed mid-write).
"""

from __future__ import annotations

import contextlib
import fcntl
import json
import logging
import os
import signal
import struct
import threading
import zlib
from collections.abc import Iterator, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from flapsim import __version__
from flapsim.core.errors import DataFileError, InputError, OutputError
from flapsim.core.io import NOTHING_WRITTEN, _jsonable, atomic_path, file_sha256
from flapsim.core.validate import require_finite

log = logging.getLogger(__name__)

MAGIC = b"\x93FLAPDB\n"
SCHEMA_VERSION = 1
DEFAULT_KIND = "flapsim-samples"

_PREAMBLE = struct.Struct("<8sIII")  # magic, schema version, header length, header CRC
_RECORD = struct.Struct("<4sIQ")  # record magic, payload CRC, payload length
_RECORD_MAGIC = b"CHNK"
_DESC = struct.Struct("<I")
_MAX_HEADER = 1 << 28
_HEADER_KEYS = ("kind", "schema_version", "flapsim_version", "fields", "finalized")


@dataclass
class ChunkResult:
    """The samples of one chunk ``[start, stop)`` (what a sample worker's ``run_chunk``
    returns; the database accepts any object with these attributes)."""

    start: int
    """first sample index of the chunk"""
    stop: int
    """one past the last sample index"""
    index: np.ndarray
    """(m,) int64 indices of the accepted samples, ascending, in [start, stop)"""
    arrays: dict[str, np.ndarray]
    """per accepted sample fields, first dimension m"""
    rejected: dict[str, int] = field(default_factory=dict)
    """reason -> number of rejected samples in the chunk"""


@dataclass
class Database:
    """A loaded database: samples sorted by index, with the header that made them."""

    path: Path | None
    header: dict
    index: np.ndarray
    """(n,) int64 sample indices, ascending"""
    arrays: dict[str, np.ndarray]
    """field -> (n, *shape) array, rows in the order of ``index``"""
    rejected: dict[str, int]
    """reason -> rejected samples, over every chunk in the file"""
    chunks: list[tuple[int, int, int]]
    """(start, stop, accepted) of every record, sorted by start"""
    torn_bytes: int = 0
    """bytes of a torn last record that were ignored (journal files only)"""

    @property
    def n(self) -> int:
        return int(self.index.shape[0])

    @property
    def finalized(self) -> bool:
        return bool(self.header.get("finalized"))

    @property
    def fields(self) -> list[dict]:
        return list(self.header.get("fields") or [])


# ---------------------------------------------------------------- encoding helpers

def canonical_json(obj: Any) -> bytes:
    """The one byte form of a JSON document used in database files (sorted keys,
    no spaces, ASCII; numpy values converted, NaN -> null)."""

    return json.dumps(_jsonable(obj), sort_keys=True, separators=(",", ":"), ensure_ascii=True,
                      allow_nan=False).encode("ascii")


def fields_spec(arrays: Mapping[str, np.ndarray]) -> list[dict]:
    """Field descriptions ``[{name, dtype, shape}]`` (sorted by name) of per-sample
    arrays whose first dimension is the sample."""
    spec = []
    for name in sorted(arrays):
        a = np.asarray(arrays[name])
        if a.ndim < 1:
            raise InputError(f"field {name!r} must have one row per sample, got a scalar")
        if a.dtype.kind not in "biuf":
            raise InputError(f"field {name!r} has dtype {a.dtype}; databases hold bool, integer "
                             "or float arrays")
        spec.append({"name": str(name), "dtype": a.dtype.newbyteorder("<").str,
                     "shape": [int(s) for s in a.shape[1:]]})
    return spec


def _encode_record(header: dict, start: int, stop: int, index: np.ndarray,
                   arrays: Mapping[str, np.ndarray], rejected: Mapping[str, int]) -> bytes:
    index = np.asarray(index)
    n = int(index.shape[0]) if index.ndim == 1 else -1
    if n < 0 or index.dtype.kind not in "iu":
        raise InputError(f"chunk {start}..{stop}: index must be a 1-d integer array")
    if not (0 <= start <= stop):
        raise InputError(f"chunk {start}..{stop}: need 0 <= start <= stop")
    if n and (index[0] < start or index[-1] >= stop or np.any(np.diff(index) <= 0)):
        raise InputError(f"chunk {start}..{stop}: accepted indices must be ascending, unique "
                         "and inside the chunk")
    bad = {k: v for k, v in rejected.items() if int(v) != v or v < 0}
    if bad:
        raise InputError(f"chunk {start}..{stop}: rejected counts must be integers >= 0, got {bad}")
    spec = header["fields"]
    names = [f["name"] for f in spec]
    if n == 0 and not arrays:
        arrays = {f["name"]: np.zeros((0, *f["shape"]), f["dtype"]) for f in spec}
    if sorted(arrays) != names:
        raise InputError(f"chunk {start}..{stop} has fields {sorted(arrays)}, the database has "
                         f"{names}")
    parts = [index.astype("<i8", copy=False).tobytes()]
    for f in spec:
        a = np.asarray(arrays[f["name"]])
        if a.shape != (n, *f["shape"]):
            raise InputError(f"chunk {start}..{stop}: field {f['name']!r} has shape {a.shape}, "
                             f"expected {(n, *f['shape'])}")
        if not np.can_cast(a.dtype, f["dtype"], casting="same_kind"):
            raise InputError(f"chunk {start}..{stop}: field {f['name']!r} is {a.dtype}, the "
                             f"database stores {np.dtype(f['dtype'])}")
        parts.append(np.ascontiguousarray(a, dtype=f["dtype"]).tobytes())
    desc = canonical_json({"start": int(start), "stop": int(stop), "n": n,
                           "rejected": {str(k): int(v) for k, v in rejected.items()}})
    payload = _DESC.pack(len(desc)) + desc + b"".join(parts)
    return _RECORD.pack(_RECORD_MAGIC, zlib.crc32(payload), len(payload)) + payload


def _encode_preamble(header: dict) -> bytes:
    text = canonical_json(header)
    return _PREAMBLE.pack(MAGIC, SCHEMA_VERSION, len(text), zlib.crc32(text)) + text


def _decode_payload(payload: bytes, header: dict, where: str) -> tuple[dict, np.ndarray, dict]:
    try:
        (dlen,) = _DESC.unpack_from(payload, 0)
        desc = json.loads(payload[4:4 + dlen].decode("ascii"))
        n, start, stop = int(desc["n"]), int(desc["start"]), int(desc["stop"])
        rejected = {str(k): int(v) for k, v in desc["rejected"].items()}
    except (struct.error, ValueError, KeyError, TypeError, AttributeError, UnicodeDecodeError):
        raise DataFileError(f"{where} has an unreadable chunk descriptor (the file is damaged); "
                            "delete it and train again") from None
    pos = 4 + dlen
    sizes = [n * 8] + [n * int(np.prod(f["shape"], dtype=np.int64)) * np.dtype(f["dtype"]).itemsize
                       for f in header["fields"]]
    if pos + sum(sizes) != len(payload) or n < 0 or not 0 <= start <= stop:
        raise DataFileError(f"{where}: chunk {start}..{stop} does not match the header's fields "
                            "(the file is damaged); delete it and train again")
    index = np.frombuffer(payload, "<i8", n, pos).astype(np.int64)
    pos += sizes[0]
    arrays = {}
    for f, size in zip(header["fields"], sizes[1:], strict=True):
        dt = np.dtype(f["dtype"])
        flat = np.frombuffer(payload, dt, size // dt.itemsize, pos)
        arrays[f["name"]] = flat.reshape(n, *f["shape"]).astype(dt.newbyteorder("="))
        pos += size
    if n and (index[0] < start or index[-1] >= stop or np.any(np.diff(index) <= 0)):
        raise DataFileError(f"{where}: chunk {start}..{stop} has indices outside it or out of "
                            "order (the file is damaged); delete it and train again")
    # training keeps only samples whose flights stayed finite: any other is damage
    require_finite(arrays, f"{where}: chunk {start}..{stop}", fix="the file is damaged or was "
                   "not written by flapsim train; delete it and train again")
    return {"start": start, "stop": stop, "n": n, "rejected": rejected}, index, arrays


# ---------------------------------------------------------------- reading

def _read_header(data: bytes, path: Path) -> tuple[dict, int]:
    if len(data) < len(MAGIC) and MAGIC.startswith(data) and data:
        raise DataFileError(f"{path} has a truncated header ({len(data)} bytes); the file is "
                            "damaged: delete it and train again")
    if data[:len(MAGIC)] != MAGIC:
        start = data[:8]
        what = ("empty" if not data else "a PNG image" if start.startswith(b"\x89PNG")
                else "a zip/npz archive" if start.startswith(b"PK") else "an HDF5 file"
                if start.startswith(b"\x89HDF") else f"starts with {start!r}")
        raise DataFileError(f"{path} is not a flapsim database ({what}); pass a file written by "
                            "flapsim train")
    if len(data) < _PREAMBLE.size:
        raise DataFileError(f"{path} has a truncated header ({len(data)} bytes); the file is "
                            "damaged: delete it and train again")
    _, schema, hlen, hcrc = _PREAMBLE.unpack_from(data, 0)
    if schema > SCHEMA_VERSION:
        raise DataFileError(f"{path} uses database schema {schema}, newer than this flapsim "
                            f"{__version__} reads ({SCHEMA_VERSION}); upgrade flapsim "
                            "(pip install -U flapsim)")
    if schema < 1:
        raise DataFileError(f"{path} has an invalid schema version {schema} (the file is "
                            "damaged); delete it and train again")
    end = _PREAMBLE.size + hlen
    if hlen > _MAX_HEADER or end > len(data):
        raise DataFileError(f"{path} has a truncated header ({len(data) - _PREAMBLE.size} of "
                            f"{hlen} bytes); the file is damaged: delete it and train again")
    text = data[_PREAMBLE.size:end]
    if zlib.crc32(text) != hcrc:
        raise DataFileError(f"{path} has a corrupt header (CRC mismatch); the file is damaged: "
                            "delete it and train again")
    try:
        header = json.loads(text.decode("ascii"))
        if not isinstance(header, dict) or any(k not in header for k in _HEADER_KEYS):
            raise ValueError
        for f in header["fields"]:
            np.dtype(f["dtype"])
            f["shape"] = [int(s) for s in f["shape"]]
    except (ValueError, TypeError, KeyError, UnicodeDecodeError):
        raise DataFileError(f"{path} has an unreadable header (missing entries or bad JSON); "
                            "delete it and train again") from None
    return header, end


def _scan(path: Path, data: bytes) -> tuple[dict, list, int, int]:
    """Header, decoded records, the end of the last good record, torn bytes."""
    header, pos = _read_header(data, path)
    final = bool(header.get("finalized"))
    records = []
    size = len(data)
    while pos < size:
        where = f"{path} (chunk at byte {pos})"
        if size - pos < _RECORD.size:
            torn = "its last chunk is cut short"
            break
        magic, crc, length = _RECORD.unpack_from(data, pos)
        end = pos + _RECORD.size + length
        if magic != _RECORD_MAGIC:
            if not any(data[pos:]):  # zero-filled tail: an interrupted write
                torn = "it ends in a zero-filled, unfinished chunk"
                break
            raise DataFileError(f"{where} is corrupt (no chunk marker); the file is damaged: "
                                "delete it and train again")
        if end > size:
            torn = "its last chunk is cut short"
            break
        payload = data[pos + _RECORD.size:end]
        if zlib.crc32(payload) != crc:
            if end == size:
                torn = "its last chunk fails its CRC"
                break
            raise DataFileError(f"{where} is corrupt (CRC mismatch); the file is damaged: delete "
                                "it and train again")
        records.append(_decode_payload(payload, header, where))
        pos = end
    else:
        return header, records, pos, 0
    if final:
        raise DataFileError(f"{path} is a finished database but {torn} (truncated or damaged "
                            "copy); copy it again or train again")
    log.warning("%s: %s (%d bytes, an interrupted write); ignoring it", path, torn, size - pos)
    return header, records, pos, size - pos


def _same_record(a: tuple, b: tuple) -> bool:
    """Whether two decoded records hold the same chunk with the same samples."""
    (da, ia, xa), (db_, ib, xb) = a, b
    return (da == db_ and np.array_equal(ia, ib) and xa.keys() == xb.keys()
            and all(np.array_equal(xa[k], xb[k]) for k in xa))


def _dedupe(records: list) -> list:
    """``records`` sorted by start, each chunk once: a chunk written twice with the same
    samples (two runs of one journal that each ran it: a sample depends only on the seed
    and its index) is one chunk, not damage."""
    records = sorted(records, key=lambda r: r[0]["start"])
    out: list = []
    for r in records:
        if out and r[0]["start"] == out[-1][0]["start"] and _same_record(out[-1], r):
            continue
        out.append(r)
    return out


def _assemble(path: Path | None, header: dict, records: list, torn: int) -> Database:
    records = _dedupe(records)
    for (a, _, _), (b, _, _) in zip(records, records[1:], strict=False):
        if b["start"] < a["stop"]:
            raise DataFileError(f"{path} has overlapping chunks {a['start']}..{a['stop']} and "
                                f"{b['start']}..{b['stop']} (the file is damaged); delete it and "
                                "train again")
    rejected: dict[str, int] = {}
    for d, _, _ in records:
        for k, v in d["rejected"].items():
            rejected[k] = rejected.get(k, 0) + v
    names = [f["name"] for f in header["fields"]]
    if records:
        index = np.concatenate([r[1] for r in records])
        arrays = {k: np.concatenate([r[2][k] for r in records]) for k in names}
    else:
        index = np.zeros(0, np.int64)
        arrays = {f["name"]: np.zeros((0, *f["shape"]), np.dtype(f["dtype"]).newbyteorder("="))
                  for f in header["fields"]}
    return Database(path=path, header=header, index=index, arrays=arrays,
                    rejected=dict(sorted(rejected.items())),
                    chunks=[(d["start"], d["stop"], d["n"]) for d, _, _ in records], torn_bytes=torn)


def _read_bytes(path: Path) -> bytes:
    _read_bytes_checks(path)
    try:
        return path.read_bytes()
    except OSError as exc:
        raise DataFileError(f"cannot read database {path}: {exc.strerror}") from None


def _read_bytes_checks(path: Path) -> None:
    if not path.exists():
        raise DataFileError(f"database {path} does not exist; check the path or create it with "
                            f"flapsim train --out {path}")
    if path.is_dir():
        raise DataFileError(f"database {path} is a folder; pass the database file")
    if not path.is_file():  # reading a device (/dev/zero) grows without end
        raise DataFileError(f"database {path} is not a regular file (a device, pipe or socket); "
                            "pass the database file")


def check_header(db_header: dict, path: Path | str, *, kind: str | None = None,
                 model_hash: str | None = None) -> None:
    """Raise :class:`DataFileError` if the database is not of ``kind`` or was built for
    another model than ``model_hash``."""
    if kind is not None and db_header.get("kind") != kind:
        raise DataFileError(f"{path} holds {db_header.get('kind')!r} samples, not {kind!r}; pass "
                            f"a {kind} database")
    if model_hash is not None and db_header.get("model_hash") != model_hash:
        raise DataFileError(f"{path} was built for model {db_header.get('model_hash')}, not this "
                            f"model ({model_hash}); train it again for this model (flapsim "
                            "train --out NEW.db)")


def load_database(path: str | os.PathLike, *, kind: str | None = None,
                  model_hash: str | None = None, require_finalized: bool = False) -> Database:
    """Load a database (finished or a training journal; a journal's torn last chunk is
    ignored). ``kind``/``model_hash``: refuse a file of another kind or model."""
    path = Path(path)
    header, records, _, torn = _scan(path, _read_bytes(path))
    check_header(header, path, kind=kind, model_hash=model_hash)
    if require_finalized and not header.get("finalized"):
        raise DataFileError(f"{path} is an unfinished training run; finish it by running the same "
                            "flapsim train command again")
    return _assemble(path, header, records, torn)


def read_header(path: str | os.PathLike) -> dict:
    """Only the header (checked: magic, schema version, CRC)."""
    path = Path(path)
    with _open_read(path) as fh:
        head = fh.read(_PREAMBLE.size)
        if len(head) == _PREAMBLE.size and head[:8] == MAGIC:
            head += fh.read(min(_PREAMBLE.unpack_from(head, 0)[2], _MAX_HEADER))
    return _read_header(head, path)[0]


@contextlib.contextmanager
def _open_read(path: Path):
    if not path.exists() or path.is_dir():
        _read_bytes(path)
    try:
        with open(path, "rb") as fh:
            yield fh
    except OSError as exc:
        raise DataFileError(f"cannot read database {path}: {exc.strerror}") from None


# ---------------------------------------------------------------- writing

@contextlib.contextmanager
def _signals_deferred() -> Iterator[None]:
    """Hold SIGINT/SIGTERM until the block is done (a write is not interrupted halfway;
    the signal is delivered right after)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    sigs = {signal.SIGINT, signal.SIGTERM}
    old = signal.pthread_sigmask(signal.SIG_BLOCK, sigs)
    try:
        yield
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, old)


def _write_atomic(path: Path, blobs: list[bytes], exclusive: bool = False,
                  left: str = NOTHING_WRITTEN) -> None:
    with atomic_path(path, exclusive=exclusive, left=left) as tmp:
        with open(tmp, "wb") as fh:
            for b in blobs:
                fh.write(b)
            fh.flush()
            os.fsync(fh.fileno())


class FinishedDatabase(InputError):
    """The journal to resume was finished meanwhile (by another run of it)."""


def _lock_file(path: Path) -> Any:
    """``path`` opened for update under an exclusive lock (a second writer is refused in one
    line), checked to still be the file at ``path``: one finished meanwhile was renamed over
    it, and the lock is then taken on the new file."""
    for _ in range(8):
        try:
            fh = open(path, "r+b")  # noqa: SIM115 - the caller closes it
        except FileNotFoundError:
            raise DataFileError(f"database {path} does not exist; check the path or create it "
                                f"with flapsim train --out {path}") from None
        except OSError as exc:
            raise InputError(f"cannot write database {path}: {exc.strerror}") from None
        try:
            fcntl.flock(fh.fileno(), fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            fh.close()
            raise InputError(f"{path} is being written by another flapsim train; wait for it or "
                             "choose another --out") from None
        try:
            st, now = os.fstat(fh.fileno()), os.stat(path)
            if (st.st_ino, st.st_dev) == (now.st_ino, now.st_dev):
                return fh
        except FileNotFoundError:
            pass
        fh.close()
    raise InputError(f"{path} keeps being replaced while it is opened; is another program "
                     "writing it? choose another --out")


def _read_locked(fh: Any, path: Path) -> bytes:
    try:
        fh.seek(0)
        return fh.read()
    except OSError as exc:
        raise DataFileError(f"cannot read database {path}: {exc.strerror}") from None


@contextlib.contextmanager
def _locked(path: Path, writer: DatabaseWriter | None = None) -> Iterator[Any]:
    """The file at ``path`` under the journal's lock (``writer``'s when it holds it)."""
    if writer is not None and not writer.closed:
        yield writer._fh
        return
    _read_bytes_checks(path)
    try:
        fh = _lock_file(path)
    except InputError:
        if os.access(path, os.W_OK):
            raise
        fh = None  # a read-only file: nobody appends to it
    if fh is None:
        with _open_read(path) as ro:
            yield ro
        return
    try:
        yield fh
    finally:
        fh.close()


class DatabaseWriter:
    """Appends chunk records to a database journal (one writer per file: an exclusive
    lock refuses a second one). What the file holds is read under the lock, so a chunk
    another run of the same journal wrote before this one took the lock is known
    (:attr:`chunks`) and not written twice."""

    def __init__(self, path: Path, header: dict, fh: Any, end: int, fsync: bool = True,
                 chunks: set[tuple[int, int]] | None = None) -> None:
        self.path = path
        self.header = header
        self.fsync = fsync
        self.chunks: set[tuple[int, int]] = set(chunks or ())
        """(start, stop) of every chunk in the file"""
        self._fh = fh
        self._fh.seek(end)
        self._fh.truncate(end)
        self._end = end

    @property
    def closed(self) -> bool:
        return self._fh.closed

    @classmethod
    def create(cls, path: str | os.PathLike, header: dict, fsync: bool = True) -> DatabaseWriter:
        """Start a new journal at ``path`` (which must not exist) with ``header``
        (``fields`` is required; kind, versions and ``finalized`` are filled in). The file
        appears whole, and never replaces one another run created meanwhile."""
        path = Path(path)
        if path.exists():
            raise InputError(f"{path} already exists; resume it or choose another --out")
        header = _complete_header(header, finalized=False)
        blob = _encode_preamble(header)
        try:
            _write_atomic(path, [blob], exclusive=True)
        except FileExistsError:
            raise InputError(f"{path} already exists; resume it or choose another --out") from None
        writer, _ = cls.resume(path, fsync)
        return writer

    @classmethod
    def resume(cls, path: str | os.PathLike, fsync: bool = True) -> tuple[DatabaseWriter, Database]:
        """Reopen a journal: its torn last chunk (if any) is cut off. The file is read after
        the lock is taken: what another run appended before is kept, never cut off."""
        path = Path(path)
        _read_bytes_checks(path)
        fh = _lock_file(path)
        try:
            header, records, end, torn = _scan(path, _read_locked(fh, path))
            if header.get("finalized"):
                raise FinishedDatabase(f"{path} is a finished database; choose another --out")
            db = _assemble(path, header, records, torn)
        except BaseException:
            fh.close()
            raise
        if torn:
            log.warning("%s: cutting off %d bytes of an interrupted chunk", path, torn)
        chunks = {(int(d["start"]), int(d["stop"])) for d, _, _ in records}
        return cls(path, header, fh, end, fsync, chunks), db

    def append(self, result: Any) -> bool:
        """Append one chunk (a :class:`ChunkResult`-like object) as one record; False (and
        nothing written) when the file holds that chunk already."""
        start, stop = int(result.start), int(result.stop)
        if (start, stop) in self.chunks:
            return False
        blob = _encode_record(self.header, start, stop, np.asarray(result.index), result.arrays,
                              result.rejected)
        with _signals_deferred():
            try:
                self._fh.seek(self._end)
                self._fh.write(blob)
                self._fh.flush()
                if self.fsync:
                    os.fsync(self._fh.fileno())
            except OSError as exc:
                # a full disk: the chunks before are whole; the part written is cut off
                with contextlib.suppress(OSError):
                    self._fh.truncate(self._end)
                raise OutputError(f"cannot write {self.path}: {exc.strerror or exc}; the "
                                  f"{len(self.chunks)} chunks written so far are kept: free "
                                  "space and run the same command again to resume") from None
            self._end += len(blob)
        self.chunks.add((start, stop))
        return True

    def close(self) -> None:
        if not self._fh.closed:
            self._fh.close()

    def __enter__(self) -> DatabaseWriter:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def _complete_header(header: dict, finalized: bool) -> dict:
    if "fields" not in header:
        raise InputError("a database header needs 'fields' (see fields_spec)")
    out = dict(header)
    out.setdefault("kind", DEFAULT_KIND)
    out.setdefault("model_hash", None)
    out.setdefault("seed", None)
    out["schema_version"] = SCHEMA_VERSION
    out["flapsim_version"] = __version__
    out["finalized"] = finalized
    # normalise through JSON so that what is compared later is what the file holds
    return json.loads(canonical_json(out))


def _write_final(path: Path, header: dict, index: np.ndarray, arrays: Mapping[str, np.ndarray],
                 rejected: Mapping[str, int], examined: int, exclusive: bool = False,
                 left: str = NOTHING_WRITTEN) -> None:
    header = _complete_header({**header, "samples": int(index.shape[0]),
                               "examined": int(examined)}, finalized=True)
    record = _encode_record(header, 0, int(examined), index, arrays,
                            dict(sorted(rejected.items())))
    with _signals_deferred():
        _write_atomic(path, [_encode_preamble(header), record], exclusive=exclusive, left=left)


def save_database(path: str | os.PathLike, header: dict, index: np.ndarray,
                  arrays: Mapping[str, np.ndarray], rejected: Mapping[str, int],
                  exclusive: bool = False) -> None:
    """Write a whole finished database at once, atomically (derived or bundled
    databases). Samples are sorted by index; ``fields`` is taken from ``arrays``;
    ``header['examined']`` (default: last index + 1) is the sample range covered.
    ``exclusive``: never replace a file at ``path`` (FileExistsError)."""
    index = np.asarray(index)
    if index.ndim != 1 or index.dtype.kind not in "iu":
        raise InputError(f"cannot save {path}: index must be a 1-d integer array")
    order = np.argsort(index, kind="stable")
    index = index[order].astype(np.int64)
    if index.size and (index[0] < 0 or np.any(np.diff(index) == 0)):
        raise InputError(f"cannot save {path}: sample indices must be unique and >= 0")
    sorted_arrays = {}
    for k, a in arrays.items():
        a = np.asarray(a)
        if a.ndim < 1 or a.shape[0] != index.size:
            raise InputError(f"cannot save {path}: field {k!r} has {a.shape[0] if a.ndim else 0} "
                             f"rows for {index.size} samples")
        sorted_arrays[k] = a[order]
    examined = int(header.get("examined", int(index[-1]) + 1 if index.size else 0))
    head = {k: v for k, v in header.items() if k not in ("samples", "examined")}
    head["fields"] = fields_spec(sorted_arrays)
    _write_final(Path(path), head, index, sorted_arrays, rejected, examined, exclusive)


def contiguous_prefix(chunks: list[tuple[int, int, int]]) -> list[tuple[int, int, int]]:
    """The chunks that tile ``[0, stop)`` without a gap, from ``chunks`` sorted by start."""
    out, at = [], 0
    for c in chunks:
        if c[0] != at:
            break
        out.append(c)
        at = c[1]
    return out


def finalize_database(path: str | os.PathLike, n_samples: int | None = None,
                      float32: bool = False, writer: DatabaseWriter | None = None) -> Database:
    """Rewrite a journal as a finished database: the first ``n_samples`` accepted
    samples by index (all of the gap-free prefix of chunks when ``None``), in index
    order, in one record; the rejected counts of the chunks used. Written to a
    temporary file and renamed over ``path``. ``float32``: store float fields in single
    precision (half the size; the journal keeps double, so a resumed run is unchanged).

    Done under the journal's lock (``writer``'s, when the caller holds it): another run of
    the same journal appending while this one reads would be cut off by the rename."""
    path = Path(path)
    with _locked(path, writer) as fh:
        return _finalize_locked(path, _read_locked(fh, path), n_samples, float32)


def _finalize_locked(path: Path, data: bytes, n_samples: int | None, float32: bool) -> Database:
    header, records, _, torn = _scan(path, data)
    records = _dedupe(records)
    db = _assemble(path, header, records, torn)
    if db.finalized:
        if n_samples is not None and db.n != n_samples:
            raise InputError(f"{path} is already finished with {db.n} samples, not {n_samples}")
        return db
    used = contiguous_prefix(db.chunks)
    total = 0
    for k, c in enumerate(used):
        total += c[2]
        if n_samples is not None and total >= n_samples:
            used = used[:k + 1]
            break
    else:
        if n_samples is not None:
            raise InputError(f"{path} has {total} samples in complete chunks, fewer than "
                             f"{n_samples}; run the training further")
    examined = used[-1][1] if used else 0
    keep = n_samples if n_samples is not None else total
    index = db.index[:keep]
    if index.size and index[-1] >= examined:  # only possible with a gap: never past the prefix
        raise InputError(f"{path}: samples beyond the complete chunks")
    arrays = {k: v[:keep] for k, v in db.arrays.items()}
    # what the journal alone needs (the size asked, for a resume) is not the database's
    fin = {k: v for k, v in header.items() if k not in ("samples", "examined", "samples_asked")}
    if float32:
        arrays = {k: v.astype("<f4") if v.dtype.kind == "f" else v for k, v in arrays.items()}
        fin["fields"] = fields_spec(arrays)
    rejected: dict[str, int] = {}
    for d, _, _ in records:
        if d["stop"] <= examined:
            for k, v in d["rejected"].items():
                rejected[k] = rejected.get(k, 0) + v
    # the finished database replaces the journal only once it is whole on disk
    _write_final(path, fin, index, arrays, rejected, examined,
                 left=f"the training journal is kept as it was ({db.n} samples in "
                      f"{len(db.chunks)} chunks): free space and run the same command again to "
                      "resume (it finishes the database)")
    return load_database(path)


#: Provenance entries the sources of a merge must share (besides the model hash): a sample's
#: dP is relative to the reference wingbeat P0, so samples around different references or
#: timesteps do not belong in one regression.
MERGE_SAME = ("P0", "reference_coef", "reference_period", "timestep")

#: Fields a merge adds: which source (0, 1, ...) and which sample index there.
MERGE_FIELDS = ("part", "source_index")

#: Relative tolerance of a merge's numeric provenance entries. The reference wingbeat is
#: fitted at run time from the capture set (a least-squares Fourier fit), so two machines, or
#: two builds of numpy's linear algebra, write coefficients that differ in their last bits:
#: the bundled database's and one trained here on 2026-12-02 differ by 5.2e-16 on
#: coefficients up to 1.05, and an exact comparison refused to merge them. Another reference
#: wingbeat or timestep differs by many orders of magnitude more.
MERGE_RTOL = 1e-9


def same_provenance(a: Any, b: Any, rtol: float = MERGE_RTOL) -> bool:
    """Whether two provenance entries agree: numbers and (nested) lists of numbers to
    ``rtol`` of the larger magnitude in the entry, anything else exactly."""
    try:
        x, y = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    except (TypeError, ValueError):
        return canonical_json(a) == canonical_json(b)
    if x.shape != y.shape or not (np.all(np.isfinite(x)) and np.all(np.isfinite(y))):
        return canonical_json(a) == canonical_json(b)  # None (absent) and NaN compare exactly
    scale = max(float(np.max(np.abs(x), initial=0.0)), float(np.max(np.abs(y), initial=0.0)))
    return bool(np.all(np.abs(x - y) <= rtol * scale))


def merge_databases(paths: list[str | os.PathLike], out: str | os.PathLike,
                    same: tuple[str, ...] = MERGE_SAME) -> Database:
    """Write the samples of the finished databases ``paths`` into one finished database
    ``out`` (atomically: a temporary file renamed), samples numbered 0.. in the order given,
    with per-sample fields ``part`` (which source) and ``source_index``. The header keeps the
    common model hash and provenance entries ``same`` and, under ``provenance.parts``, every
    source's path, sha256, sample count and whole header. Sources of another model, with
    other ``same`` entries, other fields, or unfinished, are one-line errors."""

    if len(paths) < 2:
        raise InputError(f"a merge needs at least two databases, got {len(paths)}")
    if Path(out).exists():
        raise InputError(f"{out} exists; a merge writes a new database: choose another --out, "
                         "or delete it first")
    dbs = [load_database(p, require_finalized=True) for p in paths]
    _refuse_overlap(paths, dbs)
    first, p0 = dbs[0], Path(paths[0])
    names = sorted(set(first.arrays) - set(MERGE_FIELDS))
    prov0 = first.header.get("provenance") or {}
    for p, db in zip(paths[1:], dbs[1:], strict=True):
        if db.header.get("model_hash") != first.header.get("model_hash"):
            raise InputError(f"cannot merge {p} (model {db.header.get('model_hash')}) with {p0} (model "
                             f"{first.header.get('model_hash')}): databases of different doves")
        other = sorted(set(db.arrays) - set(MERGE_FIELDS))
        if other != names:
            raise InputError(f"cannot merge {p} (fields {', '.join(other)}) with {p0} (fields "
                             f"{', '.join(names)})")
        for name in names:
            if db.arrays[name].shape[1:] != first.arrays[name].shape[1:]:
                raise InputError(f"cannot merge {p} with {p0}: field {name!r} has shape "
                                 f"{db.arrays[name].shape[1:]} there, {first.arrays[name].shape[1:]} here")
        prov = db.header.get("provenance") or {}
        for key in same:
            if not same_provenance(prov.get(key), prov0.get(key)):
                raise InputError(f"cannot merge {p} with {p0}: their provenance differs in {key!r} "
                                 "(another reference wingbeat or timestep)")
    config = _merged_config(paths, dbs)
    arrays = {name: np.concatenate([db.arrays[name] for db in dbs]) for name in names}
    arrays["part"] = np.concatenate([np.full(db.n, i, np.int64) for i, db in enumerate(dbs)])
    arrays["source_index"] = np.concatenate([db.index.astype(np.int64) for db in dbs])
    rejected: dict[str, int] = {}
    for db in dbs:
        for k, v in db.rejected.items():
            rejected[k] = rejected.get(k, 0) + int(v)
    parts = [{"path": str(Path(p).resolve()), "sha256": file_sha256(p), "samples": db.n,
              "header": db.header} for p, db in zip(paths, dbs, strict=True)]
    header = {"kind": "merged", "model_hash": first.header.get("model_hash"), "seed": None,
              "config": config, "provenance": {**{k: prov0[k] for k in same if k in prov0}, "parts": parts},
              "examined": int(sum(int(db.header.get("examined", db.n)) for db in dbs))}
    n = int(arrays["part"].shape[0])
    try:
        save_database(out, header, np.arange(n, dtype=np.int64), arrays, rejected, exclusive=True)
    except FileExistsError:
        raise InputError(f"{out} appeared while merging; it is left as it is: choose another "
                         "--out") from None
    return load_database(out)


#: Sampling settings a merged database takes from its first source even where the others
#: differ: where its flights start (the cruise speed and trunk pitch the first source's
#: pre-states were drawn around); a merge built on a database keeps that database's start.
MERGE_START_KEYS = ("cruise_speed", "pitch_centre_deg")


def _merged_config(paths: list, dbs: list[Database]) -> dict:
    """The sampling configuration of a merge (what a flight reads from a database: its dove's
    induced flow, its feather table, its capture, its start): every entry its sources share,
    and :data:`MERGE_START_KEYS` from the first. Sources sampled under other feather tables
    are refused: their wingbeats are right only for the forces they were flown with."""
    configs = [db.header.get("config") or {} for db in dbs]
    tables = {c.get("table") for c in configs}
    if len(tables) > 1:
        raise InputError(f"cannot merge {paths[1]} with {paths[0]}: sampled under other feather "
                         f"tables ({', '.join(sorted(str(t) for t in tables))})")
    first = configs[0]
    out = {k: v for k, v in first.items()
           if all(k in c and same_provenance(c[k], v) for c in configs[1:])}
    out.update({k: first[k] for k in MERGE_START_KEYS if k in first})
    return out


#: Header entries that identify the run a database's samples come from: two databases that
#: share them hold the same samples (sample i depends only on the seed and i).
_RUN_KEYS = ("kind", "worker", "config_class", "config", "seed", "model_hash")


def _runs(header: dict) -> list[str]:
    """The runs a database's samples come from: its own, or a merge's sources', recursively."""
    parts = (header.get("provenance") or {}).get("parts") if header.get("kind") == "merged" else None
    if isinstance(parts, list):
        return [r for part in parts if isinstance(part, dict)
                for r in _runs(part.get("header") or {})]
    return [canonical_json({k: header.get(k) for k in _RUN_KEYS}).decode()]


def _refuse_overlap(paths: list, dbs: list[Database]) -> None:
    """Sources that hold the same samples (the same file, the same run twice, or a merge that
    has one of them) would count each sample twice in every regression: refused."""
    seen: dict[str, Any] = {}
    for p, db in zip(paths, dbs, strict=True):
        if db.header.get("seed") is None and db.header.get("kind") != "merged":
            continue  # a database saved whole (bundled, derived): no run to compare
        for run in set(_runs(db.header)):
            if run in seen:
                raise InputError(f"cannot merge {p} with {seen[run]}: both hold the samples of "
                                 "the same run (same seed and parameters); merge databases of "
                                 "other seeds")
            seen[run] = p
