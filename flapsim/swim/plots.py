"""Plots of swims (offscreen, pyvista 2-D charts, written atomically as PNG): the
swimmer's track seen from above with the path or target it steered for, and a sweep's
results against the swept parameter."""

from __future__ import annotations

import numpy as np

from flapsim.errors import InputError
from flapsim.io import atomic_path

WINDOW = (800, 600)


def _check_png(path: str) -> None:
    if not str(path).endswith(".png"):
        raise InputError(f"plots are written as PNG: give a .png file, got {path!r}")


def _save(plotter, path: str) -> None:
    with atomic_path(path, suffix=".png") as tmp:
        plotter.screenshot(str(tmp))
    plotter.close()


def _equal_ranges(x: np.ndarray, y: np.ndarray, aspect: float) -> tuple[list, list]:
    """Axis ranges around the data with ``aspect`` = x span / y span (so that a metre
    is as long across as up)."""
    x0, x1, y0, y1 = x.min(), x.max(), y.min(), y.max()
    cx, cy = (x0 + x1) / 2, (y0 + y1) / 2
    w, h = max(x1 - x0, 1.0) * 1.1, max(y1 - y0, 1.0) * 1.1
    if w / h < aspect:
        w = h * aspect
    else:
        h = w / aspect
    return [cx - w / 2, cx + w / 2], [cy - h / 2, cy + h / 2]


def track_plot(result, path: str, title: str | None = None) -> None:
    """Top view of ``result`` (a :class:`flapsim.swim.simulate.SwimResult`): the centre
    of mass's track, the start, and the path or (moving) target it steered for."""
    import pyvista as pv

    from flapsim.swim.targets import Path, Point

    _check_png(path)
    xy = result.com[:, :2]
    xs, ys = [xy[:, 0]], [xy[:, 1]]
    chart = pv.Chart2D(x_label="x [m]", y_label="y [m]")
    t = result.target
    if isinstance(t, Path):
        chart.line(t.points[:, 0], t.points[:, 1], color="gray", width=3, label="path")
        xs.append(t.points[:, 0])
        ys.append(t.points[:, 1])
    elif isinstance(t, Point):
        where = t.at(result.times)
        if t.vx or t.vy:
            chart.line(where[:, 0], where[:, 1], color="salmon", width=2, label="target")
        chart.scatter(where[-1:, 0], where[-1:, 1], color="r", size=12, style="o",
                      label="target (end)")
        xs.append(where[:, 0])
        ys.append(where[:, 1])
    chart.line(xy[:, 0], xy[:, 1], color="b", width=2, label="centre of mass")
    chart.scatter(xy[:1, 0], xy[:1, 1], color="k", size=10, style="s", label="start")
    allx, ally = np.concatenate(xs), np.concatenate(ys)
    # the plot area is ~90 % of the window's width and ~85 % of its height
    xr, yr = _equal_ranges(allx, ally, (WINDOW[0] * 0.9) / (WINDOW[1] * 0.85))
    chart.x_range, chart.y_range = xr, yr
    chart.title = title or f"{result.stroke}: {result.seconds:g} s seen from above"
    p = pv.Plotter(off_screen=True, window_size=WINDOW)
    p.add_chart(chart)
    _save(p, path)


def sweep_plot(rows: list[dict], name: str, unit: str, path: str, stroke: str = "") -> None:
    """Two panels against the swept parameter: speeds (forward and along the track)
    and heights (head and centre of mass relative to the surface)."""
    import pyvista as pv

    _check_png(path)
    ok = [r for r in rows if "error" not in r]
    if not ok:
        raise InputError("no successful runs to plot")
    x = np.array([r["value"] for r in ok])
    order = np.argsort(x)
    x = x[order]
    p = pv.Plotter(off_screen=True, window_size=(WINDOW[0] * 2, WINDOW[1]), shape=(1, 2))
    for col, (ylab, series) in enumerate((
            ("speed [m/s]", (("speed_m_s", "forward", "b"), ("track_speed_m_s", "along track", "g"))),
            ("height above the surface [m]", (("head_height_mean_m", "head centre", "r"),
                                             ("com_height_mean_m", "centre of mass", "k"))))):
        chart = pv.Chart2D(x_label=f"{name} [{unit}]", y_label=ylab)
        for key, label, color in series:
            y = np.array([r.get(key, np.nan) for r in ok], dtype=float)[order]
            chart.line(x, y, color=color, width=2, label=label)
            chart.scatter(x, y, color=color, size=8, style="o")
        chart.title = f"{stroke} over {name}".strip()
        p.subplot(0, col)
        p.add_chart(chart)
    _save(p, path)
