"""Plots of swims, written atomically as PNG: the swimmer's track seen from above with
the path or target it steered for, and a sweep's results against the swept parameter.

matplotlib's Agg canvas, used directly (no pyplot state, no display, no GL): VTK's
offscreen windows (pyvista) terminate the EGL display that MuJoCo's renderer shares
when they close, which broke later videos in the same process.
"""

from __future__ import annotations

import numpy as np

from flapsim.core.errors import InputError
from flapsim.core.io import atomic_path
from flapsim.swim.goals import Path, Point

SIZE_IN = (8.0, 6.0)  # inches, at 100 dpi: 800 x 600 pixels
DPI = 100


def _check_png(path: str) -> None:
    if not str(path).endswith(".png"):
        raise InputError(f"plots are written as PNG: give a .png file, got {path!r}")


def _figure(ncols: int = 1):
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(SIZE_IN[0] * ncols, SIZE_IN[1]), dpi=DPI)
    FigureCanvasAgg(fig)
    return fig


def _save(fig, path: str) -> None:
    with atomic_path(path, suffix=".png") as tmp:
        fig.savefig(str(tmp), format="png", dpi=DPI)


def track_plot(result, path: str, title: str | None = None) -> None:
    """Top view of ``result`` (a :class:`flapsim.swim.simulate.SwimResult`): the centre
    of mass's track, the start, and the path or (moving) target it steered for; for a
    target with a depth, a second panel shows depth against distance along x."""

    _check_png(path)
    t = result.target
    deep = bool(getattr(t, "is_3d", False))
    fig = _figure(2 if deep else 1)
    ax = fig.add_subplot(1, 2 if deep else 1, 1)
    xy = result.com[:, :2]
    where = result.target_xyz if result.target_xyz is not None else None
    if where is not None and not np.all(np.isfinite(where)):
        where = None
    if isinstance(t, Path):
        ax.plot(t.points[:, 0], t.points[:, 1], color="0.5", lw=3, label="path")
    elif where is not None:
        if np.ptp(where[:, 0]) > 1e-9 or np.ptp(where[:, 1]) > 1e-9:
            ax.plot(where[:, 0], where[:, 1], color="salmon", lw=2, label="target")
        ax.plot(where[-1, 0], where[-1, 1], "o", color="red", ms=9, label="target (end)")
    elif isinstance(t, Point):
        w = t.at(result.times)
        ax.plot(w[-1, 0], w[-1, 1], "o", color="red", ms=9, label="target (end)")
    ax.plot(xy[:, 0], xy[:, 1], color="blue", lw=2, label="centre of mass")
    ax.plot(xy[0, 0], xy[0, 1], "s", color="black", ms=8, label="start")
    ax.set_aspect("equal", adjustable="datalim")  # a metre is as long across as up
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.grid(alpha=0.3)
    ax.legend(loc="best")
    ax.set_title(title or f"{result.stroke}: {result.seconds:g} s seen from above")
    if deep:
        ax2 = fig.add_subplot(1, 2, 2)
        if where is not None:
            ax2.plot(where[:, 0], where[:, 2], color="salmon", lw=2, label="target")
        ax2.plot(result.com[:, 0], result.com[:, 2] - result.water_level, color="blue", lw=2,
                 label="centre of mass")
        ax2.axhline(0.0, color="c", lw=1, label="water surface")
        ax2.set_xlabel("x [m]")
        ax2.set_ylabel("z [m]")
        ax2.grid(alpha=0.3)
        ax2.legend(loc="best")
        ax2.set_title("seen from the side")
        fig.tight_layout()
    _save(fig, path)


def sweep_plot(rows: list[dict], name: str, unit: str, path: str, stroke: str = "") -> None:
    """Two panels against the swept parameter: speeds (forward and along the track)
    and heights (head and centre of mass relative to the surface)."""
    _check_png(path)
    ok = [r for r in rows if "error" not in r]
    if not ok:
        raise InputError("no successful runs to plot")
    x = np.array([r["value"] for r in ok])
    order = np.argsort(x)
    x = x[order]
    fig = _figure(2)
    panels = (("speed [m/s]", (("speed_m_s", "forward", "blue"),
                               ("track_speed_m_s", "along the track", "green"))),
              ("height above the surface [m]", (("head_height_mean_m", "head centre", "red"),
                                               ("com_height_mean_m", "centre of mass", "black"))))
    for i, (ylab, series) in enumerate(panels):
        ax = fig.add_subplot(1, 2, i + 1)
        for key, label, color in series:
            y = np.array([r.get(key, np.nan) for r in ok], dtype=float)[order]
            ax.plot(x, y, "o-", color=color, lw=2, label=label)
        ax.set_xlabel(f"{name} [{unit}]")
        ax.set_ylabel(ylab)
        ax.grid(alpha=0.3)
        ax.legend(loc="best")
        ax.set_title(f"{stroke} over {name}".strip())
    fig.tight_layout()
    _save(fig, path)
