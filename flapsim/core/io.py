"""Atomic file output: results never appear half-written (write a temporary, then rename)."""

from __future__ import annotations

import contextlib
import hashlib
import json
import os
import tempfile
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np

from flapsim.core import interrupts
from flapsim.core.errors import InputError


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


@contextlib.contextmanager
def atomic_path(path: str | os.PathLike, suffix: str | None = None) -> Iterator[Path]:
    """Yield a temporary path next to ``path``; rename it onto ``path`` only on success.

    ``suffix`` keeps the extension libraries look at (``np.savez`` appends ``.npz``
    when it is missing, video writers pick a codec from it).
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
        yield tmp_path
        os.replace(tmp_path, target)
    finally:
        if tmp_path is not None and tmp_path.exists():
            tmp_path.unlink()


@contextlib.contextmanager
def atomic_video(path: str | os.PathLike, **writer_kwargs: Any) -> Iterator[Any]:
    """A video at ``path`` written through a temporary (:func:`atomic_path`); yields the
    per-frame callable (an imageio writer's ``append_data``, :func:`flapsim.core.interrupts.checked`).

    The writer is closed before the temporary is renamed or removed, on an exception too:
    imageio's ``with writer`` skips ``close()`` when its block raised, and ffmpeg, closed only
    when the writer was collected, wrote the temporary video after the cleanup had removed it
    (4 of 30 SIGTERMs under load left a one-frame ``.x.mp4.*``)."""
    import imageio.v2 as imageio

    with atomic_path(path) as tmp:
        writer = imageio.get_writer(str(tmp), **writer_kwargs)
        try:
            yield interrupts.checked(writer.append_data)
        finally:
            writer.close()


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
