"""The simple creatures of Kry et al. 2009 (Fig. 2, Fig. 3) and their locomotion runs.

Both are 16 identical links (link length 0.06 m) joined by hinges of uniform stiffness
1 N m/rad (the paper's Fig. 3 table) and damping 0.002 N m s/rad, on a ground plane with
friction 1.0 (see :mod:`flapsim.modal.build.creatures` for the design):

* ``loop``: a ring of 16 plates (0.06 x 0.12 x 0.01 m) standing upright (0.0425 kg each,
  0.68 kg in all), closed by a ``connect`` equality whose joint spring is a fixed tendon;
  21 velocity dofs, 19 after the closure (the paper's count). Lowest modes: 5.25, 5.25 Hz
  (the two ovalisation modes, a degenerate pair), then 14.75, 14.75, 28.0, 28.0 Hz; the
  paper reports 5.26, 5.26, 15.7, 14.7, 27.5, 27.5 Hz. Body length = perimeter / pi (the
  diameter of the circle with the ring's perimeter) = 0.306 m.
* ``linear``: an open chain of 16 capsules (radius 0.02 m, 0.0104 kg each, 0.166 kg in
  all) lying on the ground along y, its hinge axes alternating between the two bending
  planes (odd joints bend it out of the ground plane, even joints in it), free root at
  the middle link; 21 dofs. Modes 6 and 7 are the first bending mode in each plane,
  3.176 and 3.177 Hz (the paper: 3.18 and 5.68 Hz; it does not describe its chain, and
  no chain of 16 identical links gives its 1.79 ratio: a planar one gives 2.0 to 2.76,
  an alternating one a near-degenerate pair). Body length = its length, 0.96 m.
  Alternating axes are our reading of "a slightly different simple linear creature";
  the paper does not state them.

The controller is the paper's: modes 6 and 7 (the two lowest vibrations) as a PD
equilibrium point, 90 degrees apart, at 5.25 Hz (loop) or 5 Hz (linear).

Measured (10 s, default gaits): the loop rolls like a tank tread, -76.3 / +76.4 body
lengths for phase +90 / -90 deg (the ovalisation wave's pattern speed bounds it). The
linear creature rolls sideways like a rolling pin: the two bending modes in quadrature
turn its (shallow, ~6 cm deep) arc once round the chain per drive cycle, gravity keeps
the arc flat on the ground, so the chain rolls about its own axis, up to 2 pi r = 0.126 m
per cycle. Measured -5.73 / +5.77 body lengths for +90 / -90 deg (88 % of that bound);
5.0 .. 6.3 body lengths over amplitude +-20 % and frequency +-10 %, and 5.5 .. 6.0 with
friction 0.5 or 0.8, damping x5, link mass +20 %, RK4, or a 0.125 ms step.
"""

from __future__ import annotations

import logging
import math
import time
from dataclasses import dataclass, replace
from pathlib import Path

import mujoco
import numpy as np
from tqdm import tqdm

from flapsim.core.assets import asset_path
from flapsim.core.errors import InputError, SimulationError
from flapsim.core.loading import load_model
from flapsim.modal.analysis import ModalAnalysis, analyze
from flapsim.modal.dynamic import ModalController, two_mode_drives
from flapsim.modal.legs import find_root

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class CreatureGait:
    """Parameters of the two-mode controller for one creature."""

    amplitude_rad: float
    """alpha: set-point amplitude of the most-moving joint in each mode, rad (ours;
    the paper's alpha = 1 is in its own unstated normalisation)."""
    freq_hz: float | None
    """Drive frequency for both modes, Hz; None = the lowest vibration mode's own.
    Paper Fig. 3: 5.25 Hz (loop), 5 Hz (linear)."""
    phase_deg: float = 90.0
    """Phase of the second mode relative to the first, degrees (paper: 90)."""
    settle_s: float = 0.5
    """Undriven time to let the creature settle on the ground before measuring, s."""
    ramp_s: float = 0.5
    """Cosine ramp of the drive amplitude at the start, s."""


@dataclass(frozen=True)
class CreatureSpec:
    """A bundled creature model and its default gait."""

    filename: str
    """MJCF file in the ``creatures/`` asset folder."""
    closed_loop: bool
    """True when the body length is perimeter / pi (a ring), else the chain's length."""
    gait: CreatureGait
    """Default two-mode gait."""


CREATURES: dict[str, CreatureSpec] = {
    "loop": CreatureSpec("loop.xml", True, CreatureGait(amplitude_rad=0.3, freq_hz=None)),
    "linear": CreatureSpec("linear.xml", False, CreatureGait(amplitude_rad=0.1, freq_hz=5.0)),
}


#: A user's model: its two lowest modes at the lower one's natural frequency, each
#: moving its most-moving joint by 0.2 rad (ours: between the loop's 0.3 and the linear
#: creature's 0.1, small enough to stay linear-ish, large enough to move).
USER_GAIT = CreatureGait(amplitude_rad=0.2, freq_hz=None)


def is_model_file(name: str) -> bool:
    """True when ``name`` names an MJCF file rather than a bundled creature."""
    return name not in CREATURES and (name.endswith(".xml") or Path(name).exists())


def creature_spec(name: str) -> CreatureSpec:
    """A bundled creature, or any model file (the paper's dynamic creatures: driven by
    its two lowest modes; body length its longest horizontal extent)."""
    if name in CREATURES:
        return CREATURES[name]
    if is_model_file(name):
        if not Path(name).exists():
            raise InputError(f"model file {name!r} does not exist")
        return CreatureSpec(str(name), False, USER_GAIT)
    raise InputError(f"unknown creature {name!r}; choose one of {', '.join(CREATURES)} "
                     "or give an MJCF file with actuated joints")


def creature_file(name: str) -> Path:
    """The MJCF file of a bundled creature (or the model file ``name``)."""
    if name not in CREATURES and is_model_file(name):
        creature_spec(name)
        return Path(name)
    return Path(asset_path("creatures", creature_spec(name).filename))


def load_creature(name: str) -> mujoco.MjModel:
    """Compile a bundled creature model (or a model file)."""
    return load_model(creature_file(name))


def extent_length(model: mujoco.MjModel, data: mujoco.MjData) -> float:
    """Longest horizontal extent of the model's geometry (world geoms aside), m."""
    pts = []
    for g in range(model.ngeom):
        if model.geom_bodyid[g] == 0:
            continue
        r = float(model.geom_rbound[g])
        c = data.geom_xpos[g]
        pts += [c[:2] - r, c[:2] + r]
    if not pts:
        raise InputError("the model has no geometry on its bodies: cannot measure its length")
    p = np.array(pts)
    return float(np.max(p.max(axis=0) - p.min(axis=0)))


def body_length(model: mujoco.MjModel, closed_loop: bool) -> float:
    """Chain length: number of links times the link length (the distance between
    consecutive joints, from the child bodies' offsets); divided by pi for a ring
    (perimeter / pi, the diameter of a circle with the ring's perimeter)."""
    n_links = model.nbody - 1
    offsets = [float(np.linalg.norm(model.body_pos[b])) for b in range(2, model.nbody)]
    if n_links < 2 or not offsets:
        raise InputError("a creature needs at least two links")
    total = n_links * float(np.median(offsets))
    return total / math.pi if closed_loop else total


def analyze_creature(model: mujoco.MjModel) -> ModalAnalysis:
    """Modes of a creature about its rest pose (the closure equality included)."""
    return analyze(model)


def run_creature(
    name: str,
    seconds: float,
    gait: CreatureGait | None = None,
    *,
    progress: bool = False,
    record_every: int = 0,
    model: mujoco.MjModel | None = None,
) -> dict:
    """Simulate a creature driven by its two lowest modes and measure how far it goes.

    Returns distance travelled along x (signed, m and body lengths), the horizontal
    distance, mean speed, the modes used and the wall-clock real-time factor.
    ``record_every`` > 0 also returns the qpos trajectory every that many steps;
    ``model`` replaces the bundled model (a variant of the same creature).
    """
    spec = creature_spec(name)
    user = name not in CREATURES
    gait = gait or spec.gait
    if not (math.isfinite(seconds) and seconds > 0):
        raise InputError(f"--seconds must be a positive number, got {seconds}")
    for field_name in ("amplitude_rad", "phase_deg", "settle_s", "ramp_s"):
        if not math.isfinite(getattr(gait, field_name)):
            raise InputError(f"{field_name} must be finite")
    if gait.settle_s < 0:
        raise InputError("settle time must be non-negative")

    model = model if model is not None else load_creature(name)
    analysis = analyze_creature(model)
    drives = two_mode_drives(
        analysis, gait.amplitude_rad, phase_rad=math.radians(gait.phase_deg), freq_hz=gait.freq_hz
    )
    data = mujoco.MjData(model)
    data.qpos[:] = analysis.rest_qpos
    mujoco.mj_forward(model, data)
    dt = model.opt.timestep
    # The root's subtree com is the creature's centre of mass (the loop's root plate).
    root = find_root(model) if user else 1

    n_settle = int(round(gait.settle_s / dt))
    for _ in range(n_settle):
        mujoco.mj_step(model, data)
    mujoco.mj_forward(model, data)
    start_com = data.subtree_com[root].copy()
    controller = ModalController(model, analysis, drives, ramp_s=gait.ramp_s, start_time=data.time)

    n_steps = int(round(seconds / dt))
    frames: list[np.ndarray] = []
    bar = None
    if progress:
        bar = tqdm(total=n_steps, desc=f"{name} creature", unit="step", leave=False)
    t0 = time.perf_counter()
    chunk = max(n_steps // 100, 1)
    for k in range(n_steps):
        controller.apply(data)
        mujoco.mj_step(model, data)
        if record_every and k % record_every == 0:
            frames.append(data.qpos.copy())
        if bar is not None and (k + 1) % chunk == 0:
            bar.update(chunk)
        if k % 500 == 0:
            _check_stable(model, data, name)
    wall = time.perf_counter() - t0
    if bar is not None:
        bar.close()
    _check_stable(model, data, name)
    mujoco.mj_forward(model, data)
    end_com = data.subtree_com[root].copy()
    length = extent_length(model, rest_data(model, analysis)) if user else body_length(
        model, spec.closed_loop)
    dx = float(end_com[0] - start_com[0])
    horiz = float(np.hypot(*(end_com[:2] - start_com[:2])))
    # Ring plane tilt: the loop's hinge axis (body y) should stay horizontal. The linear
    # creature rolls about its own length, so a root axis tilt means nothing there.
    axis_y = data.xmat[root].reshape(3, 3)[:, 1]
    tilt_deg = (math.degrees(math.asin(min(abs(float(axis_y[2])), 1.0)))
                if spec.closed_loop and not user else None)
    result = {
        "creature": Path(name).stem if user else name,
        "model_file": str(Path(name).resolve()) if user else spec.filename,
        "nv": model.nv,
        "dofs_after_constraints": analysis.n_modes,
        "modes_driven": [d.mode for d in drives],
        "mode_freqs_hz": [float(analysis.freqs_hz[d.mode]) for d in drives],
        "drive_freq_hz": float(drives[0].freq_hz),
        "amplitude_rad": gait.amplitude_rad,
        "phase_deg": gait.phase_deg,
        "simulated_s": n_steps * dt,
        "settle_s": n_settle * dt,
        "body_length_m": length,
        "body_length_definition": ("longest horizontal extent at rest" if user else
                                   "perimeter / pi" if spec.closed_loop else "chain length"),
        "distance_x_m": dx,
        "distance_x_body_lengths": dx / length,
        "distance_horizontal_m": horiz,
        "distance_horizontal_body_lengths": horiz / length,
        "lateral_drift_m": float(end_com[1] - start_com[1]),
        "mean_speed_m_s": dx / (n_steps * dt),
        "mean_speed_body_lengths_s": dx / length / (n_steps * dt),
        "final_tilt_deg": tilt_deg,
        "wall_s": wall,
        "realtime_factor": n_steps * dt / wall if wall > 0 else float("inf"),
    }
    if record_every:
        result["_frames"] = np.array(frames)
    return result


def rest_data(model: mujoco.MjModel, analysis: ModalAnalysis) -> mujoco.MjData:
    d = mujoco.MjData(model)
    d.qpos[:] = analysis.rest_qpos
    mujoco.mj_forward(model, d)
    return d


def _check_stable(model: mujoco.MjModel, data: mujoco.MjData, name: str) -> None:
    # MuJoCo resets the state (and only warns) when accelerations blow up, so a diverged
    # run would otherwise report a bogus distance.
    bad = data.warning[mujoco.mjtWarning.mjWARN_BADQACC].number
    if bad or not np.all(np.isfinite(data.qpos)):
        raise SimulationError(
            f"the {name} creature simulation diverged (t={data.time:.3f} s); "
            "lower the amplitude or the drive frequency"
        )


def with_gait(name: str, **changes: object) -> CreatureGait:
    """The creature's default gait with some fields replaced (``None`` values ignored)."""
    return replace(creature_spec(name).gait, **{k: v for k, v in changes.items() if v is not None})
