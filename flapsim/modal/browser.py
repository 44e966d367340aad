"""Mode browser (Kry et al. 2009, section 5.1): the gait's modes with sliders.

The paper's user "is presented with a kinematic motion, and a set of modes (those
automatically selected by heuristics, along with a small group of low frequency modes
that were not used)" and adjusts them "by adjusting sliders for different modes". This
is that window, in pyvista: one amplitude, phase and posture-offset (beta) slider per
selected mode, amplitude sliders for a few unused low modes (start at 0), a play/pause
checkbox; every slider change re-evaluates equation 4 at once (a pose costs one
``mj_kinematics``).

Offscreen (``pv.OFF_SCREEN`` or :func:`contact_sheet`) it renders frames over one gait
cycle into a PNG contact sheet, for tests and docs.

Run: ``python -m flapsim.modal.browser --gait walk`` (needs a display), or
``python -m flapsim.modal.browser --gait trot --sheet trot.png`` (no display needed).
"""

from __future__ import annotations

import argparse
import logging
import math
import os
import time
from dataclasses import replace
from pathlib import Path

import mujoco
import numpy as np

from flapsim.core.errors import InputError
from flapsim.core.io import atomic_path
from flapsim.modal.animate import Component, SoftLimits, animate
from flapsim.modal.gaits import GaitPlan, gait, plan_gait, resolve_model, rotation_normalized_shape

log = logging.getLogger(__name__)

WINDOW_TITLE = "flapsim mode browser"
EXTRA_MODES = 3
"""How many unused low-frequency modes get an amplitude slider (at 0)."""


def _geom_mesh(model: mujoco.MjModel, g: int):
    """A pyvista mesh of geom ``g`` in the geom's own frame (None for planes)."""
    import pyvista as pv

    t = int(model.geom_type[g])
    s = np.asarray(model.geom_size[g], dtype=float)
    G = mujoco.mjtGeom
    if t == G.mjGEOM_SPHERE:
        return pv.Sphere(radius=s[0], theta_resolution=16, phi_resolution=12)
    if t == G.mjGEOM_CAPSULE:
        return pv.Capsule(center=(0, 0, 0), direction=(0, 0, 1), radius=s[0],
                          cylinder_length=2 * s[1], resolution=16)
    if t == G.mjGEOM_CYLINDER:
        return pv.Cylinder(center=(0, 0, 0), direction=(0, 0, 1), radius=s[0], height=2 * s[1],
                           resolution=16)
    if t == G.mjGEOM_BOX:
        return pv.Box(bounds=(-s[0], s[0], -s[1], s[1], -s[2], s[2]))
    if t == G.mjGEOM_ELLIPSOID:
        m = pv.Sphere(radius=1.0, theta_resolution=16, phi_resolution=12)
        m.points *= s
        return m
    return None


class ModeBrowser:
    """The gait's components as sliders over a live pyvista view of the creature."""

    def __init__(self, plan: GaitPlan, model: mujoco.MjModel, *, off_screen: bool = False,
                 window_size: tuple[int, int] = (1100, 700), extra_modes: int = EXTRA_MODES):
        import pyvista as pv

        self.model = model
        self.plan = plan
        self.rest = np.asarray(plan.analysis.rest_qpos)
        self.components = list(plan.components)
        used = {c.mode for c in self.components}
        a = plan.analysis
        extra = [m for m in a.elastic_modes if m not in used][:extra_modes]
        for m in extra:
            self.components.append(Component(rotation_normalized_shape(a, m), 0.0, 0.0, 2.0, 0.0,
                                             m, f"unused mode {m} ({a.freqs_hz[m]:.2f} Hz)"))
        self.data = mujoco.MjData(model)
        self.t = 0.0
        self.playing = True
        self.frames_drawn = 0
        self.plotter = pv.Plotter(off_screen=off_screen, window_size=list(window_size),
                                  title=WINDOW_TITLE)
        self.plotter.set_background("white")
        self.actors: list[tuple[int, object]] = []
        for g in range(model.ngeom):
            if model.geom_bodyid[g] == 0 or model.geom_rgba[g, 3] == 0:
                continue
            mesh = _geom_mesh(model, g)
            if mesh is None:
                continue
            actor = self.plotter.add_mesh(mesh, color=tuple(model.geom_rgba[g, :3]),
                                          opacity=float(model.geom_rgba[g, 3]), smooth_shading=True)
            self.actors.append((g, actor))
        self._ground()
        used_txt = ", ".join(f"{c.mode} {c.label.split()[0]}" if c.mode >= 0 else "bounce"
                             for c in self.components if c.amplitude)
        self.plotter.add_text(f"{plan.gait.name}: modes {used_txt}", font_size=8,
                              position="upper_edge")
        self.set_time(0.0)
        self.plotter.view_xz()
        self.plotter.camera.azimuth = 20
        self.plotter.camera.elevation = 12
        self.plotter.reset_camera(bounds=self._creature_bounds())

    def _creature_bounds(self) -> tuple[float, ...]:
        pts = np.asarray(self.data.geom_xpos[[g for g, _ in self.actors]])
        r = float(np.max(self.model.geom_rbound[[g for g, _ in self.actors]]))
        lo, hi = pts.min(axis=0) - r, pts.max(axis=0) + r
        return (lo[0], hi[0], lo[1], hi[1], min(lo[2], 0.0), hi[2])

    def _ground(self) -> None:
        import pyvista as pv

        mujoco.mj_forward(self.model, self.data)
        c = self.data.subtree_com[0]
        self.plotter.add_mesh(pv.Plane(center=(c[0], c[1], 0), direction=(0, 0, 1), i_size=3,
                                       j_size=2), color="lightgray", opacity=0.6)

    # -- the model ------------------------------------------------------------------------
    def pose(self, t: float) -> np.ndarray:
        return animate(self.model, self.rest, self.components, np.array([t]), SoftLimits()).qpos[0]

    def set_time(self, t: float) -> None:
        """Pose the creature at time ``t`` (s) of equation 4 and update the view."""
        self.t = float(t)
        self.data.qpos[:] = self.pose(self.t)
        mujoco.mj_kinematics(self.model, self.data)
        M = np.eye(4)
        for g, actor in self.actors:
            M[:3, :3] = self.data.geom_xmat[g].reshape(3, 3)
            M[:3, 3] = self.data.geom_xpos[g]
            actor.user_matrix = M.copy()
        self.frames_drawn += 1

    def set_param(self, k: int, name: str, value: float) -> None:
        """Change component ``k``'s 'amplitude', 'phase_rad' or 'beta' and redraw."""
        if name not in ("amplitude", "phase_rad", "beta"):
            raise InputError(f"unknown slider parameter {name!r}")
        self.components[k] = replace(self.components[k], **{name: float(value)})
        self.set_time(self.t)
        self.plotter.render()

    # -- interactive window ---------------------------------------------------------------
    def add_widgets(self) -> None:
        p = self.plotter
        n = len(self.components)
        dy = 0.85 / max(n, 1)
        for k, c in enumerate(self.components):
            y = 0.9 - k * dy
            tag = f"m{c.mode}" if c.mode >= 0 else "bounce"
            p.add_slider_widget(lambda v, k=k: self.set_param(k, "amplitude", v), (0.0, 2.0),
                                value=c.amplitude, title=f"{tag} alpha", pointa=(0.02, y),
                                pointb=(0.2, y), title_height=0.015, fmt="%.2f")
            p.add_slider_widget(lambda v, k=k: self.set_param(k, "phase_rad", math.radians(v)),
                                (-180.0, 180.0), value=math.degrees(c.phase_rad),
                                title=f"{tag} gamma deg", pointa=(0.23, y), pointb=(0.41, y),
                                title_height=0.015, fmt="%.0f")
            p.add_slider_widget(lambda v, k=k: self.set_param(k, "beta", v), (-1.0, 1.0),
                                value=c.beta, title=f"{tag} beta", pointa=(0.80, y),
                                pointb=(0.98, y), title_height=0.015, fmt="%.2f")
        p.add_checkbox_button_widget(self._toggle, value=True, position=(10, 10), size=30)
        p.add_text("play", position=(45, 14), font_size=10)

    def _toggle(self, on: bool) -> None:
        self.playing = bool(on)

    def _tick(self, _step: int = 0) -> None:
        if self.playing:
            self.set_time(self.t + 1.0 / 30.0)
            self.plotter.render()

    def show(self, *, marker: str | None = None, seconds: float | None = None) -> None:
        """Open the window. ``marker``: a file written once the window is up (for tests);
        ``seconds``: close by itself after that long (else run until closed)."""
        self.add_widgets()
        if seconds is None:
            self.plotter.add_timer_event(max_steps=10**9, duration=33, callback=self._tick)
            self.plotter.show()
            return
        self.plotter.show(interactive_update=True, auto_close=False)
        if marker:
            Path(marker).write_text(f"{os.getpid()} {self.frames_drawn}\n")
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            self._tick()
            self.plotter.update()
            time.sleep(1 / 30)
        if marker:
            Path(marker).write_text(f"{os.getpid()} {self.frames_drawn} closed\n")
        self.plotter.close()


def contact_sheet(plan: GaitPlan, model: mujoco.MjModel, path: str | os.PathLike, *,
                  frames: int = 8, cols: int = 4, tile: tuple[int, int] = (320, 240)) -> dict:
    """Render ``frames`` poses over one cycle offscreen and tile them into a PNG."""
    import imageio.v2 as imageio

    if frames < 1 or cols < 1:
        raise InputError("contact sheet needs frames >= 1 and cols >= 1")
    if Path(path).suffix.lower() != ".png":
        raise InputError(f"contact sheet {path} must be a .png")
    b = ModeBrowser(plan, model, off_screen=True, window_size=tile)
    freqs = [c.freq_hz for c in b.components if c.amplitude]
    period = 1.0 / min(freqs) if freqs else 1.0
    shots = []
    try:
        for k in range(frames):
            b.set_time(k * period / frames)
            b.plotter.render()
            shots.append(np.asarray(b.plotter.screenshot(return_img=True))[..., :3])
    finally:
        b.plotter.close()
    rows = math.ceil(frames / cols)
    h, w = shots[0].shape[:2]
    sheet = np.full((rows * h, cols * w, 3), 255, dtype=np.uint8)
    for k, img in enumerate(shots):
        r, c = divmod(k, cols)
        sheet[r * h:(r + 1) * h, c * w:(c + 1) * w] = img
    with atomic_path(path) as tmp:
        imageio.imwrite(tmp, sheet, format="png")
    return {"path": str(path), "frames": frames, "period_s": period,
            "shape": list(sheet.shape)}


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description="flapsim mode browser: a gait's modes with sliders")
    p.add_argument("--gait", default="walk")
    p.add_argument("--model", default=None)
    p.add_argument("--sheet", help="write an offscreen PNG contact sheet instead of a window")
    p.add_argument("--seconds", type=float, default=None,
                   help="close the window after this long (tests)")
    p.add_argument("--marker", help="file written once the window is open (tests)")
    args = p.parse_args(argv)
    g = gait(args.gait)
    model, _ = resolve_model(args.model or g.model)
    plan = plan_gait(model, g)
    if args.sheet:
        info = contact_sheet(plan, model, args.sheet)
        print(f"contact sheet {info['shape']} -> {args.sheet}")
        return 0
    ModeBrowser(plan, model).show(marker=args.marker, seconds=args.seconds)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
