"""One validation layer for the command line: numbers, input files and output paths are
checked while the arguments are parsed, before any model is loaded or simulated.

How a command uses it (in its ``add_arguments(parser)``)::
    from flapsim.core.validate import add_input_arg, add_output_arg, quantity, vector

    p.add_argument("--seconds", type=quantity("seconds"), default=20.0, help="...")
    p.add_argument("--current", type=vector("current", 3), default=(0, 0, 0), help="...")
    add_input_arg(p, "--path", help="a path file")                 # must exist, be a file
    add_output_arg(p, "--video", kinds=(".mp4", ".gif"), renders=True, help="...")

* :func:`quantity` / :func:`vector` / :func:`integer` are argparse ``type=`` functions: a
  value outside the shared range (:data:`RANGES`, the same for every command) is a one-line
  argparse error with the range in it (exit status 2).
* :func:`add_output_arg` declares an output path; ``flapsim.cli.main`` calls
  :func:`check_outputs` after parsing and before ``run(args)``: the folder exists and is
  writable, the path is not a folder, has one of ``kinds``, is not one of the inputs nor
  another output; ``-`` means stdout where ``stdout=True`` (``--json -``); ``renders=True``
  checks that offscreen rendering (``MUJOCO_GL``) is usable when the option is given.
* :func:`add_input_arg` declares an input file (checked to exist; outputs may not name it).
  An argument that is a name *or* a file (``--stroke crawl`` / ``--stroke my.toml``) is
  declared with ``may_be_name=True``: checked only when it is not a known name.
* ``--json`` is declared by the CLI for every command. A command written later (``eval``,
  ``view``) gets all of this by declaring its arguments with these helpers; nothing else.
* The command module itself may set ``SEED_HELP`` (say "--seed changes nothing" where it
  does not) and ``EXIT_STATUS`` (extra lines for its ``--help``), and a batch command's
  ``run`` returns ``"exit_status": 1`` when some of its runs failed (the CLI exits with it
  after writing the JSON); see :mod:`flapsim.cli.main`.

Data files: every loader of a file a user passes or flapsim reads (configuration, stroke,
path, trajectory, capture, gait and label files, databases) hands what it parsed to
:func:`require_finite`: a NaN or an infinity anywhere in it is a one-line
:class:`~flapsim.core.errors.DataFileError` naming the file and the entry (an MJCF model's
compiled arrays are searched by :func:`nonfinite_entry` in :mod:`flapsim.core.loading`).

``MUJOCO_GL`` (see :func:`gl_problem`): an unknown value, or a backend whose library is
missing, is noted when the CLI starts (rendering is then disabled so ``import mujoco``
works and ``flapsim --help`` prints) and becomes a one-line error only when a command
needs to render.
"""

from __future__ import annotations

import argparse
import ctypes.util
import importlib.util
import math
import os
import platform
import socket
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from flapsim.core.errors import DataFileError, InputError
from flapsim.core.io import write_problem


@dataclass(frozen=True)
class Range:
    """A closed or half-open interval of a physical quantity."""

    lo: float
    hi: float
    unit: str
    lo_open: bool = False
    """True: ``lo`` itself is excluded (a duration of 0 s means nothing)."""

    def contains(self, v: float) -> bool:
        if not math.isfinite(v):
            return False
        return (v > self.lo if self.lo_open else v >= self.lo) and v <= self.hi

    def describe(self) -> str:
        lo = f"{self.lo:g}"
        return (f"{'> ' + lo + ' and <= ' if self.lo_open else lo + '..'}{self.hi:g}"
                f"{' ' + self.unit if self.unit else ''}")


#: The sane ranges shared by every command (and by ``flapsim sweep``'s values).
RANGES: dict[str, Range] = {
    "seconds": Range(0.0, 3600.0, "s", lo_open=True),
    "fps": Range(1.0, 240.0, "frames/s"),
    "density": Range(100.0, 5000.0, "kg/m^3"),
    "lungs": Range(0.0, 6.0, "L"),
    "rate": Range(0.05, 5.0, "cycles/s"),
    "friction": Range(0.0, 1000.0, "N s/m^3"),
    "current": Range(-5.0, 5.0, "m/s"),
    "flow_ratio": Range(0.0, 1.0, ""),
    "timestep": Range(1e-4, 0.01, "s"),
    "mass": Range(1e-6, 1000.0, "kg"),
    "side": Range(1e-3, 10.0, "m"),
    "position": Range(-1000.0, 1000.0, "m"),
    "velocity": Range(-10.0, 10.0, "m/s"),
    "source": Range(-10.0, 10.0, "m^3/s"),
    "circulation": Range(-50.0, 50.0, "m^2/s"),
    "lookahead": Range(0.0, 100.0, "m", lo_open=True),
    "radius": Range(0.5, 1000.0, "m"),
    "angle_deg": Range(-360.0, 360.0, "deg"),
    "freq": Range(0.0, 50.0, "Hz", lo_open=True),
    "scale": Range(0.0, 1000.0, "", lo_open=True),
    "stiffness": Range(0.0, 1e6, "N m/rad", lo_open=True),
    "soft_limit_deg": Range(0.0, 90.0, "deg"),
    "polygons": Range(1, 100_000, "polygons"),
    "cycles": Range(0.0, 100.0, "cycles", lo_open=True),
    # a dove's start: pitched past vertical is no start; the tail bends within +-40 deg
    # (its joint range, as training checks it)
    "pitch_deg": Range(-90.0, 90.0, "deg"),
    "roll_deg": Range(-90.0, 90.0, "deg"),
    "tail_bias_deg": Range(-40.0, 40.0, "deg"),
    "speed": Range(0.0, 30.0, "m/s"),
}


def check_quantity(name: str, value: float, flag: str | None = None) -> float:
    """``value`` if it lies in ``RANGES[name]``, else a one-line :class:`InputError`."""
    r = RANGES[name]
    v = float(value)
    if not r.contains(v):
        raise InputError(f"{flag or '--' + name} must be {r.describe()}, got {value:g}")
    return v


def _float(text: str, what: str) -> float:
    try:
        return float(text)
    except (TypeError, ValueError):
        raise argparse.ArgumentTypeError(f"expected {what}, got {text!r}") from None


def quantity(name: str) -> Callable[[str], float]:
    """argparse ``type=``: a finite number within ``RANGES[name]``."""
    r = RANGES[name]

    def parse(text: str) -> float:
        v = _float(text, f"a number ({r.describe()})")
        if not r.contains(v):
            raise argparse.ArgumentTypeError(f"must be {r.describe()}, got {text}")
        return v

    parse.__name__ = name
    return parse


def vector(name: str | Sequence[str], n: int) -> Callable[[str], tuple[float, ...]]:
    """argparse ``type=``: ``n`` comma-separated numbers, each within its range
    (``name`` one range for all, or one range name per component)."""
    names = [name] * n if isinstance(name, str) else list(name)
    if len(names) != n:
        raise ValueError("one range name per component")

    count = {2: "two", 3: "three", 4: "four"}.get(n, str(n))
    what = f"{count} finite comma-separated numbers"

    def parse(text: str) -> tuple[float, ...]:
        parts = [s.strip() for s in str(text).split(",")]
        if len(parts) != n:
            raise argparse.ArgumentTypeError(f"expected {what}, got {text!r}")
        out = []
        for part, nm in zip(parts, names, strict=True):
            r = RANGES[nm]
            try:
                v = float(part)
            except ValueError:
                raise argparse.ArgumentTypeError(f"expected {what}, got {text!r}") from None
            if not r.contains(v):
                raise argparse.ArgumentTypeError(f"{part} in {text!r} must be {r.describe()}")
            out.append(v)
        return tuple(out)

    parse.__name__ = "vector"
    return parse


def integer(lo: int, hi: int, unit: str = "") -> Callable[[str], int]:
    """argparse ``type=``: an integer within ``lo..hi``."""

    def parse(text: str) -> int:
        try:
            v = int(str(text).strip())
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected a whole number {lo}..{hi}, got {text!r}") \
                from None
        if not lo <= v <= hi:
            raise argparse.ArgumentTypeError(f"must be {lo}..{hi}{' ' + unit if unit else ''}, got {v}")
        return v

    parse.__name__ = "integer"
    return parse


def integer_list(lo: int, hi: int, unit: str = "") -> Callable[[str], list[int]]:
    """argparse ``type=``: comma-separated integers, each within ``lo..hi``."""
    one = integer(lo, hi, unit)

    def parse(text: str) -> list[int]:
        parts = [s for s in str(text).split(",") if s.strip()]
        if not parts:
            raise argparse.ArgumentTypeError("expected comma-separated whole numbers, got nothing")
        return [one(s) for s in parts]

    parse.__name__ = "integer list"
    return parse


# -- numbers read from data files ---------------------------------------------------------

def nonfinite_entry(value: object, where: str = "") -> tuple[str, float] | None:
    """The place (``keys.arm[2]``, ``angles[40, 3]``) and value of the first NaN or infinity
    in ``value``, a parsed data file: dicts, lists and tuples are walked, numpy arrays
    searched, numbers tested, anything else (text, booleans, None) is no number. None when
    every number is finite."""
    if isinstance(value, bool | str | bytes) or value is None:
        return None
    if isinstance(value, float | np.floating):
        return None if math.isfinite(value) else (where or "the value", float(value))
    if isinstance(value, np.ndarray):
        if value.dtype.kind != "f":
            return None
        bad = np.argwhere(~np.isfinite(value))
        if not len(bad):
            return None
        at = tuple(int(i) for i in bad[0])
        index = f"[{', '.join(map(str, at))}]" if at else ""
        return f"{where or 'the array'}{index}", float(value[at])
    if isinstance(value, dict):
        for k, v in value.items():
            found = nonfinite_entry(v, f"{where}.{k}" if where else str(k))
            if found:
                return found
        return None
    if isinstance(value, list | tuple):
        for i, v in enumerate(value):
            found = nonfinite_entry(v, f"{where}[{i}]")
            if found:
                return found
    return None


def require_finite(value: object, file: str | os.PathLike, where: str = "",
                   fix: str = "correct that entry") -> None:
    """A one-line :class:`DataFileError` naming ``file`` and the entry when ``value`` (a data
    file's parsed contents, or part of it at ``where``) holds a NaN or an infinity: the one
    check every loader of a data file makes. Such a number was taken before and turned into
    motion that never steered or a simulation that diverged far from its cause."""
    found = nonfinite_entry(value, where)
    if found is not None:
        place, v = found
        raise DataFileError(f"{file}: {place} is {v!r}, a non-finite number (NaN or infinity); "
                            f"{fix}")


# -- files -------------------------------------------------------------------------------

@dataclass(frozen=True)
class _Output:
    dest: str
    flag: str
    kinds: tuple[str, ...] | None
    renders: bool
    stdout: bool


@dataclass(frozen=True)
class _Input:
    dest: str
    flag: str
    may_be_name: bool


def _declare(parser: argparse.ArgumentParser, key: str, spec: object) -> None:
    """Add ``spec`` to the parser's default ``key`` (a tuple). Argument groups share their
    parser's defaults, so a declaration made on a (mutually exclusive) group counts too."""
    parser.set_defaults(**{key: tuple(parser.get_default(key) or ()) + (spec,)})


def add_output_arg(parser: argparse.ArgumentParser, flag: str, *, kinds: Sequence[str] | None = None,
                   renders: bool = False, stdout: bool = False, **kwargs) -> argparse.Action:
    """``parser.add_argument(flag, **kwargs)`` for an output path, checked by
    :func:`check_outputs` before the command runs (``kinds``: allowed suffixes)."""
    kwargs.setdefault("metavar", "PATH")
    action = parser.add_argument(flag, **kwargs)
    _declare(parser, "_outputs", _Output(action.dest, flag, tuple(k.lower() for k in kinds)
                                         if kinds else None, renders, stdout))
    return action


def add_input_arg(parser: argparse.ArgumentParser, flag: str, *, may_be_name: bool = False,
                  **kwargs) -> argparse.Action:
    """``parser.add_argument(flag, **kwargs)`` for an input file that must exist (unless
    ``may_be_name`` and it does not look like a path: ``--stroke crawl``)."""
    action = parser.add_argument(flag, **kwargs)
    _declare(parser, "_inputs", _Input(action.dest, flag, may_be_name))
    return action


def _looks_like_path(text: str) -> bool:
    return os.sep in text or "." in Path(text).name or Path(text).exists()


def check_inputs(args: argparse.Namespace) -> list[tuple[str, Path]]:
    """Every declared input exists and is a readable file; returns (flag, resolved path)."""
    found = []
    for spec in getattr(args, "_inputs", ()):
        value = getattr(args, spec.dest, None)
        values = value if isinstance(value, list) else [value]
        for v in values:
            if v is None:
                continue
            text = str(v)
            if spec.may_be_name and not _looks_like_path(text):
                continue
            p = Path(text).expanduser()
            if not p.exists():
                raise InputError(f"{spec.flag} {text} does not exist")
            if p.is_dir():
                raise InputError(f"{spec.flag} {text} is a folder; name a file")
            if not p.is_file():  # reading /dev/zero grew until the system killed flapsim
                raise InputError(f"{spec.flag} {text} is not a regular file (a device, pipe or "
                                 "socket); name a file")
            if not os.access(p, os.R_OK):
                raise InputError(f"{spec.flag} {text}: not readable (permissions)")
            found.append((spec.flag, p.resolve()))
    return found


def check_output_path(flag: str, value: str, kinds: Sequence[str] | None = None) -> Path:
    """One output path: suffix, not a folder, folder exists, and the temporary file the
    output is written through (:func:`flapsim.core.io.atomic_path`) can be created there."""
    p = Path(str(value)).expanduser()
    if kinds and p.suffix.lower() not in kinds:
        raise InputError(f"{flag} {value}: must end in {' or '.join(kinds)}")
    if p.is_dir() or str(value).endswith(os.sep):
        raise InputError(f"{flag} {value} is a folder; name a file in it")
    if p.exists() and not p.is_file():  # a device (/dev/full) is no place for a result
        raise InputError(f"{flag} {value} is not a regular file (a device, pipe or socket); "
                         "name a file")
    parent = p.parent if str(p.parent) else Path(".")
    if not parent.exists():
        raise InputError(f"{flag} {value}: folder {parent} does not exist (create it first)")
    if not parent.is_dir():
        raise InputError(f"{flag} {value}: {parent} is not a folder")
    if not os.access(parent, os.W_OK | os.X_OK):
        raise InputError(f"{flag} {value}: folder {parent} is not writable")
    problem = write_problem(p)  # the permission bits can say yes where no file can be made
    if problem is not None:
        raise InputError(f"{flag} {value}: cannot create a file in {parent} ({problem})")
    return p


def declare_options(parser: argparse.ArgumentParser) -> None:
    """Remember the parser's options (dest -> flag) for :func:`check_not_empty`; called once
    every option is added."""
    parser.set_defaults(_options=tuple((a.dest, a.option_strings[-1]) for a in parser._actions
                                       if a.option_strings and a.dest != "help"))


def check_not_empty(args: argparse.Namespace) -> None:
    """An option given an empty value (``--sizes ""``) is refused, for every command: a
    command would otherwise take it as "not given" and do something else than asked."""
    for dest, flag in getattr(args, "_options", ()):
        value = getattr(args, dest, None)
        values = value if isinstance(value, list) else [value]
        if any(isinstance(v, str) and not v.strip() for v in values):
            raise InputError(f"{flag} is given an empty value; give one, or leave {flag} out")


def check_outputs(args: argparse.Namespace) -> None:
    """Check every declared input and output of a parsed command line (see the module
    docstring); a one-line :class:`InputError` before any work."""
    check_not_empty(args)
    inputs = check_inputs(args)
    seen: dict[Path, str] = {}
    renders = False
    for spec in getattr(args, "_outputs", ()):
        value = getattr(args, spec.dest, None)
        if value is None or value is False:
            continue
        if str(value) == "-":
            if spec.stdout:
                continue
            raise InputError(f"{spec.flag} -: only --json can go to stdout; name a file")
        p = check_output_path(spec.flag, str(value), spec.kinds).resolve()
        for flag, q in inputs:
            if q == p:
                raise InputError(f"{spec.flag} {value} is the input of {flag}: writing it would "
                                 "replace the input; name another file")
        if p in seen:
            raise InputError(f"{seen[p]} and {spec.flag} name the same file {value}")
        seen[p] = spec.flag
        renders = renders or spec.renders
    if renders:
        require_gl()


# -- MUJOCO_GL ---------------------------------------------------------------------------

_GL_NOTE = "FLAPSIM_GL_PROBLEM"
_GL_OFF = ("disable", "disabled", "off", "false", "0")
_GL_VALID = ("", "enable", "enabled", "on", "true", "1", "glfw", "glx", "egl", "osmesa")


def gl_problem(value: str | None = None,
               find_library: Callable[[str], str | None] | None = None) -> str | None:
    """Why ``MUJOCO_GL`` (or ``value``) cannot render, or None: an unknown value, or the
    library of the backend it names is not installed (checked without importing mujoco,
    whose import fails on such a value)."""

    find = find_library or ctypes.util.find_library
    v = (os.environ.get("MUJOCO_GL", "") if value is None else value).lower().strip()
    if v in _GL_OFF:
        return None
    if v not in _GL_VALID:
        return (f"MUJOCO_GL={v!r} is not a MuJoCo GL backend; use egl (offscreen), osmesa "
                "(software) or glfw (a display)")

    lib = {"egl": "EGL", "osmesa": "OSMesa", "glx": "GL"}.get(v)
    if lib and not find(lib):
        return f"MUJOCO_GL={v} but its library lib{lib} is not installed; try MUJOCO_GL=egl"
    if v in ("egl", "osmesa"):
        if importlib.util.find_spec("OpenGL") is None:
            return f"MUJOCO_GL={v} needs PyOpenGL (pip install PyOpenGL)"
        plat = os.environ.get("PYOPENGL_PLATFORM", "").lower()
        if plat and plat != v:
            return f"MUJOCO_GL={v} but PYOPENGL_PLATFORM={plat}: unset it or make them agree"
    elif platform.system() == "Linux" and v != "glx" and importlib.util.find_spec("glfw") is None:
        return (f"MUJOCO_GL={v or '(unset)'} means GLFW, whose Python package is not installed; "
                "use MUJOCO_GL=egl for offscreen rendering")
    return None


def address_problem(address: str, timeout_s: float = 5.0) -> str | None:
    """Why the Ray cluster at ``address`` (``HOST:PORT``, ``ray://HOST:PORT``; ``auto`` and
    ``local`` are Ray's own) cannot be reached within ``timeout_s``, or None. Ray itself
    retried an unreachable address for minutes, printing only its warnings."""
    if address in ("auto", "local"):
        return None
    hostport = address.split("://", 1)[1] if "://" in address else address
    host, _, port = hostport.rpartition(":")
    if not host or not port.isdigit() or not 0 < int(port) < 65536:
        return f"--address {address!r} must be HOST:PORT (or ray://HOST:PORT, auto, local)"
    try:
        with socket.create_connection((host.strip("[]"), int(port)), timeout=timeout_s):
            return None
    except OSError as exc:
        why = exc.strerror or str(exc) or "timed out"
        return (f"cannot reach the Ray cluster at {address} ({why}, within {timeout_s:g} s): "
                "start it (ray start --head) or check --address")


def display_problem(display: str | None = None) -> str | None:
    """Why the X display ``display`` (default ``$DISPLAY``) cannot be opened, or None (also
    where there is no libX11 to ask). Asked before the viewer starts: GLFW's own failure
    printed MuJoCo's error, exited 1 and left ``MUJOCO_LOG.TXT`` in the working folder."""
    name = os.environ.get("DISPLAY", "") if display is None else display
    lib = ctypes.util.find_library("X11")
    if not name or lib is None:
        return None
    try:
        x11 = ctypes.CDLL(lib)
    except OSError:
        return None
    x11.XOpenDisplay.restype = ctypes.c_void_p
    x11.XOpenDisplay.argtypes = [ctypes.c_char_p]
    x11.XCloseDisplay.argtypes = [ctypes.c_void_p]
    # a few tries: a server that is resetting (its last client just left) or busy refuses a
    # connection for a moment
    for attempt in range(4):
        handle = x11.XOpenDisplay(name.encode())
        if handle:
            break
        time.sleep(0.25 * (attempt + 1))
    if not handle:
        return (f"cannot open display {name} (no X server answers there): start one (Xvfb "
                f"{name} &), or render offscreen with --video")
    x11.XCloseDisplay(handle)
    return None


def guard_gl() -> None:
    """Called by the CLI before mujoco is imported: an unusable ``MUJOCO_GL`` is noted
    (for :func:`require_gl`) and rendering disabled, so that everything else still works.
    Without a display and without ``MUJOCO_GL`` the command line renders offscreen (EGL)."""
    if "MUJOCO_GL" not in os.environ and not os.environ.get("DISPLAY"):
        os.environ["MUJOCO_GL"] = "egl"
    problem = gl_problem()
    if problem and "mujoco" not in __import__("sys").modules:
        os.environ[_GL_NOTE] = problem
        os.environ["MUJOCO_GL"] = "disable"


def require_gl() -> None:
    """One-line :class:`InputError` when offscreen rendering cannot work."""
    problem = os.environ.get(_GL_NOTE)
    if problem:
        raise InputError(f"cannot render: {problem}")
    v = os.environ.get("MUJOCO_GL", "").lower().strip()
    if v in _GL_OFF:
        raise InputError(f"cannot render: MUJOCO_GL={v} disables rendering; use MUJOCO_GL=egl")
