"""Where the dove's muscle power goes in free flight (:func:`power_budget`): a wingbeat
repeated from the standard cruise start (by default the reference wingbeat P0 with the tail
bias: the base controller), over whole wingbeats. ``studies/dove_power_budget.py`` prints it.

A polygon's lift is perpendicular to its relative flow, so it does no work against it: the
air takes energy out of the bird through drag and skin friction, D . V_rel + F_f . V_rel with
V_rel = w - (the centroid's velocity over the step), and, where the wings see their own
downwash w (the induced flow), through the work of every force on the air it pushes down,
-F . w (the induced power; w = 0 in still air). What the
servos put in (their generalized force times the step's mean velocity) goes there, into the
joints' and tendons' dampers, and into the bird's mechanical energy (kinetic, gravitational
and springs: MuJoCo's ``mjENBL_ENERGY``). :func:`power_budget` averages each term over the
wingbeats after ``skip``, with what the balance leaves (``other_W``: the feathers'
twist-hinge torques and the integrator), the work rate of every generalized force against
the energy's own rate (the work-energy theorem, which closes to ~1 % of the muscles' power
when nothing acts but these forces), and the feathers' drag dissipation split by stroke
(the left shoulder's flap velocity: down or up) and by angle of attack, the trunk's climb
rate and change of speed (their net force along the flight over the weight: 0 in trim) and
the peak aerodynamic force on both wings' feathers over the weight.
"""

from __future__ import annotations

from dataclasses import replace

import mujoco
import numpy as np

from flapsim.bird.body.model import Dove
from flapsim.bird.flight.cycle import heading_and_climb
from flapsim.bird.flight.dove_flight import BODY_TABLE, DoveFlight, FlightConfig
from flapsim.bird.flight.wingbeat import (
    ReferenceWingbeat,
    control_table,
    p0,
    reference_wingbeat,
    with_tail_bias,
    with_twist_bias,
)
from flapsim.core.errors import InputError

AOA_BINS_DEG = (0.0, 15.0, 30.0, 45.0, 60.0, 90.0, 180.0)


def power_budget(wingbeats: int = 6, skip: int = 2, table: str | None = None,
                 tail_bias_deg: float | None = None, twist_bias_deg: float = 0.0,
                 p: np.ndarray | None = None, speed: float | None = None,
                 config: FlightConfig | None = None, induced: bool = False,
                 ref: ReferenceWingbeat | None = None) -> dict:
    """Each term of the energy balance, W, averaged over wingbeats ``skip`` .. ``wingbeats``
    of the base flight (``table``: the feathers' coefficient table; ``tail_bias_deg``: the
    tail bend added to P0; ``twist_bias_deg``: both shoulder twists added, + pronates), with
    the feathers' drag dissipation by stroke and by angle of attack, the vertical aerodynamic
    force over the weight and the mean forward speed (see the module). ``p``: fly this
    wingbeat instead (the biases are then not applied); ``speed``: the start's forward speed,
    m/s (default the cruise start's 7); ``config``: the start and the table (pitch, speed,
    tail bias) as ``flapsim fly`` sets them, instead of the defaults; ``induced``: the dove
    whose wings see their own downwash (:meth:`Dove.load`), whose downwash DOF are left out of
    every work term (they are the air's, not the bird's); ``ref``: the reference wingbeat P0 is
    relative to (default: the bundled capture's)."""
    if not 0 <= skip < wingbeats:
        raise InputError(f"need 0 <= skip < wingbeats, got skip {skip}, wingbeats {wingbeats}")
    cfg = config or FlightConfig()
    cfg = replace(cfg, table=cfg.table if table is None else table,
                  speed=cfg.speed if speed is None else float(speed))
    if not 1.0 <= cfg.speed <= 30.0:
        raise InputError(f"the start's speed must be 1-30 m/s, got {cfg.speed}")
    bias = cfg.tail_bias_deg if tail_bias_deg is None else tail_bias_deg
    if p is None:
        p = with_twist_bias(with_tail_bias(p0(), bias), twist_bias_deg)
    elif np.shape(p) != np.shape(p0()) or not np.all(np.isfinite(p)):
        raise InputError(f"a wingbeat is {np.size(p0())} finite parameters, got shape {np.shape(p)}")
    dove = Dove.load(induced=induced)
    fl = DoveFlight(dove, ref or reference_wingbeat(), cfg.table, use_rollout=False)
    m, d = fl.model, fl.data
    m.opt.enableflags |= mujoco.mjtEnableBit.mjENBL_ENERGY
    flap = m.jnt_dofadr[mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, "l_shoulder_flap")]
    feather = fl.polygons.table != BODY_TABLE
    # the wings' feathers (primaries and secondaries, not the tail's rectrices)
    wing = np.array([lb.split("_")[-1][:1] in ("p", "s") and lb[:2] in ("l_", "r_")
                     for lb in fl.polygons.labels])
    # the downwash each polygon sees (its group's induced-flow DOF velocity; none: still air)
    group = (fl.aero.induced.polygon_group if fl.aero.induced is not None
             else np.full(len(fl.polygons.labels), -1))
    sees = group >= 0
    steps = []
    try:
        fl.reset(cfg, p)
        for wb in range(wingbeats):
            ctrl, _, _ = control_table(fl.ref, p, m.opt.timestep, fl.kp, fl.kv)
            for k in range(len(ctrl)):
                # the forces that act over the step: the step's control at the state it starts
                # from (a servo's force read after the step, with the previous control, is off
                # by kp x one step of the target's motion: -7 W instead of +14 W here)
                d.ctrl[:] = ctrl[k]
                mujoco.mj_forward(m, d)
                rep = fl.aero.evaluate(d)
                air = np.zeros((len(group), 3))
                if sees.any():
                    air[sees] = d.qvel[fl.aero.induced_dofs].reshape(-1, 3)[group[sees]]
                steps.append({
                    "air": air,
                    "wb": wb, "points": rep.points, "drag": rep.drag, "lift": rep.lift,
                    "friction": rep.friction, "aoa": rep.aoa, "energy": float(d.energy.sum()),
                    "up": float((rep.drag + rep.lift + rep.friction)[:, 2].sum()),
                    "wing_force": float(np.linalg.norm(
                        (rep.drag + rep.lift + rep.friction)[wing].sum(axis=0))),
                    "z": float(d.qpos[2]), "time": float(d.time),
                    "speed": float(np.hypot(d.qvel[0], d.qvel[1])),
                    "down": bool(d.qvel[flap] < 0.0), "v0": d.qvel.copy(),
                    "f_act": d.qfrc_actuator.copy(), "f_damp": d.qfrc_damper.copy(),
                    "f_all": d.qfrc_actuator + d.qfrc_passive + d.qfrc_constraint})
                mujoco.mj_step(m, d)
                steps[-1]["v1"] = d.qvel.copy()
    finally:
        fl.close()
    # every step of the wingbeats averaged that has a next step (its end state)
    use = [k for k in range(len(steps) - 1) if steps[k]["wb"] >= skip]
    bird_dof = np.ones(m.nv, dtype=bool)
    bird_dof[fl.aero.induced_dofs] = False
    out = _summarise(steps, use, feather, m.opt.timestep, dove.mass, bird_dof)
    first, last = steps[use[0]], steps[use[-1] + 1]
    T = last["time"] - first["time"]
    out["climb_m_s"] = (last["z"] - first["z"]) / T
    out["accel_m_s2"] = (last["speed"] - first["speed"]) / T
    # the mean net force along the flight over the weight: m a / (m g)
    out["net_forward_per_weight"] = out["accel_m_s2"] / 9.81
    out["peak_wing_force_per_weight"] = (max(steps[k]["wing_force"] for k in use)
                                         / (dove.mass * 9.81))
    return out


def _summarise(steps: list[dict], use: list[int], feather: np.ndarray, dt: float,
               mass: float, bird_dof: np.ndarray | None = None) -> dict:
    col = lambda key, shift=0: np.array([steps[k + shift][key] for k in use])  # noqa: E731
    v = 0.5 * (col("v0") + col("v1"))  # the step's mean velocity: its work closes the balance
    if bird_dof is not None:
        v = v * bird_dof
    work = lambda key: np.einsum("ij,ij->i", col(key), v)  # noqa: E731
    # the relative flow: the air's velocity at the polygon (still air, or the wing's own
    # downwash) less the centroid's velocity over the step
    air = col("air")
    vrel = air - (col("points", 1) - col("points")) / dt
    drag, lift, fric = (np.einsum("sij,sij->si", col(key), vrel)
                        for key in ("drag", "lift", "friction"))
    # what the bird loses to the air is -F . v = F . vrel - F . w: besides the dissipation
    # F . vrel, the work its forces do on the air they push down (the induced power)
    induced = -np.einsum("sij,sij->s", col("drag") + col("lift") + col("friction"), air)
    down, aoa = col("down"), np.degrees(col("aoa"))
    T = len(use) * dt
    out = {
        "seconds": T, "mass_kg": mass,
        "muscle_W": float(work("f_act").mean()),
        "dampers_W": float(-work("f_damp").mean()),
        "drag_feathers_W": float(drag[:, feather].sum(1).mean()),
        "drag_body_W": float(drag[:, ~feather].sum(1).mean()),
        "friction_W": float(fric.sum(1).mean()),
        "lift_work_W": float(lift.sum(1).mean()),
        "induced_W": float(induced.mean()),
        "mechanical_energy_rate_W": float((col("energy", 1) - col("energy")).sum() / T),
        "work_rate_all_forces_W": float(work("f_all").mean()),
        "aero_up_per_weight": float(col("up").mean() / (mass * 9.81)),
        "mean_speed_m_s": float(col("speed").mean()),
    }
    # mechanical cost of transport: the servos' work per weight and distance flown
    out["cost_of_transport"] = out["muscle_W"] / (mass * 9.81 * out["mean_speed_m_s"])
    # what the air and the dampers do not account for: the twist hinges' own torques
    # (stops, the plates' inertia), the springs' and gravity's work being in the energy
    out["other_W"] = (out["muscle_W"] - out["dampers_W"] - out["drag_feathers_W"]
                      - out["drag_body_W"] - out["friction_W"] - out["induced_W"]
                      - out["mechanical_energy_rate_W"])
    fd = drag[:, feather]
    out["drag_feathers_downstroke_W"] = float(fd[down].sum() / len(use))
    out["drag_feathers_upstroke_W"] = float(fd[~down].sum() / len(use))
    fa = aoa[:, feather]
    bins = {}
    for lo, hi in zip(AOA_BINS_DEG[:-1], AOA_BINS_DEG[1:], strict=True):
        sel = (fa >= lo) & (fa < hi)
        bins[f"{lo:g}-{hi:g}"] = float(np.where(sel, fd, 0.0).sum() / len(use))
    out["drag_feathers_by_aoa_W"] = bins
    return out


def wingbeat_balance(fl: DoveFlight, p: np.ndarray, wingbeats: int = 6, skip: int = 2,
                     speed: float = 7.0) -> dict | None:
    """The cheap part of :func:`power_budget`, for searches over many wingbeats: wingbeat
    ``p`` repeated ``wingbeats`` times on flight ``fl`` (rigid dove, built with
    ``use_rollout=False``) from the cruise start at ``speed`` m/s, measured over wingbeats
    ``skip``..: the servos' mean power (their generalized force over each step times the
    step's mean velocity, W), the trunk's climb rate (m/s) and change of speed (m/s^2), the
    rate of the bird's mechanical energy taken as its whole mass moving with the trunk
    (m (v dv/dt + g dz/dt), W: the wings' own kinetic energy repeats from wingbeat to
    wingbeat), the end speed (m/s), the trunk's pitch at each wingbeat's end (deg, nose up
    +), the heading of the centre of mass's velocity at the start and at each wingbeat's end
    (deg, + left, unwrapped: the turn per wingbeat is its difference) and the mass (kg). None
    when the flight diverges (a trunk speed over 50 m/s or a non-finite velocity)."""
    if not 0 <= skip < wingbeats:
        raise InputError(f"need 0 <= skip < wingbeats, got skip {skip}, wingbeats {wingbeats}")
    m, d = fl.model, fl.data
    fl.reset(FlightConfig(speed=float(speed)), p)
    ctrl, _, _ = control_table(fl.ref, p, m.opt.timestep, fl.kp, fl.kv)
    mass = float(fl.dove.mass)
    work, n, pitch = 0.0, 0, []
    heading = [com_heading_deg(fl)]
    z0 = v0 = t0 = 0.0
    for wb in range(wingbeats):
        if wb == skip:
            z0, v0, t0 = float(d.qpos[2]), float(np.linalg.norm(d.qvel[0:3])), float(d.time)
        for k in range(len(ctrl)):
            d.ctrl[:] = ctrl[k]
            before = d.qvel.copy()
            # qfrc_actuator after the step is the one computed at the state it started from
            # with this step's control: the force that acted over it
            mujoco.mj_step(m, d)
            if not np.all(np.isfinite(d.qvel[0:6])) or np.abs(d.qvel[0:3]).max() > 50.0:
                return None
            if wb >= skip:
                work += float(d.qfrc_actuator @ (0.5 * (before + d.qvel)))
                n += 1
        pitch.append(float(np.degrees(fl.reduced_state()[0])))  # the state's pitch, nose up +
        heading.append(com_heading_deg(fl))
    T = float(d.time) - t0
    z1, v1 = float(d.qpos[2]), float(np.linalg.norm(d.qvel[0:3]))
    return {"power_W": work / n, "climb_m_s": (z1 - z0) / T, "accel_m_s2": (v1 - v0) / T,
            "energy_rate_W": mass * (0.5 * (v1**2 - v0**2) + 9.81 * (z1 - z0)) / T,
            "speed_m_s": v1, "pitch_deg": pitch,
            "heading_deg": np.degrees(np.unwrap(np.radians(heading))).tolist(), "mass_kg": mass}


def com_heading_deg(fl: DoveFlight) -> float:
    """Heading of the centre of mass's velocity, deg (+ left)."""
    return float(np.degrees(heading_and_climb(fl.com_velocity())[0]))
