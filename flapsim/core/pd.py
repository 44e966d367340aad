"""PD servos in the flight paper's form (eq. 6): ``tau = kp (qd - q) + kv (qd' - q')``.

Two ways to apply it, both vectorized over joints (and over any leading batch axes):

* :func:`pd_torque` computes the torque from the current state, for explicit use
  (``data.qfrc_applied`` or motor actuators).
* :func:`pd_ctrl` gives the control of a MuJoCo *affine* actuator that produces the same
  torque inside ``mj_step``: ``<general gaintype="fixed" biastype="affine" gainprm="1"
  biasprm="0 -kp -kv"/>`` yields ``force = ctrl - kp q - kv q'``, so with
  ``ctrl = kp qd + kv qd'`` it is the paper's servo, and MuJoCo's implicit integrators
  (``implicitfast``) treat the ``-kv q'`` term implicitly: stable at any gain, with no
  Python work per step beyond writing ``ctrl``. :func:`affine_gains` reads kp, kv back
  from such a model.
"""

from __future__ import annotations

import mujoco
import numpy as np

from flapsim.core.errors import ModelError


def pd_torque(kp, kv, q_target, v_target, q, v) -> np.ndarray:
    """``kp (q_target - q) + kv (v_target - v)`` (arrays broadcast)."""
    return np.asarray(kp) * (np.asarray(q_target) - q) + np.asarray(kv) * (np.asarray(v_target) - v)


def pd_ctrl(kp, kv, q_target, v_target) -> np.ndarray:
    """Control of an affine PD actuator (``biasprm = 0, -kp, -kv``): ``kp qd + kv qd'``."""
    return np.asarray(kp) * np.asarray(q_target) + np.asarray(kv) * np.asarray(v_target)


def affine_gains(model: mujoco.MjModel) -> tuple[np.ndarray, np.ndarray]:
    """(kp, kv) per actuator of a model whose actuators are affine PD servos."""
    if model.nu == 0:
        raise ModelError("model has no actuators")
    gain = model.actuator_gainprm[:, 0]
    bias = model.actuator_biasprm[:, :3]
    ok = (model.actuator_biastype == mujoco.mjtBias.mjBIAS_AFFINE) & (gain == 1.0) & (bias[:, 0] == 0)
    if not ok.all():
        bad = [mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_ACTUATOR, i) for i in np.flatnonzero(~ok)]
        raise ModelError(f"actuators {bad} are not affine PD servos (gainprm 1, biasprm 0 -kp -kv)")
    return -bias[:, 1].copy(), -bias[:, 2].copy()
