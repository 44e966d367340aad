"""Step a simulation and turn divergence into a one-line :class:`SimulationError`.

MuJoCo resets a diverged state silently (with a warning counter and a log file); a
user should instead hear what happened and what to try.
"""

from __future__ import annotations

import mujoco
import numpy as np

from flapsim.core.callbacks import DISPATCHER
from flapsim.core.errors import SimulationError

# MuJoCo's own divergence checks (each resets the state and counts a warning)
_BAD = [int(w) for w in (mujoco.mjtWarning.mjWARN_BADQPOS, mujoco.mjtWarning.mjWARN_BADQVEL,
                         mujoco.mjtWarning.mjWARN_BADQACC)]


def step(model: mujoco.MjModel, data: mujoco.MjData, nstep: int = 1, what: str = "simulation") -> None:
    """``mj_step`` ``nstep`` times (in C), then check that nothing diverged.

    Raises :class:`SimulationError` naming ``what``, the time and the likely fix when
    MuJoCo reported an unstable acceleration, the state is not finite, or a force
    provider reported a non-finite force.
    """
    before = sum(int(data.warning[w].number) for w in _BAD)
    mujoco.mj_step(model, data, nstep=nstep)
    DISPATCHER.check(data)
    if sum(int(data.warning[w].number) for w in _BAD) != before or not (
        np.all(np.isfinite(data.qpos)) and np.all(np.isfinite(data.qvel))
    ):
        raise SimulationError(
            f"{what} diverged at t={data.time:.4f} s (NaN or huge acceleration): lower the "
            f"timestep (now {model.opt.timestep:g} s) or check gains and inputs"
        )
