"""The learned wingbeat controller (the flight paper, sec. 4.2).

Each wingbeat, from the current full state the bird first flies the reference wingbeat
P0 in a throw-away simulation (-> S0, the "instantaneous reference"); the target state
S_target for the end of the wingbeat gives dS = S_target - S0; a regression over the
database's (dS_i, dP_i) pairs gives dP, and the bird flies P0 + dP for real.

Regression (:class:`Regressor`):

* ``knn`` (the paper's eq. 3-4): the k nearest dS_i under the weighted squared distance
  d = (dS - dS_i) W (dS - dS_i)^T, W = diag(w1, w1, w2, w2, w2, w3, w3, w3) with
  (w1, w2, w3) = (0.2, 0.24, 0.4), found with a kd-tree on sqrt(W)-scaled states, averaged
  with weights 1/d; k = 0.5 % of the database by default (paper: 50 of 10,000).
* ``lwlr``: locally weighted linear regression over a neighbourhood of the same kind (a
  weighted affine fit dP ~ a + B (dS_i - dS), ridge-regularised, evaluated at dS, i.e.
  ``a``): unlike the average, it extrapolates the local trend, so it can ask for more than
  the neighbours did. Its default k is 2 % of the database, the largest of the paper's
  Table I sweep (:data:`DEFAULT_K_SHARE`): a fit of 9 coefficients per parameter needs more
  neighbours than an average, and with 0.5 % the controller depended on the database's
  random draw (docs/flight_log.md, "How much the database's random draw matters").
* requests are first clipped, per dimension, to the [2 %, 98 %] quantiles of the
  database's dS (``clip_request``, :data:`DEFAULT_CLIP_REQUEST`): the local fit is only
  trusted where its samples are.

Mirror images (:func:`mirror_samples`, on by default in :func:`load_controller`): the dove
is mirror symmetric, so every sample's mirror image (left and right swapped: roll, sideways
velocity, roll and yaw rates negated; the wingbeat's left and right DOF swapped) is an exact
sample of the same bird, and the regression searches both. Without them the controller's
answer to a request and to its mirror image differ as much as the answers themselves do
(random samples are not mirror balanced), so the bird recovers from a push one way and
not the other. The paper mirrors its capture data; this mirrors the database.

Targets (:class:`CruiseTarget`, :class:`SteerTarget`) turn a task (hold altitude, speed and
heading; or steer by alpha and climb by beta in one wingbeat) into S_target: a
coordinated turn banks by atan(v omega / g) (the paper's eq. 5 with the centrifugal force
m v omega), the body keeps its trim angle of attack to the flight path, and the angular
velocity is the trim's plus the turn rate.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field

import numpy as np
from scipy.spatial import cKDTree

from flapsim.bird import cycle
from flapsim.bird.flight import DoveFlight, FlightConfig
from flapsim.bird.lookahead import ReferenceLookahead
from flapsim.bird.model import MIRROR_PERM
from flapsim.bird.sampling import pose_quat, project_to_ranges
from flapsim.bird.wingbeat import N_PARAMS, ReferenceWingbeat, p0, with_tail_bias
from flapsim.errors import InputError, SimulationError
from flapsim.fluid.coefficients import get_table

log = logging.getLogger(__name__)

#: The paper's distance weights (orientation, linear velocity, angular velocity).
PAPER_WEIGHTS = (0.2, 0.24, 0.4)
GRAVITY = 9.81


def weight_vector(w: tuple[float, float, float] = PAPER_WEIGHTS) -> np.ndarray:
    """diag(W) of eq. 3: (w1, w1, w2, w2, w2, w3, w3, w3)."""
    w1, w2, w3 = w
    return np.array([w1, w1, w2, w2, w2, w3, w3, w3], dtype=float)


#: The reduced-state components by which :attr:`WingbeatController.refine` ranks the
#: wingbeats it simulates and raises its request: pitch, roll and the body-frame velocity,
#: weighted as the regression weighs them (the paper's eq. 3 weights over each component's
#: spread in the database), and not the angular velocity. At a wingbeat's end the trunk's
#: angular velocity is dominated by its counter-rotation against the wings (measured in an
#: 8 m turn: the roll rate swings from +10 to -20 rad/s within 5 ms of the upstroke, and
#: wingbeats end at +-8-11 rad/s while the roll angle moves 2 deg), and the path target asks
#: for none of it (whatever P0 gives). The forward speed is judged against the speed asked
#: without the target's integral surplus (``speed_surplus``; see
#: :meth:`WingbeatController.choose`).
REFINE_COMPONENTS = np.array([True, True, True, True, True, False, False, False])


def correction_goal(S_t: np.ndarray, S_ref: np.ndarray, speed_surplus: float = 0.0,
                    reach: tuple[np.ndarray | None, np.ndarray | None] | None = None) -> np.ndarray:
    """The state :attr:`WingbeatController.refine` aims at: the target ``S_t`` less the path
    target's integral ``speed_surplus`` on the forward speed, and with ``reach`` = (lo, hi)
    each component's change from the reference wingbeat's end ``S_ref`` clipped to [lo, hi]
    (the request's clip: :attr:`WingbeatController.refine_goal` ``reachable``)."""
    goal = np.array(S_t, dtype=float)
    goal[2] -= float(speed_surplus)
    if reach is not None and reach[0] is not None:
        ref = np.asarray(S_ref, float)
        goal = ref + np.clip(goal - ref, reach[0], reach[1])
    return goal


def refine_error(S: np.ndarray, S_target: np.ndarray, weights: np.ndarray) -> float:
    """sqrt((S - S_t) W (S - S_t)^T) over :data:`REFINE_COMPONENTS`, diag W = ``weights``."""
    w = np.where(REFINE_COMPONENTS, np.asarray(weights, float), 0.0)
    d = np.asarray(S, float) - np.asarray(S_target, float)
    return float(np.sqrt(d @ (w * d)))


#: Sign of each reduced-state component in the mirror image (x forward, y left, z up):
#: pitch, roll, body velocity x y z, body angular velocity x y z.
MIRROR_STATE = np.array([1.0, -1.0, 1.0, -1.0, 1.0, -1.0, 1.0, -1.0])


def mirror_samples(dS: np.ndarray, dP: np.ndarray, P0: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The samples followed by their mirror images: dS with roll, sideways velocity, roll
    and yaw rates negated; dP such that P0 + dP' is the mirror wingbeat of P0 + dP (exact
    for any P0, symmetric or not)."""
    dS, dP, P0 = np.asarray(dS, float), np.asarray(dP, float), np.asarray(P0, float)
    if dS.ndim != 2 or dS.shape[1] != 8 or dP.ndim != 2 or dP.shape[1] != N_PARAMS or len(dP) != len(dS):
        raise InputError(f"mirror_samples needs dS (n, 8) and dP (n, {N_PARAMS}), got {dS.shape} and "
                         f"{dP.shape}")
    s, t = slice(0, -1, 2), slice(1, -1, 2)
    full = dP + P0
    mirrored = full.copy()
    mirrored[:, s] = full[:, s][:, MIRROR_PERM]
    mirrored[:, t] = full[:, t][:, MIRROR_PERM]
    return np.vstack([dS, dS * MIRROR_STATE]), np.vstack([dP, mirrored - P0])


#: The share of the database's dS left outside each dimension's range to which a request is
#: clipped by default (:class:`Regressor`'s ``clip_request``): measured on the flight suite with
#: the bundled database, k = 100, 0.02 keeps figure8, figure8-level, wind-steady and the flock
#: to three digits, completes wind-gusts (lost without) and survives 3 N pushes from the side
#: (lost without); 0.05 and 0.1 trade the sideways pushes for the upward and forward ones.
DEFAULT_CLIP_REQUEST = 0.02

#: The most simulated corrections per wingbeat (:attr:`WingbeatController.refine`).
MAX_REFINE = 5

#: What :attr:`WingbeatController.refine` aims its corrections at and ranks the wingbeats it
#: simulates by (:attr:`WingbeatController.refine_goal`): ``reachable``, the target with each
#: component's change from P0's end clipped as the request is (the database's [q, 1 - q]
#: quantiles, ``clip_request``), or ``full``, the target itself.
REFINE_GOALS = ("reachable", "full")


#: Default neighbours as a share of the samples searched, per regression method. k-NN: the
#: paper's best, 0.5 %. LWLR: 2 %, the largest share of the paper's Table I sweep (0.3-2 %).
#: Measured on eight databases trained alike (10,000 samples, seeds 1-8; nine flight
#: scenarios: the three figures of eight, the sinusoid, the forest and four winds), the mean
#: number completed was 3.9 with 0.5 %, 5.5 with 1 %, 6.25 with 2 %, 7.25 with 4 % and 6.9
#: with 8 %; but from 4 % on no database followed the sinusoid's 10 m turns and the bundled
#: one's figure-of-eight Ef rose past the paper's 0.145 m (0.18 m against 0.10 at 2 %). Why:
#: over 0.5 % of the samples the answer is mostly the draw's own noise. Asked the same 608
#: requests (the bundled database's level figure of eight), the eight databases' answers
#: differed by 0.22 of each parameter's spread (mean standard deviation across draws), 5.7x
#: as much as the answer changed along the whole flight (0.038); with 2 %: 0.10 against 0.028,
#: and a 2 % nudge of a request moved the answer 0.035 instead of 0.071. That noise lies mostly
#: where dS does not see it (29 parameters for 8 numbers): it leaves the one-wingbeat response
#: alone but changes the flight's energy and the joints' states from one wingbeat to the next.
DEFAULT_K_SHARE = {"knn": 0.005, "lwlr": 0.02}

#: :class:`Regressor`'s ``k_dense`` by default, as a share of the samples searched (the
#: paper's k share), per feather model: on for the rigid dove (its suite completed more on
#: all five database draws tried, or as many), off for the modal one (fewer on three of five).
DEFAULT_K_DENSE_SHARE = {"rigid": 0.005, "modal": 0.0}
#: Where the neighbourhood grows from ``k_dense`` to ``k``: the request's distance to its
#: ``k_dense``-th neighbour against these quantiles of the samples' own such distances.
DENSE_QUANTILES = (0.10, 0.25)


def resolve_k(n: int, k: int | None, method: str) -> int:
    """The neighbours a :class:`Regressor` over ``n`` samples uses: ``k``, or by default
    :data:`DEFAULT_K_SHARE` of ``method``; at most ``n``."""
    return min(n, k if k is not None else default_k(n, DEFAULT_K_SHARE[method]))


def default_k(n: int, fraction: float = DEFAULT_K_SHARE["knn"]) -> int:
    """k as ``fraction`` of ``n`` samples (at least 1); by default the paper's best k-NN share,
    0.5 % (:data:`DEFAULT_K_SHARE` has each method's)."""
    return max(1, int(round(fraction * n)))


class Regressor:
    """k-NN (eq. 3-4) or locally weighted linear regression from dS to dP.

    ``context`` (n, 8), optional: each sample's start state S; with ``context_weight`` > 0
    the neighbours are found by the distance over dS AND the start state,
    d = |dS - dS_i|_W^2 + context_weight |S - S_i|_W^2 (each part in units of its spread,
    the paper's weights on top), and LWLR fits dP affine in both, so a sample from a state
    unlike the bird's (a sideslip, a steep bank) is not a neighbour of a cruise request just
    because its dS is. :meth:`predict` then needs the bird's current S.

    ``k_dense`` > 0 (LWLR only): a neighbourhood that follows the samples' density. A
    request whose ``k_dense``-th neighbour is as near as it is for the densest 10 % of the
    samples themselves (:data:`DENSE_QUANTILES`) is fitted to ``k_dense`` neighbours, one as
    far as for the sparsest 75 % to ``k``, and between the two to a geometric blend of the
    counts. Cruise and path following ask for changes the samples crowd around, where few
    neighbours follow them closely; a push or a sharp turn asks for one among sparse
    samples, where many neighbours keep the fit steady (measured, see docs/flight.md).

    ``clip_request`` q > 0: each component of a requested dS is first clipped to the
    [q, 1 - q] quantiles of the database's dS. A local (LWLR) model holds only where its
    samples are; a request far outside them (a path target asking 40 deg of roll in one
    wingbeat, where 96 % of the bundled samples change it by less than 31) is extrapolated into a
    wingbeat that rolls the bird 1-4 deg, while the clipped request is answered by a
    wingbeat the database has seen do it (measured after a 3 N sideways push: 11 deg).
    """

    def __init__(self, dS: np.ndarray, dP: np.ndarray, k: int | None = None,
                 weights: tuple[float, float, float] = PAPER_WEIGHTS, method: str = "knn",
                 ridge: float = 0.03, normalize: bool = True, context: np.ndarray | None = None,
                 context_weight: float = 0.0, clip_request: float = 0.0, k_dense: int = 0) -> None:
        dS, dP = np.asarray(dS, float), np.asarray(dP, float)
        if dS.ndim != 2 or dS.shape[1] != 8 or dP.ndim != 2 or len(dP) != len(dS):
            raise InputError(f"regression needs dS (n, 8) and dP (n, m), got {dS.shape} and {dP.shape}")
        if len(dS) == 0:
            raise InputError("the database holds no samples")
        if not (np.all(np.isfinite(dS)) and np.all(np.isfinite(dP))):
            raise InputError("the database holds non-finite samples")
        if method not in ("knn", "lwlr"):
            raise InputError(f"regression method must be knn or lwlr, got {method!r}")
        if not (np.isfinite(clip_request) and 0.0 <= clip_request < 0.5):
            raise InputError(f"the request clip must be a share 0 <= q < 0.5, got {clip_request}")
        if not (np.isfinite(context_weight) and context_weight >= 0):
            raise InputError(f"the state weight must be a finite number >= 0, got {context_weight}")
        self.dS, self.dP = dS, dP
        self.w = weight_vector(weights)
        if normalize:
            # the paper's weights in units of each dimension's spread in the database
            self.w = self.w / np.maximum(dS.std(axis=0), 1e-12) ** 2
        self.normalize = normalize
        self.sqrt_w = np.sqrt(self.w)
        self.context = None
        self.context_weight = float(context_weight)
        X = dS * self.sqrt_w
        if context_weight > 0:
            if context is None:
                raise InputError("a state weight > 0 needs each sample's start state S")
            C = np.asarray(context, float)
            if C.shape != dS.shape or not np.all(np.isfinite(C)):
                raise InputError(f"the start states must be {dS.shape} finite numbers, got {C.shape}")
            wc = weight_vector(weights) * context_weight
            if normalize:
                wc = wc / np.maximum(C.std(axis=0), 1e-12) ** 2
            self.context, self.sqrt_wc = C, np.sqrt(wc)
            X = np.hstack([X, C * self.sqrt_wc])
        self.k = resolve_k(len(dS), k, method)
        if self.k < 1:
            raise InputError(f"k must be >= 1, got {k}")
        self.method = method
        self.ridge = ridge
        self.tree = cKDTree(X)
        self.k_dense = int(k_dense)
        self.dense_radii: tuple[float, float] | None = None
        if self.k_dense:
            if method != "lwlr":
                raise InputError("a density-following neighbourhood (k_dense) is LWLR's")
            if not 1 <= self.k_dense <= self.k:
                raise InputError(f"k_dense must be 1..k ({self.k}), got {k_dense}")
            if self.k_dense < self.k and self.n > self.k_dense + 1:
                # the samples' own distances to their k_dense-th neighbour (itself excluded),
                # from a fixed subset: deterministic and ~50 ms for 20,000 samples
                sub = np.random.default_rng(0).choice(self.n, min(self.n, 2000), replace=False)
                d, _ = self.tree.query(X[sub], k=self.k_dense + 1)
                lo, hi = np.quantile(d[:, -1], DENSE_QUANTILES)
                self.dense_radii = (float(lo), float(max(hi, lo * (1 + 1e-9))))
        self.dP_lo, self.dP_hi = dP.min(axis=0), dP.max(axis=0)
        self.clip_request = float(clip_request)
        self.dS_lo = self.dS_hi = None
        if clip_request > 0:
            self.dS_lo, self.dS_hi = np.quantile(dS, [clip_request, 1.0 - clip_request], axis=0)

    @property
    def n(self) -> int:
        return len(self.dS)

    @property
    def conditioned(self) -> bool:
        """Whether :meth:`predict` needs the current start state (``context_weight`` > 0)."""
        return self.context is not None

    def _query_point(self, x: np.ndarray, s: np.ndarray | None) -> np.ndarray:
        q = np.asarray(x, float) * self.sqrt_w
        if self.context is None:
            return q
        s = np.asarray(s, float) if s is not None else None
        if s is None or s.shape != (8,) or not np.all(np.isfinite(s)):
            raise InputError(f"a state-conditioned regression needs the current state S (8 finite "
                             f"numbers), got {s}")
        return np.concatenate([q, s * self.sqrt_wc])

    def neighbours(self, x: np.ndarray, k: int | None = None, s: np.ndarray | None = None
                   ) -> tuple[np.ndarray, np.ndarray]:
        """(weighted squared distances (k,), indices (k,)) of the k nearest samples (to dS
        ``x`` and, when conditioned, start state ``s``)."""
        k = k or self.k
        dist, idx = self.tree.query(self._query_point(x, s), k=k)
        return np.atleast_1d(dist) ** 2, np.atleast_1d(idx)

    def predict(self, x: np.ndarray, s: np.ndarray | None = None) -> np.ndarray:
        """dP for a differential state ``x`` (8,) (from start state ``s`` (8,): needed when
        :attr:`conditioned`, ignored otherwise)."""
        x = np.asarray(x, float)
        if x.shape != (8,) or not np.all(np.isfinite(x)):
            raise InputError(f"a differential state has 8 finite numbers, got {x}")
        if self.dS_lo is not None:
            # ask for no more than the database's wingbeats did (see ``clip_request``)
            x = np.clip(x, self.dS_lo, self.dS_hi)
        if self.method == "lwlr":
            # a local linear model may extrapolate: never past the database's own wingbeats
            return np.clip(self._lwlr(x, s), self.dP_lo, self.dP_hi)
        d2, idx = self.neighbours(x, s=s)
        return idw_average(d2, self.dP[idx])

    def neighbourhood(self, x: np.ndarray, s: np.ndarray | None = None) -> int:
        """How many neighbours LWLR fits for request ``x``: ``k``, or with ``k_dense`` between
        it and ``k`` by the samples' density there (see the class)."""
        if self.dense_radii is None:
            return self.k
        d2, _ = self.neighbours(x, self.k_dense, s)
        lo, hi = self.dense_radii
        t = min(1.0, max(0.0, (float(np.sqrt(d2[-1])) - lo) / (hi - lo)))
        return int(round(np.exp(np.log(self.k_dense) + t * (np.log(self.k) - np.log(self.k_dense)))))

    def _lwlr(self, x: np.ndarray, s: np.ndarray | None = None) -> np.ndarray:
        m = 8 if self.context is None else 16  # inputs of the affine fit: dS (and S)
        # an affine fit in m inputs needs a neighbourhood of > m + 1
        k = max(self.neighbourhood(x, s), 4 * (m + 1))
        d2, idx = self.neighbours(x, min(k, self.n), s)
        h2 = max(float(d2.max()), 1e-12)
        wts = np.exp(-d2 / h2)  # Gaussian kernel with the neighbourhood's radius
        X = (self.dS[idx] - x) * self.sqrt_w
        if self.context is not None:
            X = np.hstack([X, (self.context[idx] - s) * self.sqrt_wc])
        A = np.hstack([np.ones((len(idx), 1)), X])
        Aw = A * wts[:, None]
        G = A.T @ Aw
        G[1:, 1:] += self.ridge * np.trace(G[1:, 1:]) / m * np.eye(m) + 1e-12 * np.eye(m)
        coef = np.linalg.solve(G, Aw.T @ self.dP[idx])
        return coef[0]


def idw_average(d2: np.ndarray, values: np.ndarray) -> np.ndarray:
    """Eq. 4: the average of ``values`` weighted by 1 / d; an exact match (d = 0) wins."""
    exact = d2 <= 1e-300
    if np.any(exact):
        return values[exact].mean(axis=0)
    w = 1.0 / d2
    return (w @ values) / w.sum()


# -- targets --------------------------------------------------------------------------------


@dataclass(frozen=True)
class Trim:
    """The reduced state of steady level flight at the start of a wingbeat (pitch, angular
    velocity and velocity direction in the body frame oscillate within a wingbeat, so the
    target takes them at the same phase)."""

    S: np.ndarray
    """(8,) mean reduced state at wingbeat starts."""

    @property
    def pitch(self) -> float:
        return float(self.S[0])

    @property
    def aoa(self) -> float:
        """Body pitch above the flight path (velocity) at the wingbeat start, rad."""
        v = self.S[2:5]
        return float(-np.arctan2(v[2], v[0]))


def trim_of_base_flight(fl: DoveFlight, P0: np.ndarray, cfg: FlightConfig | None = None,
                        wingbeats: int = 6, skip: int = 2) -> Trim:
    """Mean start-of-wingbeat state of the base controller over ``wingbeats`` after ``skip``,
    flown in still air whatever the flight's wind: the target adds the wind to the air-relative
    trim (:func:`target_state`). Flown in a 2 m/s crosswind from a start along +x, the base
    flight sideslipped, and its mean body-frame velocity put the angle of attack at 8.2 deg
    against the still-air trim's 2.8: every wingbeat then asked 5.4 deg more angle of attack,
    the dove slowed to ~4.5 m/s and did not reach the 40 m path's end in time."""
    states = []
    with fl.flow.still():
        fl.reset(cfg or FlightConfig(), P0)
        for i in range(skip + wingbeats):
            cycle.fly_cycle(fl, None, P0)
            if i >= skip:
                states.append(fl.reduced_state())
    S = np.mean(states, axis=0)
    S[1] = 0.0
    S[3] = 0.0
    S[5] = 0.0
    S[7] = 0.0
    return Trim(S)


def target_state(trim: Trim, speed: float, heading: float, climb: float, turn_rate: float,
                 S_now: np.ndarray | None = None, settle_s: float = 0.2,
                 wind: np.ndarray | None = None, aoa_per_g: float = 0.0) -> np.ndarray:
    """S at the end of a wingbeat flying at ``speed`` along (``heading``, ``climb``) and
    turning at ``turn_rate`` (rad/s, + left) in a coordinated turn: banked by
    atan(v omega / g) toward the inside, nose ``trim.aoa`` above the flight path.

    ``wind`` (world, m/s): the heading, climb and speed then describe the velocity through
    the AIR, which the body's attitude follows (a bird crabs into a crosswind); S carries
    the body-frame velocity over the ground, as the reduced state measures it.

    The angular velocity asked is the trim's, plus the turn rate, plus the rates that would
    take the pitch and roll of ``S_now`` (where the reference wingbeat would leave the bird)
    to the target's in ``settle_s`` seconds: without them the target asks for an
    orientation while holding the rates that keep it from getting there.

    ``aoa_per_g`` (rad per g, default 0: the trim's angle of attack in any turn): the nose is
    asked ``aoa_per_g (n - 1)`` higher above the flight path in a turn of load factor
    n = 1 / cos(bank). A banked wing at the level trim's angle of attack carries only
    cos(bank) of the weight; quasi-steady lift grows with the angle of attack (the reference
    wingbeat at 7 m/s: 1.01 of the weight at 5 deg, 1.41 at 15 deg, ~25 deg per g).
    """
    import mujoco

    bank = float(np.arctan2(speed * turn_rate, GRAVITY))
    # wind axes first (heading, climb, then the bank about the flight path), then the body's
    # angle of attack about its own y axis: the bank turns about the velocity, so the
    # body-frame velocity has no sideslip
    # (left wing down by ``bank`` is a rotation about the forward axis by -bank: y left)
    # the load factor of the coordinated turn (cos(bank) floored: a bank near 90 deg asks at
    # most 5 g's worth)
    aoa = trim.aoa + aoa_per_g * (1.0 / max(float(np.cos(bank)), 0.2) - 1.0)
    R = (_rot_z(heading) @ _rot_y(-climb) @ _rot_x(-bank)
         @ _rot_y(-aoa))
    del mujoco
    v = speed * np.array([np.cos(climb) * np.cos(heading), np.cos(climb) * np.sin(heading),
                          np.sin(climb)])
    if wind is not None:
        v = v + np.asarray(wind, float)
    w_body = trim.S[5:8] + R.T @ np.array([0.0, 0.0, turn_rate])
    from flapsim.bird.flight import pitch_roll

    p, r = pitch_roll(R)
    if S_now is not None and settle_s <= 0:
        # no demand on the angular velocity: whatever the reference wingbeat would give
        w_body = S_now[5:8].copy()
    elif S_now is not None:
        # d(pitch)/dt = -w_y and d(roll)/dt = -w_x * ROLL_SIGN (body axes x fwd, y left, z up)
        w_body[1] -= (p - S_now[0]) / settle_s
        w_body[0] -= ROLL_RATE_SIGN * (r - S_now[1]) / settle_s
    return np.array([p, r, *(R.T @ v), *w_body])


def _rot_x(a: float) -> np.ndarray:
    c, s = np.cos(a), np.sin(a)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def _rot_y(a: float) -> np.ndarray:
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def _rot_z(a: float) -> np.ndarray:
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def _roll_rate_sign() -> float:
    """+1 if a positive body-x angular velocity decreases :func:`pitch_roll`'s roll, else -1."""
    import mujoco

    from flapsim.bird.flight import pitch_roll

    q = np.array([np.cos(0.05), np.sin(0.05), 0.0, 0.0])  # small rotation about +x
    R = np.zeros(9)
    mujoco.mju_quat2Mat(R, q)
    return 1.0 if pitch_roll(R.reshape(3, 3))[1] < 0 else -1.0


ROLL_RATE_SIGN = _roll_rate_sign()


def bank_to_roll(bank_left: float) -> float:
    """The roll angle (in :func:`~flapsim.bird.flight.pitch_roll`'s convention) of a bank
    with the left wing down by ``bank_left`` rad (a left turn)."""
    import mujoco

    from flapsim.bird.flight import pitch_roll

    # left wing down = rotation about +x (forward) by -bank in a right-handed frame with
    # y to the left: find which sign pitch_roll reports for it
    th = -bank_left
    q = np.array([np.cos(th / 2), np.sin(th / 2), 0.0, 0.0])
    R = np.zeros(9)
    mujoco.mju_quat2Mat(R, q)
    return pitch_roll(R.reshape(3, 3))[1]


@dataclass
class CruiseTarget:
    """Hold an altitude, a speed and a heading: the outer loop of the wingbeat controller.

    Proportional-integral on each error: the wingbeat controller reaches a requested state
    change only in part (the regression's gain is below one and biased), so a proportional
    loop alone leaves steady offsets (measured: +3.5 deg heading, -0.5 m/s speed over 100
    wingbeats); the integrals remove them. The integrals are the target's state (a new
    flight needs a new target, or :meth:`reset`).
    """

    trim: Trim
    altitude: float
    """m."""
    speed: float = FlightConfig.speed
    """m/s."""
    heading: float = 0.0
    """rad (+ left of +x)."""
    k_altitude: float = 0.6
    """Climb rate asked per metre of altitude error, 1/s."""
    ki_altitude: float = 0.15
    """... per metre-second of its integral, 1/s^2."""
    max_climb_deg: float = 8.0
    """Largest climb/descent angle asked, deg."""
    k_heading: float = 1.5
    """Turn rate asked per radian of heading error, 1/s."""
    ki_heading: float = 0.4
    """... per radian-second of its integral, 1/s^2."""
    max_bank_deg: float = 30.0
    """Largest bank asked, deg."""
    ki_speed: float = 0.3
    """Speed asked above the target per m/s-second of the speed error's integral, 1/s."""
    max_speed_offset: float = 2.0
    """Largest speed offset the integral may ask, m/s."""
    settle_s: float = 0.0
    """Time over which pitch and roll errors are asked to close through the angular velocity,
    s (see :func:`target_state`); 0 (default): ask no angular velocity, keep the reference
    wingbeat's. Measured with the bundled database (100 wingbeats from -10..10 deg of roll):
    0 held all six starts, 0.2 s four (an undamped roll oscillation in the others, also after
    ~150 wingbeats from 2 deg), 0.4 s four: the boundary angular velocity swings with every
    flap, and asking for it drags the regression off what matters."""
    integrals: np.ndarray = field(default_factory=lambda: np.zeros(3))
    """Running integrals of (altitude, heading, speed) errors."""
    speed_surplus: float = 0.0
    """The speed the last target asked above ``speed`` by its integral, m/s."""

    def simulates(self, count: int) -> bool:
        """Whether the ``count``-th wingbeat since a (re)start simulates P0."""
        return count < self.warmup or (count - self.warmup) % self.every == 0

    def reset(self) -> None:
        self.integrals[:] = 0.0

    def __call__(self, e0: cycle.CycleEnd) -> np.ndarray:
        dt = e0.duration
        h, _ = cycle.heading_and_climb(e0.com_vel)
        e_h = float(cycle.wrap(self.heading - h))
        e_z = float(e0.trunk_pos[2]) - self.altitude
        e_v = self.speed - float(np.linalg.norm(e0.com_vel))
        lim = np.array([self.speed * np.sin(np.radians(self.max_climb_deg)) / max(self.ki_altitude, 1e-9),
                        np.radians(self.max_bank_deg) / max(self.ki_heading, 1e-9),
                        self.max_speed_offset / max(self.ki_speed, 1e-9)])
        self.integrals[:] = np.clip(self.integrals + dt * np.array([e_z, e_h, e_v]), -lim, lim)
        iz, ih, iv = self.integrals
        max_rate = GRAVITY * np.tan(np.radians(self.max_bank_deg)) / self.speed
        rate = float(np.clip(self.k_heading * e_h + self.ki_heading * ih, -max_rate, max_rate))
        speed = self.speed + self.ki_speed * iv
        self.speed_surplus = self.ki_speed * iv  # what the refinement leaves to this loop
        vz = -self.k_altitude * e_z - self.ki_altitude * iz
        climb = float(np.clip(np.arcsin(np.clip(vz / speed, -1, 1)),
                              -np.radians(self.max_climb_deg), np.radians(self.max_climb_deg)))
        return target_state(self.trim, speed, h + rate * dt, climb, rate, e0.S, self.settle_s)


@dataclass
class SteerTarget:
    """Steer by ``alpha`` and climb by ``beta`` (rad) over one wingbeat, relative to where the
    reference wingbeat would have taken the bird, at its speed."""

    trim: Trim
    alpha: float
    beta: float
    settle_s: float = 0.2
    max_bank_deg: float = 60.0
    """Largest bank asked (a coordinated turn at alpha per wingbeat would ask
    atan(v alpha / (T g)): 74 deg for 30 deg per wingbeat)."""

    def __call__(self, e0: cycle.CycleEnd) -> np.ndarray:
        h, c = cycle.heading_and_climb(e0.com_vel)
        speed = float(np.linalg.norm(e0.com_vel))
        max_rate = GRAVITY * np.tan(np.radians(self.max_bank_deg)) / max(speed, 1e-3)
        rate = float(np.clip(self.alpha / e0.duration, -max_rate, max_rate))
        return target_state(self.trim, speed, h + self.alpha, c + self.beta, rate, e0.S,
                            self.settle_s)


def fit_steering_signature(dS: np.ndarray, alpha: np.ndarray, beta: np.ndarray) -> np.ndarray:
    """(8, 2) matrix D with dS ~ D (alpha, beta): the state change that comes with steering
    alpha and elevation beta in a database (least squares through the origin, since the
    reference wingbeat itself is dS = 0 at alpha = beta = 0)."""
    A = np.stack([np.asarray(alpha, float), np.asarray(beta, float)], axis=1)
    D, *_ = np.linalg.lstsq(A, np.asarray(dS, float), rcond=None)
    return D.T


@dataclass
class SignatureTarget:
    """Steer by ``alpha`` and climb by ``beta`` in one wingbeat, asked in the state space the
    controller regresses over: S0 + D (alpha, beta), with D the database's steering
    signature (:func:`fit_steering_signature`). The paper places wingbeats in the alpha-beta
    plane by angles "computed from dS"; this is the inverse of that map."""

    D: np.ndarray
    alpha: float
    beta: float

    def __call__(self, e0: cycle.CycleEnd) -> np.ndarray:
        return e0.S + self.D @ np.array([self.alpha, self.beta])


@dataclass
class PathTurnTarget:
    """Turn the flight path by ``alpha`` (left +) and ``beta`` (up +) within one wingbeat,
    relative to where the reference wingbeat takes it, keeping the reference's attitude
    and rates: S0 with its body-frame velocity rotated by alpha about the body's z axis
    and beta about its y axis. Unlike :class:`SteerTarget` (a coordinated turn, which
    S can only express as bank and yaw rate because it is heading invariant) this asks
    for the change of flight direction itself, in the frame S is measured in."""

    alpha: float
    beta: float

    def __call__(self, e0: cycle.CycleEnd) -> np.ndarray:
        v = e0.S[2:5]
        ca, sa, cb, sb = np.cos(self.alpha), np.sin(self.alpha), np.cos(self.beta), np.sin(self.beta)
        Rz = np.array([[ca, -sa, 0.0], [sa, ca, 0.0], [0.0, 0.0, 1.0]])
        Ry = np.array([[cb, 0.0, -sb], [0.0, 1.0, 0.0], [sb, 0.0, cb]])  # +beta tips +x up
        S = e0.S.copy()
        S[2:5] = Rz @ Ry @ v
        return S


# -- a cheaper S0 -----------------------------------------------------------------------------

PREDICT_MODES = ("simulate", "coarse", "regression")

#: Step rate of ``predict="coarse"``'s throw-away wingbeat, Hz (the flight's own is 2400).
COARSE_RATE_HZ = 1600.0


def _rot_z(a: float) -> np.ndarray:
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


@dataclass
class S0Predictor:
    """S0 (where P0 would end) without simulating P0 on most wingbeats: EXPERIMENTAL, not
    robust (see below); the default is to simulate P0 every wingbeat.

    S alone does not determine S0: the full state also holds the joint angles and rates and
    the feather hinges, which S omits. Over the bundled database (start states after a random
    pre-wingbeat) an S -> S0 regression misses S0 by 10-35 % of dS's spread; along a
    controlled flight (start states after controlled wingbeats) it is biased (vy by 0.05 m/s,
    roll by 0.01 rad) but its error varies slowly. So: a locally weighted linear regression
    S -> S0 over the database's (S, S0) pairs, plus a bias measured by simulating P0 on the
    first ``warmup`` wingbeats after a (re)start (a new flight, or a state the flight did not
    reach by the last controlled wingbeat), then every ``every``-th, and on the next one too
    whenever a simulated wingbeat shows that the prediction would have missed by more than
    ``tolerance``; the bias is low-passed with ``gain``. The world quantities of a predicted
    end (centre-of-mass velocity, trunk position and orientation) are the start's plus the
    change P0 made in the last simulated prediction, in the start's heading frame.

    Measured (bundled database): cruise and the level figure of eight fly as with simulated
    S0 (level figure of eight Ep/Er/Eo/Ef 0.042/0.026/0.011/0.105 against 0.042/0.026/0.010/
    0.098) at 1.4-1.6x the speed, but the rising figure of eight is LOST (wingbeat ~160-250)
    with every variant tried (bias gain 0.5/1, tolerance halved: 212 of 305 wingbeats
    simulated); in its climbing lobe the regression's misses are correlated (vy 0.15-0.4
    m/s, pitch 0.05-0.18 rad). That path is on a knife edge even with S0 simulated: asked
    6.995-7.005 m/s it completes 6 of 7 runs (lost at 7.003), this predictor 2 of 7, and
    Gaussian errors of 1-100 % of the typical miss added to the simulated S0 lose it in 1-3
    of 3 seeds. An S0 model fitted online on the flight's own simulated wingbeats (joint state
    and the last wingbeat as inputs) halved the misses and completed 1 of 7: not kept.
    """

    regressor: Regressor
    """S (8) -> S0 (8)."""
    every: int = 4
    gain: float = 0.5
    warmup: int = 8
    """Wingbeats simulated after a (re)start before predicting: the start's hidden state (a
    reset pose) is unlike a controlled flight's, and the bias moves fast while it settles."""
    tolerance: tuple = (0.02, 0.02, 0.1, 0.1, 0.1)
    """Largest acceptable miss of the prediction (pitch, roll rad; body velocity m/s): when a
    simulated wingbeat shows that the prediction would have missed S0 by more (its
    innovation), the next wingbeat is simulated too, until it would not."""
    _next: int = 0
    bias: np.ndarray = field(default_factory=lambda: np.zeros(8))
    count: int = 0
    """Wingbeats since the last restart (0: the next one simulates)."""
    _last_end: np.ndarray | None = None
    _delta: tuple | None = None

    def __post_init__(self) -> None:
        if int(self.every) < 1:
            raise InputError(f"the S0 prediction simulates every N-th wingbeat, N >= 1; got {self.every}")
        if int(self.warmup) < 1:
            raise InputError(f"the S0 prediction simulates >= 1 wingbeat after a start, got {self.warmup}")
        if not 0.0 < self.gain <= 1.0:
            raise InputError(f"the S0 bias gain must be in (0, 1], got {self.gain}")

    @classmethod
    def from_arrays(cls, S: np.ndarray, S0: np.ndarray, k: int = 200, **kw) -> S0Predictor:
        return cls(Regressor(S, S0, k=k, weights=(1.0, 1.0, 1.0), method="lwlr"), **kw)

    def reset(self) -> None:
        self.count, self.bias[:], self._last_end, self._delta, self._next = 0, 0.0, None, None, 0

    def reference(self, ctl: WingbeatController, snap: cycle.Snapshot) -> cycle.CycleEnd:
        """P0's end from ``snap``: simulated (and the bias updated) or predicted."""
        import mujoco

        fl = ctl.flight
        if self._last_end is None or not np.array_equal(snap.physics, self._last_end):
            self.reset()  # a new flight, or a state set from outside: measure the bias afresh
        cycle.restore(fl, snap)
        d = fl.data
        S = fl.reduced_state()
        pos, quat, vel = d.qpos[0:3].copy(), d.qpos[3:7].copy(), fl.com_velocity()
        R = _rot_z(cycle.heading_and_climb(vel)[0])
        guess = self.regressor.predict(S)
        if self.count >= self._next:
            e0 = cycle.fly_cycle(fl, snap, ctl.P0, ctl.ref)
            miss = e0.S - guess
            innovation = miss - self.bias  # what the prediction would have missed by
            calm = self.count > 0 and bool(np.all(np.abs(innovation[:5]) <= self.tolerance))
            self.bias = miss if self.count == 0 else (1 - self.gain) * self.bias + self.gain * miss
            self._next = self.count + (self.every if calm and self.count + 1 >= self.warmup else 1)
            q_rel = np.empty(4)
            mujoco.mju_negQuat(q_rel, quat)
            mujoco.mju_mulQuat(q_rel, q_rel, e0.trunk_quat)
            self._delta = (R.T @ (e0.com_vel - vel), R.T @ (e0.trunk_pos - pos - e0.duration * vel),
                           q_rel, e0.duration)
        else:
            dv, dp, q_rel, T = self._delta
            q = np.empty(4)
            mujoco.mju_mulQuat(q, quat, q_rel)
            physics = snap.physics.copy()
            physics[0] += T
            e0 = cycle.CycleEnd(cycle.Snapshot(physics, snap.warmstart, snap.userdata), guess + self.bias,
                                pos + T * vel + R @ dp, q, vel + R @ dv, T, 0.0, predicted=True)
        self.count += 1
        return e0

    def flown(self, end: cycle.CycleEnd) -> None:
        """The wingbeat flown ended at ``end``: the next prediction continues from there."""
        self._last_end = end.snapshot.physics


@dataclass
class CoarsePredictor:
    """S0 from P0 simulated every wingbeat, as the paper does, but at a coarser step
    (``rate_hz``, default 1600 Hz against the flight's 2400) on a copy of the flight
    (:meth:`~flapsim.bird.flight.DoveFlight.twin`: the same forces, flows and plucked
    feathers), so the prediction costs 2/3 of a wingbeat instead of one. Only the prediction
    is coarse: the wingbeat flown is stepped at the flight's own rate.

    Measured along the rising figure of eight (bundled database; S0 at 1600 Hz against
    2400 Hz, every wingbeat): RMS differences 0.0016/0.0009 rad in pitch/roll, 0.003-0.016
    m/s in the body velocity, 0.014-0.036 rad/s in the angular velocity, 1-2 % of the
    database's dS spread; the rising figure of eight completes at all 7 asked speeds
    6.995-7.005 m/s, against 3 of 7 at 1400 Hz and none at 1300. At 1200 Hz the misses are
    5-10x larger and it is lost, with or without a bias correction from fine wingbeats;
    likely (inferred, not tested) because the servos of the light distal joints (kp 10
    N m/rad on the wrist's 2.4e-6 kg m^2 effective inertia: ~320 Hz) are then stepped at
    omega dt = 1.7, near the explicit position feedback's limit of 2 (0.84 at 2400 Hz, 1.3
    at 1600 Hz)."""

    rate_hz: float = COARSE_RATE_HZ
    _twin: object = None
    _of: object = None

    def reference(self, ctl: WingbeatController, snap: cycle.Snapshot) -> cycle.CycleEnd:
        """P0's end from ``snap``, simulated on the coarse copy."""
        if self._twin is None or self._of is not ctl.flight:
            self._twin, self._of = ctl.flight.twin(self.rate_hz), ctl.flight
        return cycle.fly_cycle(self._twin, snap, ctl.reference_params(), ctl.ref)

    def flown(self, end: cycle.CycleEnd) -> None:
        """Nothing carries over between wingbeats."""

    def reset(self) -> None:
        """Nothing carries over between wingbeats."""


# -- the controller -------------------------------------------------------------------------


@dataclass
class ControlStep:
    """What the controller did in one wingbeat."""

    P: np.ndarray
    """The wingbeat flown."""
    dS_target: np.ndarray
    """S_target - S0."""
    S_target: np.ndarray
    reference: cycle.CycleEnd
    """Where P0 would have ended."""
    end: cycle.CycleEnd
    """Where P ended."""
    projected: bool
    """True when P0 + dP left a joint range and was pulled back in."""
    simulated: int = 1
    """Wingbeats simulated to choose it (1 + :attr:`WingbeatController.refine`; 1 when the
    answer is flown as it is); P0's simulation for S0 not counted."""


@dataclass
class WingbeatController:
    """P = P0 + regression(S_target - S0), one wingbeat at a time."""

    flight: DoveFlight
    regressor: Regressor
    P0: np.ndarray = field(default_factory=lambda: with_tail_bias(p0(), FlightConfig.tail_bias_deg))
    lo: np.ndarray | None = None
    hi: np.ndarray | None = None
    predictor: S0Predictor | CoarsePredictor | None = None
    """None (default): S0 from a simulation of P0 every wingbeat (the paper); else simulated
    at a coarser step (:class:`CoarsePredictor`) or predicted (:class:`S0Predictor`)."""
    carry: float = 0.0
    """Share c of the last wingbeat's change from P0 that the next wingbeat starts from:
    its reference is P0 + c (P_last - P0), simulated for S0 as P0 is, and the regression's
    dP is added to it (0, the default: P0 every wingbeat, the paper's). In a sustained turn
    or after a push the answer to a request falls short of it (the regression delivers part
    of a requested change); carrying the last answer keeps what was reached and asks only
    the rest (integral action in wingbeat space). The sum stays within the database's dP."""
    refine: int = 0
    """Simulated corrections per wingbeat (0, the default: the regression's answer is flown
    as it is, the paper's). With N > 0 the answer P1 is simulated from the wingbeat's start
    before it is flown; where it would end short of the target, the request is raised by the
    shortfall in pitch, roll and velocity (:data:`REFINE_COMPONENTS`) and answered again, N
    times, and of the N + 1 wingbeats simulated the one that ends nearest the target, in the
    regression's own metric, is flown. Its simulation is the flight itself: the chosen end is
    restored, not flown again, unless a push or a record asks for it. The regression's local
    model holds near the samples' calm, near-level start states; in a steep bank the same dP
    rolls the bird differently (measured: asked -8.7 deg of roll, flown -45.6), and the
    simulation sees it. Each correction costs one wingbeat's simulation."""
    lookahead: ReferenceLookahead | None = None
    """None (default): each wingbeat's reference is simulated when it is needed. A
    :class:`~flapsim.bird.lookahead.ReferenceLookahead` (:func:`enable_lookahead`): with
    ``refine`` > 0 and S0 simulated, the next wingbeat's reference is simulated from each
    best-so-far candidate's end in a second thread while the next correction runs; the flight
    is the same to the bit, the wall time shorter on two free cores."""
    refine_goal: str = "full"
    """What the corrections aim at and rank by (:data:`REFINE_GOALS`): ``full``, the target
    (the default here; :func:`load_controller` uses :data:`DEFAULT_REFINE_GOAL`), or
    ``reachable``, the target with each component's change from P0's end clipped as the
    request is (needs the regression's ``clip_request``). Far from what any wingbeat can do
    in one beat (the forward speed a slowing dove is asked, 2-4 m/s short), the unreachable
    part of the shortfall outweighs the rest in the ranking, and the wingbeat that keeps a
    little more speed is flown over the one that holds the bank or the pitch asked."""
    _last: np.ndarray | None = field(default=None, repr=False)

    def __post_init__(self) -> None:
        if self.refine_goal not in REFINE_GOALS:
            raise InputError(f"refine_goal must be one of {', '.join(REFINE_GOALS)}, got "
                             f"{self.refine_goal!r}")
        if (isinstance(self.refine, bool) or not isinstance(self.refine, (int, np.integer))
                or not 0 <= int(self.refine) <= MAX_REFINE):
            raise InputError(f"refine (simulated corrections per wingbeat) must be 0..{MAX_REFINE}, "
                             f"got {self.refine!r}")
        if self.regressor.dP.shape[1] != N_PARAMS:
            raise InputError(f"database dP has {self.regressor.dP.shape[1]} columns, expected {N_PARAMS}")
        if not (np.isfinite(self.carry) and 0.0 <= self.carry <= 1.0):
            raise InputError(f"the wingbeat carry must be a share 0..1, got {self.carry}")
        if self.lo is None or self.hi is None:
            self.lo, self.hi = cycle.model_dof_ranges(self.flight)

    def reset(self) -> None:
        """Forget the last wingbeat (a new flight)."""
        self._last = None
        if self.predictor is not None:
            self.predictor.reset()
        if self.lookahead is not None:
            self.lookahead.drop()

    def reference_params(self) -> np.ndarray:
        """The wingbeat simulated for S0 and added to: P0 + carry (P_last - P0)."""
        return self._reference_after(self._last)

    def _reference_after(self, last: np.ndarray | None) -> np.ndarray:
        if self.carry == 0.0 or last is None:
            return self.P0
        return self.P0 + self.carry * (last - self.P0)

    @property
    def ref(self) -> ReferenceWingbeat:
        return self.flight.ref

    def choose(self, target, snap: cycle.Snapshot | None = None, record: bool = False,
               push: cycle.Push | None = None) -> ControlStep:
        """Decide and fly one wingbeat toward ``target`` (a callable: P0's end -> S_target).
        ``push`` acts on the wingbeat flown only: the controller's prediction cannot see it
        coming."""
        fl = self.flight
        S_now = None
        if self.regressor.conditioned:
            if snap is not None:
                cycle.restore(fl, snap)
            S_now = fl.reduced_state()  # the wingbeat's start state, as the samples' S
        snap = snap or cycle.snapshot(fl)
        base = self.reference_params()
        if self.predictor is None:
            e0 = self.lookahead.take(snap, base) if self.lookahead is not None else None
            if e0 is None:
                e0 = cycle.fly_cycle(fl, snap, base, self.ref)
        else:
            e0 = self.predictor.reference(self, snap)
        S_t = np.asarray(target(e0), float)
        dS = S_t - e0.S
        Pp, projected = self._answer(dS, S_now, base)
        end, tried = None, 1
        if self.refine:
            # the forward speed is judged against the speed asked, less what the target's
            # integral asks on top: with it, a bird short of speed for long (a tight turn
            # winds the integral up to 2 m/s) is asked a speed no wingbeat reaches, and the
            # ranking turned into "lose the least speed" (pushed 6 N sideways, the dove drifted
            # 11 m from the path before turning back: 2.2 m without the corrections)
            reg = self.regressor
            reach = (reg.dS_lo, reg.dS_hi) if self.refine_goal == "reachable" else None
            goal = correction_goal(S_t, e0.S, float(getattr(target, "speed_surplus", 0.0)), reach)
            Pp, projected, end, tried = self._refined(snap, Pp, projected, dS, goal, S_now, base)
        if end is None or push is not None or record:
            end = cycle.fly_cycle(fl, snap, Pp, self.ref, record=record, push=push)
        else:
            cycle.restore(fl, end.snapshot)  # the chosen wingbeat's simulation was the flight
        self._last = Pp
        if self.predictor is not None:
            self.predictor.flown(end)
        return ControlStep(Pp, dS, S_t, e0, end, projected, tried)

    def _answer(self, dS: np.ndarray, S_now, base: np.ndarray) -> tuple[np.ndarray, bool]:
        """The wingbeat for request ``dS`` (within the joint ranges) and whether it was pulled
        back into them."""
        dP = self.regressor.predict(dS, S_now)
        if base is not self.P0:
            # what is carried plus the answer, within the database's own wingbeats
            dP = np.clip(base - self.P0 + dP, self.regressor.dP_lo, self.regressor.dP_hi)
        P = self.P0 + dP
        Pp = project_to_ranges(self.ref, P, self.lo, self.hi)
        return Pp, bool(np.max(np.abs(Pp - P)) > 1e-12)

    def _refined(self, snap, P, projected, dS, S_t, S_now, base):
        """:attr:`refine`: (wingbeat, projected, its simulated end or None, wingbeats
        simulated)."""
        best, request, n = None, dS.copy(), int(self.refine)
        for i in range(n + 1):
            try:
                e = cycle.fly_cycle(self.flight, snap, P, self.ref)
            except SimulationError:
                break  # this answer diverges from here: not a candidate, and nothing to correct
            err = refine_error(e.S, S_t, self.regressor.w)
            if best is None or err < best[0]:
                best = (err, P, projected, e)
                if self.lookahead is not None and self.predictor is None:
                    # the next wingbeat's reference if this one is flown, on the other core
                    # while the next correction is simulated here
                    self.lookahead.submit(e.snapshot, self._reference_after(P), self.ref)
            if i == n:
                break
            request = request + np.where(REFINE_COMPONENTS, S_t - e.S, 0.0)
            P, projected = self._answer(request, S_now, base)
        if best is None:
            return P, projected, None, i + 1  # flown as it is: its divergence is reported there
        return best[1], best[2], best[3], i + 1

    @property
    def predict(self) -> str:
        """How S0 is found: ``simulate``, ``coarse`` (:class:`CoarsePredictor`) or
        ``regression`` (:class:`S0Predictor`)."""
        if self.predictor is None:
            return "simulate"
        return "coarse" if isinstance(self.predictor, CoarsePredictor) else "regression"


@dataclass
class BaseController:
    """The base controller in the learned one's interface: always P0 (for comparisons)."""

    flight: DoveFlight
    P0: np.ndarray

    def choose(self, target, snap: cycle.Snapshot | None = None, record: bool = False,
               push: cycle.Push | None = None) -> ControlStep:
        fl = self.flight
        end = cycle.fly_cycle(fl, snap, self.P0, fl.ref, record=record, push=push)
        S_t = np.asarray(target(end), float)
        return ControlStep(self.P0.copy(), S_t - end.S, S_t, end, end, False)


# -- a controlled flight ----------------------------------------------------------------------


@dataclass
class ControlledFlight:
    """Per-wingbeat record of a flight under the learned controller."""

    steps: list[ControlStep]
    start_pos: np.ndarray
    """Trunk position at the start, m."""
    wall_time: float
    """Wall-clock seconds (the P0 predictions included)."""

    @property
    def positions(self) -> np.ndarray:
        """(n + 1, 3) trunk position at the start and at each wingbeat's end."""
        return np.vstack([self.start_pos, [s.end.trunk_pos for s in self.steps]])

    @property
    def velocities(self) -> np.ndarray:
        """(n, 3) centre-of-mass velocity at each wingbeat's end."""
        return np.array([s.end.com_vel for s in self.steps])

    @property
    def params(self) -> np.ndarray:
        """(n, 29) wingbeats flown."""
        return np.array([s.P for s in self.steps])

    @property
    def states(self) -> np.ndarray:
        """(n, 8) reduced state at each wingbeat's end."""
        return np.array([s.end.S for s in self.steps])

    @property
    def simulated_s(self) -> float:
        return float(sum(s.end.duration for s in self.steps))


def fly_controlled(controller, target, wingbeats: int, progress: bool = False,
                   record: bool = False) -> ControlledFlight:
    """Fly ``wingbeats`` wingbeats under ``controller`` toward ``target`` from the flight's
    current state."""
    import time

    fl = controller.flight
    start = fl.data.qpos[0:3].copy()
    it = range(wingbeats)
    if progress:
        from tqdm import tqdm

        it = tqdm(it, desc="wingbeats", unit="wb")
    steps = []
    t0 = time.perf_counter()
    for _ in it:
        steps.append(controller.choose(target, record=record))
    return ControlledFlight(steps, start, time.perf_counter() - t0)


def start_cruise(fl: DoveFlight, P0: np.ndarray, cfg: FlightConfig | None = None,
                 roll_deg: float = 0.0) -> None:
    """The standard cruise start (:meth:`DoveFlight.reset`), rolled by ``roll_deg`` (in
    :func:`~flapsim.bird.flight.pitch_roll`'s convention) about the trunk's forward axis."""
    import mujoco

    cfg = cfg or FlightConfig()
    fl.reset(cfg, P0)
    if roll_deg:
        d = fl.data
        q = pose_quat(np.radians(cfg.pitch_deg), np.radians(roll_deg))
        d.qpos[3:7] = q
        mujoco.mj_forward(fl.model, d)


def cruise_metrics(f: ControlledFlight, target: CruiseTarget) -> dict:
    """Largest deviations from the cruise target over the flight (at wingbeat ends)."""
    pos = f.positions[1:]
    vel = f.velocities
    speed = np.linalg.norm(vel, axis=1)
    heading = np.arctan2(vel[:, 1], vel[:, 0])
    S = f.states
    return {
        "wingbeats": len(f.steps),
        "simulated_s": f.simulated_s,
        "max_altitude_deviation": float(np.max(np.abs(pos[:, 2] - target.altitude))),
        "final_altitude_deviation": float(pos[-1, 2] - target.altitude),
        "max_speed_deviation": float(np.max(np.abs(speed - target.speed))),
        "mean_speed": float(speed.mean()),
        "max_heading_deviation_deg": float(np.degrees(np.max(np.abs(cycle.wrap(heading - target.heading))))),
        "max_abs_roll_deg": float(np.degrees(np.max(np.abs(S[:, 1])))),
        "pitch_range_deg": [float(np.degrees(S[:, 0].min())), float(np.degrees(S[:, 0].max()))],
        "distance": float(np.linalg.norm(pos[-1, :2] - f.start_pos[:2])),
        "projected_wingbeats": int(sum(s.projected for s in f.steps)),
        "max_range_excess_deg": float(np.degrees(max(s.end.range_excess for s in f.steps))),
        "real_time_factor": f.simulated_s / f.wall_time if f.wall_time > 0 else float("nan"),
    }


# -- loading --------------------------------------------------------------------------------

#: The bundled controller database, made by ``flapsim train --samples 10000 --pre-pitch-deg 10
#: --pre-roll-deg 10 --seed 1 --float32 --out dove_controller.db`` (phase 1; 236-277 s on two
#: idle cores; 2.3 MB: float32, exactly the float64 run's samples rounded). Regenerate it after
#: any change to the dove model: a database of another model is refused by its model hash.
BUNDLED_DB = "dove_controller.db"


BUNDLED_MODAL_DB = "dove_controller_modal.db"
"""The modal-feather dove's database: the rigid one's command with ``--feathers modal``
(phase 1, 10,000 samples, pre-states within 10 deg, seed 2, float32)."""


def bundled_database_path(feathers: str = "rigid"):
    """The bundled controller database of the rigid (default) or the modal-feather dove
    (``Dove.load(feathers="modal")`` with the default :class:`~flapsim.bird.feather_modes.
    ModalParams`)."""
    from pathlib import Path

    names = {"rigid": BUNDLED_DB, "modal": BUNDLED_MODAL_DB}
    if feathers not in names:
        raise InputError(f"feathers must be 'rigid' or 'modal', got {feathers!r}")
    return Path(__file__).resolve().parent / "data" / names[feathers]


def database_table(db_path=None, feathers: str = "rigid") -> str:
    """The feather coefficient table a controller database (default: the bundled one of the
    ``feathers`` dove) was sampled with: its sampling configuration's, or the default table
    where it names none (a merged database, say). A learned controller flies with that table
    only."""
    from flapsim.bird.database import read_header

    cfg = read_header(db_path or bundled_database_path(feathers)).get("config") or {}
    return str(cfg.get("table") or FlightConfig.table)


#: The learned controller's default :attr:`WingbeatController.carry`, per dove (docs/flight_log.md,
#: "Carrying the last wingbeat"): measured over five databases each; with modal feathers
#: 0.4 follows the figure of eight closer but survives fewer pushes, so they keep 0.
DEFAULT_CARRY = {"rigid": 0.4, "modal": 0.0}

#: Simulated corrections per wingbeat (:attr:`WingbeatController.refine`) by dove (docs/flight_log.md,
#: "Wingbeats checked by simulation"; ``scripts/dove_refine_study.py``): 2 for rigid feathers,
#: measured over five databases at 7 m/s (level circles of 3-8 m both ways followed 31 of 50
#: times against 8; 6 and 8 N pushes from four sides survived 40 of 40 against 36; the suite
#: 17 of 22 against 15 on the bundled database) at half the real-time factor; 0 for modal
#: ones (their bundled database: the same verdicts on 5-8 m circles both ways and 8 N pushes
#: from the left and below, the figure of eight's Ef 0.231 against 0.240 m, at 0.64x the
#: speed).
DEFAULT_REFINE = {"rigid": 2, "modal": 0}

#: :attr:`WingbeatController.refine_goal` by dove. ``reachable`` was measured on the rigid dove
#: and not made its default (docs/flight_log.md, "Corrections aimed at what a wingbeat can reach": 17 of
#: the 22 scenarios as ``full``, but 8 N rather than 10 N pushes from all six directions, and
#: 76 of 100 user-path starts against 83).
DEFAULT_REFINE_GOAL = {"rigid": "full", "modal": "full"}


#: :func:`load_controller`'s ``lookahead`` (and the CLI's ``--lookahead``).
LOOKAHEAD_MODES = ("auto", "on", "off")


def usable_cores() -> int:
    """CPU cores this process may run on."""
    import os

    try:
        return len(os.sched_getaffinity(0))
    except (AttributeError, OSError):  # not on Linux
        return os.cpu_count() or 1


def make_lookahead(flight: DoveFlight, mode: str, refine: int, predict: str
                   ) -> ReferenceLookahead | None:
    """The :class:`~flapsim.bird.lookahead.ReferenceLookahead` ``mode`` asks for
    (:func:`load_controller`'s ``lookahead``), or None."""
    if mode not in LOOKAHEAD_MODES:
        raise InputError(f"--lookahead must be one of {', '.join(LOOKAHEAD_MODES)}, got {mode!r}")
    if mode == "off":
        return None
    why = None
    if not refine:
        why = "it runs beside the simulated corrections: use --refine 1 or more"
    elif predict != "simulate":
        why = f"it simulates S0 ahead: use --predict simulate, not {predict}"
    elif flight.aero.flow.has_python:
        why = "a Python flow field runs under the GIL every step: nothing to run beside it"
    elif flight.modal is not None and not flight.modal.engine:
        why = ("a copy of a modal dove needs its modes integrated by the engine "
               "(ModalParams(integration='engine'), the default)")
    elif mode == "auto" and usable_cores() < 2:
        why = "one CPU core"
    if why is None:
        return ReferenceLookahead(flight)
    if mode == "on":
        raise InputError(f"--lookahead on: {why}")
    return None


def load_controller(flight: DoveFlight, db_path=None, method: str = "lwlr", k: int | None = None,
                    weights: tuple[float, float, float] = PAPER_WEIGHTS,
                    predict: str = "simulate", predict_every: int = 4,
                    mirror: bool = True, state_weight: float = 0.0,
                    clip_request: float = DEFAULT_CLIP_REQUEST,
                    k_dense: int | None = None, carry: float | None = None,
                    refine: int | None = None, refine_goal: str | None = None,
                    lookahead: str = "off") -> WingbeatController:
    """A controller over a database (default: the bundled one of ``flight``'s dove, rigid or
    modal feathers) built for ``flight``'s model;
    a database of another model, or a foreign/corrupt file, is a one-line error.

    ``mirror`` (default): the regression searches the samples and their mirror images
    (:func:`mirror_samples`); ``k`` (default :data:`DEFAULT_K_SHARE`: 2 % for LWLR, 0.5 %
    for k-NN) counts among both.

    ``k_dense`` > 0 (LWLR): neighbours where the request lies among densely packed samples,
    growing to ``k`` where they are sparse (:class:`Regressor`); 0: always ``k``, the paper's
    fixed neighbourhood; None (default): :data:`DEFAULT_K_DENSE_SHARE` of the samples searched
    for LWLR (docs/flight_log.md, "A neighbourhood that follows the samples' density"), 0 for k-NN.

    ``state_weight`` > 0: the neighbours are chosen by dS and by the wingbeat's start state
    (the samples' S field; :class:`Regressor`'s ``context_weight``); 0 (default): by dS only,
    the paper's eq. 3. ``clip_request`` q > 0 (default :data:`DEFAULT_CLIP_REQUEST`):
    requests are clipped to the [q, 1 - q] quantiles of the database's dS first
    (:class:`Regressor`); 0: not clipped, the paper's.

    ``carry`` (None: :data:`DEFAULT_CARRY` for the flight's dove, 0 with ``predict=
    "regression"``): the share of the last wingbeat's change the next one starts from
    (:attr:`WingbeatController.carry`; 0: P0 every wingbeat, the paper's).

    ``refine`` (None: :data:`DEFAULT_REFINE` for the flight's dove): simulated corrections
    per wingbeat (:attr:`WingbeatController.refine`; 0: the regression's answer is flown as
    it is, the paper's). ``refine_goal`` (None: :data:`DEFAULT_REFINE_GOAL` for the
    flight's dove): what the corrections aim at (:attr:`WingbeatController.refine_goal`).

    ``predict``: ``simulate`` (default; the paper) flies P0 every wingbeat for S0;
    ``coarse`` flies it every wingbeat at :data:`COARSE_RATE_HZ` (:class:`CoarsePredictor`);
    ``regression`` predicts it from the database's (S, S0) pairs and simulates P0 only
    every ``predict_every``-th wingbeat (:class:`S0Predictor`).

    ``lookahead`` (:data:`LOOKAHEAD_MODES`): ``on`` simulates the next wingbeat's reference
    in a second thread while the corrections run (:attr:`WingbeatController.lookahead`: the
    same flight, less wall time on two free cores), and is a one-line error where it cannot
    (no corrections, S0 not simulated, a Python flow field); ``auto`` turns it on where it
    can and two CPU cores are free to this process; ``off`` (default) never."""
    if predict not in PREDICT_MODES:
        raise InputError(f"S0 prediction must be one of {', '.join(PREDICT_MODES)}, got {predict!r}")
    if carry is None:
        # the default carries nothing where S0 is predicted for P0 alone
        carry = 0.0 if predict == "regression" else DEFAULT_CARRY.get(flight.dove.feathers, 0.0)
    carry = float(carry)
    if not (np.isfinite(carry) and 0.0 <= carry <= 1.0):
        raise InputError(f"--carry must be a share 0..1, got {carry}")
    if carry and predict == "regression":
        raise InputError("--carry needs S0 simulated (--predict simulate or coarse): --predict "
                         "regression predicts the reference wingbeat P0's end only")
    if predict == "coarse" and flight.modal is not None and not flight.modal.engine:
        raise InputError("--predict coarse needs rigid feathers or modal ones integrated by the "
                         "engine (ModalParams(integration='engine'), the default)")
    from flapsim.bird.database import load_database

    path = db_path or bundled_database_path(flight.dove.feathers)
    db = load_database(path, model_hash=flight.dove.hash(), require_finalized=True)
    for name in ("dS", "dP"):
        if name not in db.arrays:
            raise InputError(f"{path} has no {name!r} field: not a wingbeat controller database")
    sampled = (db.header.get("config") or {}).get("table")
    flown = get_table(flight.table).name
    if sampled and sampled != flown:
        raise InputError(f"{path} was sampled with the {sampled} feather table but this flight uses "
                         f"{flown}: fly it with --table {sampled} (its wingbeats are right only for "
                         "the forces they were sampled with)")
    prov = db.header.get("provenance", {})
    P0 = np.asarray(prov.get("P0", with_tail_bias(p0(), FlightConfig.tail_bias_deg)), float)
    dS, dP = db.arrays["dS"], db.arrays["dP"]
    S = None
    if state_weight:
        if "S" not in db.arrays:
            raise InputError(f"{path} has no 'S' field: a state weight needs the samples' start states")
        S = db.arrays["S"]
    if mirror:
        dS, dP = mirror_samples(dS, dP, P0)
        S = None if S is None else np.vstack([S, S * MIRROR_STATE])
    if k_dense is None:
        share = DEFAULT_K_DENSE_SHARE.get(flight.dove.feathers, 0.0) if method == "lwlr" else 0.0
        # the default never exceeds k (a user's smaller --k); an explicit value is checked
        k_dense = min(default_k(len(dS), share), resolve_k(len(dS), k, method)) if share > 0 else 0
    elif k_dense < 0 or (k_dense and method != "lwlr"):
        raise InputError(f"--k-dense must be 0 (off) or >= 1 with --method lwlr, got {k_dense}")
    reg = Regressor(dS, dP, k=k, weights=weights, method=method, context=S, context_weight=state_weight,
                    clip_request=clip_request, k_dense=int(k_dense))
    refine = DEFAULT_REFINE.get(flight.dove.feathers, 0) if refine is None else refine
    if refine_goal is None:
        refine_goal = DEFAULT_REFINE_GOAL.get(flight.dove.feathers, "full")
    if refine_goal == "reachable" and reg.dS_lo is None:
        refine_goal = "full"  # no clip, nothing to clip the goal to: the same thing
    # it checks refine and refine_goal
    ctl = WingbeatController(flight, reg, P0, carry=carry, refine=refine, refine_goal=refine_goal)
    ctl.lookahead = make_lookahead(flight, lookahead, refine, predict)
    if predict == "regression":
        ctl.predictor = _predictor(db, path, predict_every)
    elif predict == "coarse":
        ctl.predictor = CoarsePredictor()
    return ctl


def _predictor(db, path, every: int) -> S0Predictor:
    for name in ("S", "S0"):
        if name not in db.arrays:
            raise InputError(f"{path} has no {name!r} field: --predict regression needs the "
                             "database's (S, S0) pairs")
    return S0Predictor.from_arrays(db.arrays["S"], db.arrays["S0"], every=every)


def attach_predictor(ctl: WingbeatController, db_path=None, every: int = 4) -> WingbeatController:
    """Switch ``ctl`` (made by :func:`load_controller` over ``db_path``) to
    ``predict="regression"`` (and to carry 0: the prediction is of P0's end)."""
    from flapsim.bird.database import load_database

    ctl.carry = 0.0  # the regression predicts P0's end only: nothing is carried
    ctl.reset()
    path = db_path or bundled_database_path(ctl.flight.dove.feathers)
    db = load_database(path, model_hash=ctl.flight.dove.hash(), require_finalized=True)
    ctl.predictor = _predictor(db, path, every)
    return ctl
