"""Evaluation plots (PNG, matplotlib's Agg canvas, written atomically): a flown path in 3D
against the path asked, with the metrics per wingbeat beside it."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from flapsim.bird.tasks.path_control import quat_distance
from flapsim.core.io import atomic_path


def flight_plot(path, r, out: str | Path, title: str = "", forest=None) -> None:
    """Left: the path (grey) and the trunk's positions at wingbeat ends (blue) in 3D, the
    trees as vertical lines. Right: the paper's per-wingbeat errors (Ep, Ef in m; Er, Eo in
    rad) and the steering per wingbeat."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure


    fig = Figure(figsize=(14.0, 6.0), dpi=100)
    FigureCanvasAgg(fig)
    ax = fig.add_subplot(1, 2, 1, projection="3d")
    pts = path.point(np.linspace(0.0, path.length, 600))
    ax.plot(pts[:, 0], pts[:, 1], pts[:, 2], color="0.55", lw=2.5, label="path")
    pos = r.positions
    if len(r.qpos if r.qpos is not None else []):
        ax.plot(r.qpos[:, 0], r.qpos[:, 1], r.qpos[:, 2], color="tab:blue", lw=1.0, label="flown")
    else:
        ax.plot(pos[:, 0], pos[:, 1], pos[:, 2], color="tab:blue", lw=1.0, label="flown")
    ax.scatter(*pos[0], color="black", s=30, label="start")
    if forest is not None:
        for t in forest.trees:
            ax.plot([t.x, t.x], [t.y, t.y], [0.0, t.height], color="tab:green", lw=1.5, alpha=0.6)
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_zlabel("z [m]")
    lo, hi = pts.min(0), pts.max(0)
    span = float(np.max(hi - lo)) / 2 + 1.0
    mid = (lo + hi) / 2
    ax.set_xlim(mid[0] - span, mid[0] + span)
    ax.set_ylim(mid[1] - span, mid[1] + span)
    ax.set_zlim(max(0.0, mid[2] - span / 2), mid[2] + span / 2)
    ax.legend(loc="upper left")
    ax.set_title(title)
    bx = fig.add_subplot(1, 2, 2)
    n = len(r.quats)
    if n:
        wb = np.arange(1, n + 1)
        ep = [float(np.linalg.norm(d[0] - p)) for d, p in zip(r.desired, pos[1:], strict=False)]
        er = [quat_distance(q, d[1]) for d, q in zip(r.desired, r.quats, strict=False)]
        eo = [quat_distance(r.quats[i], r.quats[i + 1]) for i in range(n - 1)]
        ef = [path.distance(p) for p in pos[1:]]
        bx.plot(wb[:len(ep)], ep, label="Ep [m]")
        bx.plot(wb[:len(er)], er, label="Er [rad]")
        bx.plot(wb[1:], eo, label="Eo [rad]")
        bx.plot(wb, ef, label="Ef [m]")
        bx2 = bx.twinx()
        bx2.plot(wb, r.steering_deg, color="0.6", lw=0.8, ls=":", label="steering [deg]")
        bx2.set_ylabel("steering per wingbeat [deg]")
    bx.set_xlabel("wingbeat")
    bx.set_ylabel("error per wingbeat")
    bx.set_yscale("symlog", linthresh=0.05)
    bx.grid(alpha=0.3)
    bx.legend(loc="upper left")
    with atomic_path(out, suffix=".png") as tmp:
        fig.savefig(str(tmp), format="png", dpi=100)
