"""Shared fixtures: every test leaves the process-wide passive callback clean; a
virtual X display for the window tests."""

import shutil
import subprocess
import time
from pathlib import Path

import pytest

from flapsim.sim.callbacks import DISPATCHER


@pytest.fixture(autouse=True)
def _clean_dispatcher(request):
    yield
    # a module that shares one flight between its tests (``SHARED_FLIGHT = True``) keeps its
    # force providers registered until the module is done
    if not getattr(request.module, "SHARED_FLIGHT", False):
        DISPATCHER.clear()


@pytest.fixture(scope="module", autouse=True)
def _clean_dispatcher_after_module():
    yield
    DISPATCHER.clear()


def _free_display() -> int:
    for n in range(91, 190):
        if not Path(f"/tmp/.X{n}-lock").exists() and not Path(f"/tmp/.X11-unix/X{n}").exists():
            return n
    raise RuntimeError("no free X display number in :91-:189")


class XDisplay:
    """A running Xvfb display; processes started with :meth:`spawn` are stopped with it."""

    def __init__(self, name: str) -> None:
        self.name = name
        self.procs: list[subprocess.Popen] = []

    def spawn(self, args: list[str], env: dict) -> subprocess.Popen:
        proc = subprocess.Popen(args, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT)
        self.procs.append(proc)
        return proc


@pytest.fixture
def xvfb_display():
    """A fresh Xvfb display (:class:`XDisplay`), stopped afterwards with everything spawned
    on it; skips the test when Xvfb or xdotool is not installed (.ci/run installs both)."""
    if shutil.which("Xvfb") is None or shutil.which("xdotool") is None:
        pytest.skip("Xvfb and xdotool are needed to open a window on a virtual display")
    n = _free_display()
    xvfb = subprocess.Popen(["Xvfb", f":{n}", "-screen", "0", "1280x800x24", "-nolisten", "tcp"],
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    display = XDisplay(f":{n}")
    try:
        for _ in range(200):
            if Path(f"/tmp/.X11-unix/X{n}").exists():
                break
            time.sleep(0.05)
        assert Path(f"/tmp/.X11-unix/X{n}").exists(), "Xvfb did not start within 10 s"
        yield display
    finally:
        for proc in [*display.procs, xvfb]:
            _stop(proc)


def _stop(proc: subprocess.Popen) -> None:
    """Terminate a child process (SIGTERM lets Xvfb remove its lock file and socket)."""
    if proc.poll() is None:
        proc.terminate()
        try:
            proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait(timeout=10)
