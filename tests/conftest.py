"""Shared fixtures: every test leaves the process-wide passive callback clean; a
virtual X display for the window tests."""

import fcntl
import os
import shutil
import subprocess
import time
from pathlib import Path

import pytest

# flapsim leaves MUJOCO_GL alone; the offscreen tests need a backend chosen before mujoco loads
if "MUJOCO_GL" not in os.environ and not os.environ.get("DISPLAY"):
    os.environ["MUJOCO_GL"] = "egl"

from flapsim.core.callbacks import DISPATCHER


def pytest_collection_modifyitems(config, items):
    """Files holding a slow test first (the order otherwise kept): ``-n auto --dist loadfile``
    hands files out in this order, and a long file handed out last kept one worker busy for
    minutes after the other had finished."""
    slow_files = {item.path for item in items if item.get_closest_marker("slow")}
    items.sort(key=lambda item: item.path not in slow_files)


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


def _x_sockets() -> set[str]:
    """The X display sockets listening on this machine: files in /tmp/.X11-unix and Linux's
    abstract ones (``@/tmp/.X11-unix/X<n>``), which another mount namespace (a container, a
    private /tmp) shares with this one while its lock files and socket files stay invisible."""
    try:
        lines = Path("/proc/net/unix").read_text().splitlines()[1:]
    except OSError:
        return set()
    return {ln.split()[-1].lstrip("@") for ln in lines if "/.X11-unix/X" in ln}


def _display_taken(n: int) -> bool:
    return (Path(f"/tmp/.X{n}-lock").exists() or Path(f"/tmp/.X11-unix/X{n}").exists()
            or f"/tmp/.X11-unix/X{n}" in _x_sockets())


def _start_xvfb() -> tuple[subprocess.Popen, int]:
    """Xvfb on a free display number in :91-:189. Choosing the number and starting the server
    hold a lock file, so two test processes (``pytest -n 2``) never pick the same number.
    A number is free when no lock file, socket file or abstract socket names it; if the server
    still exits at once (another X server took the number meanwhile), the next one is tried:
    a client of that number would otherwise reach the other server, which may refuse it (VTK
    then fell back to an EGL window no one sees). (Xvfb's own ``-displayfd`` choice gave a
    display that VTK then could not connect to under that load.)"""
    with open("/tmp/flapsim-tests-xvfb.lock", "a") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        try:
            for n in range(91, 190):
                if _display_taken(n):
                    continue
                # -noreset: by default the server resets when its last client leaves (the
                # fixture's own probe), and a client connecting during the reset was refused
                proc = subprocess.Popen(["Xvfb", f":{n}", "-screen", "0", "1280x800x24", "-nolisten",
                                         "tcp", "-noreset"], stdout=subprocess.DEVNULL,
                                        stderr=subprocess.DEVNULL)
                # the lock is held until the server has claimed the number
                for _ in range(200):
                    if Path(f"/tmp/.X11-unix/X{n}").exists() or proc.poll() is not None:
                        break
                    time.sleep(0.05)
                time.sleep(0.2)  # a server refused the number exits right after binding
                if proc.poll() is None:
                    return proc, n
            raise RuntimeError("no free X display number in :91-:189")
        finally:
            fcntl.flock(lock, fcntl.LOCK_UN)


class XDisplay:
    """A running Xvfb display; processes started with :meth:`spawn` are stopped with it."""

    def __init__(self, name: str) -> None:
        self.name = name
        self.procs: list[subprocess.Popen] = []

    def env(self, **extra: str) -> dict:
        """The environment of a process drawing on this display and nowhere else: DISPLAY
        named explicitly (another X server may be the session's), no Wayland, MuJoCo's
        viewer on GLFW's X11 library, VTK (pyvista) on an X window rather than its EGL
        fallback, and pyvista not forced off screen."""
        env = {k: v for k, v in os.environ.items()
               if k not in ("WAYLAND_DISPLAY", "XDG_SESSION_TYPE", "PYVISTA_OFF_SCREEN")}
        env.update(DISPLAY=self.name, MUJOCO_GL="glfw", PYGLFW_LIBRARY_VARIANT="x11",
                   VTK_DEFAULT_OPENGL_WINDOW="vtkXOpenGLRenderWindow")
        env.update(extra)
        return env

    def spawn(self, args: list[str], env: dict) -> subprocess.Popen:
        proc = subprocess.Popen(args, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT)
        self.procs.append(proc)
        return proc

    def window(self, app: subprocess.Popen, env: dict, timeout: float = 60.0) -> str:
        """The id of ``app``'s MuJoCo window once it is open (the test fails with the app's
        output if it never opens), after a second for the first frames to draw and the key
        callback to be live."""
        windows: list[str] = []
        deadline = time.monotonic() + timeout
        while not windows and time.monotonic() < deadline and app.poll() is None:
            found = subprocess.run(["xdotool", "search", "--name", "MuJoCo"], env=env,
                                   capture_output=True, text=True, timeout=10)
            windows = found.stdout.split()
            time.sleep(0.2)
        assert windows, app.communicate(timeout=30)[0].decode()[-2000:]
        time.sleep(1.0)
        return windows[0]

    def geometry(self, window: str, env: dict) -> tuple[int, int, int, int]:
        """The window's x, y, width and height on the display, pixels."""
        geo = subprocess.run(["xdotool", "getwindowgeometry", "--shell", window], env=env,
                             capture_output=True, text=True, check=True, timeout=10).stdout
        g = dict(line.split("=") for line in geo.split() if "=" in line)
        return int(g["X"]), int(g["Y"]), int(g["WIDTH"]), int(g["HEIGHT"])


@pytest.fixture
def xvfb_display():
    """A fresh Xvfb display (:class:`XDisplay`), stopped afterwards with everything spawned
    on it; skips the test when Xvfb or xdotool is not installed (.ci/run installs both)."""
    if shutil.which("Xvfb") is None or shutil.which("xdotool") is None:
        pytest.skip("Xvfb and xdotool are needed to open a window on a virtual display")
    xvfb, n = _start_xvfb()
    display = XDisplay(f":{n}")
    try:
        for _ in range(200):
            if Path(f"/tmp/.X11-unix/X{n}").exists():
                break
            time.sleep(0.05)
        assert Path(f"/tmp/.X11-unix/X{n}").exists(), "Xvfb did not start within 10 s"
        # the socket appears before the server takes clients: under load a window opened at
        # once got "bad X server connection"; wait until a client is answered
        env = display.env()
        for _ in range(100):
            ok = subprocess.run(["xdotool", "getdisplaygeometry"], env=env, capture_output=True,
                                timeout=10).returncode == 0
            if ok:
                break
            time.sleep(0.1)
        assert ok, "Xvfb took no client within 10 s"
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


@pytest.fixture
def sigterm_with_workers():
    """``run(cmd, cwd, settle_s)``: start a ``flapsim`` command line (the repository on
    PYTHONPATH), wait until it has two worker processes, let them work ``settle_s``, send
    SIGTERM, and return (exit status, stderr, the workers still alive half a second later)."""
    import os
    import signal
    import sys

    root = Path(__file__).resolve().parents[1]

    def alive(pid: str) -> bool:
        try:
            return "zombie" not in Path(f"/proc/{pid}/status").read_text().lower()
        except OSError:
            return False

    def run(args: list[str], cwd: Path, settle_s: float) -> tuple[int, str, list[str]]:
        proc = subprocess.Popen([sys.executable, "-m", "flapsim.cli.main", *args], cwd=cwd,
                                env=dict(os.environ, PYTHONPATH=str(root)),
                                stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        try:
            t_end = time.monotonic() + 120
            kids: list[str] = []
            while len(kids) < 2:  # both workers started
                assert proc.poll() is None and time.monotonic() < t_end, proc.communicate()
                time.sleep(0.1)
                kids = subprocess.run(["pgrep", "-P", str(proc.pid)], capture_output=True,
                                      text=True).stdout.split()
            time.sleep(settle_s)
            proc.send_signal(signal.SIGTERM)
            _, err = proc.communicate(timeout=60)
        finally:
            if proc.poll() is None:
                proc.kill()
        time.sleep(0.5)
        return proc.returncode, err, [k for k in kids if alive(k)]

    return run

