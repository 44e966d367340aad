"""Find the bundled model folders from the installed package, never from the working directory.

In a wheel the three top-level asset folders are installed as ``flapsim/bird_mjcf``,
``flapsim/swimmer_mjcf`` and ``flapsim/creatures``; in a source checkout (editable
install, or tests run from the repository) they sit beside the package folder.
"""

from __future__ import annotations

from pathlib import Path

from flapsim.core.errors import ModelError

ASSET_FOLDERS = ("bird_mjcf", "swimmer_mjcf", "creatures")
_PACKAGE_DIR = Path(__file__).resolve().parent.parent  # flapsim/, above core/


def asset_dir(name: str) -> Path:
    """Absolute path of one bundled asset folder (``bird_mjcf``, ``swimmer_mjcf``, ``creatures``)."""
    if name not in ASSET_FOLDERS:
        raise ModelError(f"unknown asset folder {name!r}; choose one of {', '.join(ASSET_FOLDERS)}")
    for candidate in (_PACKAGE_DIR / name, _PACKAGE_DIR.parent / name):
        if candidate.is_dir():
            return candidate
    raise ModelError(
        f"asset folder {name!r} not found next to {_PACKAGE_DIR}; reinstall flapsim (pip install .)"
    )


def asset_path(folder: str, filename: str) -> Path:
    """Absolute path of a bundled file, with a clear error when it is missing."""
    path = asset_dir(folder) / filename
    if not path.exists():
        available = sorted(p.name for p in asset_dir(folder).iterdir() if not p.name.startswith("."))
        raise ModelError(f"no bundled file {folder}/{filename}; available: {', '.join(available)}")
    return path


def bundled_models() -> dict[str, list[Path]]:
    """Every MJCF file shipped with the package, by folder."""
    return {f: sorted(asset_dir(f).glob("*.xml")) for f in ASSET_FOLDERS}
