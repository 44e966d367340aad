"""Control layers (the paper's Fig. 2).

Layer 1, the basic stroke layer (:class:`BasicStrokeLayer`): cycle through a stroke's
keyframed pose graph at a stroke rate and drive the PD muscles towards the
interpolated pose.

Layer 2, the per-cycle perturbation layer: :class:`flapsim.swim.per_cycle.CycleLayer`
re-blends the stroke's six ``[cycle.*]`` sequences into the tables at the start of
every cycle (:meth:`BasicStrokeLayer.set_tables`).

Layer 3, the continuous perturbation layer, applied 50 times a second:
:class:`flapsim.swim.continuous.HandRules` (the paper's palm-orientation and arm-reach
rules, as offsets on single joints, :attr:`BasicStrokeLayer.extra`) and
:class:`FeedbackLayer`, which blends the stroke's named perturbations (offset cycles,
see :mod:`flapsim.swim.strokes`) with weights that feedback rules set from the
swimmer's state: treading water's balance.
"""

from __future__ import annotations

import math

import mujoco
import numpy as np

from flapsim.core.errors import InputError
from flapsim.swim.feedback import signals, weight
from flapsim.swim.model import Swimmer
from flapsim.swim.muscles import KP, kind_of, pd_controls
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
        #: extra motor torque [N m] per actuator added after the PD (and clipped to the
        #: motor's range): the continuous layer's joint offsets, kp x offset
        self.extra = np.zeros(swimmer.model.nu)
        self.extra_on = False
        #: the stroke's own tables, untouched by :meth:`set_tables` (which writes into
        #: :attr:`tables`, the arrays the PD reads)
        self.base_tables = StrokeTables(self.tables.q.copy(), self.tables.v.copy(), stroke)

    def set_tables(self, tables: StrokeTables) -> None:
        """Swim on ``tables`` (same shape) from now on: the per-cycle layer's blend."""
        self._tq[:] = tables.q.reshape(-1)
        self._tv[:] = tables.v.reshape(-1)

    def rest_layers(self, t: float) -> tuple[float, str | None]:
        """Leave the stroke for a manoeuvre: the layer stack above (``stack``, set by
        :class:`~flapsim.swim.simulate.LayerStack`, where there is one) rests in its ``basic``
        mode; returns what :meth:`resume` needs (the stroke rate, Hz, and the stack's mode)."""
        stack = getattr(self, "stack", None)
        saved = (self.rate_hz, stack.mode if stack is not None else None)
        if stack is not None:
            stack.set_mode("basic", t)
        return saved

    def resume(self, saved: tuple[float, str | None], t: float) -> None:
        """Back to the stroke's own tables, from its cycle's start, at the rate and with the
        layers :meth:`rest_layers` saved."""
        rate, mode = saved
        self.rate_hz, self.phase = rate, 0.0
        self.set_tables(self.base_tables)
        stack = getattr(self, "stack", None)
        if stack is not None and mode is not None:
            stack.set_mode(mode, t)

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
        if self.extra_on:
            np.clip(data.ctrl + self.extra, self.lo, self.hi, out=data.ctrl)
        self.phase += self.rate_hz * dt
        if self.phase >= 1.0:
            self.phase -= 1.0
            self.cycles += 1


class FeedbackLayer:
    """Continuous perturbations: call :meth:`update` at the control rate (and the basic
    layer's :meth:`BasicStrokeLayer.apply` before every step as usual).

    Tables for each perturbation at weight +1 and -1 are sampled once; an update blends
    them into the basic layer's targets (quaternions renormalised), so it costs a few
    array operations, not a re-interpolation.
    """

    def __init__(self, basic: BasicStrokeLayer, reference: np.ndarray | None = None,
                 target: object | None = None) -> None:
        self.basic = basic
        sw = basic.swimmer
        st = basic.stroke
        if not st.perturbations:
            raise InputError(f"stroke {st.name!r} has no [perturb.*] sections to feed back")
        self.names = list(st.perturbations)
        base = basic.tables
        self._base_q, self._base_v = base.q.copy(), base.v.copy()
        self._dq: list[tuple[np.ndarray, np.ndarray]] = []
        self._dv: list[tuple[np.ndarray, np.ndarray]] = []
        n = base.q.shape[0]
        for name in self.names:
            plus = stroke_tables(st, sw.joints, n, {name: 1.0})
            minus = stroke_tables(st, sw.joints, n, {name: -1.0})
            # one hemisphere with the base, so that the blend is a short nlerp
            for t in (plus, minus):
                for a in self._ball_cols(sw):
                    flip = np.einsum("ij,ij->i", t.q[:, a:a + 4], base.q[:, a:a + 4]) < 0
                    t.q[flip, a:a + 4] *= -1
            self._dq.append((plus.q - base.q, minus.q - base.q))
            self._dv.append((plus.v - base.v, minus.v - base.v))
        # only the columns some perturbation moves are re-blended (lean: 8 of 40)
        touched_q = sorted({int(c) for pair in self._dq for d in pair
                            for c in np.flatnonzero(np.abs(d).max(axis=0) > 0)})
        touched_v = sorted({int(c) for pair in self._dv for d in pair
                            for c in np.flatnonzero(np.abs(d).max(axis=0) > 0)})
        balls = self._ball_cols(sw)
        # a ball joint's quaternion is renormalised as a whole: blend all 4 columns
        for a in balls:
            if any(a <= c < a + 4 for c in touched_q):
                touched_q = sorted(set(touched_q) | set(range(a, a + 4)))
        self._cq = np.asarray(touched_q, dtype=np.int64)
        self._cv = np.asarray(touched_v, dtype=np.int64)
        self._balls = [int(np.searchsorted(self._cq, a)) for a in balls if a in set(touched_q)]
        self._dq = [(p[:, self._cq].copy(), m[:, self._cq].copy()) for p, m in self._dq]
        self._dv = [(p[:, self._cv].copy(), m[:, self._cv].copy()) for p, m in self._dv]
        self._q0 = self._base_q[:, self._cq].copy()
        self._v0 = self._base_v[:, self._cv].copy()
        # views of the basic layer's flat target tables (what pd_controls reads)
        self._tq = basic._tq.reshape(self._base_q.shape)
        self._tv = basic._tv.reshape(self._base_v.shape)
        self.trunk = sw.body["thorax"]
        self.root = sw.body["pelvis"]
        self.reference = (np.asarray(reference, dtype=float)[:2].copy() if reference is not None
                          else sw.com()[:2])
        # heading: along the trunk's long axis when prone, its front when upright
        self.forward_axis = 2 if st.posture == "prone" else 0
        #: something with ``heading(com_xy, vel_xy, t) -> rad`` (flapsim.swim.goals),
        #: or None: hold the start heading
        self.target = target
        self.desired_heading = 0.0
        #: heading [rad] of the frame the signals' x and y are measured in (0: the world's,
        #: whose +x is the start heading); an upright swimmer facing elsewhere (treading
        #: water where a swim ended) leans and drifts in its own frame
        self.frame_yaw = 0.0
        self.weights = {k: 0.0 for k in self.names}
        self._last_t: float | None = None
        self.history: list[list[float]] = []

    def rebase(self, tables: StrokeTables) -> None:
        """The basic tables changed (the per-cycle layer's blend): blend the feedback
        perturbations onto ``tables`` from now on. Call before :meth:`update`."""
        self._q0 = tables.q[:, self._cq].copy()
        self._v0 = tables.v[:, self._cv].copy()

    def reset(self, reference: np.ndarray | None = None) -> None:
        """Start over: weights back to 0, the smoothing restarted, and the reference
        point (drift signals) at ``reference`` or the swimmer's centre of mass now."""
        self.weights = {k: 0.0 for k in self.names}
        self._last_t = None
        self.reference = (np.asarray(reference, dtype=float)[:2].copy() if reference is not None
                          else self.basic.swimmer.com()[:2])
        if self.target is not None and hasattr(self.target, "reset"):
            self.target.reset()

    @staticmethod
    def _ball_cols(sw: Swimmer) -> list[int]:
        cols, c = [], 0
        for t in sw.joints.types:
            if t == 1:
                cols.append(c)
            c += 4 if t == 1 else 1
        return cols

    def update(self, data: mujoco.MjData) -> dict[str, float]:
        """Measure the signals, set each perturbation's weight, blend the targets."""
        sw = self.basic.swimmer
        now = float(data.time)
        if self._last_t is not None and now < self._last_t:
            self.reset()  # the simulation was reset under us: start over
        if self.target is not None:
            mujoco.mj_subtreeVel(sw.model, data)
            com = data.subtree_com[self.root]
            self.desired_heading = self.target.heading(com[:2].copy(),
                                                       data.subtree_linvel[self.root][:2].copy(),
                                                       float(data.time))
        values = signals(sw.model, data, self.trunk, self.root, self.reference,
                         self.forward_axis, self.desired_heading)
        if self.frame_yaw:
            c, s = math.cos(self.frame_yaw), math.sin(self.frame_yaw)
            for k in ("tilt", "tilt_rate", "offset", "vel"):
                x, y = values[f"{k}_x"], values[f"{k}_y"]
                values[f"{k}_x"], values[f"{k}_y"] = c * x + s * y, -s * x + c * y
        q = self._q0.copy()
        v = self._v0.copy()
        dt = now - self._last_t if self._last_t is not None else 0.0
        self._last_t = now
        for i, name in enumerate(self.names):
            p = self.basic.stroke.perturbations[name]
            w = weight(p.gains, p.bias, values)
            if p.smooth_s > 0.0:  # from 0 at the start, like a muscle that has to move
                w = self.weights[name] + (w - self.weights[name]) * min(1.0, dt / p.smooth_s)
            self.weights[name] = w
            if w > 0:
                q += w * self._dq[i][0]
                v += w * self._dv[i][0]
            elif w < 0:
                q -= w * self._dq[i][1]
                v -= w * self._dv[i][1]
        for a in self._balls:
            q[:, a:a + 4] /= np.linalg.norm(q[:, a:a + 4], axis=1, keepdims=True)
        self._tq[:, self._cq] = q
        self._tv[:, self._cv] = v
        self.history.append([self.weights[k] for k in self.names])
        return self.weights

    def summary(self) -> dict:
        """Per perturbation: mean weight, mean |weight|, fraction of time saturated."""
        if not self.history:
            return {}
        h = np.asarray(self.history)
        return {name: {"mean": float(h[:, i].mean()), "mean_abs": float(np.abs(h[:, i]).mean()),
                       "saturated_fraction": float((np.abs(h[:, i]) >= 1.0 - 1e-12).mean())}
                for i, name in enumerate(self.names)}
