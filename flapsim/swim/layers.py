"""Control layers. Layer 1, the basic stroke layer: cycle through a stroke's keyframed
pose graph at a stroke rate and drive the PD muscles towards the interpolated pose.

(The paper's per-cycle perturbation and continuous layers are not implemented yet.)
"""

from __future__ import annotations

import mujoco
import numpy as np

from flapsim.errors import InputError
from flapsim.swim.model import Swimmer
from flapsim.swim.pd import KP, kind_of, pd_controls
from flapsim.swim.strokes import Stroke, StrokeTables, stroke_tables


class BasicStrokeLayer:
    """Stroke clock + PD: call :meth:`apply` before every physics step."""

    def __init__(self, swimmer: Swimmer, stroke: Stroke, rate_hz: float | None = None,
                 gain_scale: float = 1.0, nsamp: int = 240) -> None:
        self.swimmer = swimmer
        self.stroke = stroke
        self.tables: StrokeTables = stroke_tables(stroke, swimmer.joints, nsamp)
        self.rate_hz = stroke.rate_hz if rate_hz is None else float(rate_hz)
        if not (0.05 <= self.rate_hz <= 5.0):
            raise InputError(f"stroke rate must be 0.05..5 Hz, got {self.rate_hz}")
        m = swimmer.model
        j = swimmer.joints
        kp, kv = [], []
        for name, t, da in zip(j.names, j.types, j.dadr, strict=True):
            n = 3 if t == 1 else 1
            kp += [KP[kind_of(name)] * gain_scale] * n
            kv += list(m.dof_damping[da:da + n])
        self.kp = np.asarray(kp, dtype=float)
        self.kv = np.asarray(kv, dtype=float)
        self.lo = np.ascontiguousarray(m.actuator_ctrlrange[:, 0])
        self.hi = np.ascontiguousarray(m.actuator_ctrlrange[:, 1])
        self.phase = 0.0
        self.cycles = 0
        self.target = np.zeros(self.tables.q.shape[1])
        self._tq = self.tables.q.reshape(-1)
        self._tv = self.tables.v.reshape(-1)
        self._n = self.tables.q.shape[0]

    def start_pose(self, phase: float = 0.0) -> np.ndarray:
        """Target joint positions (non-root qpos) at ``phase``."""
        tmp = np.zeros(self.swimmer.model.nu)
        pd_controls(self.swimmer.data.qpos, self.swimmer.joints.types, self.swimmer.joints.qadr,
                    self.swimmer.joints.dadr, self.swimmer.joints.actuator, self._tq, self._tv,
                    self._n, phase, 0.0, self.kp, self.kv, self.lo, self.hi, tmp, self.target)
        return self.target.copy()

    def apply(self, data: mujoco.MjData, dt: float) -> None:
        """Write the motor controls for the current phase, then advance it by ``dt``."""
        j = self.swimmer.joints
        pd_controls(data.qpos, j.types, j.qadr, j.dadr, j.actuator, self._tq, self._tv,
                    self._n, self.phase, self.rate_hz, self.kp, self.kv, self.lo, self.hi,
                    data.ctrl, self.target)
        self.phase += self.rate_hz * dt
        if self.phase >= 1.0:
            self.phase -= 1.0
            self.cycles += 1
