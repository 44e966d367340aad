"""The learned controller's regression from a requested change of state dS to a change of
wingbeat dP over the database's samples (the flight paper, sec. 4.2, eq. 3-4), and the
samples' mirror images.

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
  random draw (docs/design/flight.md, "How much the database's random draw matters").
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
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from flapsim.bird.body.params import MIRROR_PERM
from flapsim.bird.flight.wingbeat import N_PARAMS
from flapsim.core.errors import InputError

#: The paper's distance weights (orientation, linear velocity, angular velocity).
PAPER_WEIGHTS = (0.2, 0.24, 0.4)


def weight_vector(w: tuple[float, float, float] = PAPER_WEIGHTS) -> np.ndarray:
    """diag(W) of eq. 3: (w1, w1, w2, w2, w2, w3, w3, w3)."""
    w1, w2, w3 = w
    return np.array([w1, w1, w2, w2, w2, w3, w3, w3], dtype=float)


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
        r = float(np.sqrt(d2[-1]))
        # hi == lo == 0 where most samples repeat (duplicates): the step at lo stands in
        t = min(1.0, max(0.0, (r - lo) / (hi - lo))) if hi > lo else float(r > lo)
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
