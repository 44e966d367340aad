"""Evaluation plots (PNG, matplotlib's Agg canvas, written atomically): a flown path in 3D
against the path asked, with the metrics per wingbeat beside it.

Readable first: linear axes with units, a legend entry for every line, and a floor under
every auto-scaled axis (:func:`floored_limits`), so that round-off on a straight flight
(steering of 1e-13 deg) is drawn as the flat line it is, not as a swing filling the axis."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from flapsim.bird.tasks.path_control import quat_distance
from flapsim.core.io import atomic_path

STEERING_FLOOR_DEG = 1.0
"""The steering axis spans at least +-this, deg: below it no steering a viewer could see."""
POSITION_FLOOR_M = 0.05
"""The position errors' axis reaches at least this, m (a few body lengths' fraction)."""
ANGLE_FLOOR_DEG = 2.0
"""The orientation errors' axis reaches at least this, deg."""


def floored_limits(values, floor: float, symmetric: bool = False,
                   margin: float = 0.08) -> tuple[float, float]:
    """Axis limits that hold ``values`` (NaNs ignored) with a ``margin`` share of the span
    around them and span at least ``[-floor, floor]`` (``symmetric``, for signed values) or
    ``[0, floor]`` (for magnitudes)."""
    v = np.asarray(values, float).ravel()
    v = v[np.isfinite(v)]
    lo = min(float(v.min()) if v.size else 0.0, -floor if symmetric else 0.0)
    hi = max(float(v.max()) if v.size else 0.0, floor)
    pad = margin * (hi - lo)
    if symmetric:
        m = max(abs(lo), abs(hi)) + pad
        return -m, m
    return (lo - pad if lo < 0 else 0.0), hi + pad


def plot_stem(name: str, path_file: str | None = None, tag: str = "") -> str:
    """The file name (no suffix) of a run's plot and video: the user's path file's own name
    for a path file (two files flown into one folder keep two sets of outputs), else the
    scenario's; ``tag`` tells runs of one scenario apart (the mirror flight)."""
    stem = Path(path_file).stem if path_file else name
    return stem + (f"-{tag}" if tag else "")


def wingbeat_errors(path, r) -> dict[str, np.ndarray]:
    """The paper's errors per wingbeat: Ep and Ef in m, Er and Eo in deg."""
    pos = r.positions
    n = len(r.quats)
    ep = [float(np.linalg.norm(d[0] - p)) for d, p in zip(r.desired, pos[1:], strict=False)]
    er = [np.degrees(quat_distance(q, d[1])) for d, q in zip(r.desired, r.quats, strict=False)]
    eo = [np.degrees(quat_distance(r.quats[i], r.quats[i + 1])) for i in range(n - 1)]
    ef = [path.distance(p) for p in pos[1:]]
    return {"Ep": np.array(ep), "Er": np.array(er), "Eo": np.array(eo), "Ef": np.array(ef)}


def flight_plot(path, r, out: str | Path, title: str = "", forest=None) -> dict:
    """Left: the path (grey) and the flown trajectory in 3D coloured by its distance from the
    path (m), the start marked, the trees as vertical lines. Right, above: the position
    errors per wingbeat (Ep, Ef in m); middle: the orientation errors (Er, Eo in deg);
    below: the steering per wingbeat (deg). Returns the axes' limits (for checks)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure
    from mpl_toolkits.mplot3d.art3d import Line3DCollection

    fig = Figure(figsize=(15.0, 7.0), dpi=100, layout="constrained")
    FigureCanvasAgg(fig)
    grid = fig.add_gridspec(3, 2, width_ratios=(1.25, 1.0))
    ax = fig.add_subplot(grid[:, 0], projection="3d")
    pts = path.point(np.linspace(0.0, path.length, 600))
    ax.plot(pts[:, 0], pts[:, 1], pts[:, 2], color="0.45", lw=2.0, label="path asked")
    pos = np.asarray(r.positions, float)
    flown = r.qpos[:, 0:3] if r.qpos is not None and len(r.qpos) else pos
    flown = flown[:: max(1, len(flown) // 3000)]
    err = np.array([path.distance(p) for p in flown])
    segs = np.stack([flown[:-1], flown[1:]], axis=1)
    emax = max(float(np.nanmax(err)) if err.size else 0.0, POSITION_FLOOR_M)
    lc = Line3DCollection(segs, cmap="plasma", lw=1.8, label="flown (colour: distance from path)")
    lc.set_array(0.5 * (err[:-1] + err[1:]) if len(err) > 1 else np.zeros(0))
    lc.set_clim(0.0, emax)
    ax.add_collection(lc)
    fig.colorbar(lc, ax=ax, shrink=0.55, pad=0.08, label="distance from the path [m]")
    ax.scatter(*flown[0], color="tab:green", s=60, marker="o", depthshade=False, label="start")
    ax.scatter(*flown[-1], color="black", s=40, marker="x", depthshade=False, label="end")
    if forest is not None:
        for i, t in enumerate(forest.trees):
            ax.plot([t.x, t.x], [t.y, t.y], [0.0, t.height], color="tab:green", lw=1.5,
                    alpha=0.6, label="trees" if i == 0 else None)
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_zlabel("altitude z [m]")
    both = np.vstack([pts, flown])
    lo, hi = both.min(0), both.max(0)
    span = float(np.max(hi - lo)) / 2 + 1.0
    mid = (lo + hi) / 2
    ax.set_xlim(mid[0] - span, mid[0] + span)
    ax.set_ylim(mid[1] - span, mid[1] + span)
    ax.set_zlim(max(0.0, mid[2] - span / 2), mid[2] + span / 2)
    ax.legend(loc="upper left")
    ax.set_title(title)

    px = fig.add_subplot(grid[0, 1])
    ox = fig.add_subplot(grid[1, 1], sharex=px)
    sx = fig.add_subplot(grid[2, 1], sharex=px)
    n = len(r.quats)
    wb = np.arange(1, n + 1)
    e = wingbeat_errors(path, r) if n else {k: np.zeros(0) for k in ("Ep", "Er", "Eo", "Ef")}
    steer = np.asarray(r.steering_deg if n else [], float)
    px.plot(wb[:len(e["Ep"])], e["Ep"], color="tab:blue", label="Ep: position vs target [m]")
    px.plot(wb[:len(e["Ef"])], e["Ef"], color="tab:orange", label="Ef: distance from path [m]")
    ox.plot(wb[:len(e["Er"])], e["Er"], color="tab:red", label="Er: orientation vs target [deg]")
    ox.plot(wb[1:len(e["Eo"]) + 1], e["Eo"], color="tab:purple",
            label="Eo: orientation change per wingbeat [deg]")
    sx.plot(wb[:len(steer)], steer, color="tab:green", lw=1.2,
            label="steering: heading change per wingbeat [deg]")
    sx.axhline(0.0, color="0.6", lw=0.6, label="straight on")
    limits = {"position_m": floored_limits(np.concatenate([e["Ep"], e["Ef"]]), POSITION_FLOOR_M),
              "orientation_deg": floored_limits(np.concatenate([e["Er"], e["Eo"]]), ANGLE_FLOOR_DEG),
              "steering_deg": floored_limits(steer, STEERING_FLOOR_DEG, symmetric=True)}
    px.set_ylim(*limits["position_m"])
    ox.set_ylim(*limits["orientation_deg"])
    sx.set_ylim(*limits["steering_deg"])
    px.set_ylabel("position error [m]")
    ox.set_ylabel("orientation error [deg]")
    sx.set_ylabel("steering [deg]")
    sx.set_xlabel("wingbeat")
    for a in (px, ox, sx):
        a.grid(alpha=0.3)
        a.legend(loc="upper right", fontsize=8)
        a.ticklabel_format(axis="y", style="plain", useOffset=False)
    with atomic_path(out, suffix=".png") as tmp:
        fig.savefig(str(tmp), format="png", dpi=100)
    # what was drawn, read back from the axes
    return {"position_m": px.get_ylim(), "orientation_deg": ox.get_ylim(),
            "steering_deg": sx.get_ylim(), "legend": [t.get_text() for a in (ax, px, ox, sx)
                                                      for t in a.get_legend().get_texts()],
            "yscale": [a.get_yscale() for a in (px, ox, sx)]}
