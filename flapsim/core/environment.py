"""The software a result was computed with.

A controlled flight is chaotic: near the limits of what the dove can do, a verdict turns on
the last bits of a least-squares fit or a kd-tree query, and those bits depend on the
packages and on the processor (numerical libraries pick their kernels by CPU): the same
commit has lost ``climb-turn-15`` at wingbeat 55 on one machine and followed it within
1.76 m on another. So every command's JSON carries :func:`versions`,
and an evaluation's resumable journal is keyed by them too (a run read back must be the run
that would be flown again).
"""

from __future__ import annotations

import platform
from importlib import metadata

from flapsim import __version__

#: The packages whose numerics decide a simulation's result.
PACKAGES = ("mujoco", "numpy", "scipy", "numba")


def versions() -> dict[str, str | None]:
    """flapsim's, Python's and :data:`PACKAGES`' versions (None: not installed), the
    machine's architecture and its processor's model."""
    out: dict[str, str | None] = {"flapsim": __version__, "python": platform.python_version()}
    for name in PACKAGES:
        try:
            out[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            out[name] = None
    out["machine"] = platform.machine()
    out["cpu"] = _cpu_model()
    return out


def _cpu_model() -> str | None:
    """The processor's model name (Linux), else ``platform.processor()`` or None."""
    try:
        with open("/proc/cpuinfo") as f:
            for line in f:
                if line.startswith("model name"):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or None


def tag() -> str:
    """:func:`versions` in one line, e.g. ``flapsim 0.1.0, python 3.11.7, mujoco 3.17.0, ...``."""
    return ", ".join(f"{k} {v}" for k, v in versions().items())
