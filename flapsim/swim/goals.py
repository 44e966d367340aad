"""Where a swimmer should go: a heading, a point, waypoints, a timed trajectory, or a
path to follow.

A target answers ``heading(com_xy, vel_xy, t) -> rad``, the horizontal direction to
swim in now (``t``: simulated time [s]); 3D targets (a point with a depth, waypoints,
trajectories with a z column) also answer ``elevation(com, t) -> rad``, the angle
above the horizontal to swim at, and ``position(t)`` (x, y, z). The per-cycle layer
(:class:`flapsim.swim.per_cycle.CycleLayer`) turns the difference to the swimmer's heading
and pitch into weights of the stroke's yaw and pitch sequences. World coordinates: the
swimmer starts at the origin facing +x, the water surface at z = 0.

Path files are plain text, one ``x, y`` point [m] per line (commas or spaces; ``#``
comments and a non-numeric header line are allowed), e.g. exported from a spreadsheet.
Trajectory files (the paper: "read as a trajectory from a file") have ``t, x, y`` or
``t, x, y, z`` per line [s, m]: the target is where the file says at each time
(linear between lines, held after the last).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path as FilePath

import numpy as np

from flapsim.core.errors import DataFileError, InputError
from flapsim.core.validate import require_finite


@dataclass
class Heading:
    """Hold a fixed heading [rad, from +x towards +y]."""

    angle: float = 0.0

    def heading(self, com_xy: np.ndarray, vel_xy: np.ndarray, t: float = 0.0) -> float:
        return self.angle

    def describe(self) -> dict:
        return {"kind": "heading", "heading_deg": math.degrees(self.angle)}


@dataclass
class Point:
    """Swim to a point [m], which may move at a constant velocity (``vx``, ``vy``) [m/s]
    (the paper's horizontally moving target); ``reached`` within ``radius`` [m]."""

    x: float
    y: float
    radius: float = 0.5
    vx: float = 0.0
    vy: float = 0.0
    #: depth of the point [m, z]; None: a point on the surface that sets no pitch
    z: float | None = None

    def __post_init__(self) -> None:
        if not all(math.isfinite(v) for v in (self.x, self.y, self.vx, self.vy)):
            raise InputError(f"target point and velocity must be finite, got ({self.x}, "
                             f"{self.y}) moving ({self.vx}, {self.vy})")
        if self.z is not None and not (math.isfinite(self.z) and -50.0 <= self.z <= 0.5):
            raise InputError(f"target depth z must be -50..0.5 m, got {self.z}")
        if not self.radius > 0:
            raise InputError("target radius must be > 0 m")

    @property
    def is_3d(self) -> bool:
        return self.z is not None

    def position(self, t: float) -> np.ndarray:
        """(x, y, z) [m] at time ``t`` (z = 0 for a surface point)."""
        x, y = self.at(t)
        return np.array([x, y, self.z if self.z is not None else 0.0])

    def elevation(self, com: np.ndarray, t: float = 0.0) -> float:
        """Angle above the horizontal from ``com`` to the point [rad]."""
        return _elevation(com, self.position(t))

    def at(self, t: float | np.ndarray) -> np.ndarray:
        """Where the point is at time(s) ``t`` [s]: (..., 2)."""
        t = np.asarray(t, dtype=float)[..., None]
        return np.array([self.x, self.y]) + t * np.array([self.vx, self.vy])

    def heading(self, com_xy: np.ndarray, vel_xy: np.ndarray, t: float = 0.0) -> float:
        px, py = self.at(t)
        return math.atan2(py - com_xy[1], px - com_xy[0])

    def velocity(self, t: float = 0.0) -> np.ndarray:
        """The point's horizontal velocity (vx, vy) [m/s]."""
        return np.array([self.vx, self.vy])

    def distance(self, com_xy: np.ndarray, t: float | np.ndarray = 0.0) -> np.ndarray:
        """Distance(s) [m] from centre-of-mass position(s) (..., 2) to the point at
        time(s) ``t``."""
        return np.linalg.norm(np.asarray(com_xy)[..., :2] - self.at(t), axis=-1)

    def describe(self) -> dict:
        out = {"kind": "point", "x_m": self.x, "y_m": self.y, "radius_m": self.radius}
        if self.vx or self.vy:
            out.update(vx_m_s=self.vx, vy_m_s=self.vy)
        if self.z is not None:
            out["z_m"] = self.z
        return out


@dataclass
class Circle:
    """A target circling ``centre`` (x, y) [m] on a circle of ``orbit`` [m] at ``speed``
    [m/s] (anticlockwise seen from above), starting at angle ``phase`` [rad] from +x;
    ``reached`` within ``radius`` [m] (as a :class:`Point`)."""

    centre: tuple[float, float] = (0.0, 0.0)
    orbit: float = 3.0
    speed: float = 0.4
    phase: float = 0.0
    radius: float = 0.5

    def __post_init__(self) -> None:
        vals = (*self.centre, self.orbit, self.speed, self.phase, self.radius)
        if len(self.centre) != 2 or not all(math.isfinite(v) for v in vals):
            raise InputError(f"a circling target needs a finite centre (x, y), orbit, speed, "
                             f"phase and radius, got {self.centre}, {self.orbit}, {self.speed}, "
                             f"{self.phase}, {self.radius}")
        if not (self.orbit > 0 and self.speed >= 0 and self.radius > 0):
            raise InputError("a circling target needs an orbit > 0 m, a speed >= 0 m/s and a "
                             "radius > 0 m")

    def _angle(self, t: float | np.ndarray) -> np.ndarray:
        return self.phase + np.asarray(t, dtype=float) * self.speed / self.orbit

    def at(self, t: float | np.ndarray) -> np.ndarray:
        """(x, y) at time(s) ``t`` [s]: (..., 2)."""
        a = self._angle(t)
        return np.stack([self.centre[0] + self.orbit * np.cos(a),
                         self.centre[1] + self.orbit * np.sin(a)], -1)

    def position(self, t: float) -> np.ndarray:
        return np.array([*self.at(t), 0.0])

    def velocity(self, t: float = 0.0) -> np.ndarray:
        a = float(self._angle(t))
        return self.speed * np.array([-math.sin(a), math.cos(a)])

    def heading(self, com_xy: np.ndarray, vel_xy: np.ndarray, t: float = 0.0) -> float:
        px, py = self.at(t)
        return math.atan2(py - com_xy[1], px - com_xy[0])

    def distance(self, com_xy: np.ndarray, t: float | np.ndarray = 0.0) -> np.ndarray:
        return np.linalg.norm(np.asarray(com_xy)[..., :2] - self.at(t), axis=-1)

    def describe(self) -> dict:
        return {"kind": "circle", "centre_m": list(self.centre), "orbit_m": self.orbit,
                "speed_m_s": self.speed, "phase_deg": math.degrees(self.phase), "radius_m": self.radius}


def _elevation(com: np.ndarray, p: np.ndarray) -> float:
    d = np.asarray(p, dtype=float) - np.asarray(com, dtype=float)[:3]
    return math.atan2(d[2], math.hypot(d[0], d[1]))


@dataclass
class Waypoints:
    """Swim to 3D points in order (x, y, z) [m]: the next one becomes the target when the
    centre of mass comes within ``radius`` [m] of the current one (3D distance)."""

    points: np.ndarray
    radius: float = 0.75
    _i: int = field(default=0, init=False, repr=False)
    #: time [s] each point was reached (None: not yet)
    reached: list = field(default_factory=list, init=False, repr=False)

    def __post_init__(self) -> None:
        p = np.asarray(self.points, dtype=float)
        if p.ndim != 2 or p.shape[1] != 3 or len(p) < 1 or not np.all(np.isfinite(p)):
            raise InputError(f"waypoints must be finite (x, y, z) rows, got shape {p.shape}")
        self.points = p
        if not self.radius > 0:
            raise InputError("waypoint radius must be > 0 m")
        self.reset()

    is_3d = True

    def reset(self) -> None:
        self._i = 0
        self.reached = [None] * len(self.points)

    def update(self, com: np.ndarray, t: float) -> None:
        """Advance to the next point once the current one is reached."""
        while self._i < len(self.points) and \
                np.linalg.norm(np.asarray(com)[:3] - self.points[self._i]) <= self.radius:
            self.reached[self._i] = float(t)
            self._i += 1

    def reached_by(self, index: int, t: float) -> None:
        """Count point ``index`` reached at ``t`` by a rule of its own (a surface dive's:
        the head or the pelvis within the radius, where the centre of mass may stay just
        outside it) and go on to the next, if it is the current one."""
        if self._i == index and index < len(self.points):
            self.reached[index] = float(t)
            self._i += 1

    @property
    def current(self) -> int:
        return min(self._i, len(self.points) - 1)

    def position(self, t: float) -> np.ndarray:
        return self.points[self.current].copy()

    def heading(self, com_xy: np.ndarray, vel_xy: np.ndarray, t: float = 0.0) -> float:
        p = self.points[self.current]
        return math.atan2(p[1] - com_xy[1], p[0] - com_xy[0])

    def elevation(self, com: np.ndarray, t: float = 0.0) -> float:
        self.update(com, t)
        return _elevation(com, self.points[self.current])

    def describe(self) -> dict:
        return {"kind": "waypoints", "points": self.points.tolist(), "radius_m": self.radius}


@dataclass
class Trajectory:
    """A target that moves along a timed polyline: ``table`` rows (t, x, y, z) [s, m],
    times increasing; linear in between, held before the first and after the last."""

    table: np.ndarray
    name: str = "trajectory"
    #: whether the file gave depths (then the swimmer also pitches for them)
    is_3d: bool = False
    radius: float = 0.5

    def __post_init__(self) -> None:
        a = np.asarray(self.table, dtype=float)
        if a.ndim != 2 or a.shape[1] != 4 or len(a) < 2 or not np.all(np.isfinite(a)):
            raise InputError(f"a trajectory needs >= 2 finite (t, x, y, z) rows, got {a.shape}")
        if np.any(np.diff(a[:, 0]) <= 0):
            raise InputError("trajectory times must increase")
        self.table = a

    def position(self, t: float) -> np.ndarray:
        a = self.table
        return np.array([np.interp(t, a[:, 0], a[:, k]) for k in (1, 2, 3)])

    def at(self, t: float | np.ndarray) -> np.ndarray:
        """(x, y) at time(s) ``t``: (..., 2)."""
        t = np.asarray(t, dtype=float)
        a = self.table
        return np.stack([np.interp(t, a[:, 0], a[:, 1]), np.interp(t, a[:, 0], a[:, 2])], -1)

    def heading(self, com_xy: np.ndarray, vel_xy: np.ndarray, t: float = 0.0) -> float:
        p = self.position(t)
        return math.atan2(p[1] - com_xy[1], p[0] - com_xy[0])

    def elevation(self, com: np.ndarray, t: float = 0.0) -> float:
        return _elevation(com, self.position(t))

    def velocity(self, t: float = 0.0) -> np.ndarray:
        """Horizontal velocity (vx, vy) [m/s] along the segment at time ``t`` (0 before
        the first line and after the last)."""
        a = self.table
        i = int(np.searchsorted(a[:, 0], t, side="right")) - 1
        if i < 0 or i >= len(a) - 1:
            return np.zeros(2)
        return (a[i + 1, 1:3] - a[i, 1:3]) / (a[i + 1, 0] - a[i, 0])

    def describe(self) -> dict:
        return {"kind": "trajectory", "name": self.name, "rows": len(self.table),
                "duration_s": float(self.table[-1, 0] - self.table[0, 0]), "3d": self.is_3d}


def load_trajectory(path: str) -> Trajectory:
    """Read a trajectory file (see the module docstring); one-line errors name the line."""
    p = FilePath(path)
    rows = _read_rows(p, (3, 4), "'t, x, y' or 't, x, y, z'")
    if len({len(r) for r in rows}) != 1:
        raise DataFileError(f"{p}: every line needs the same number of columns (3 or 4)")
    a = np.asarray(rows, dtype=float)
    is_3d = a.shape[1] == 4
    if not is_3d:
        a = np.column_stack([a, np.zeros(len(a))])
    if len(a) < 2:
        raise DataFileError(f"{p}: a trajectory needs at least two lines, found {len(a)}")
    if np.any(np.diff(a[:, 0]) <= 0):
        raise DataFileError(f"{p}: times (first column) must increase from line to line")
    if is_3d and not (np.all(a[:, 3] <= 0.5) and np.all(a[:, 3] >= -50)):
        raise DataFileError(f"{p}: depths (z, fourth column) must be -50..0.5 m")
    return Trajectory(a, p.name, is_3d)


def _read_rows(p: FilePath, ncols: tuple[int, ...], what: str) -> list[list[float]]:
    if not p.is_file():
        raise DataFileError(f"file {p} does not exist")
    try:
        text = p.read_text()
    except (OSError, UnicodeDecodeError) as exc:
        raise DataFileError(f"cannot read {p} as text ({exc})") from None
    rows, first = [], True
    for lineno, line in enumerate(text.splitlines(), 1):
        line = line.split("#", 1)[0].strip()
        if not line:
            continue
        try:
            vals = [float(x) for x in line.replace(",", " ").split()]
        except ValueError:
            if first:  # a header line
                first = False
                continue
            raise DataFileError(f"{p} line {lineno}: expected {what} numbers, got {line!r}"
                                ) from None
        first = False
        if len(vals) not in ncols:
            raise DataFileError(f"{p} line {lineno}: expected {what}, got {len(vals)} numbers")
        require_finite(dict(zip(("t", "x", "y", "z"), vals, strict=False)), f"{p} line {lineno}")
        rows.append(vals)
    return rows


#: The largest path coordinate accepted, m.
MAX_PATH_COORD_M = 1e6


@dataclass
class Path:
    """Follow a polyline (n, 2) [m]: steer at the point ``lookahead`` [m] further along
    the path than the closest one (the flight paper's pure-pursuit look-ahead). The
    closest point is searched only a little behind and ahead of the last one, so that
    a path that crosses itself (a figure of eight) is followed in order."""

    points: np.ndarray
    lookahead: float = 2.0
    name: str = "path"
    _s: float = field(default=0.0, init=False, repr=False)

    def __post_init__(self) -> None:
        p = np.asarray(self.points, dtype=float)
        if p.ndim != 2 or p.shape[1] != 2 or len(p) < 2:
            raise InputError(f"a path needs at least two (x, y) points, got shape {p.shape}")
        if not np.all(np.isfinite(p)):
            raise InputError("path points must be finite")
        if np.abs(p).max() > MAX_PATH_COORD_M:
            # far beyond any pool or lake; larger values overflow the segment lengths
            raise InputError(f"path points must lie within {MAX_PATH_COORD_M:g} m of the origin "
                             f"(metres), got {np.abs(p).max():g}")
        seg = np.linalg.norm(np.diff(p, axis=0), axis=1)
        keep = np.concatenate([[True], seg > 1e-9])  # drop repeated points
        self.points = p[keep]
        if len(self.points) < 2:
            raise InputError("a path needs two distinct points")
        seg = np.linalg.norm(np.diff(self.points, axis=0), axis=1)
        self.cum = np.concatenate([[0.0], np.cumsum(seg)])
        if not self.lookahead > 0:
            raise InputError("path look-ahead must be > 0 m")

    @property
    def length(self) -> float:
        return float(self.cum[-1])

    def at(self, s: float) -> np.ndarray:
        """The point at arc length ``s`` [m] (clamped to the ends)."""
        s = min(max(s, 0.0), self.length)
        i = int(np.clip(np.searchsorted(self.cum, s, side="right") - 1, 0, len(self.cum) - 2))
        f = (s - self.cum[i]) / (self.cum[i + 1] - self.cum[i])
        return self.points[i] + f * (self.points[i + 1] - self.points[i])

    def project(self, xy: np.ndarray, s_lo: float = 0.0, s_hi: float = math.inf
                ) -> tuple[float, float]:
        """(arc length, distance) of the closest path point to ``xy`` with arc length in
        [s_lo, s_hi]."""
        i0 = max(0, int(np.searchsorted(self.cum, s_lo, side="right")) - 1)
        i1 = min(len(self.cum), int(np.searchsorted(self.cum, s_hi, side="left")) + 1)
        a, b = self.points[i0:i1 - 1], self.points[i0 + 1:i1]
        c0, c1 = self.cum[i0:i1 - 1], self.cum[i0 + 1:i1]
        ab = b - a
        t = np.clip(np.einsum("ij,ij->i", xy - a, ab) / np.einsum("ij,ij->i", ab, ab), 0, 1)
        # keep each segment's closest point inside the arc-length window
        s = np.clip(c0 + t * (c1 - c0), s_lo, s_hi)
        t = np.clip((s - c0) / (c1 - c0), 0, 1)
        pts = a + t[:, None] * ab
        d = np.linalg.norm(pts - xy, axis=1)
        k = int(np.argmin(d))
        return float(c0[k] + t[k] * (c1[k] - c0[k])), float(d[k])

    def advance(self, xy: np.ndarray, s_prev: float) -> tuple[float, float]:
        """(progress, distance): the closest point to ``xy`` searched from 1 m behind to
        3 m ahead of the progress so far ``s_prev`` [m]; progress never goes back."""
        s, d = self.project(xy, s_prev - 1.0, s_prev + 3.0)
        return max(s_prev, s), d

    def track(self, xy: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Progress along the path [m] and distance from it [m] for each point of a
        track (n, 2), in order, as the steering sees them."""
        s, prog, dist = 0.0, [], []
        for p in np.asarray(xy, dtype=float):
            s, d = self.advance(p, s)
            prog.append(s)
            dist.append(d)
        return np.asarray(prog), np.asarray(dist)

    def heading(self, com_xy: np.ndarray, vel_xy: np.ndarray, t: float = 0.0) -> float:
        self._s, _ = self.advance(np.asarray(com_xy, dtype=float), self._s)
        aim = self.at(self._s + self.lookahead)
        return math.atan2(aim[1] - com_xy[1], aim[0] - com_xy[0])

    def reset(self) -> None:
        self._s = 0.0

    def describe(self) -> dict:
        return {"kind": "path", "name": self.name, "points": len(self.points),
                "length_m": self.length, "lookahead_m": self.lookahead}


def figure_eight(radius: float = 6.0, n: int = 200, lookahead: float = 2.0) -> Path:
    """A figure of eight from the origin heading +x: a loop of ``radius`` [m] turning left
    (centre (0, r)), then one turning right (centre (0, -r)), back to the origin."""
    if not (0.5 <= radius <= 1000.0):
        raise InputError(f"figure-of-eight radius must be 0.5..1000 m, got {radius}")
    t = np.linspace(0.0, 2.0 * math.pi, n // 2, endpoint=False)
    left = np.column_stack([radius * np.sin(t), radius * (1.0 - np.cos(t))])
    right = np.column_stack([radius * np.sin(t), -radius * (1.0 - np.cos(t))])
    pts = np.vstack([left, right, [[0.0, 0.0]]])
    return Path(pts, lookahead, name=f"figure-of-eight r={radius:g} m")


def load_path(path: str, lookahead: float = 2.0) -> Path:
    """Read a path file (see the module docstring); one-line errors name the bad line."""
    p = FilePath(path)
    if not p.is_file():
        raise DataFileError(f"path file {p} does not exist")
    try:
        text = p.read_text()
    except (OSError, UnicodeDecodeError) as exc:
        raise DataFileError(f"cannot read path file {p} as text ({exc})") from None
    pts = []
    first = True
    for lineno, line in enumerate(text.splitlines(), 1):
        line = line.split("#", 1)[0].strip()
        if not line:
            continue
        parts = line.replace(",", " ").split()
        try:
            vals = [float(x) for x in parts]
        except ValueError:
            if first:  # a header line
                first = False
                continue
            raise DataFileError(f"{p} line {lineno}: expected 'x, y' numbers, got {line!r}"
                                ) from None
        first = False
        if len(vals) != 2:
            raise DataFileError(f"{p} line {lineno}: expected 2 numbers (x, y), got {len(vals)}")
        require_finite(dict(zip(("x", "y"), vals, strict=True)), f"{p} line {lineno}")
        pts.append(vals)
    if len(pts) < 2:
        raise DataFileError(f"{p}: a path needs at least two points, found {len(pts)}")
    try:
        return Path(np.asarray(pts), lookahead, name=p.name)
    except InputError as exc:
        raise DataFileError(f"{p}: {exc}") from None
