"""Path shapes for the flight scenarios (the flight paper's sec. 7), as point lists that
:class:`~flapsim.bird.tasks.path_control.FlightPath` turns into splines. Metres; the bird starts at the
first point, flying along the first tangent."""

from __future__ import annotations

import numpy as np

from flapsim.bird.tasks.path_control import FlightPath

START_HEIGHT = 10.0
"""Height of the paths' start, m (the cruise start)."""


def figure8(lobe_m: float = 35.0, rise_m: float = 3.0, n: int = 160) -> FlightPath:
    """A figure of eight ``2 lobe_m`` long and ``lobe_m`` wide, starting at its crossing
    heading +x; it rises ``rise_m`` on the first (left-turning) lobe and comes back down
    on the second: ascending and descending turns (``rise_m = 0``: level)."""
    t = np.linspace(0.0, 2 * np.pi, n)
    z = START_HEIGHT + rise_m * np.sin(t) ** 2 * np.sign(np.sin(t))
    return FlightPath(np.stack([2 * lobe_m * np.sin(t), lobe_m * np.sin(2 * t), z], 1))


def sinusoid(amplitude_m: float = 4.0, wavelength_m: float = 40.0, waves: float = 4.0,
             n_per_wave: int = 24) -> FlightPath:
    """Rapid side-to-side turns: y = A sin(2 pi x / wavelength), level (smallest turn radius
    wavelength^2 / (4 pi^2 A))."""
    x = np.linspace(0.0, waves * wavelength_m, int(waves * n_per_wave) + 1)
    y = amplitude_m * np.sin(2 * np.pi * x / wavelength_m)
    return FlightPath(np.stack([x, y, np.full_like(x, START_HEIGHT)], 1))


def inclined_circle(radius_m: float = 3.6, incline_deg: float = 0.0, turns: float = 1.25,
                    n_per_turn: int = 48) -> FlightPath:
    """A circle of ``radius_m`` in a plane tilted ``incline_deg`` about the start heading's
    axis (+x), turning left from the start: the path climbs on one side and descends on the
    other, steepest (``incline_deg``) a quarter turn from the start."""
    t = np.linspace(0.0, 2 * np.pi * turns, int(turns * n_per_turn) + 1)
    x = radius_m * np.sin(t)
    y = radius_m * (1.0 - np.cos(t))
    a = np.radians(incline_deg)
    # tilt about the x axis: y' = y cos a, z' = y sin a
    return FlightPath(np.stack([x, y * np.cos(a), START_HEIGHT + y * np.sin(a)], 1))


def straight(length_m: float = 40.0, heading_deg: float = 0.0) -> FlightPath:
    """A level straight line."""
    h = np.radians(heading_deg)
    s = np.linspace(0.0, length_m, 5)
    return FlightPath(np.stack([s * np.cos(h), s * np.sin(h), np.full_like(s, START_HEIGHT)], 1))


def forest_path() -> FlightPath:
    """The forest flight (paper: 263 m through a 50 x 50 x 15 m wood with climbs, glides and
    spiral turns): a closed-ish tour of the 50 m square at 4-11 m height, with a rising
    spiral, a gliding descent and turns both ways, 263 m long (scaled to it exactly)."""
    pts = np.array([
        [-20.0, -20.0, 6.0], [-5.0, -21.0, 6.5], [10.0, -18.0, 7.5], [19.0, -8.0, 8.5],
        [16.0, 5.0, 9.5], [5.0, 8.0, 10.0], [-6.0, 3.0, 10.5], [-4.0, -8.0, 11.0],
        [8.0, -6.0, 10.5], [12.0, 6.0, 9.5], [6.0, 17.0, 8.5], [-8.0, 20.0, 7.5],
        [-19.0, 12.0, 6.5], [-20.0, -2.0, 5.5], [-12.0, -12.0, 5.0], [0.0, -13.0, 5.0],
    ])
    p = FlightPath(pts)
    scale = 263.0 / p.length
    c = pts.mean(axis=0) * np.array([1.0, 1.0, 0.0])
    scaled = (pts - c) * np.array([scale, scale, 1.0]) + c
    # the horizontal scale keeps the heights (and so the climb angles flatten a little)
    return FlightPath(scaled)


def perturbed_copy(path: FlightPath, offset_m: np.ndarray, jitter_m: float,
                   rng: np.random.Generator, horizontal: bool = False) -> FlightPath:
    """A follower's path (the paper's flocks): the leader's points moved by ``offset_m`` and
    each by a random displacement of at most ``jitter_m`` in a random direction
    (``horizontal``: in a random horizontal direction)."""
    pts = path.points + np.asarray(offset_m, float)
    d = rng.normal(size=pts.shape)
    if horizontal:
        d[:, 2] = 0.0
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    return FlightPath(pts + d * rng.uniform(0.0, jitter_m, size=(len(pts), 1)))


# -- paths a user's file would give: held out of the scenarios ------------------------------
# The issue asks that any path a dove can fly (turn radius >= 3 m, climb <= 30 deg) be
# followed, tested on paths that are not among the scenarios: these are those paths. They
# start where they start turning (no straight lead-in), as a point list a user draws would, so
# the dove enters at 7 m/s and must roll into the turn on its first wingbeats. The natural
# spline through the points overshoots a circle's curvature near its ends (a 3 m helix has
# 2.4 m there; :meth:`~flapsim.bird.tasks.path_control.FlightPath.geometry` measures it).


def helix(radius_m: float, climb_deg: float, turns: float, side: float = 1.0) -> FlightPath:
    """A helix of ``radius_m`` turning left (``side`` -1: right) from heading +x, climbing at
    ``climb_deg`` (negative: descending; 0: a level circle), 48 points a turn."""
    t = np.linspace(0.0, 2 * np.pi * turns, int(48 * turns) + 1)
    z = START_HEIGHT + radius_m * t * np.tan(np.radians(climb_deg))
    return FlightPath(np.stack([radius_m * np.sin(t), side * radius_m * (1 - np.cos(t)), z], 1))


def s_curve(radius_m: float = 3.5) -> FlightPath:
    """A half circle of ``radius_m`` to the left, then one to the right, with 6 m straight
    ends, level: a roll reversal from a steep bank (3.5 m: 1.74 g at 7 m/s)."""
    t = np.linspace(0.0, np.pi, 25)
    left = np.stack([radius_m * np.sin(t), radius_m * (1 - np.cos(t))], 1)
    right = np.stack([-radius_m * np.sin(t), 2 * radius_m + radius_m * (1 - np.cos(t))], 1)
    xy = np.vstack([[[-6.0, 0.0], [-3.0, 0.0]], left, right[1:],
                    [[3.0, 4 * radius_m], [6.0, 4 * radius_m]]])
    return FlightPath(np.c_[xy, np.full(len(xy), START_HEIGHT)])


def climb_then_turn() -> FlightPath:
    """A 5 deg climb of 30 m, a wide right-about turn and a gentle descent back."""
    h = START_HEIGHT
    return FlightPath(np.array([[0, 0, h], [15, 0, h + 1.3], [30, 0, h + 2.6], [40, 4, h + 2.6],
                                [44, 12, h + 2.6], [40, 20, h + 2.6], [30, 22, h + 2.0],
                                [20, 22, h + 1.0]], dtype=float))


USER_PATHS = {
    "circle-3-left": lambda: helix(3.0, 0.0, 1.0),
    "circle-3-right": lambda: helix(3.0, 0.0, 1.0, -1.0),
    "circle-4-left": lambda: helix(4.0, 0.0, 1.0),
    "circle-4-right": lambda: helix(4.0, 0.0, 1.0, -1.0),
    "helix-3-up-3-right": lambda: helix(3.0, 3.0, 1.5, -1.0),
    "helix-4-up-5": lambda: helix(4.0, 5.0, 1.5),
    "helix-5-up-8": lambda: helix(5.0, 8.0, 1.25),
    "helix-3-down-10-right": lambda: helix(3.0, -10.0, 1.5, -1.0),
    "s-curve-3.5": lambda: s_curve(3.5),
    "climb-then-turn": climb_then_turn,
}
"""The ten held-out paths by name (``studies/dove_verdict_spread.py
user``): each a function returning a fresh :class:`~flapsim.bird.tasks.path_control.FlightPath`."""
