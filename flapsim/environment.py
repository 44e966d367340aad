"""The software a result was computed with.

A controlled flight is chaotic: near the limits of what the dove can do, a verdict turns on
the last bits of a least-squares fit or a kd-tree query. Measured in session 18: the same
commit (24f0683) lost ``climb-turn-15`` at wingbeat 55 with the packages installed then,
where it had been followed within 1.76 m with those of session 15. So every command's JSON
carries :func:`versions`, and an evaluation's resumable journal is keyed by them too (a run
read back must be the run that would be flown again).
"""

from __future__ import annotations

import platform
from importlib import metadata

from flapsim import __version__

#: The packages whose numerics decide a simulation's result.
PACKAGES = ("mujoco", "numpy", "scipy", "numba")


def versions() -> dict[str, str | None]:
    """flapsim's, Python's and :data:`PACKAGES`' versions (None: not installed), and the
    machine's architecture."""
    out: dict[str, str | None] = {"flapsim": __version__, "python": platform.python_version()}
    for name in PACKAGES:
        try:
            out[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            out[name] = None
    out["machine"] = platform.machine()
    return out


def tag() -> str:
    """:func:`versions` in one line, e.g. ``flapsim 0.1.0, python 3.11.7, mujoco 3.17.0, ...``."""
    return ", ".join(f"{k} {v}" for k, v in versions().items())
