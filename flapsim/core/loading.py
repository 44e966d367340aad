"""Load MJCF models with one-line errors, and with the passive callback suspended."""

from __future__ import annotations

import os
from pathlib import Path

import mujoco
import numpy as np

from flapsim.core.callbacks import DISPATCHER
from flapsim.core.errors import ModelError
from flapsim.core.validate import nonfinite_entry

#: prefixes of MjModel's per-object arrays, and the object kind a row of each is
_OBJECTS = {"body_": mujoco.mjtObj.mjOBJ_BODY, "geom_": mujoco.mjtObj.mjOBJ_GEOM,
            "jnt_": mujoco.mjtObj.mjOBJ_JOINT, "site_": mujoco.mjtObj.mjOBJ_SITE,
            "actuator_": mujoco.mjtObj.mjOBJ_ACTUATOR, "tendon_": mujoco.mjtObj.mjOBJ_TENDON}


def _nonfinite_field(model: mujoco.MjModel) -> str | None:
    """Where the first compiled number of ``model`` that is not finite lies (``body_mass[1]
    (body 'leg') is inf``), or None: MuJoCo compiles ``mass="inf"`` as it is written."""
    for name in sorted(dir(model), key=lambda n: ("mass" not in n, n)):
        if name.startswith("_"):
            continue
        try:
            value = getattr(model, name)
        except Exception:  # noqa: BLE001 - some attributes exist only for some models
            continue
        if not isinstance(value, np.ndarray):
            continue
        found = nonfinite_entry(value, name)
        if found is None:
            continue
        kind = next((k for p, k in _OBJECTS.items() if name.startswith(p)), None)
        row = int(np.argwhere(~np.isfinite(value))[0][0])
        label = mujoco.mj_id2name(model, kind, row) if kind is not None else None
        owner = f" ({str(kind).split('_')[-1].lower()} {label!r})" if label else ""
        return f"{found[0]}{owner} is {found[1]!r}"
    return None


def load_model(source: str | os.PathLike, *, is_xml: bool = False) -> mujoco.MjModel:
    """Compile an MJCF file (meshes resolve relative to it) or an XML string.

    Raises :class:`ModelError` with MuJoCo's own one-line reason on malformed input, and
    for a file that holds a number that is not finite: MuJoCo only warns about a NaN (and
    puts its default in its place) and compiles an infinity as it is.
    """
    nan_warnings: list[str] = []
    with DISPATCHER.suspended():
        try:
            if is_xml:
                return mujoco.MjModel.from_xml_string(str(source))
            path = Path(source)
            if not path.exists():
                raise ModelError(f"model file {path} does not exist")
            previous = mujoco.get_mju_user_warning()

            def warn(message: str) -> None:
                if "NaN" in message:
                    nan_warnings.append(" ".join(message.split()))
                elif previous is not None:
                    previous(message)

            mujoco.set_mju_user_warning(warn)
            try:
                model = mujoco.MjModel.from_xml_path(str(path))
            finally:
                mujoco.set_mju_user_warning(previous)
        except ValueError as exc:
            where = "XML string" if is_xml else str(source)
            reason = " ".join(str(exc).split())
            raise ModelError(f"cannot load {where}: {reason} (fix the MJCF and retry)") from None
    if nan_warnings:
        raise ModelError(f"model file {path}: a number is NaN, not finite (MuJoCo: "
                         f"{nan_warnings[0]}); write a finite number there")
    found = _nonfinite_field(model)
    if found is not None:
        raise ModelError(f"model file {path}: its compiled {found}, a non-finite number (NaN or "
                         "infinity); write a finite number in the MJCF")
    return model
