"""Steer the dove in MuJoCo's viewer (the flight paper's interactive control).

The learned wingbeat controller flies the dove one wingbeat at a time (``choose``: the P0
prediction, the regression, the wingbeat itself); each wingbeat's recorded steps are then
played back in the shared :class:`flapsim.render.viewer.AnimalViewer` at real time, on a display
copy of the state (the controller restores snapshots on its own ``MjData``). Keys, read by
the simulation loop between wingbeats (the viewer's key callback only queues them):

* Left / Right: turn rate +-5 deg/s (steering; the bird banks into the turn);
* Up / Down: climb angle +-1 deg (elevation);
* Page Up / Page Down: speed +-0.25 m/s;
* End: level flight straight on (turn rate and climb to 0);
* double-click (left button) on the ground: fly toward that point (the heading turned to it,
  the turn rate asked back to 0; the bird banks into the turn as for the keys);
* Insert: a push of 6 N for 0.1 s from the left, at the trunk's centre of mass;
* Delete: a 1-cosine gust of 3 m/s across the flight, 0.5 s;
* Home: chase / free camera (the chase camera turns with the bird's heading);
* Escape: close the viewer (the results are returned as when the time is up).

A push is drawn as a red arrow into the trunk, a gust as a blue one, for a second. The
first wingbeat (which compiles the force kernels) is flown before the window opens, with a
line in the terminal instead of a loading screen; the overlay and the results give the
achieved real-time factor.

With a path (``path=``) the bird follows it instead (keys still push and gust) and the
path is drawn. With modal feathers (``feathers="modal"``, with their own bundled database or
another trained on that dove) the feathers are drawn bent each frame
(:class:`flapsim.bird.body.drawing.FeatherDrawing`, the videos' drawing).
"""

from __future__ import annotations

import sys
import time
from dataclasses import dataclass, field

import mujoco
import numpy as np

from flapsim.bird.body.drawing import FeatherDrawing
from flapsim.bird.control.controller import database_pitch, database_speed, start_cruise
from flapsim.bird.control.targets import CruiseTarget, trim_of_base_flight
from flapsim.bird.flight import cycle
from flapsim.bird.flight.dove_flight import FlightConfig
from flapsim.bird.tasks.config import PathControlConfig
from flapsim.bird.tasks.flight_tasks import PushSpec, Task, build_flight
from flapsim.bird.tasks.path_control import PathTarget, start_on_path
from flapsim.bird.tasks.path_shapes import straight
from flapsim.fluid.flow import ROW, Gust
from flapsim.render.viewer import (
    FLASH_S,
    FRAME_S,
    KEY_DELETE,
    KEY_DOWN,
    KEY_END,
    KEY_INSERT,
    KEY_LEFT,
    KEY_NAMES,
    KEY_PAGE_DOWN,
    KEY_PAGE_UP,
    KEY_RIGHT,
    KEY_UP,
    AnimalViewer,
    Arrow,
    Marker,
    Polyline,
)

TURN_STEP_DEG_S = 5.0
CLIMB_STEP_DEG = 1.0
SPEED_STEP = 0.25
PUSH_N = 6.0
GUST_M_S = 3.0
GUST_S = 0.5


@dataclass
class Command:
    """What the keys ask; the simulation loop turns it into the target state."""

    turn_rate_deg_s: float = 0.0
    climb_deg: float = 0.0
    speed: float = 7.0
    pushes: int = 0
    gusts: int = 0
    events: list = field(default_factory=list)

    def apply(self, key: int, t: float) -> tuple[bool, bool]:
        """Update from one key; returns (push now, gust now)."""
        push = gust = False
        if key in (KEY_LEFT, KEY_RIGHT):
            s = 1.0 if key == KEY_LEFT else -1.0
            self.turn_rate_deg_s = float(np.clip(self.turn_rate_deg_s + s * TURN_STEP_DEG_S, -40, 40))
        elif key in (KEY_UP, KEY_DOWN):
            s = 1.0 if key == KEY_UP else -1.0
            self.climb_deg = float(np.clip(self.climb_deg + s * CLIMB_STEP_DEG, -10, 10))
        elif key in (KEY_PAGE_UP, KEY_PAGE_DOWN):
            s = 1.0 if key == KEY_PAGE_UP else -1.0
            self.speed = float(np.clip(self.speed + s * SPEED_STEP, 5.0, 9.0))
        elif key == KEY_END:
            self.turn_rate_deg_s = self.climb_deg = 0.0
        elif key == KEY_INSERT:
            push = True
            self.pushes += 1
        elif key == KEY_DELETE:
            gust = True
            self.gusts += 1
        else:
            return False, False
        self.events.append({"t": t, "key": KEY_NAMES.get(key, key), "turn_rate_deg_s":
                            self.turn_rate_deg_s, "climb_deg": self.climb_deg, "speed": self.speed})
        return push, gust


def view_flight(seconds: float, db=None, method: str = "lwlr", k: int | None = None,
                path=None, launch=None, feathers: str = "rigid",
                path_control: PathControlConfig | None = None, **options) -> dict:
    """Fly the dove under the keys for ``seconds`` of simulated time (or until the window
    closes); returns what happened (keys, headings, distance). ``feathers``: ``rigid`` or
    ``modal`` (``db``: by default the bundled database of that dove); ``path_control``: the
    path target's tuning (None: the dove's defaults); ``options``: the controller's
    (:func:`~flapsim.bird.control.controller.load_controller`: ``mirror``, ``predict``,
    ``config``, ...)."""

    # a gust primitive that is inert (zero amplitude) until Delete re-packs it in place
    fl, ctl = build_flight(Task(path if path is not None else _dummy_path(),
                                flow=(Gust((0.0, 1.0, 0.0), 0.0, 0.0, GUST_S),), feathers=feathers),
                           db, method, k, **options)
    view: AnimalViewer | None = None
    try:
        cmd = Command(speed=database_speed(db, feathers))  # the speed its samples describe
        cfg = FlightConfig(speed=cmd.speed, pitch_deg=database_pitch(db, feathers))
        trim = trim_of_base_flight(fl, ctl.P0, cfg)
        if path is not None:
            start_on_path(fl, ctl.P0, path, cmd.speed, pitch_deg=cfg.pitch_deg)
            tuning = path_control or PathControlConfig.for_dove(feathers)
            target = PathTarget(trim, path, speed=cmd.speed, **tuning.target_settings(cmd.speed))
        else:
            start_cruise(fl, ctl.P0, cfg)
            target = CruiseTarget(trim, altitude=cfg.height, speed=cmd.speed)
        draw = None
        if fl.dove.modal is not None:
            draw = FeatherDrawing(fl.dove)
        # what is drawn: the dove with its primaries' twist hinges in the skeleton (a flight
        # state's qpos[ix] is its qpos), or the display copy with bendable feathers (the
        # modal dove's own qpos layout)
        m, ix = fl.dove.drawing() if draw is None else (draw.model, draw.ix)
        shown = mujoco.MjData(m)
        _place(m, shown, fl.frame()[ix], draw)
        items = [Polyline(path.point(np.linspace(0, path.length, 400)))] if path is not None else []
        dt = float(m.opt.timestep)
        stride = max(1, int(round(FRAME_S / dt)))
        heading0 = float(np.arctan2(*fl.com_velocity()[[1, 0]]))
        headings, positions = [heading0], [fl.data.qpos[0:3].copy()]
        wall0 = time.perf_counter()
        status = "time up"
        max_wind = 0.0
        v_prev = fl.com_velocity()
        while fl.data.time < seconds:
            t = float(fl.data.time)
            push_now = False
            for key in view.pending_keys() if view is not None else ():
                p, g = cmd.apply(key, t)
                push_now |= p
                if g:
                    h = float(np.arctan2(v_prev[1], v_prev[0]))
                    _gust(fl, t, v_prev)
                    # the gust blows from the left: a blue arrow toward the bird, drawn
                    # beside it as it flies on (the chase camera leaves a fixed one behind)
                    across = np.array([-np.sin(h), np.cos(h), 0.0])
                    view.flash(lambda a=across: Arrow(shown.xpos[fl.dove.trunk] + 0.9 * a,
                                                      -0.6 * a, width=0.025,
                                                      rgba=(0.15, 0.45, 1.0, 1.0)),
                               t, GUST_S + FLASH_S)
            for point in view.pending_clicks() if view is not None else ():
                if isinstance(target, CruiseTarget):  # a path is followed, not steered
                    _fly_toward(target, cmd, point, positions[-1], t)
                    # where it was sent, drawn on the ground until the next click
                    items = [Marker(point, radius=1.0)]
            push = None
            if push_now:
                heading = float(np.arctan2(v_prev[1], v_prev[0]))
                force = PushSpec(t, PUSH_N, "left").world_force(heading)
                push = cycle.Push(fl.dove.trunk, force, int(round(0.1 / dt)))
                # a red arrow along the push, ending at the trunk as it flies on, 0.1 m per
                # newton
                f = np.asarray(force, float)
                view.flash(lambda f=f: Arrow(shown.xpos[fl.dove.trunk] - 0.1 * f, 0.1 * f * 0.9,
                                             width=0.025), t)
            if isinstance(target, CruiseTarget):
                # the commands integrate into the cruise target's heading and altitude
                target.speed = cmd.speed
                target.heading += np.radians(cmd.turn_rate_deg_s) * 0.1075
                target.altitude += cmd.speed * np.sin(np.radians(cmd.climb_deg)) * 0.1075
            else:
                target.speed = cmd.speed
                target.begin(fl.data.qpos[0:3], v_prev)
            if view is None:
                print("flapsim view: dove and controller loaded; flying the first wingbeat "
                      "(compiling the force kernels)...", file=sys.stderr, flush=True)
            step = ctl.choose(target, record=True, push=push)
            e = step.end
            if view is None:  # the window opens on a flying bird, not on a loading screen
                print(f"flapsim view: opening the viewer ({time.perf_counter() - wall0:.1f} s "
                      "to load); Esc closes it", file=sys.stderr, flush=True)
                view = AnimalViewer(m, shown, fl.dove.trunk, distance=1.4, launch=launch)
                wall0 = time.perf_counter()
            v_prev = e.com_vel
            headings.append(float(np.arctan2(e.com_vel[1], e.com_vel[0])))
            max_wind = max(max_wind, float(np.linalg.norm(
                fl.flow.velocity(e.trunk_pos[None].copy(), float(fl.data.time))[0])))
            positions.append(e.trunk_pos.copy())
            frames = e.qpos[stride - 1::stride]
            t_start = t
            running = True
            for i, q in enumerate(frames):
                shown.time = t_start + (i + 1) * stride * dt
                _place(m, shown, q[ix], draw)
                steer = ("following the path\n-" if path is not None else
                         f"{cmd.turn_rate_deg_s:+.0f} deg/s\n{cmd.climb_deg:+.0f} deg")
                texts = ("steering\nelevation\nspeed\nwind\nkeys\n",
                         f"{steer}\n"
                         f"{np.linalg.norm(e.com_vel):.2f} m/s (asked {cmd.speed:.2f})\n"
                         f"{_wind_text(fl, shown.time)}\n"
                         "arrows: steer/climb, PgUp/PgDn: speed, End: level,\n"
                         "double-click: fly toward it, Insert: push, Delete: gust")
                if not view.show(shown.time, items, texts):
                    running = False
                    break
            if not running:
                status = "closed by Escape" if view.closed_by else "window closed"
                break
        wall = time.perf_counter() - wall0
        rtf = view.real_time_factor if view is not None else None
    finally:
        if view is not None:
            view.close()
        fl.close()
    h = np.unwrap(np.array(headings))
    pos = np.array(positions)
    return {"status": status, "simulated_s": float(fl.data.time), "wall_s": wall,
            "heading_change_deg": float(np.degrees(h[-1] - h[0])),
            "altitude_change_m": float(pos[-1, 2] - pos[0, 2]),
            "distance_m": float(np.sum(np.linalg.norm(np.diff(pos, axis=0), axis=1))),
            "final_command": {"turn_rate_deg_s": cmd.turn_rate_deg_s, "climb_deg": cmd.climb_deg,
                              "speed": cmd.speed},
            "pushes": cmd.pushes, "gusts": cmd.gusts, "events": cmd.events,
            "max_wind_m_s": max_wind,
            "real_time_factor": rtf,
            "frames_drawn": view.frames if view is not None else 0,
            "frames_dropped": view.dropped if view is not None else 0,
            "wingbeats": len(headings) - 1}


def _fly_toward(target, cmd: Command, point: np.ndarray, position: np.ndarray, t: float) -> None:
    """Turn the cruise target's heading to the horizontal bearing of ``point`` from
    ``position`` (world, m), with no turn rate asked on top; logged as a click event."""
    bearing = float(np.arctan2(point[1] - position[1], point[0] - position[0]))
    target.heading += float(cycle.wrap(bearing - target.heading))
    cmd.turn_rate_deg_s = 0.0
    cmd.events.append({"t": t, "key": "double-click", "click": [float(v) for v in point],
                       "heading_deg": float(np.degrees(bearing)), "turn_rate_deg_s": 0.0,
                       "climb_deg": cmd.climb_deg, "speed": cmd.speed})


def _place(m: mujoco.MjModel, shown: mujoco.MjData, qpos: np.ndarray, draw) -> None:
    """Show state ``qpos``: positions, the bent feathers (modal), then ``mj_forward``."""
    shown.qpos[:] = qpos
    if draw is not None:
        draw.apply(shown)
    mujoco.mj_forward(m, shown)


def _dummy_path():
    return straight(10.0)


def _gust(fl, t: float, v: np.ndarray) -> None:
    """Re-pack the flow's gust row (row 1) as a 3 m/s gust from the left starting now."""
    h = float(np.arctan2(v[1], v[0]))
    row = Gust((-np.sin(h), np.cos(h), 0.0), GUST_M_S, t, GUST_S).pack()
    fl.flow.params[ROW:2 * ROW] = row


def _wind_text(fl, t: float) -> str:
    w = fl.flow.velocity(fl.data.qpos[None, 0:3].copy(), t)[0]
    return f"{np.linalg.norm(w):.1f} m/s"
