"""Path control (the flight paper, sec. 4.3) and its evaluation measures (sec. 7, eq. 12-15).

A :class:`FlightPath` is a smooth 3D curve through given points (a cubic spline in
arc-length-like chord parameter). Each wingbeat :class:`PathTarget` finds the closest path
point (searching forward from the last one, so a path that crosses itself is followed in
order), looks ``lookahead_s`` seconds ahead at the current speed (paper: 1 s, ~7 m), and
builds a cubic Hermite recovery curve from the bird's position and velocity to that point
and its tangent. The end of the wingbeat on that curve is the desired position (evaluated,
once the wingbeat is flown, at the time it actually ended: :meth:`PathTarget.end`); the
curve's direction there is the desired flight direction (heading and climb), and its curvature the
turn, flown banked so that lift balances gravity and the centrifugal force (the paper's
eq. 5: F_lift = -m g - m v^2/r n, i.e. tan(bank) = v^2 / (g r) for a level turn). That
becomes the wingbeat controller's target state (:func:`~flapsim.bird.control.targets.target_state`).
One departure: the bank asked is the curve's ``bank_lead_s`` after the wingbeat's end (the
evaluation's desired attitude keeps the curve's bank at the end), because the dove's roll
follows a request over a few wingbeats and a bank asked for the end arrives late.

Paths load from a CSV with a header row ``x,y,z`` (metres, one point per row) or a JSON
list of ``[x, y, z]`` (or ``{"points": [...]}``); bad files get one-line errors.
"""

from __future__ import annotations

import csv
import io
import json
from dataclasses import dataclass, field
from pathlib import Path

import mujoco
import numpy as np
from scipy.interpolate import CubicSpline
from scipy.spatial import cKDTree

from flapsim.bird.control.controller import start_cruise
from flapsim.bird.control.targets import GRAVITY, Trim, target_state
from flapsim.bird.flight import cycle
from flapsim.bird.flight.dove_flight import FlightConfig
from flapsim.core.errors import DataFileError, InputError
from flapsim.core.validate import require_finite

MAX_COORD_M = 1e5
"""Largest path coordinate, m (100 km: far beyond any flight; bounds the spline's samples)."""
MAX_LENGTH_M = 1e6
"""Longest path, m (its 5 cm search samples then take ~0.5 GB at most)."""
SUSTAINED_ARC_M = 2.0
"""Arc over which a turn's curvature is averaged to call it sustained, m."""


def turn_speed(curvature: float, load_factor: float) -> float:
    """The speed (m/s) at which a level turn of ``curvature`` (1/m) needs ``load_factor`` g:
    n^2 = 1 + (v^2 kappa / g)^2, so v = sqrt(g sqrt(n^2 - 1) / kappa)."""
    return float(np.sqrt(GRAVITY * np.sqrt(load_factor**2 - 1.0) / curvature))


@dataclass(frozen=True)
class FlightPath:
    """A smooth curve through ``points`` (n >= 2, metres)."""

    points: np.ndarray
    """(n, 3) the points the path passes through, m."""

    def __post_init__(self) -> None:
        p = np.asarray(self.points, dtype=float)
        if p.ndim != 2 or p.shape[1] != 3:
            raise InputError(f"a path needs (n, 3) points, got shape {p.shape}")
        if len(p) < 2:
            raise InputError(f"a path needs at least 2 points, got {len(p)}")
        if not np.all(np.isfinite(p)):
            raise InputError("path points must be finite numbers (found NaN or inf)")
        if np.max(np.abs(p)) > MAX_COORD_M:
            raise InputError(f"path points must be within +-{MAX_COORD_M:g} m of the origin (the "
                             f"largest is {np.max(np.abs(p)):.3g} m): give metres")
        seg = np.linalg.norm(np.diff(p, axis=0), axis=1)
        if seg.sum() > MAX_LENGTH_M:
            raise InputError(f"a path may be at most {MAX_LENGTH_M:g} m long, got {seg.sum():.3g} m")
        if np.any(seg < 1e-6):
            k = int(np.flatnonzero(seg < 1e-6)[0])
            raise InputError(f"path points {k + 1} and {k + 2} are the same point: remove one")
        object.__setattr__(self, "points", p)
        knots = np.concatenate([[0.0], np.cumsum(seg)])
        object.__setattr__(self, "_knots", knots)
        bc = "natural" if len(p) > 2 else "not-a-knot"
        object.__setattr__(self, "_spline", CubicSpline(knots, p, bc_type=bc))
        # dense samples for closest-point search and arc length
        n = max(200, int(knots[-1] / 0.05))
        u = np.linspace(0.0, knots[-1], n)
        pts = self._spline(u)
        s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(pts, axis=0), axis=1))])
        object.__setattr__(self, "_u", u)
        object.__setattr__(self, "_pts", pts)
        object.__setattr__(self, "_s", s)

    @property
    def length(self) -> float:
        """Arc length, m."""
        return float(self._s[-1])

    def _param(self, s: float | np.ndarray) -> np.ndarray:
        return np.interp(np.clip(s, 0.0, self.length), self._s, self._u)

    def point(self, s: float | np.ndarray) -> np.ndarray:
        """Point(s) at arc length ``s`` (clamped to the path)."""
        return self._spline(self._param(s))

    def tangent(self, s: float | np.ndarray) -> np.ndarray:
        """Unit tangent(s) at arc length ``s``."""
        d = self._spline(self._param(s), 1)
        return d / np.linalg.norm(d, axis=-1, keepdims=True)

    def ahead(self, s: float) -> tuple[np.ndarray, np.ndarray]:
        """(point, unit tangent) at arc length ``s``, continuing straight along the last
        tangent beyond the path's end (a look-ahead target there would otherwise stop at the
        end point, and the recovery curve would squeeze a second's flight into the last few
        metres, bending the bird off the line just before it arrives)."""
        if s <= self.length:
            return self.point(s), self.tangent(s)
        t = self.tangent(self.length)
        return self.point(self.length) + (s - self.length) * t, t

    def closest(self, p: np.ndarray, lo: float = 0.0, hi: float | None = None) -> float:
        """Arc length of the path point nearest ``p`` among arc lengths [lo, hi]."""
        hi = self.length if hi is None else hi
        # the window's samples by bisection (arc lengths ascend): the cost is the window's,
        # not the path's (a mask over every sample took 1 s per wingbeat on a 910 km path)
        a = int(np.searchsorted(self._s, lo - 1e-9, side="left"))
        b = int(np.searchsorted(self._s, hi + 1e-9, side="right"))
        if b <= a:
            idx = np.array([np.argmin(np.abs(self._s - np.clip(lo, 0, self.length)))])
        else:
            idx = np.arange(a, b)
        d = np.linalg.norm(self._pts[idx] - np.asarray(p, float), axis=1)
        return float(self._s[idx[np.argmin(d)]])

    def distance(self, p: np.ndarray) -> float:
        """Distance from ``p`` to the nearest path point, m (a KD-tree of the samples, built
        once: the cost grows with the log of the path's length, not with the length)."""
        tree = self.__dict__.get("_tree")
        if tree is None:
            tree = cKDTree(self._pts)
            object.__setattr__(self, "_tree", tree)
        q = np.asarray(p, float)
        _, k = tree.query(q)
        # the distance as the brute-force search computed it, to the bit
        return float(np.linalg.norm(self._pts[[int(k)]] - q, axis=1)[0])

    def off_path(self, p: np.ndarray) -> float:
        """How far ``p`` is off the path, m: :meth:`distance`, except that a point past the
        path's end (ahead of the plane through the end normal to its tangent) is measured to
        the line the end's tangent continues, as :meth:`ahead` continues the path. A flight
        ends on the wingbeat after the one that began at the path's end, 1-2 wingbeats (1-2 m
        at 8.5 m/s) past it: measured to the end point, a bird flying exactly along the line
        would end that far "off" it."""
        q = np.asarray(p, float)
        end, t = self.point(self.length), self.tangent(self.length)
        along = float((q - end) @ t)
        if along <= 0.0:
            return self.distance(q)
        return float(min(self.distance(q), np.linalg.norm(q - end - along * t)))

    def curvature(self, s: float | np.ndarray) -> np.ndarray:
        """Curvature(s) ``|r' x r''| / |r'|^3`` at arc length ``s``, 1/m."""
        u = self._param(s)
        d1, d2 = self._spline(u, 1), self._spline(u, 2)
        return np.linalg.norm(np.cross(d1, d2), axis=-1) / np.linalg.norm(d1, axis=-1) ** 3

    def sustained_curvature(self, lo: float = 0.0, hi: float | None = None,
                            arc_m: float = SUSTAINED_ARC_M) -> float:
        """The largest curvature averaged over ``arc_m`` of arc between arc lengths ``lo`` and
        ``hi`` (at least ``arc_m`` of path, ending at ``hi``), 1/m: the turn a flier must hold,
        not the spikes of the natural spline's ends (a circle's curvature overshoots by 21 %
        within its first and last metre)."""
        hi = self.length if hi is None else min(hi, self.length)
        ss = np.arange(max(0.0, min(lo, hi - arc_m)), hi + 0.125, 0.25)
        k = self.curvature(np.clip(ss, 0.0, self.length))
        n = min(max(1, int(round(arc_m / 0.25))), len(k))
        return float(np.max(np.convolve(k, np.full(n, 1.0 / n), mode="valid")))

    def geometry(self, step_m: float = 0.05) -> PathGeometry:
        """The path's tightest turn and steepest climb and descent, sampled every ``step_m``
        of arc length and at the spline's knots (a cubic spline's curvature peaks there: its
        third derivative jumps): what a flier must manage to follow it."""
        s = np.linspace(0.0, self.length, max(2, int(np.ceil(self.length / step_m)) + 1))
        s = np.unique(np.concatenate([s, np.interp(self._knots, self._u, self._s)]))
        kappa = self.curvature(s)
        climb = np.degrees(np.arcsin(np.clip(self.tangent(s)[:, 2], -1.0, 1.0)))
        i = int(np.argmax(kappa))
        sustained = self.sustained_curvature()
        return PathGeometry(
            length_m=self.length,
            min_radius_m=float(1.0 / kappa[i]) if kappa[i] > 0 else float("inf"),
            min_radius_at_m=float(s[i]),
            sustained_radius_m=float(1.0 / sustained) if sustained > 1e-9 else float("inf"),
            max_climb_deg=float(max(0.0, climb.max())),
            max_descent_deg=float(max(0.0, -climb.min())),
        )


@dataclass(frozen=True)
class PathGeometry:
    """What a path asks of a flier (:meth:`FlightPath.geometry`)."""

    length_m: float
    """Arc length, m."""
    min_radius_m: float
    """Smallest radius of curvature (3D: turns, pull-ups and their mix), m; inf if straight."""
    min_radius_at_m: float
    """Arc length where it is, m."""
    sustained_radius_m: float
    """Smallest radius held over 2 m of arc (:meth:`FlightPath.sustained_curvature`), m; inf
    if straight: the turn a flier must sustain."""
    max_climb_deg: float
    """Steepest climb of the tangent above the horizontal, deg (0 if it never climbs)."""
    max_descent_deg: float
    """Steepest descent below the horizontal, deg (0 if it never descends)."""

    def as_dict(self) -> dict:
        return {"length_m": self.length_m,
                "min_radius_m": self.min_radius_m if np.isfinite(self.min_radius_m) else None,
                "min_radius_at_m": self.min_radius_at_m,
                "sustained_radius_m": (self.sustained_radius_m if np.isfinite(self.sustained_radius_m)
                                       else None),
                "max_climb_deg": self.max_climb_deg,
                "max_descent_deg": self.max_descent_deg}


def _point(path: Path, where: str, item) -> list[float]:
    """One path point (x, y, z) from a CSV row or a JSON item, or a one-line error naming it."""
    if not isinstance(item, (list, tuple)) or len(item) != 3:
        got = f"{len(item)} values" if isinstance(item, (list, tuple)) else repr(item)[:40]
        raise DataFileError(f"path file {path}: {where} must be 3 numbers x, y, z, got {got}")
    out = []
    for c in item:
        try:
            if isinstance(c, bool):
                raise ValueError
            out.append(float(c.strip() if isinstance(c, str) else c))
        except (TypeError, ValueError):
            raise DataFileError(f"path file {path}: {where}: {str(c)[:20]!r} is not a number "
                                "(metres)") from None
    require_finite(dict(zip("xyz", out, strict=True)), f"path file {path}: {where}")
    return out


def load_path(path: str | Path) -> FlightPath:
    """A path from a CSV (header ``x,y,z``) or JSON file, with one-line errors."""
    path = Path(path)
    try:
        raw = path.read_bytes()
    except FileNotFoundError:
        raise DataFileError(f"path file {path} does not exist") from None
    except IsADirectoryError:
        raise DataFileError(f"path file {path} is a folder; name a .csv or .json file") from None
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError:
        raise DataFileError(f"path file {path} is not text: give a CSV with header x,y,z or a "
                            "JSON list of [x, y, z]") from None
    try:
        if path.suffix.lower() == ".json" or text.lstrip().startswith(("[", "{")):
            data = json.loads(text)
            if isinstance(data, dict):
                data = data.get("points")
            if not isinstance(data, list):
                raise DataFileError(f"path file {path}: expected a JSON list of [x, y, z] points "
                                    "(or {\"points\": [...]})")
            pts = np.array([_point(path, f"point {i + 1}", p) for i, p in enumerate(data)],
                           dtype=float).reshape(-1, 3)
        else:
            rows = list(csv.reader(io.StringIO(text)))
            numbered = [(i + 1, r) for i, r in enumerate(rows) if r and any(c.strip() for c in r)]
            if not numbered or [c.strip().lower() for c in numbered[0][1]] != ["x", "y", "z"]:
                raise DataFileError(f"path file {path}: the first row must be the header x,y,z")
            pts = np.array([_point(path, f"line {i}", r) for i, r in numbered[1:]],
                           dtype=float).reshape(-1, 3)
    except DataFileError:
        raise
    except (ValueError, TypeError, json.JSONDecodeError) as exc:
        raise DataFileError(f"path file {path}: not a list of x, y, z numbers ({exc})") from None
    try:
        return FlightPath(pts.reshape(-1, 3) if pts.ndim == 2 and pts.shape[1] == 3 else pts)
    except InputError as exc:
        raise DataFileError(f"path file {path}: {exc}") from None


def hermite(p0: np.ndarray, v0: np.ndarray, p1: np.ndarray, v1: np.ndarray, T: float,
            t: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Position, velocity and acceleration at time ``t`` of the cubic Hermite curve from
    (p0, v0) at 0 to (p1, v1) at ``T``."""
    u = t / T
    h00, h10, h01, h11 = 2 * u**3 - 3 * u**2 + 1, u**3 - 2 * u**2 + u, -2 * u**3 + 3 * u**2, u**3 - u**2
    d00, d10, d01, d11 = 6 * u**2 - 6 * u, 3 * u**2 - 4 * u + 1, -6 * u**2 + 6 * u, 3 * u**2 - 2 * u
    a00, a10, a01, a11 = 12 * u - 6, 6 * u - 4, -12 * u + 6, 6 * u - 2
    m0, m1 = T * np.asarray(v0, float), T * np.asarray(v1, float)
    p = h00 * p0 + h10 * m0 + h01 * p1 + h11 * m1
    v = (d00 * p0 + d10 * m0 + d01 * p1 + d11 * m1) / T
    a = (a00 * p0 + a10 * m0 + a01 * p1 + a11 * m1) / T**2
    return p, v, a


def bank_for_turn(v: np.ndarray, a: np.ndarray) -> float:
    """The bank (rad, + left wing down) that tilts lift to balance gravity and the
    centrifugal force of following acceleration ``a`` at velocity ``v`` (eq. 5): the
    horizontal acceleration across the flight direction over g."""
    v = np.asarray(v, float)
    a = np.asarray(a, float)
    vh = np.array([v[0], v[1], 0.0])
    n = np.linalg.norm(vh)
    if n < 1e-9:
        return 0.0
    left = np.array([-vh[1], vh[0], 0.0]) / n
    a_lat = float(a @ left)  # > 0: turning left
    return float(np.arctan2(a_lat, GRAVITY + float(a[2])))


@dataclass
class PathTarget:
    """The wingbeat controller's target state for following ``path`` (see the module doc)."""

    trim: Trim
    path: FlightPath
    speed: float = 7.0
    """Flight speed asked, m/s."""
    lookahead_s: float = 1.0
    """Look-ahead time, s (paper: 1 s)."""
    ki_speed: float = 0.3
    """Speed asked above ``speed`` per m/s-second of speed error, 1/s."""
    ki_altitude: float = 0.15
    """Climb rate asked per metre-second of height error below the path, 1/s^2."""
    max_bank_deg: float = 45.0
    """Largest bank asked, deg (tasks ask the dove's default,
    :data:`~flapsim.bird.tasks.flight_tasks.DEFAULT_MAX_BANK_DEG`: 60 for the rigid dove)."""
    bank_lead_s: float = 0.3
    """The bank asked is the recovery curve's this long after the wingbeat's end, s (0: at
    its end, the paper's). The learned controller delivers only part of a roll change per
    wingbeat (about half of it), so a bank asked for the wingbeat's end arrives late
    and the path loop overshoots: pushed 8 N sideways, the bundled database's dove swung
    across the path in growing arcs (rolls of +-60 deg) and was lost; asking ahead it returned
    to the path. Eight databases, the whole suite: 0.2 s, 0.3 s and 0.4 s against none
    (docs/design/flight.md, "Asking the bank ahead")."""
    max_climb_deg: float = 15.0
    """Largest climb/descent angle asked, deg."""
    climb_per_speed_deficit: float = 0.0
    """Speed first: the climb asked drops this much per m/s of airspeed below the speed asked,
    rad s/m (0: the speed and height loops are independent, as before). With too little thrust
    to climb at the speed asked, the height loop asked more climb as the bird fell behind, and
    the nose-up wingbeats traded the rest of the speed away: on a 7 deg, 80 m climb the dove
    slowed from 7 to 2.7 m/s and did not finish in time."""
    aoa_per_g_deg: float = 0.0
    """The nose is asked this much higher above the flight path per g of the turn's load
    factor above 1, deg (:func:`~flapsim.bird.control.targets.target_state`'s ``aoa_per_g``; 0: the
    level trim's angle of attack in every turn, the paper's). Tasks default to the dove's
    :data:`~flapsim.bird.tasks.flight_tasks.DEFAULT_AOA_PER_G_DEG` (40 for rigid feathers, with the
    controller's carry; docs/design/flight.md, "Carrying the last wingbeat")."""
    turn_load_factor: float = 0.0
    """Slowing for tight turns (0, the default: the speed asked is ``speed`` everywhere, the
    paper's). Otherwise ahead of a turn the speed asked drops to ``sqrt(g r sqrt(n^2 - 1))``,
    the speed at which a level turn of the tightest sustained radius ``r`` (curvature averaged
    over 2 m of arc) within the next two look-ahead distances needs this load factor ``n``, but
    not below ``turn_speed_floor``; a task starts at the speed asked where it starts. A turn's load
    factor grows with v^2 / r, and the wing holds little more than 1.2 g at 7 m/s
    (:mod:`flapsim.bird.flight.limits`), so a bird turns tighter by flying slower there."""
    turn_speed_floor: float = 6.5
    """The lowest speed asked for a turn, m/s (the bundled database's dove, trained around
    7 +- 0.3 m/s, follows 4 m circles at 6.5 m/s and loses even 6 m ones at 6 m/s)."""
    s: float = 0.0
    """Progress along the path (arc length of the last closest point), m."""
    integrals: np.ndarray = field(default_factory=lambda: np.zeros(2))
    """Running integrals of (speed, height) errors."""
    speed_surplus: float = 0.0
    """The speed the last target asked above the speed asked by the integral, m/s (a
    wingbeat controller that checks its wingbeats by simulation judges the speed without it:
    :attr:`~flapsim.bird.control.controller.WingbeatController.refine`)."""
    desired: list = field(default_factory=list)
    """(position, quaternion) the recovery curve has at the end of each wingbeat, for the
    evaluation."""
    asked: list = field(default_factory=list)
    """(speed m/s, heading rad, climb rad, bank rad) asked of each wingbeat."""
    wind: object = None
    """``wind(position, t) -> (3,)`` world air velocity the bird feels (None: still air):
    the path's ground track is then flown with the airspeed ``speed`` along the air-relative
    direction that makes it good (crabbing into a crosswind)."""
    wind_memory_s: float = 1.0
    """The wind the path is crabbed against is the wind felt, averaged with this time
    constant (a first-order lag over wingbeats, s; 0: the wind of the moment). A steady wind
    is crabbed into just the same; a 0.5 s gust is not: asked to crab into each wingbeat's
    wind, the dove swung its heading 24 deg within two wingbeats of a 3 m/s side gust's
    onset and rolled to 60 deg. The speed asked is airspeed in the wind of the moment, and
    the target's ground velocity carries that wind (the bird is asked to keep its airspeed
    and heading and be carried, then the path loop brings it back)."""
    _start: tuple | None = None
    _wind_est: np.ndarray | None = None
    _curve: tuple | None = None

    def __post_init__(self) -> None:
        if not (np.isfinite(self.bank_lead_s) and 0.0 <= self.bank_lead_s <= self.lookahead_s):
            raise InputError(f"the bank lead must be 0..{self.lookahead_s:g} s (the look-ahead), "
                             f"got {self.bank_lead_s}")
        if not (np.isfinite(self.max_climb_deg) and 5.0 <= self.max_climb_deg <= 60.0):
            raise InputError(f"the steepest climb asked must be 5..60 deg, got {self.max_climb_deg}")
        if not (np.isfinite(self.max_bank_deg) and 10.0 <= self.max_bank_deg <= 80.0):
            raise InputError(f"the largest bank asked must be 10..80 deg, got {self.max_bank_deg}")
        if not (np.isfinite(self.aoa_per_g_deg) and 0.0 <= self.aoa_per_g_deg <= 90.0):
            raise InputError(f"the angle of attack per g must be 0..90 deg, got {self.aoa_per_g_deg}")
        if not (np.isfinite(self.climb_per_speed_deficit) and 0.0 <= self.climb_per_speed_deficit <= 1.0):
            raise InputError("the climb given up per m/s of missing airspeed must be 0..1 rad s/m, "
                             f"got {self.climb_per_speed_deficit}")
        if not (np.isfinite(self.wind_memory_s) and 0.0 <= self.wind_memory_s <= 60.0):
            raise InputError(f"the wind memory must be 0..60 s, got {self.wind_memory_s}")
        if not (np.isfinite(self.turn_load_factor)
                and (self.turn_load_factor == 0.0 or 1.0 < self.turn_load_factor <= 5.0)):
            raise InputError("the turns' load factor must be 0 (no slowing) or above 1 and at most "
                             "5 g, got "
                             f"{self.turn_load_factor}")
        if not (np.isfinite(self.turn_speed_floor) and 0.5 <= self.turn_speed_floor <= self.speed):
            raise InputError(f"the turns' lowest speed must be 0.5..{self.speed:g} m/s (the speed "
                             f"asked), got {self.turn_speed_floor}")

    def speed_for(self, s: float, window_m: float) -> float:
        """The speed asked at progress ``s`` (m) looking ``window_m`` ahead: ``speed``, or less
        ahead of a turn tighter than ``turn_load_factor`` allows at ``speed``."""
        if self.turn_load_factor == 0.0:
            return self.speed
        # the sustained turn, not the natural spline's end spikes, which no bird slows for
        kappa = self.path.sustained_curvature(s, s + window_m)
        if kappa <= 1e-9:
            return self.speed
        return float(np.clip(turn_speed(kappa, self.turn_load_factor), self.turn_speed_floor, self.speed))

    def flight_time(self, step_m: float = 0.5, wing_load_factor: float | None = None) -> float:
        """Seconds the whole path takes at the speeds asked (:meth:`speed_for` along it, with
        the window :meth:`__call__` uses): ``length / speed`` without ``turn_load_factor``.
        ``wing_load_factor`` n: nowhere faster than the speed at which a level turn of the
        path's sustained radius there needs n (a wing that holds n g flies such a turn no
        faster, whatever it is asked)."""
        if self.turn_load_factor == 0.0 and wing_load_factor is None:
            return self.path.length / self.speed
        if wing_load_factor is not None and not (np.isfinite(wing_load_factor) and wing_load_factor > 1.0):
            raise InputError(f"a wing's load factor must be above 1, got {wing_load_factor}")
        n = max(1, int(np.ceil(self.path.length / step_m)))
        ds = self.path.length / n
        window = 2.0 * self.lookahead_s * self.speed
        total = 0.0
        for i in range(n):
            s = (i + 0.5) * ds
            v = self.speed_for(s, window)
            if wing_load_factor is not None:
                kappa = self.path.sustained_curvature(s, s + SUSTAINED_ARC_M)
                if kappa > 1e-9:
                    v = min(v, turn_speed(kappa, wing_load_factor))
            total += ds / v
        return float(total)

    def begin(self, position: np.ndarray, velocity: np.ndarray) -> None:
        """The bird's trunk position and centre-of-mass velocity as the wingbeat begins: where
        the recovery curve starts, as the paper says (call it before every wingbeat)."""
        self._start = (np.asarray(position, float).copy(), np.asarray(velocity, float).copy())

    @property
    def done(self) -> bool:
        """True once the closest point is the path's end."""
        return self.s >= self.path.length - 1e-6

    def __call__(self, e0: cycle.CycleEnd) -> np.ndarray:
        dt = e0.duration  # the curve starts as the wingbeat begins; it ends dt later on it
        if self._start is None:
            raise InputError("PathTarget.begin(position, velocity) must be called before each "
                             "wingbeat: the recovery curve starts there")
        p, v = self._start
        speed_now = float(np.linalg.norm(v))
        # progress never goes back, and looks at most a few seconds ahead (self-crossing paths)
        self.s = self.path.closest(p, self.s - 1.0, self.s + 3.0 * max(speed_now, self.speed))
        s_t = self.s + self.lookahead_s * max(speed_now, 1.0)
        p_t, t_t = self.path.ahead(s_t)
        t_t = t_t * max(speed_now, 1.0)
        T = self.lookahead_s
        pd, vd, ad = hermite(p, v, p_t, t_t, T, min(dt, T))
        self._curve = (p, v, p_t, t_t, T)
        w = (np.zeros(3) if self.wind is None
             else np.asarray(self.wind(p, float(e0.snapshot.physics[0])), float))
        if self._wind_est is None or self.wind_memory_s <= 0.0:
            self._wind_est = w.copy()
        else:
            self._wind_est = self._wind_est + (1.0 - np.exp(-dt / self.wind_memory_s)) * (w - self._wind_est)
        w_crab = self._wind_est
        # the speed asked: slower ahead of a tight turn (turn_load_factor), looking two
        # look-ahead distances on, as slowing down takes time
        v_ref = self.speed_for(self.s, 2.0 * self.lookahead_s * max(speed_now, self.speed))
        e_v = v_ref - float(np.linalg.norm(v - w))  # the speed asked is airspeed
        e_z = float(self.path.point(self.s)[2] - p[2])
        # anti-windup: the integrals may ask at most 2 m/s of speed and 1 m/s of climb
        lim = np.array([2.0 / max(self.ki_speed, 1e-9), 1.0 / max(self.ki_altitude, 1e-9)])
        self.integrals = np.clip(self.integrals + dt * np.array([e_v, e_z]), -lim, lim)
        speed = v_ref + self.ki_speed * self.integrals[0]
        self.speed_surplus = self.ki_speed * float(self.integrals[0])
        # the ground track asked (vd's direction), flown at airspeed ``speed``: ground speed s
        # along the unit track d with |s d - w| = speed
        d = vd / max(float(np.linalg.norm(vd)), 1e-9)
        dw = float(d @ w_crab)
        s_ground = dw + np.sqrt(max(speed**2 - float(w_crab @ w_crab) + dw**2, 0.0))
        va = s_ground * d - w_crab  # through the (steady part of the) air
        heading = float(np.arctan2(va[1], va[0]))
        vz = float(va[2]) + self.ki_altitude * self.integrals[1]
        vz -= self.climb_per_speed_deficit * max(0.0, e_v) * speed  # speed first
        climb = float(np.clip(np.arcsin(np.clip(vz / max(speed, 1e-3), -1, 1)),
                              -np.radians(self.max_climb_deg), np.radians(self.max_climb_deg)))
        lim_bank = np.radians(self.max_bank_deg)
        bank = float(np.clip(bank_for_turn(vd, ad), -lim_bank, lim_bank))  # the curve's, at dt
        if self.bank_lead_s > 0:
            # ask the bank the curve will have bank_lead_s later: the roll lags the request
            _, v_lead, a_lead = hermite(p, v, p_t, t_t, T, min(dt + self.bank_lead_s, T))
            asked = float(np.clip(bank_for_turn(v_lead, a_lead), -lim_bank, lim_bank))
        else:
            asked = bank
        turn_rate = GRAVITY * np.tan(asked) / max(speed, 1e-3)
        S = target_state(self.trim, speed, heading, climb, turn_rate, e0.S, settle_s=0.0,
                         wind=None if self.wind is None else w,
                         aoa_per_g=np.radians(self.aoa_per_g_deg))
        # the evaluation compares the bird with the curve itself (the paper's eq. 13-14)
        self.desired.append((pd, _attitude_quat(heading, climb + self.trim.aoa, bank)))
        self.asked.append((speed, heading, climb, asked))
        return S

    def end(self, duration: float) -> None:
        """The wingbeat just flown lasted ``duration`` s: its desired position becomes the
        recovery curve's point at that time. The target was set at the reference wingbeat's
        predicted end, but the wingbeat flown has its own timewarp (the learned controller's
        wingbeats are ~5 % shorter than P0's on the figure of eight), and comparing the bird's
        end with the curve at another time would count the curve's own progress in between
        (~7 m/s x 5 ms = 3.5 cm along the track, every wingbeat) as a position error."""
        if self._curve is None or not self.desired:
            raise InputError("PathTarget.end(duration) comes after the target was asked for a wingbeat")
        p, v, p_t, t_t, T = self._curve
        pd = hermite(p, v, p_t, t_t, T, min(float(duration), T))[0]
        self.desired[-1] = (pd, self.desired[-1][1])
        self._curve = None


def _attitude_quat(heading: float, pitch: float, bank_left: float) -> np.ndarray:
    qz = np.array([np.cos(heading / 2), 0.0, 0.0, np.sin(heading / 2)])
    qy = np.array([np.cos(-pitch / 2), 0.0, np.sin(-pitch / 2), 0.0])
    qx = np.array([np.cos(-bank_left / 2), np.sin(-bank_left / 2), 0.0, 0.0])
    t, q = np.empty(4), np.empty(4)
    mujoco.mju_mulQuat(t, qz, qy)
    mujoco.mju_mulQuat(q, t, qx)
    return q


def quat_distance(a: np.ndarray, b: np.ndarray) -> float:
    """||log(a^-1 b)||, the paper's geodesic distance between orientations (eq. 13-14,
    [Lee 2008]): the quaternion logarithm's norm, which is HALF the rotation angle between
    them, rad (Lee's exp(v) = (cos|v|, sin|v| v/|v|) rotates by 2|v|)."""
    d = abs(float(np.clip(np.dot(a, b) / (np.linalg.norm(a) * np.linalg.norm(b)), -1.0, 1.0)))
    return float(np.arccos(d))


def path_metrics(path: FlightPath, positions: np.ndarray, quats: np.ndarray,
                 desired: list) -> dict:
    """The paper's Ep, Er, Eo, Ef (eq. 12-15) over the wingbeat ends: sums and per-wingbeat
    means. ``positions``/``quats``: (n, 3)/(n, 4) at the wingbeat ends; ``desired``: the
    (position, quaternion) the path controller asked for each wingbeat."""
    n = len(positions)
    if n == 0 or len(desired) != n:
        raise InputError(f"need one desired configuration per wingbeat ({n}), got {len(desired)}")
    ep = [float(np.linalg.norm(d[0] - p)) for d, p in zip(desired, positions, strict=True)]
    er = [quat_distance(q, d[1]) for d, q in zip(desired, quats, strict=True)]
    eo = [quat_distance(quats[i], quats[i + 1]) for i in range(n - 1)]
    ef = [path.distance(p) for p in positions]
    out = {}
    for name, v in (("Ep", ep), ("Er", er), ("Eo", eo), ("Ef", ef)):
        out[name] = float(np.sum(v))
        out[f"{name}_per_wingbeat"] = float(np.mean(v)) if len(v) else 0.0
    out["max_path_distance"] = float(np.max(ef))
    return out


def start_on_path(fl, P0: np.ndarray, path: FlightPath, speed: float,
                  wind: np.ndarray | None = None, pitch_deg: float = 0.0) -> None:
    """The cruise start moved to the path's first point, heading along its first tangent
    (trunk pitched ``pitch_deg`` nose up, velocity along the tangent at ``speed``). In a
    ``wind`` (world, m/s) the bird starts as it would be flying there: ``speed`` through the
    air, crabbed so that its ground track is the tangent."""

    t = path.tangent(0.0)
    heading = float(np.arctan2(t[1], t[0]))
    ground = speed * t
    if wind is not None and np.any(wind):
        w = np.asarray(wind, float)
        tw = float(t @ w)
        ground = (tw + np.sqrt(max(speed**2 - float(w @ w) + tw**2, 0.0))) * t
        va = ground - w
        heading = float(np.arctan2(va[1], va[0]))
    start_cruise(fl, P0, FlightConfig(speed=speed, pitch_deg=pitch_deg))
    d = fl.data
    qz = np.array([np.cos(heading / 2), 0.0, 0.0, np.sin(heading / 2)])
    q = np.empty(4)
    mujoco.mju_mulQuat(q, qz, d.qpos[3:7].copy())
    d.qpos[0:3] = path.point(0.0)
    d.qpos[3:7] = q
    d.qvel[0:3] = ground
    mujoco.mj_forward(fl.model, d)
