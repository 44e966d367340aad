"""Load MJCF models with one-line errors, and with the passive callback suspended."""

from __future__ import annotations

import os
from pathlib import Path

import mujoco

from flapsim.core.callbacks import DISPATCHER
from flapsim.core.errors import ModelError


def load_model(source: str | os.PathLike, *, is_xml: bool = False) -> mujoco.MjModel:
    """Compile an MJCF file (meshes resolve relative to it) or an XML string.

    Raises :class:`ModelError` with MuJoCo's own one-line reason on malformed input.
    """
    with DISPATCHER.suspended():
        try:
            if is_xml:
                return mujoco.MjModel.from_xml_string(str(source))
            path = Path(source)
            if not path.exists():
                raise ModelError(f"model file {path} does not exist")
            return mujoco.MjModel.from_xml_path(str(path))
        except ValueError as exc:
            where = "XML string" if is_xml else str(source)
            reason = " ".join(str(exc).split())
            raise ModelError(f"cannot load {where}: {reason} (fix the MJCF and retry)") from None
