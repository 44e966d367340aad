"""Dynamic modal control: drive chosen vibration modes with an equilibrium-point PD law
(Kry et al. 2009, section 4.1).

The PD equilibrium point moves as

    theta_d(t) = theta_0 + sum_i alpha_i r(t) phi_i sin(2 pi f_i t + gamma_i)

with ``phi_i = R N u_i`` the (max-normalised) mode shape and ``r(t)`` a short cosine
ramp from 0 to 1 so the drive starts without a jolt. The PD stiffness is exactly the
analysis stiffness ``K`` and the damping is the model's ``C``:
    tau = K (theta_d - theta) + C (theta_d' - theta').

The model's own joint (and tendon) springs and dampers already supply
``-K (theta - theta_0) - C theta'``, so the controller's motors add only
``K (theta_d - theta_0) + C theta_d'``: a series-elastic drive whose motor moves each
spring's set point. No force other than these joint torques is applied.

The motor commands come from the actuators' moment arms at the rest pose (exact for
joint and fixed-tendon transmissions): ``ctrl = pinv(A^T diag(gain)) tau``; a model
whose actuators cannot produce the mode torques is refused with the dofs named.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Sequence
from dataclasses import dataclass

import mujoco
import numpy as np

from flapsim.core.errors import InputError, ModelError
from flapsim.modal.analysis import ModalAnalysis, _actuator_moment, integrate_displacement

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class ModeDrive:
    """One driven mode of the equilibrium-point controller."""

    mode: int
    """Mode index, 0-based counting rigid modes first (the paper's numbering)."""
    amplitude: float
    """alpha_i: amplitude of the set-point oscillation of the most-moving joint, rad."""
    phase_rad: float = 0.0
    """gamma_i: phase of the sinusoid, rad (the paper uses 0 and pi/2)."""
    freq_hz: float | None = None
    """f~_i: drive frequency, Hz; None = the mode's natural frequency."""


def two_mode_drives(
    analysis: ModalAnalysis,
    amplitude: float,
    *,
    phase_rad: float = math.pi / 2,
    freq_hz: float | None = None,
) -> list[ModeDrive]:
    """The paper's simple-creature controller: the two lowest non-rigid modes, the
    second ``phase_rad`` (default +90 deg) ahead, both at ``freq_hz`` (default: the
    lower mode's natural frequency)."""
    if analysis.n_modes - analysis.n_rigid < 2:
        raise ModelError("the model has fewer than two vibration modes; nothing to combine")
    first = analysis.n_rigid
    f = float(analysis.freqs_hz[first]) if freq_hz is None else float(freq_hz)
    return [
        ModeDrive(first, amplitude, 0.0, f),
        ModeDrive(first + 1, amplitude, phase_rad, f),
    ]


class ModalController:
    """Equilibrium-point PD control along chosen modes, through the model's motors.

    Call :meth:`apply` before every ``mj_step`` (it writes ``data.ctrl``), or use
    :meth:`control` to get the motor commands for a time.
    """

    def __init__(
        self,
        model: mujoco.MjModel,
        analysis: ModalAnalysis,
        drives: Sequence[ModeDrive],
        *,
        ramp_s: float = 0.5,
        start_time: float = 0.0,
    ) -> None:
        if model.nv != analysis.nv:
            raise InputError(
                f"the analysis has {analysis.nv} dofs but the model {model.nv}: analyse this model"
            )
        if not drives:
            raise InputError("give at least one mode to drive")
        if ramp_s < 0 or not math.isfinite(ramp_s):
            raise InputError(f"ramp_s must be a non-negative number of seconds, got {ramp_s}")
        for d in drives:
            analysis._check_mode(d.mode)
            if d.mode < analysis.n_rigid:
                raise InputError(
                    f"mode {d.mode} is rigid (modes 0..{analysis.n_rigid - 1}); "
                    "drive a vibration mode"
                )
            if not (math.isfinite(d.amplitude) and math.isfinite(d.phase_rad)):
                raise InputError(f"mode {d.mode}: amplitude and phase must be finite")
            if d.freq_hz is not None and not (math.isfinite(d.freq_hz) and d.freq_hz > 0):
                raise InputError(f"mode {d.mode}: frequency must be a positive number of Hz")
        self.model = model
        self.analysis = analysis
        self.drives = tuple(drives)
        self.ramp_s = float(ramp_s)
        self.start_time = float(start_time)

        # Columns: alpha_i * phi_i (nv, n_drive).
        self.shapes = np.column_stack(
            [d.amplitude * analysis.shape(d.mode, "max") for d in self.drives]
        )
        self.omega = np.array(
            [
                2 * math.pi * (analysis.freqs_hz[d.mode] if d.freq_hz is None else d.freq_hz)
                for d in self.drives
            ]
        )
        self.phase = np.array([d.phase_rad for d in self.drives])

        self.actuators, gain_map = _motor_map(model, analysis)
        tau_k = analysis.stiffness @ self.shapes  # torque per unit sin(.)
        tau_c = analysis.damping @ self.shapes  # torque per unit of d/dt
        self._ctrl_k = gain_map @ tau_k
        self._ctrl_c = gain_map @ tau_c
        # Refuse models whose motors cannot produce the mode torques.
        moment = _actuator_moment(model, _rest_data(model, analysis))[self.actuators]
        gains = model.actuator_gainprm[self.actuators, 0]
        for name, tau, ctrl in (("stiffness", tau_k, self._ctrl_k), ("damping", tau_c, self._ctrl_c)):
            made = moment.T @ (gains[:, None] * ctrl)
            err = np.abs(made - tau)
            scale = max(float(np.max(np.abs(tau))), 1e-300)
            if np.any(err > 1e-6 * scale):
                bad = sorted({analysis.dof_labels[k] for k in np.nonzero(err > 1e-6 * scale)[0]})
                raise ModelError(
                    f"the model's motors cannot produce the mode {name} torques on dofs "
                    f"{', '.join(bad[:8])}: add a <motor> on each of those joints"
                )
        self._warned_limits = False
        limited = model.actuator_ctrllimited[self.actuators].astype(bool)
        self._limited = limited if limited.any() else None
        self._lo, self._hi = model.actuator_ctrlrange[self.actuators].T.copy()

    # -- the set point -------------------------------------------------------------------
    def _ramp(self, t: float) -> tuple[float, float]:
        if self.ramp_s <= 0 or t >= self.ramp_s:
            return (1.0, 0.0) if t >= 0 else (0.0, 0.0)
        if t <= 0:
            return 0.0, 0.0
        x = math.pi * t / self.ramp_s
        return 0.5 * (1 - math.cos(x)), 0.5 * math.sin(x) * math.pi / self.ramp_s

    def _weights(self, time: float) -> tuple[np.ndarray, np.ndarray]:
        """Per-drive multipliers of alpha_i phi_i for position and velocity."""
        t = time - self.start_time
        r, dr = self._ramp(t)
        arg = self.omega * t + self.phase
        s, c = np.sin(arg), np.cos(arg)
        return r * s, r * self.omega * c + dr * s

    def target_displacement(self, time: float) -> tuple[np.ndarray, np.ndarray]:
        """Set point minus rest pose (tangent space, nv) and its time derivative."""
        w, wd = self._weights(time)
        return self.shapes @ w, self.shapes @ wd

    def target_qpos(self, time: float) -> np.ndarray:
        """The PD equilibrium point theta_d(t) as a pose (nq,)."""

        dq, _ = self.target_displacement(time)
        return integrate_displacement(self.model, self.analysis.rest_qpos, dq)

    def control(self, time: float) -> np.ndarray:
        """Commands for :attr:`actuators` at ``time``: K dtheta_d + C dtheta_d'."""
        w, wd = self._weights(time)
        return self._ctrl_k @ w + self._ctrl_c @ wd

    def apply(self, data: mujoco.MjData) -> None:
        """Write this step's motor commands into ``data.ctrl``."""
        u = self.control(data.time)
        data.ctrl[self.actuators] = u
        if self._limited is not None and not self._warned_limits:
            if np.any(self._limited & ((u < self._lo) | (u > self._hi))):
                log.warning("motor commands exceed ctrlrange; MuJoCo clamps them")
                self._warned_limits = True


def _rest_data(model: mujoco.MjModel, analysis: ModalAnalysis) -> mujoco.MjData:
    data = mujoco.MjData(model)
    data.qpos[:] = analysis.rest_qpos
    mujoco.mj_forward(model, data)
    return data


def _motor_map(model: mujoco.MjModel, analysis: ModalAnalysis) -> tuple[np.ndarray, np.ndarray]:
    """Indices of motor-like actuators and the map from generalized force to their ctrl."""
    motor = [
        a
        for a in range(model.nu)
        if model.actuator_dyntype[a] == mujoco.mjtDyn.mjDYN_NONE
        and model.actuator_gaintype[a] == mujoco.mjtGain.mjGAIN_FIXED
        and model.actuator_biastype[a] == mujoco.mjtBias.mjBIAS_NONE
        and model.actuator_gainprm[a, 0] != 0
    ]
    if not motor:
        raise ModelError(
            "the model has no motor actuators (gain fixed, no bias, no dynamics): add a "
            "<motor joint=...> on each joint the modes move"
        )
    idx = np.array(motor, dtype=np.int64)
    moment = _actuator_moment(model, _rest_data(model, analysis))[idx]
    gains = model.actuator_gainprm[idx, 0]
    # generalized force = moment^T (gain * ctrl)  ->  ctrl = pinv(moment^T diag(gain)) tau
    return idx, np.linalg.pinv(moment.T * gains[None, :])
