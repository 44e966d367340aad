"""A signal that Python could not deliver as an exception, kept until a long loop asks.

Python runs a signal handler in the main thread between two bytecodes, wherever they are.
Where that is Python code called back from C that cannot pass an exception on (the at-fork
hooks the logging module registers, run inside ``os.fork`` and ``subprocess``; MuJoCo's
warning callback), the exception is printed and dropped, and the command carries on as if
nothing had happened. Measured: ``flapsim modes --video`` sent SIGINT on a loaded machine,
0.3 s after its video's temporary file appeared, kept rendering its 15,000 frames in 5 of
about 29 tries (and timed a CI test out); each printed a KeyboardInterrupt traceback ending
in ``logging._releaseLock``. With :func:`check` in the frame loop: 28 of 28 stopped.

So the CLI's SIGINT and SIGTERM handlers (:func:`signalled`) also :func:`record` the
exception here, and long loops (video frames, parallel chunks) call :func:`check`, which
raises it again. The CLI clears it when a command ends (:func:`clear`), so an in-process
caller starts clean.

Where a signal must not be raised at all, :func:`deferred` holds it until its block ends:
around each frame handed to a video writer (:func:`checked`). Raised inside the writer (after
ffmpeg's fork but before ``Popen`` returned, or in a pipe write), it leaves ffmpeg running, or
killed without a wait, and ffmpeg then created the temporary video file again after the
cleanup had removed it (measured: 1 of 40 SIGTERMs on a loaded machine left a ``.x.mp4.*``
file behind).
"""

from __future__ import annotations

import contextlib
from collections.abc import Callable, Iterator
from typing import Any

_pending: type[BaseException] | None = None
_deferring: bool = False


class Terminated(BaseException):
    """SIGTERM, raised in the main thread so that temporary files are cleaned up (a
    BaseException, like KeyboardInterrupt, so that ``except Exception`` does not catch it)."""


def signalled(exc_type: type[BaseException]) -> None:
    """What a signal handler does: record ``exc_type`` and raise it, unless a
    :func:`deferred` block holds it (it is raised when the block ends)."""
    record(exc_type)
    if not _deferring:
        raise exc_type()


@contextlib.contextmanager
def deferred() -> Iterator[None]:
    """Signals that arrive in the block are recorded, not raised, and raised as it ends."""
    global _deferring
    outer, _deferring = _deferring, True
    try:
        yield
    finally:
        _deferring = outer
    if not outer:
        check()


def record(exc_type: type[BaseException]) -> None:
    """Remember that a signal asked for ``exc_type`` (called by the signal handler before
    it raises)."""
    global _pending
    _pending = exc_type


def check() -> None:
    """Raise the recorded exception, if a signal left one (once: it is then cleared)."""
    global _pending
    exc, _pending = _pending, None
    if exc is not None:
        raise exc()


def pending() -> type[BaseException] | None:
    """The exception a signal recorded since the command began and :func:`check` has not
    raised since, if any (not cleared: the handler's own raise leaves it recorded). A signal
    raised inside a C call that converts it into an error of its own (ctypes wraps an
    exception raised while it converts an argument in ``ArgumentError``) leaves the signal
    recorded: the caller can tell the wrapped error for what it is."""
    return _pending


def clear() -> None:
    """Forget any recorded signal (a command's end)."""
    global _pending
    _pending = None


def checked(fn: Callable[..., Any]) -> Callable[..., Any]:
    """``fn`` for a per-frame loop, made safe against signals: each call first raises a
    recorded signal (:func:`check`), and runs :func:`deferred`. Made for a video writer's
    ``append_data``: its first frame forks ffmpeg, and every frame blocks in a pipe write to
    it; a signal raised inside the writer makes it kill ffmpeg without waiting, and ffmpeg,
    still starting, then created the temporary video after the cleanup had removed it (1 of
    40 SIGTERMs under load left ``.x.mp4.*``, and one CI-like run with three jobs on two
    cores). Raised after the frame, it lets the writer close ffmpeg and wait for it."""

    def call(*args, **kwargs):
        check()
        with deferred():
            return fn(*args, **kwargs)

    return call
