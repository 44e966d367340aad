"""A signal that Python could not deliver as an exception, kept until a long loop asks.

Python runs a signal handler in the main thread between two bytecodes, wherever they are.
Where that is Python code called back from C that cannot pass an exception on (the at-fork
hooks the logging module registers, run inside ``os.fork`` and ``subprocess``; MuJoCo's
warning callback), the exception is printed and dropped, and the command carries on as if
nothing had happened. Measured: ``flapsim modes --video`` sent SIGINT on a loaded machine,
0.3 s after its video's temporary file appeared, kept rendering its 15,000 frames in 5 of
about 29 tries (and timed a CI test out); each printed a KeyboardInterrupt traceback ending
in ``logging._releaseLock``. With :func:`check` in the frame loop: 28 of 28 stopped.

So the CLI's SIGINT and SIGTERM handlers also :func:`record` the exception here, and long
loops (video frames, parallel chunks) call :func:`check`, which raises it again. The CLI
clears it when a command ends (:func:`clear`), so an in-process caller starts clean.
"""

from __future__ import annotations

_pending: type[BaseException] | None = None


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


def clear() -> None:
    """Forget any recorded signal (a command's end)."""
    global _pending
    _pending = None


def checked(fn):
    """``fn`` that first raises a recorded signal (:func:`check`): for a per-frame callback
    handed to a long simulation loop (a video writer's ``append_data``)."""

    def call(*args, **kwargs):
        check()
        return fn(*args, **kwargs)

    return call
