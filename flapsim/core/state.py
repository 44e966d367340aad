"""Snapshots of a full ``MjData`` state, for deterministic replays and what-if branches.

A :class:`Snapshot` holds ``mjSTATE_INTEGRATION``: time, qpos, qvel, act, warm-start
accelerations, controls, applied forces and mocap poses, i.e. everything ``mj_step``
reads. Restoring it and stepping again reproduces the original run bit for bit (the
flight paper's sampling simulates P0 and P0 + dP from the same state this way).
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np

from flapsim.core.errors import InputError

SPEC = mujoco.mjtState.mjSTATE_INTEGRATION


@dataclass(frozen=True)
class Snapshot:
    """A saved state of one model (``nq``/``nv`` checked on restore)."""

    state: np.ndarray
    """The packed ``mjSTATE_INTEGRATION`` vector."""
    nq: int
    """Model position size, for a sanity check."""
    nv: int
    """Model velocity size."""

    @property
    def time(self) -> float:
        return float(self.state[0])


def save(model: mujoco.MjModel, data: mujoco.MjData) -> Snapshot:
    """Copy the full integration state of ``data``."""
    s = np.empty(mujoco.mj_stateSize(model, SPEC))
    mujoco.mj_getState(model, data, s, SPEC)
    return Snapshot(s, model.nq, model.nv)


def restore(model: mujoco.MjModel, data: mujoco.MjData, snap: Snapshot, forward: bool = True
            ) -> None:
    """Put ``data`` back into the saved state (and recompute derived quantities)."""
    if (snap.nq, snap.nv) != (model.nq, model.nv) or snap.state.size != mujoco.mj_stateSize(
            model, SPEC):
        raise InputError(f"snapshot is for a model with nq={snap.nq}, nv={snap.nv}; this model has "
                         f"nq={model.nq}, nv={model.nv}")
    mujoco.mj_setState(model, data, snap.state, SPEC)
    if forward:
        mujoco.mj_forward(model, data)
