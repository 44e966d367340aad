"""Phase 1 of the flight paper's resampling (sec. 5.1): training samples (S, dS, dP).

Wingbeats. Every capture cycle is fitted by a 29-number wingbeat ``P`` (least squares
against the reference, :meth:`ReferenceWingbeat.fit`) and placed in the steering /
elevation plane by its (alpha, beta). The plane is cut into a 4 x 4 grid of bins with
equal counts along each axis (the paper sizes bins "such that each bin has sufficiently
many samples"); in each bin a PCA of every joint's (s_i, t_i) pairs gives an ellipse (the
timewarp, one number, a segment), and new wingbeats are drawn uniformly inside those
ellipses scaled by ``sigma`` (paper: 2..4), each joint independently, in a bin drawn
uniformly (so rare steering/elevation combinations are sampled as often as common ones).

States. A random pre-state S' (pitch and roll within +-45 deg, angular velocity within
+-4 deg/s and linear velocity within +-0.3 m/s of cruise, both in the body frame) is
filled in with the average joint pose at the start of a wingbeat and resting feathers;
one pre-simulation wingbeat with a random wingbeat gives a state S with natural joint and
feather variation. From S the bird flies P0 (-> S0) and P0 + dP (-> S1); the sample is
(S, dS = S1 - S0, dP) with the steering alpha and elevation beta that dP caused (the change
in heading and climb angle of the centre-of-mass velocity against the P0 flight).

Every sample depends only on (seed, index): sample i draws from
``numpy.random.default_rng([seed, i])`` and starts from a freshly reset simulation, so a
database is identical for any number of workers. Samples whose commanded joint trajectory
leaves a joint range, or whose simulation diverges, are counted and rejected.
"""

from __future__ import annotations

import logging
from dataclasses import asdict, dataclass, fields
from pathlib import Path

import mujoco
import numpy as np

from flapsim.bird.body.model import Dove
from flapsim.bird.body.params import N_DOF
from flapsim.bird.control.database import ChunkResult, load_database
from flapsim.bird.flight import cycle
from flapsim.bird.flight.capture import CAPTURE_FILES, CaptureSet, load_capture, reference_capture
from flapsim.bird.flight.dove_flight import DoveFlight, FlightConfig, pose_quat
from flapsim.bird.flight.wingbeat import (
    N_PARAMS,
    RANGE_TOLERANCE,
    ReferenceWingbeat,
    p0,
    reference_wingbeat,
    with_flap_and_beat,
    with_tail_bias,
    with_twist_bias,
)
from flapsim.bird.training.manifold import Manifold, WingbeatSet
from flapsim.core.errors import DataFileError, InputError, SimulationError
from flapsim.core.io import file_sha256

log = logging.getLogger(__name__)

#: Per-sample fields stored in a database (name -> trailing shape).
FIELDS: dict[str, tuple[int, ...]] = {
    "S": (8,),          # state at which P0 and P0 + dP start
    "S0": (8,),         # state after P0
    "dS": (8,),         # (state after P0 + dP) - S0
    "dP": (N_PARAMS,),  # wingbeat change
    "alpha": (),        # steering caused by dP, rad (+ left)
    "beta": (),         # elevation caused by dP, rad (+ up)
    "dspeed": (),       # change of centre-of-mass speed caused by dP, m/s
}


# -- wingbeat distribution ------------------------------------------------------------------


def capture_wingbeats(cap: CaptureSet, ref: ReferenceWingbeat, n_phase: int = 96) -> WingbeatSet:
    """Fit every capture cycle's P against the reference; alpha/beta from the capture labels."""
    if np.any(~np.isfinite(cap.steering_deg)) or np.any(~np.isfinite(cap.elevation_deg)):
        raise DataFileError("the capture lacks per-cycle steering/elevation angles (NaN): phase-1 "
                            "sampling bins wingbeats by them; give steering_deg/elevation_deg")
    cycles = cap.cycle_matrix(n_phase)
    P = np.array([ref.fit(c, dur) for c, dur in zip(cycles, cap.durations, strict=True)])
    return WingbeatSet(P - p0(), np.radians(cap.steering_deg), np.radians(cap.elevation_deg))


@dataclass(frozen=True)
class Ellipses:
    """Per-bin sampling ellipses over the (alpha, beta) grid."""

    alpha_edges: np.ndarray
    """(nb + 1,) bin edges in alpha (outer edges open)."""
    beta_edges: np.ndarray
    """(nb + 1,) bin edges in beta."""
    centre: np.ndarray
    """(nbin, 29) mean dP of each bin."""
    axes: np.ndarray
    """(nbin, 14, 2, 2) per joint: columns are the ellipse's semi-axes (1 std) in (s, t)."""
    w_std: np.ndarray
    """(nbin,) standard deviation of the timewarp in each bin."""
    count: np.ndarray
    """(nbin,) examples each bin was fitted from."""

    @classmethod
    def fit(cls, ws: WingbeatSet, bins: int = 4, min_count: int = 8) -> Ellipses:
        """Equal-count edges along each axis; a bin with fewer than ``min_count`` examples
        borrows its nearest examples (in alpha/beta, scaled by their spreads)."""
        n = len(ws.dP)
        if n < min_count:
            raise InputError(f"need at least {min_count} example wingbeats to fit ellipses, got {n}")
        qs = np.linspace(0, 1, bins + 1)
        ae, be = np.quantile(ws.alpha, qs), np.quantile(ws.beta, qs)
        ia = np.clip(np.searchsorted(ae, ws.alpha, side="right") - 1, 0, bins - 1)
        ib = np.clip(np.searchsorted(be, ws.beta, side="right") - 1, 0, bins - 1)
        sa, sb = max(np.std(ws.alpha), 1e-9), max(np.std(ws.beta), 1e-9)
        nbin = bins * bins
        centre = np.empty((nbin, N_PARAMS))
        axes = np.empty((nbin, N_DOF, 2, 2))
        w_std = np.empty(nbin)
        count = np.empty(nbin, int)
        for a in range(bins):
            for b in range(bins):
                k = a * bins + b
                sel = np.flatnonzero((ia == a) & (ib == b))
                if len(sel) < min_count:
                    ca, cb = (ae[a] + ae[a + 1]) / 2, (be[b] + be[b + 1]) / 2
                    d = ((ws.alpha - ca) / sa) ** 2 + ((ws.beta - cb) / sb) ** 2
                    sel = np.argsort(d)[:min_count]
                count[k] = len(sel)
                X = ws.dP[sel]
                centre[k] = X.mean(axis=0)
                for j in range(N_DOF):
                    st = X[:, 2 * j:2 * j + 2]
                    C = np.cov(st.T) + 1e-12 * np.eye(2)
                    lam, V = np.linalg.eigh(C)
                    axes[k, j] = V * np.sqrt(np.maximum(lam, 0.0))
                w_std[k] = X[:, -1].std()
        return cls(ae, be, centre, axes, w_std, count)

    def draw(self, rng: np.random.Generator, sigma: float) -> tuple[np.ndarray, int]:
        """One dP: a bin uniformly, then each joint's (s, t) uniformly in its ellipse scaled by
        ``sigma``, and the timewarp uniformly in +-sigma std."""
        k = int(rng.integers(len(self.centre)))
        # uniform in the unit disk: radius sqrt(u)
        r = np.sqrt(rng.random(N_DOF))
        th = rng.random(N_DOF) * 2 * np.pi
        u = np.stack([r * np.cos(th), r * np.sin(th)], axis=1)  # (14, 2)
        st = np.einsum("jab,jb->ja", self.axes[k], u) * sigma
        dP = self.centre[k].copy()
        dP[0:-1:2] += st[:, 0]
        dP[1:-1:2] += st[:, 1]
        dP[-1] += sigma * self.w_std[k] * (2 * rng.random() - 1)
        return dP, k


# -- joint ranges ---------------------------------------------------------------------------


def trajectory_bounds(ref: ReferenceWingbeat, p: np.ndarray, n_phase: int = 64
                      ) -> tuple[np.ndarray, np.ndarray]:
    """(min, max) over the cycle of each DOF's commanded angle under wingbeat ``p``."""
    q, _ = ref.evaluate(p, np.arange(n_phase) / n_phase * ref.duration(p))
    return q.min(axis=0), q.max(axis=0)


def in_ranges(ref: ReferenceWingbeat, p: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> bool:
    qmin, qmax = trajectory_bounds(ref, p)
    return bool(np.all(qmin >= lo) and np.all(qmax <= hi))


# -- configuration and the worker -----------------------------------------------------------


class StoredConfig:
    """A dataclass configuration that databases store as JSON (provenance) and read back."""

    #: How error messages name it.
    kind = "configuration"

    def to_dict(self) -> dict:
        return asdict(self)

    @classmethod
    def from_dict(cls, d: dict):
        names = {f.name for f in fields(cls)}
        unknown = set(d) - names
        if unknown:
            raise DataFileError(f"{cls.kind} has unknown keys {sorted(unknown)}: written by a newer "
                                "flapsim? upgrade flapsim")
        return cls(**d)


@dataclass(frozen=True)
class SamplingConfig(StoredConfig):
    """Every parameter of a phase-1 sampling run (stored in the database for provenance)."""

    kind = "sampling configuration"

    seed: int = 0
    """Base seed: sample i draws from ``default_rng([seed, i])``."""
    sigma: float = 3.0
    """Ellipse scale (paper: 2..4)."""
    bins: int = 4
    """Bins per axis of the (alpha, beta) grid (paper: 4)."""
    pitch_deg: float = 45.0
    """Pre-state pitch drawn within +-this, deg (paper: 45)."""
    roll_deg: float = 45.0
    """Pre-state roll drawn within +-this, deg (paper: 45)."""
    pitch_centre_deg: float = 0.0
    """The pre-state pitch range's centre, deg (paper: 0, a level trunk). A dove whose trimmed
    trunk flies pitched (the cruise dove: 18 deg at a wingbeat's start) is sampled around that
    attitude: its cruise velocity is then level, not along the trunk."""
    angvel_deg_s: float = 4.0
    """Pre-state angular velocity within +-this per body axis, deg/s (paper: 4)."""
    linvel: float = 0.3
    """Pre-state linear velocity within +-this per body axis around cruise, m/s (paper: 0.3)."""
    cruise_speed: float = FlightConfig.speed
    """Cruise speed the pre-state is drawn around, m/s (paper: ~7)."""
    tail_bias_deg: float = FlightConfig.tail_bias_deg
    """Tail bend added to every wingbeat, deg (paper: 17)."""
    twist_bias_deg: float = 0.0
    """Shoulder twist added to every wingbeat on both sides, deg (- supinates: more angle of
    attack); 0 for the bundled database. The reference wingbeat is P0 with both biases."""
    table: str = FlightConfig.table
    """Feather coefficient table."""
    source: str = "capture"
    """Where example wingbeats come from: ``capture`` (the bundled capture set, mirrored),
    or the path of a database whose (dP, alpha, beta) serve as examples (phase 2)."""
    capture: str = ""
    """A capture file instead of the bundled one (``.npz``, ``.bvh``, ``.csv``)."""
    extrapolate: float = 0.0
    """Phase 2 only: > 0 draws this share of samples along the fitted control manifold
    beyond the examples' steering/elevation extremes (see :mod:`flapsim.bird.training.discovery`)."""
    extrapolate_scale: float = 1.6
    """How far beyond the extremes, as a multiple of the examples' largest |alpha|/|beta|."""
    feathers: str = "rigid"
    """``rigid`` or ``modal`` (bending) feathers: the dove the samples are flown with (a
    database is bound to its model)."""
    centre_flap_scale: float = 1.0
    """The sampled wingbeats (pre-simulation and sample) are drawn around P0 with both
    shoulder-flap strokes scaled by this, instead of around P0 itself (1: the paper's)."""
    centre_timewarp: float = 1.0
    """... and the cycle's duration multiplied by this (< 1: a faster beat). The wingbeats a
    tight turn or a steep climb needs lie beyond the capture's ellipses around P0
    (``studies/dove_turn_limit.py``); P0 and the samples' dP stay P0-relative, so such a
    database merges with one sampled around P0."""
    centre_wingbeat: tuple = ()
    """The 29 parameters of the wingbeat phase 1 draws around instead (the biases included,
    as flown; empty: P0 with ``centre_flap_scale`` and ``centre_timewarp``). For a wingbeat
    found by ``studies/dove_wingbeat_search.py``, say the fastest steady climb: the
    capture's ellipses then spread around it, and the samples' dP stay P0-relative, so such
    a database merges with one sampled around P0."""

    reference_wingbeat: tuple = ()
    """The 29 parameters of the reference wingbeat P0 itself (the biases included, as flown;
    empty: the capture's mean cycle with ``tail_bias_deg`` and ``twist_bias_deg``). A gait the
    capture does not hold, say a wingbeat trimmed for slow flight under a bird wing's section
    (``studies/dove_trim_power.py`` writes one): the controller predicts S0 by flying it and
    its samples' dP are offsets from it, so the trim it measures is that gait's."""

    capture_preset: str = "slow"
    """The bundled capture the examples and the reference wingbeat P0 come from: ``slow``
    (the paper's conditions) or ``cruise`` (:data:`~flapsim.bird.flight.capture.CAPTURE_FILES`)."""
    induced: bool = False
    """Whether the dove's wings see their own downwash (rigid feathers only)."""

    def __post_init__(self) -> None:
        # JSON gives a list back: a tuple keeps the configuration frozen and comparable
        object.__setattr__(self, "centre_wingbeat", tuple(float(x) for x in self.centre_wingbeat))
        object.__setattr__(self, "reference_wingbeat",
                           tuple(float(x) for x in self.reference_wingbeat))

    def to_dict(self) -> dict:
        d = asdict(self)
        if d["feathers"] == "rigid":
            del d["feathers"]  # rigid databases keep the configuration they always had
        if d["twist_bias_deg"] == 0.0:
            del d["twist_bias_deg"]  # likewise
        if d["capture_preset"] == "slow":
            del d["capture_preset"]  # likewise
        if not d["induced"]:
            del d["induced"]  # likewise
        if d["pitch_centre_deg"] == 0.0:
            del d["pitch_centre_deg"]  # likewise
        for k in ("centre_flap_scale", "centre_timewarp"):
            if d[k] == 1.0:
                del d[k]  # likewise
        for k in ("centre_wingbeat", "reference_wingbeat"):
            if not d[k]:
                del d[k]  # likewise
            else:
                d[k] = list(d[k])
        return d

    def validate(self) -> None:
        if self.feathers not in ("rigid", "modal"):
            raise InputError(f"feathers must be rigid or modal, got {self.feathers!r}")
        if self.capture_preset not in CAPTURE_FILES:
            raise InputError(f"unknown capture {self.capture_preset!r}; choose one of "
                             f"{', '.join(CAPTURE_FILES)}")
        if self.induced and self.feathers != "rigid":
            raise InputError("the induced flow needs rigid feathers")
        if not (0 < self.sigma <= 10):
            raise InputError(f"--sigma must be in (0, 10], got {self.sigma}")
        if not (1 <= self.bins <= 10):
            raise InputError(f"bins must be 1..10, got {self.bins}")
        if not (np.isfinite(self.pitch_centre_deg) and abs(self.pitch_centre_deg) <= 45.0):
            raise InputError(f"--pre-pitch-centre-deg must be within -45..45, got "
                             f"{self.pitch_centre_deg}")
        for name in ("pitch_deg", "roll_deg", "angvel_deg_s", "linvel"):
            v = getattr(self, name)
            if not np.isfinite(v) or v < 0:
                raise InputError(f"{name} must be a finite non-negative number, got {v}")
        if not (1.0 <= self.cruise_speed <= 20.0):
            raise InputError(f"--pre-speed (the cruise speed) must be 1..20 m/s, got {self.cruise_speed}")
        if not (np.isfinite(self.tail_bias_deg) and abs(self.tail_bias_deg) <= 40.0):
            raise InputError(f"--tail-bias-deg must be within -40..40 (the tail's range), got "
                             f"{self.tail_bias_deg}")
        if not (np.isfinite(self.twist_bias_deg) and abs(self.twist_bias_deg) <= 30.0):
            raise InputError(f"--twist-bias-deg must be within -30..30, got {self.twist_bias_deg}")
        if not (np.isfinite(self.centre_flap_scale) and 0.5 <= self.centre_flap_scale <= 2.0):
            raise InputError(f"--centre-flap-scale must be within 0.5..2, got {self.centre_flap_scale}")
        if not (np.isfinite(self.centre_timewarp) and 0.5 <= self.centre_timewarp <= 2.0):
            raise InputError(f"--centre-timewarp must be within 0.5..2, got {self.centre_timewarp}")
        if self.centre_wingbeat:
            c = np.asarray(self.centre_wingbeat)
            if c.shape != (N_PARAMS,) or not np.all(np.isfinite(c)) or not 0.5 <= c[-1] <= 2.0:
                raise InputError(f"--centre-wingbeat must be {N_PARAMS} finite wingbeat parameters "
                                 f"with a timewarp within 0.5..2, got {c.size} numbers")
            if self.centre_flap_scale != 1.0 or self.centre_timewarp != 1.0:
                raise InputError("--centre-wingbeat gives the whole centre: leave out "
                                 "--centre-flap-scale and --centre-timewarp")
        if self.reference_wingbeat:
            c = np.asarray(self.reference_wingbeat)
            if c.shape != (N_PARAMS,) or not np.all(np.isfinite(c)) or not 0.5 <= c[-1] <= 2.0:
                raise InputError(f"--reference-wingbeat must be {N_PARAMS} finite wingbeat "
                                 f"parameters with a timewarp within 0.5..2, got {c.size} numbers")


def sample_fields(S: np.ndarray, dP: np.ndarray, e0: cycle.CycleEnd, e1: cycle.CycleEnd
                  ) -> tuple[dict[str, np.ndarray] | None, str]:
    """A sample's :data:`FIELDS` from the reference wingbeat's end ``e0`` and the flown one's
    ``e1`` (both from state ``S``), or (None, "left_range") when either pressed a joint past
    its range by more than :data:`RANGE_TOLERANCE`."""
    if e0.range_excess > RANGE_TOLERANCE or e1.range_excess > RANGE_TOLERANCE:
        return None, "left_range"
    h0, c0 = cycle.heading_and_climb(e0.com_vel)
    h1, c1 = cycle.heading_and_climb(e1.com_vel)
    return {
        "S": S, "S0": e0.S, "dS": e1.S - e0.S, "dP": dP,
        "alpha": np.float64(cycle.wrap(h1 - h0)), "beta": np.float64(c1 - c0),
        "dspeed": np.float64(np.linalg.norm(e1.com_vel) - np.linalg.norm(e0.com_vel)),
    }, ""


def collect_chunk(sample, start: int, stop: int) -> ChunkResult:
    """Run ``sample(i)`` -> (fields or None, rejection reason) over [start, stop)."""
    keep, rows, rejected = [], [], {}
    for i in range(start, stop):
        out, why = sample(i)
        if out is not None and not all(np.all(np.isfinite(v)) for v in out.values()):
            out, why = None, "non_finite"  # a database holding one is refused when read
        if out is None:
            rejected[why] = rejected.get(why, 0) + 1
        else:
            keep.append(i)
            rows.append(out)
    arrays = {k: (np.array([r[k] for r in rows], dtype=float) if rows
                  else np.empty((0, *shape))) for k, shape in FIELDS.items()}
    return ChunkResult(start, stop, np.array(keep, dtype=np.int64), arrays, rejected)


def load_examples(config: SamplingConfig, ref: ReferenceWingbeat) -> WingbeatSet:
    if config.source == "capture":
        if config.capture:
            cap = load_capture(config.capture).with_mirror()
        else:
            cap = reference_capture(with_mirror=True, preset=config.capture_preset)
        return capture_wingbeats(cap, ref)

    db = load_database(Path(config.source))
    return WingbeatSet(db.arrays["dP"], db.arrays["alpha"], db.arrays["beta"])


class SampleWorker:
    """Builds the dove once and turns sample indices into samples."""

    def __init__(self, config: SamplingConfig) -> None:
        config.validate()
        self.config = config
        self.ref = reference_wingbeat(config.capture_preset)
        self.examples = load_examples(config, self.ref)
        self.ellipses = Ellipses.fit(self.examples, config.bins)
        self.dove = Dove.load(feathers=config.feathers, induced=config.induced)
        self.flight = DoveFlight(self.dove, self.ref, config.table)
        self.lo, self.hi = cycle.model_dof_ranges(self.flight)
        self.P0 = reference_of(config)
        self.centre = sampling_centre(self.P0, config) - self.P0
        self.manifold = None
        if config.extrapolate > 0:
            self.manifold = Manifold.fit(self.examples)

    def header(self) -> dict:
        return {
            "kind": "phase1" if self.config.source == "capture" else "phase2",
            "model_hash": self.dove.hash(),
            "timestep": float(self.dove.model.opt.timestep),
            "reference_period": float(self.ref.period),
            "reference_coef": self.ref.coef.tolist(),
            "reference_cycles": int(self.ref.n_cycles),
            "P0": self.P0.tolist(),
            "dof_lo": self.lo.tolist(),
            "dof_hi": self.hi.tolist(),
            "examples": int(len(self.examples.dP)),
            "source_sha256": (file_sha256(self.config.source) if self.config.source != "capture"
                              else None),
            "bin_counts": self.ellipses.count.tolist(),
        }

    def close(self) -> None:
        self.flight.close()

    # -- one sample ------------------------------------------------------------------------
    def pre_state(self, rng: np.random.Generator) -> cycle.Snapshot:
        """S' filled in with the reference pose at phase 0 and resting feathers."""
        c = self.config
        fl = self.flight
        fl.reset(FlightConfig(speed=0.0, tail_bias_deg=c.tail_bias_deg), self.P0)
        d = fl.data
        pitch = np.radians(c.pitch_deg) * (2 * rng.random() - 1)
        roll = np.radians(c.roll_deg) * (2 * rng.random() - 1)
        cruise = np.array([c.cruise_speed, 0.0, 0.0])
        if c.pitch_centre_deg:
            # the trimmed trunk's level flight seen from the trunk: nose-up pitch th turns
            # the level velocity by th nose-down in the body frame
            th = np.radians(c.pitch_centre_deg)
            pitch = pitch + th
            cruise = c.cruise_speed * np.array([np.cos(th), 0.0, -np.sin(th)])
        q = pose_quat(pitch, roll)
        v_body = cruise + c.linvel * (2 * rng.random(3) - 1)
        w_body = np.radians(c.angvel_deg_s) * (2 * rng.random(3) - 1)
        R = np.zeros(9)
        mujoco.mju_quat2Mat(R, q)
        d.qpos[3:7] = q
        d.qvel[0:3] = R.reshape(3, 3) @ v_body
        d.qvel[3:6] = w_body
        mujoco.mj_forward(fl.model, d)
        return cycle.snapshot(fl)

    def draw_wingbeat(self, rng: np.random.Generator) -> np.ndarray | None:
        """A random dP (around the examples), or ``None`` when it leaves a joint range."""
        if self.manifold is not None and rng.random() < self.config.extrapolate:
            dP = self.manifold.draw_beyond(rng, self.config.extrapolate_scale)
        else:
            dP, _ = self.ellipses.draw(rng, self.config.sigma)
            dP = dP + self.centre
        if dP[-1] <= -0.5 or not in_ranges(self.ref, self.P0 + dP, self.lo, self.hi):
            return None
        return dP

    def sample(self, index: int) -> tuple[dict[str, np.ndarray] | None, str]:
        """Sample ``index``: (fields, "") or (None, rejection reason)."""
        rng = np.random.default_rng([self.config.seed, index])
        pre = self.pre_state(rng)
        dP_pre = self.draw_wingbeat(rng)
        dP = self.draw_wingbeat(rng)
        if dP_pre is None or dP is None:
            return None, "out_of_range"
        fl = self.flight
        try:
            start = cycle.fly_cycle(fl, pre, self.P0 + dP_pre, self.ref).snapshot
            S = fl.reduced_state()
            e0 = cycle.fly_cycle(fl, start, self.P0, self.ref)
            e1 = cycle.fly_cycle(fl, start, self.P0 + dP, self.ref)
        except SimulationError:
            return None, "diverged"
        return sample_fields(S, dP, e0, e1)

    def run_chunk(self, start: int, stop: int) -> ChunkResult:
        return collect_chunk(self.sample, start, stop)


def reference_of(config: SamplingConfig) -> np.ndarray:
    """The reference wingbeat P0 of ``config``'s samples: ``reference_wingbeat`` when given,
    else the capture's mean cycle with the tail and twist biases."""
    if config.reference_wingbeat:
        return np.asarray(config.reference_wingbeat, float)
    return with_twist_bias(with_tail_bias(p0(), config.tail_bias_deg), config.twist_bias_deg)


def sampling_centre(P0: np.ndarray, config: SamplingConfig) -> np.ndarray:
    """The wingbeat phase 1 draws around: ``centre_wingbeat`` when given, else P0 with both
    shoulder-flap scales multiplied by ``centre_flap_scale`` and the timewarp by
    ``centre_timewarp``."""

    if config.centre_wingbeat:
        return np.asarray(config.centre_wingbeat, float)
    return with_flap_and_beat(P0, config.centre_flap_scale, config.centre_timewarp)


