"""The reference wingbeat and the 29-number parameterized wingbeat (the flight paper, sec. 4.1).

The reference wingbeat is the phase-aligned average of all capture cycles, stored as a
truncated Fourier series per DOF (a smooth periodic function of phase, with analytic
derivative). A parameterized wingbeat ``P = (s1, t1, ..., s14, t14, w)`` changes it:
    q_i(t) = m_i + s_i (r_i(phi) - m_i) + t_i,   phi = t / (w T0),  0 <= t < w T0

with ``r_i`` the reference, ``m_i`` its cycle mean and ``T0`` the mean capture period:
``s_i`` scales the stroke about its mean (a scale about zero would also move the mean,
mixing the roles of ``s`` and ``t``), ``t_i`` translates it, and ``w`` stretches the
whole cycle in time (all DOF together). P0 = (1, 0, ..., 1, 0, 1) is the reference.

The PD servo follows ``q(t)`` and ``q'(t)`` every step (paper eq. 6); see
:func:`control_table` and :mod:`flapsim.core.pd`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from flapsim.bird.body.params import DOF_NAMES, MIRROR_PERM, N_DOF
from flapsim.bird.flight.capture import CaptureSet, reference_capture
from flapsim.core.errors import InputError
from flapsim.core.pd import pd_ctrl

N_PARAMS = 2 * N_DOF + 1
TAIL_BEND = DOF_NAMES.index("tail_bend")


def p0() -> np.ndarray:
    """The reference wingbeat's parameters: all scales 1, translations 0, timewarp 1."""
    p = np.zeros(N_PARAMS)
    p[0:-1:2] = 1.0
    p[-1] = 1.0
    return p


def split(p: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
    """(scales (14,), translations (14,), timewarp) of a 29-vector."""
    p = np.asarray(p, dtype=float)
    if p.shape != (N_PARAMS,):
        raise InputError(f"a wingbeat has {N_PARAMS} parameters, got shape {p.shape}")
    if not np.all(np.isfinite(p)) or p[-1] <= 0:
        raise InputError("wingbeat parameters must be finite with a positive timewarp")
    return p[0:-1:2], p[1:-1:2], float(p[-1])


def join(scales: np.ndarray, translations: np.ndarray, timewarp: float) -> np.ndarray:
    p = np.empty(N_PARAMS)
    p[0:-1:2] = scales
    p[1:-1:2] = translations
    p[-1] = timewarp
    return p


def mirror_params(p: np.ndarray) -> np.ndarray:
    """The mirror-image wingbeat (left and right DOF swapped)."""
    s, t, w = split(p)
    return join(s[MIRROR_PERM], t[MIRROR_PERM], w)


def with_twist_bias(p: np.ndarray, bias_deg: float) -> np.ndarray:
    """``p`` with both shoulder twists translated by ``bias_deg`` (the same on both sides,
    so the wingbeat stays symmetric; - supinates the wings: more angle of attack)."""
    q = np.array(p, dtype=float)
    for side in "lr":
        q[2 * DOF_NAMES.index(f"{side}_shoulder_twist") + 1] += np.radians(bias_deg)
    return q


def with_flap_and_beat(p: np.ndarray, flap_scale: float = 1.0, timewarp: float = 1.0) -> np.ndarray:
    """``p`` with both shoulder-flap scales multiplied by ``flap_scale`` (a wider stroke) and
    its timewarp by ``timewarp`` (< 1: a faster beat); symmetric like ``p``."""
    q = np.array(p, dtype=float)
    for side in "lr":
        q[2 * DOF_NAMES.index(f"{side}_shoulder_flap")] *= flap_scale
    q[-1] *= timewarp
    return q


def with_tail_bias(p: np.ndarray, bias_deg: float) -> np.ndarray:
    """``p`` with the tail bend translated by ``bias_deg`` (the paper's +17 deg: tail up)."""
    q = np.array(p, dtype=float)
    q[2 * TAIL_BEND + 1] += np.radians(bias_deg)
    return q


@dataclass(frozen=True)
class ReferenceWingbeat:
    """The average capture cycle as Fourier series: ``r(phi) = a0 + sum a_k cos + b_k sin``."""

    coef: np.ndarray
    """(14, 2H+1) Fourier coefficients per DOF: a0, then (a_k, b_k) for k = 1..H, rad."""
    period: float
    """Mean capture cycle duration T0, s."""
    n_cycles: int
    """How many cycles were averaged."""

    @property
    def harmonics(self) -> int:
        return (self.coef.shape[1] - 1) // 2

    @property
    def mean(self) -> np.ndarray:
        """Cycle mean of each DOF, rad."""
        return self.coef[:, 0]

    def _basis(self, phase: np.ndarray, derivative: bool = False) -> np.ndarray:
        ph = np.atleast_1d(np.asarray(phase, dtype=float))
        k = np.arange(1, self.harmonics + 1)
        arg = 2 * np.pi * ph[:, None] * k
        out = np.empty((len(ph), 2 * self.harmonics + 1))
        if derivative:
            out[:, 0] = 0.0
            out[:, 1::2] = -2 * np.pi * k * np.sin(arg)
            out[:, 2::2] = 2 * np.pi * k * np.cos(arg)
        else:
            out[:, 0] = 1.0
            out[:, 1::2] = np.cos(arg)
            out[:, 2::2] = np.sin(arg)
        return out

    def angles(self, phase: np.ndarray) -> np.ndarray:
        """(n, 14) reference angles at phases (periodic, any real phase)."""
        return self._basis(phase) @ self.coef.T

    def dphase(self, phase: np.ndarray) -> np.ndarray:
        """(n, 14) derivative of the reference angles with respect to phase."""
        return self._basis(phase, True) @ self.coef.T

    @classmethod
    def from_capture(cls, cap: CaptureSet, n_phase: int = 96, harmonics: int = 8
                     ) -> ReferenceWingbeat:
        """Phase-align every cycle, average, and fit ``harmonics`` Fourier terms."""
        if cap.n_cycles < 1:
            raise InputError("the capture has no cycles to average")
        mean_cycle = cap.cycle_matrix(n_phase).mean(axis=0)  # (n_phase, 14)
        return cls.from_cycle(mean_cycle, float(cap.durations.mean()), harmonics, cap.n_cycles)

    @classmethod
    def from_cycle(cls, cycle: np.ndarray, period: float, harmonics: int = 8,
                   n_cycles: int = 1) -> ReferenceWingbeat:
        """The Fourier fit of one cycle ``(n_phase, 14)`` sampled at phases j / n_phase, rad,
        lasting ``period`` s (a kinematic model's cycle, or the average of a capture's)."""
        cycle = np.asarray(cycle, dtype=float)
        if cycle.ndim != 2 or cycle.shape[1] != N_DOF or len(cycle) < 2 * harmonics + 1:
            raise InputError(f"a cycle is (n_phase >= {2 * harmonics + 1}, {N_DOF}) angles, got "
                             f"shape {cycle.shape}")
        phase = np.arange(len(cycle)) / len(cycle)
        dummy = cls(np.zeros((N_DOF, 2 * harmonics + 1)), 1.0, 0)
        B = dummy._basis(phase)
        coef, *_ = np.linalg.lstsq(B, cycle, rcond=None)
        return cls(coef.T.copy(), float(period), n_cycles)

    def evaluate(self, p: np.ndarray, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Target angles (n, 14) and angular velocities (n, 14) of wingbeat ``p`` at times
        ``t`` since the cycle start."""
        s, tr, w = split(p)
        T = w * self.period
        phase = np.asarray(t, dtype=float) / T
        m = self.mean
        q = m + s * (self.angles(phase) - m) + tr
        qd = s * self.dphase(phase) / T
        return q, qd

    def duration(self, p: np.ndarray) -> float:
        """Cycle duration of wingbeat ``p``, s."""
        return split(p)[2] * self.period

    def fit(self, cycle: np.ndarray, duration: float) -> np.ndarray:
        """The wingbeat parameters that best reproduce one phase-aligned cycle
        ((n_phase, 14), phases j/n_phase) lasting ``duration`` s (least squares per DOF)."""
        n = len(cycle)
        r = self.angles(np.arange(n) / n) - self.mean
        s = np.empty(N_DOF)
        t = np.empty(N_DOF)
        for i in range(N_DOF):
            A = np.stack([r[:, i], np.ones(n)], axis=1)
            (s[i], c), *_ = np.linalg.lstsq(A, cycle[:, i], rcond=None)
            t[i] = c - self.mean[i]
        return join(s, t, duration / self.period)


_REFERENCE: dict[str, ReferenceWingbeat] = {}


def reference_wingbeat(preset: str = "slow") -> ReferenceWingbeat:
    """The reference wingbeat of a bundled capture set (with its mirror: symmetric): the
    paper's slow-flight conditions, or ``preset="cruise"``."""
    if preset not in _REFERENCE:
        cap = reference_capture(with_mirror=True, preset=preset)
        _REFERENCE[preset] = ReferenceWingbeat.from_capture(cap)
    return _REFERENCE[preset]


def control_table(ref: ReferenceWingbeat, p: np.ndarray, dt: float, kp: np.ndarray,
                  kv: np.ndarray, t0: float = 0.0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per-step PD actuator controls for one cycle of wingbeat ``p``.

    Step k starts at time ``t0 + k dt`` (k = 0..n-1, ``n = round(duration / dt)``) and
    tracks the targets at that time. Returns (ctrl (n, 14), target angles (n, 14),
    target rates (n, 14)).
    """
    n = max(1, int(round(ref.duration(p) / dt)))
    t = t0 + dt * np.arange(n)
    q, qd = ref.evaluate(p, t)
    return pd_ctrl(kp, kv, q, qd), q, qd


def _deviations(ref: ReferenceWingbeat) -> np.ndarray:
    """(64, 14) the reference wingbeat's angles about their means over one cycle (asked for
    every controlled wingbeat: kept on the reference, which is immutable)."""
    r = ref.__dict__.get("_deviations64")
    if r is None:
        r = ref.angles(np.arange(64) / 64) - ref.mean
        r.setflags(write=False)
        ref.__dict__["_deviations64"] = r
    return r


def project_to_ranges(ref: ReferenceWingbeat, p: np.ndarray, lo: np.ndarray, hi: np.ndarray,
                      margin: float = np.radians(1.0)) -> np.ndarray:
    """The nearest wingbeat (per DOF: shrink the scale, then shift) whose commanded
    trajectory stays ``margin`` inside every joint range."""
    s, t, w = split(p)
    s, t = s.copy(), t.copy()
    m = ref.mean
    r = _deviations(ref)
    lo_m, hi_m = lo + margin, hi - margin
    for i in range(N_DOF):
        if not np.isfinite(lo[i]) and not np.isfinite(hi[i]):
            continue
        dev = s[i] * r[:, i]
        span = dev.max() - dev.min()
        room = hi_m[i] - lo_m[i]
        if span > room and span > 0:
            s[i] *= room / span
            dev = s[i] * r[:, i]
        qmin, qmax = m[i] + t[i] + dev.min(), m[i] + t[i] + dev.max()
        if qmin < lo_m[i]:
            t[i] += lo_m[i] - qmin
        elif qmax > hi_m[i]:
            t[i] -= qmax - hi_m[i]
    return join(s, t, w)


#: Largest excursion beyond a joint range a simulated sample may make, rad: MuJoCo's limits
#: are soft (solref), a wingbeat that presses into a limit overshoots it by a fraction of a
#: degree; more than this means the limit did not hold.
RANGE_TOLERANCE = np.radians(2.0)
