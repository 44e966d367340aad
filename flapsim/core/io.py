"""Atomic file output: results never appear half-written (write a temporary, then rename)."""

from __future__ import annotations

import contextlib
import errno
import hashlib
import json
import os
import stat
import tempfile
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np

from flapsim.core import interrupts
from flapsim.core.errors import DataFileError, InputError, OutputError


def _temporary(target: Path, suffix: str | None) -> Path:
    """Create the empty temporary file :func:`atomic_path` writes ``target`` through, beside it."""
    parent = target.parent if str(target.parent) else Path(".")
    fd, tmp = tempfile.mkstemp(prefix=f".{target.name}.",
                               suffix=suffix if suffix is not None else target.suffix, dir=parent)
    os.close(fd)
    return Path(tmp)


def write_problem(path: str | os.PathLike, suffix: str | None = None) -> str | None:
    """Why ``path`` cannot be written, or None: the temporary file :func:`atomic_path`
    would write it through is created beside it and removed again. Permission bits say
    too little (``/proc`` is writable for its owner, yet no file can be created in it; a
    read-only mount or a full quota neither), so this is the proof, before any work."""
    try:
        with interrupts.deferred():
            tmp = _temporary(Path(path), suffix)
            tmp.unlink()
    except OSError as exc:
        return exc.strerror or str(exc)
    return None


#: errno values that say the file system refused to store what was written
_NO_ROOM = {errno.ENOSPC, errno.EDQUOT, errno.EFBIG, errno.EIO, errno.EROFS}


#: What an output the system refused leaves, said after the reason (see :func:`atomic_path`).
NOTHING_WRITTEN = "nothing was written there (free space, or choose another place)"


def output_failed(target: Path, exc: OSError, left: str = NOTHING_WRITTEN) -> OutputError:
    """The one-line error for an output the system refused to store; ``left`` says what
    the user still has and what to do."""
    return OutputError(f"cannot write {target}: {exc.strerror or exc}; {left}")


@contextlib.contextmanager
def atomic_path(path: str | os.PathLike, suffix: str | None = None,
                exclusive: bool = False, left: str = NOTHING_WRITTEN) -> Iterator[Path]:
    """Yield a temporary path next to ``path``; rename it onto ``path`` only on success.

    ``suffix`` keeps the extension libraries look at (``np.savez`` appends ``.npz``
    when it is missing, video writers pick a codec from it). ``exclusive``: never replace
    a file at ``path`` (FileExistsError; a hard link, atomic like the rename). A write the
    file system refuses (a full disk, a quota) is an :class:`OutputError` naming ``path``,
    then ``left``: what is left of the user's work (a file rewritten in place is as it was).
    """
    target = Path(path)
    parent = target.parent if str(target.parent) else Path(".")
    if not parent.exists():
        raise InputError(f"cannot write {target}: folder {parent} does not exist (create it first)")
    tmp_path: Path | None = None
    try:
        # a signal between mkstemp and this try left the temporary file behind (seen at
        # SIGTERM on a loaded machine): the CLI's handlers hold it until the name is kept
        with interrupts.deferred():
            try:
                tmp_path = _temporary(target, suffix)
            except OSError as exc:
                raise InputError(f"cannot write {target}: {exc.strerror or exc}") from exc
        # mkstemp creates 0600; give the result the permissions a plain open() would
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(tmp_path, 0o666 & ~umask)
        try:
            yield tmp_path
            if exclusive:
                os.link(tmp_path, target)
            else:
                os.replace(tmp_path, target)
        except OSError as exc:
            if exc.errno in _NO_ROOM:
                raise output_failed(target, exc, left) from None
            raise
    finally:
        if tmp_path is not None and tmp_path.exists():
            tmp_path.unlink()


#: Containers whose structure :func:`check_mp4` reads.
MP4_SUFFIXES = (".mp4", ".m4v", ".mov")


def check_mp4(path: str | os.PathLike) -> str | None:
    """Why the MP4/QuickTime file at ``path`` is unplayable, or None: its top-level boxes must
    tile the file and hold a ``moov`` (the index a player needs; ffmpeg writes it last, so an
    encoder stopped by a full disk leaves a file without it)."""
    size = os.path.getsize(path)
    seen = set()
    pos = 0
    with open(path, "rb") as fh:
        while pos < size:
            fh.seek(pos)
            head = fh.read(16)
            if len(head) < 8:
                return f"a box header is cut short at byte {pos}"
            length, kind = int.from_bytes(head[:4], "big"), head[4:8]
            if length == 1:
                if len(head) < 16:
                    return f"a box header is cut short at byte {pos}"
                length = int.from_bytes(head[8:16], "big")
            elif length == 0:
                length = size - pos
            if length < 8 or pos + length > size:
                return f"the {kind.decode('latin-1')!r} box at byte {pos} is cut short"
            seen.add(kind)
            pos += length
    if b"moov" not in seen:
        return "it has no index (moov box)"
    return None


@contextlib.contextmanager
def atomic_video(path: str | os.PathLike, **writer_kwargs: Any) -> Iterator[Any]:
    """A video at ``path`` written through a temporary (:func:`atomic_path`); yields the
    per-frame callable (an imageio writer's ``append_data``, :func:`flapsim.core.interrupts.checked`).

    The writer is closed before the temporary is renamed or removed, on an exception too:
    imageio's ``with writer`` skips ``close()`` when its block raised, and ffmpeg, closed only
    when the writer was collected, wrote the temporary video after the cleanup had removed it
    (4 of 30 SIGTERMs under load left a one-frame ``.x.mp4.*``).

    imageio neither checks ffmpeg's exit status nor the file it left: on a full disk ffmpeg
    printed "No space left on device", exited 1, and an MP4 without its index was kept as
    the video. So a frame the encoder refused, its exit status and the container's structure
    (:func:`check_mp4`) are checked; each failure is an :class:`OutputError` naming ``path``,
    and the temporary is removed."""
    import imageio.v2 as imageio

    target = Path(path)
    with atomic_path(path) as tmp:
        writer = imageio.get_writer(str(tmp), **writer_kwargs)
        append = interrupts.checked(writer.append_data)
        proc: list[Any] = []

        def frame(*args: Any, **kwargs: Any) -> Any:
            try:
                out = append(*args, **kwargs)
            except OSError as exc:  # imageio's own IOError: the pipe to a stopped ffmpeg
                first = str(exc).strip().splitlines()[0] if str(exc).strip() else "stopped"
                raise OutputError(f"cannot write {target}: the video encoder stopped ({first}); "
                                  "is the disk full?") from None
            if not proc:
                gen = getattr(writer, "_write_gen", None)  # imageio's ffmpeg frame generator
                p = getattr(getattr(gen, "gi_frame", None), "f_locals", {}).get("p")
                if p is not None:
                    proc.append(p)
            return out

        try:
            yield frame
        finally:
            writer.close()
        status = proc[0].returncode if proc else None
        if status:
            how = f"exit status {status}" if status > 0 else f"signal {-status}"
            raise OutputError(f"cannot write {target}: the video encoder (ffmpeg) failed ({how}); "
                              "is the disk full? nothing was written there")
        if target.suffix.lower() in MP4_SUFFIXES and tmp.stat().st_size:
            why = check_mp4(tmp)
            if why is not None:
                raise OutputError(f"cannot write {target}: the video is unplayable ({why}); is "
                                  "the disk full? nothing was written there")


def _jsonable(obj: Any) -> Any:
    if isinstance(obj, dict):
        return {str(k): _jsonable(v) for k, v in obj.items()}
    if isinstance(obj, list | tuple):
        return [_jsonable(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return _jsonable(obj.tolist())
    if isinstance(obj, np.integer):
        return int(obj)
    if isinstance(obj, np.floating | float):
        f = float(obj)
        return f if np.isfinite(f) else None
    if isinstance(obj, np.bool_):
        return bool(obj)
    if isinstance(obj, Path):
        return str(obj)
    return obj


def write_json(path: str | os.PathLike, data: dict) -> None:
    """Write ``data`` as JSON atomically (numpy scalars/arrays converted; NaN -> null)."""
    text = json.dumps(_jsonable(data), indent=2, sort_keys=False) + "\n"
    with atomic_path(path) as tmp:
        tmp.write_text(text)


def save_npz(path: str | os.PathLike, **arrays: Any) -> None:
    """``np.savez_compressed`` atomically (no pickles: object arrays are refused)."""
    for name, a in arrays.items():
        if np.asarray(a).dtype == object:
            raise InputError(f"cannot save {name!r} to {path}: object arrays need pickles")
    with atomic_path(path, suffix=".npz") as tmp:
        np.savez_compressed(tmp, **arrays)


def file_sha256(path: str | Path) -> str:
    """Content hash of a file (provenance of databases built from other databases)."""

    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


#: The largest data file (journal, table, path) read whole: a runaway file is refused in one
#: line rather than read until memory runs out.
MAX_READ_BYTES = 1 << 31


def read_regular(path: str | os.PathLike, what: str, limit: int = MAX_READ_BYTES) -> bytes:
    """The bytes of the regular file ``path``, read with a size cap. A device, FIFO or
    folder is refused (reading ``/dev/zero`` grew without end until the system killed the
    process), as is a file over ``limit`` bytes: a one-line :class:`DataFileError` naming it."""
    p = Path(path)
    try:
        st = p.stat()
    except FileNotFoundError:
        raise DataFileError(f"{what} {p} does not exist") from None
    except OSError as exc:
        raise DataFileError(f"cannot read {what} {p}: {exc.strerror or exc}") from None
    if not stat.S_ISREG(st.st_mode):
        kind = "a folder" if stat.S_ISDIR(st.st_mode) else "not a regular file (a device, pipe or socket)"
        raise DataFileError(f"{what} {p} is {kind}; name a file")
    try:
        with open(p, "rb") as fh:
            data = fh.read(limit + 1)
    except OSError as exc:
        raise DataFileError(f"cannot read {what} {p}: {exc.strerror or exc}") from None
    if len(data) > limit:
        raise DataFileError(f"{what} {p} is larger than {limit} bytes; is it the right file?")
    return data
