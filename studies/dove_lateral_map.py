"""How unstable is a dove's lateral motion from one wingbeat to the next, and can wingbeats
chosen once a beat hold it?

The learned controller picks one wingbeat per beat. Whether any once-a-beat choice of
wingbeats can hold a pushed dove is a property of the wingbeat-to-wingbeat map, which this
study measures around the reference wingbeat flown in cruise. By the bird's left-right symmetry
the lateral part of the reduced state (roll, body-frame sideways velocity, roll rate and yaw
rate) decouples from the longitudinal part to first order, so the map's lateral linearisation

    x_{k+1} = A x_k + B u_k

is found by central differences: A from one wingbeat flown from the settled state with each
lateral state perturbed, B from one wingbeat flown with each antisymmetric wingbeat parameter
moved (the left wing's scale or translation of a DOF up, the right wing's down: 12 inputs).
A's eigenvalues say how fast a lateral disturbance grows per wingbeat (|lambda| > 1: unstable).
A discrete linear-quadratic regulator on (A, B) then chooses each wingbeat's antisymmetric
part from the state at its start; flown on the nonlinear dove it is pushed sideways for 0.1 s
at the third wingbeat's start (the flight suite's push) and the trunk's roll at every
wingbeat's end, the sideways drift and the servos' power are printed, open loop beside it.
Every force is the feathers' and the body's; the wingbeats are the paper's 29-number family
(no reflex within a beat, nothing on the trunk).

    python studies/dove_lateral_map.py --dove cruise --push 3,6,8
    python studies/dove_lateral_map.py --dove robofly
"""

from __future__ import annotations

import argparse

import mujoco
import numpy as np
import scipy.linalg

from flapsim.bird.body.model import Dove
from flapsim.bird.body.params import DOF_NAMES
from flapsim.bird.flight.dove_flight import CRUISE, DoveFlight, FlightConfig
from flapsim.bird.flight.wingbeat import control_table, p0, reference_wingbeat, with_tail_bias
from flapsim.core.errors import SimulationError
from flapsim.core.io import write_json

LATERAL = (1, 3, 5, 7)
"""Indices of the lateral part in the reduced state: roll, v_y, omega_x, omega_z."""
LATERAL_NAMES = ("roll", "v_y", "omega_x", "omega_z")
WING_DOFS = ("shoulder_flap", "shoulder_sweep", "shoulder_twist", "elbow_flex", "elbow_twist",
             "wrist_flex")
STATE_EPS = np.concatenate([[np.radians(1.0), 0.05, 0.1, 0.1],
                            np.full(len(WING_DOFS), np.radians(0.5)), np.full(len(WING_DOFS), 1.0)])
"""Central-difference steps: 1 deg, 0.05 m/s, 0.1 rad/s, 0.1 rad/s for the trunk (small against
a push's 0.5-5 m/s, large against the solver's round-off), 0.5 deg and 1 rad/s for the wing
DOF pairs (the servos track within a few degrees at rates of ~50 rad/s)."""
SCALE_EPS, SHIFT_EPS = 0.02, np.radians(1.0)
PUSH_S, PUSH_WINGBEAT, SETTLE = 0.1, 2, 4


def dove(kind: str) -> tuple[DoveFlight, np.ndarray, FlightConfig]:
    """The flight, its reference parameters and its start: the cruise dove (bird wing, induced
    flow, cruise wingbeat) or the default robofly dove."""
    if kind == "cruise":
        fl = DoveFlight(Dove.load(induced=True), ref=reference_wingbeat("cruise"),
                        table="bird_wing", use_rollout=False)
        cfg = CRUISE
    else:
        fl = DoveFlight(Dove.load(), use_rollout=False)
        cfg = FlightConfig()
    return fl, with_tail_bias(p0(), cfg.tail_bias_deg), cfg


def inputs() -> tuple[list[str], np.ndarray]:
    """The antisymmetric input directions (12, 29): left parameter up, right down."""
    names, rows = [], []
    for dof in WING_DOFS:
        il, ir = DOF_NAMES.index(f"l_{dof}"), DOF_NAMES.index(f"r_{dof}")
        for part, off, eps in (("scale", 0, SCALE_EPS), ("shift", 1, SHIFT_EPS)):
            e = np.zeros(len(p0()))
            e[2 * il + off], e[2 * ir + off] = eps, -eps
            names.append(f"{dof}.{part}")
            rows.append(e)
    return names, np.array(rows)


class Snapshot:
    """The full physics state (and the solver's warm start) of a flight, to fly from again."""

    def __init__(self, fl: DoveFlight) -> None:
        m, d = fl.model, fl.data
        self.spec = mujoco.mjtState.mjSTATE_FULLPHYSICS
        self.state = np.empty(mujoco.mj_stateSize(m, self.spec))
        mujoco.mj_getState(m, d, self.state, self.spec)
        self.warm = d.qacc_warmstart.copy()

    def restore(self, fl: DoveFlight) -> None:
        m, d = fl.model, fl.data
        mujoco.mj_setState(m, d, self.state, self.spec)
        d.qacc_warmstart[:] = self.warm
        mujoco.mj_forward(m, d)


def perturb(fl: DoveFlight, j: int, eps: float) -> None:
    """Move state ``j`` of :func:`lateral` by ``eps``, the others' values kept."""
    m, d = fl.model, fl.data
    R = np.zeros(9)
    mujoco.mju_quat2Mat(R, d.qpos[3:7])
    R = R.reshape(3, 3)
    v_body = R.T @ d.qvel[0:3]
    if j == 0:  # roll: turn the trunk about its own forward axis, body-frame velocity kept
        dq = np.array([np.cos(eps / 2), np.sin(eps / 2), 0.0, 0.0])
        q = np.zeros(4)
        mujoco.mju_mulQuat(q, d.qpos[3:7], dq)
        d.qpos[3:7] = q
        R2 = np.zeros(9)
        mujoco.mju_quat2Mat(R2, q)
        d.qvel[0:3] = R2.reshape(3, 3) @ v_body
    elif j == 1:
        d.qvel[0:3] += eps * R[:, 1]
    elif j < 4:
        d.qvel[3 + (0 if j == 2 else 2)] += eps
    else:  # a wing DOF pair's angle (j < 10) or rate moved apart
        il, ir = _pair(fl, WING_DOFS[(j - 4) % len(WING_DOFS)])
        adr = fl.dove.qadr if j < 4 + len(WING_DOFS) else fl.dove.dadr
        arr = d.qpos if j < 4 + len(WING_DOFS) else d.qvel
        arr[adr[il]] += eps
        arr[adr[ir]] -= eps
    mujoco.mj_forward(m, d)


def _pair(fl: DoveFlight, dof: str) -> tuple[int, int]:
    return DOF_NAMES.index(f"l_{dof}"), DOF_NAMES.index(f"r_{dof}")


def lateral(fl: DoveFlight) -> np.ndarray:
    """The lateral state: the trunk's four, then each wing DOF pair's angle difference and
    rate difference (half left minus right): the servos' lag carries an antisymmetric
    wingbeat into the next one."""
    d, dv = fl.data, fl.dove
    pairs = [_pair(fl, n) for n in WING_DOFS]
    dq = [(d.qpos[dv.qadr[il]] - d.qpos[dv.qadr[ir]]) / 2 for il, ir in pairs]
    dqd = [(d.qvel[dv.dadr[il]] - d.qvel[dv.dadr[ir]]) / 2 for il, ir in pairs]
    return np.concatenate([fl.reduced_state()[list(LATERAL)], dq, dqd])


def linearise(fl: DoveFlight, P: np.ndarray, start: Snapshot, E: np.ndarray
              ) -> tuple[np.ndarray, np.ndarray]:
    """(A (n, n), B (n, n_inputs)) of the lateral wingbeat map at ``start`` flying ``P``."""
    def end(p: np.ndarray, j: int | None = None, eps: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
        start.restore(fl)
        if j is not None:
            perturb(fl, j, eps)
        x0 = lateral(fl)
        fl.run_cycle(p, record=False)
        return x0, lateral(fl)

    dX, dY = [], []
    for j, eps in enumerate(STATE_EPS):
        xp, yp = end(P, j, eps)
        xm, ym = end(P, j, -eps)
        dX.append(xp - xm)
        dY.append(yp - ym)
    A = np.array(dY).T @ np.linalg.inv(np.array(dX).T)
    B = np.empty((len(STATE_EPS), len(E)))
    for i, e in enumerate(E):
        B[:, i] = (end(P + e)[1] - end(P - e)[1]) / 2.0
    return A, B


def lqr(A: np.ndarray, B: np.ndarray, q_scale: np.ndarray, r_weight: float) -> np.ndarray:
    """The discrete LQR gain K (u = -K x) with state costs 1/q_scale^2 and every input (one
    difference step each) costing ``r_weight``."""
    Q = np.zeros((B.shape[0], B.shape[0]))
    Q[:len(q_scale), :len(q_scale)] = np.diag(1.0 / q_scale ** 2)
    R = r_weight * np.eye(B.shape[1])
    X = scipy.linalg.solve_discrete_are(A, B, Q, R)
    return np.linalg.solve(R + B.T @ X @ B, B.T @ X @ A)


def fly(fl: DoveFlight, P: np.ndarray, cfg: FlightConfig, E: np.ndarray, K: np.ndarray | None,
        push_n: float, wingbeats: int, u_max: float) -> dict:
    """Fly ``wingbeats`` from the settled start, pushed ``push_n`` N along +y for
    :data:`PUSH_S` at wingbeat :data:`PUSH_WINGBEAT`; ``K`` None: open loop."""
    m, d = fl.model, fl.data
    trunk = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, "trunk")
    fl.reset(cfg, P)
    for _ in range(SETTLE):
        fl.run_cycle(P, record=False)
    y0, z0, t0 = float(d.qpos[1]), float(d.qpos[2]), float(d.time)
    x_ref = lateral(fl)
    rolls, us, work = [], [], 0.0
    steps = int(round(PUSH_S / m.opt.timestep))
    try:
        for wb in range(wingbeats):
            u = np.zeros(len(E)) if K is None else np.clip(-K @ (lateral(fl) - x_ref), -u_max, u_max)
            us.append(float(np.abs(u).max()))
            p = P + u @ E
            ctrl = control_table(fl.ref, p, m.opt.timestep, fl.kp, fl.kv)[0]
            for k in range(len(ctrl)):
                d.ctrl[:] = ctrl[k]
                d.xfrc_applied[trunk, 1] = push_n if (wb == PUSH_WINGBEAT and k < steps) else 0.0
                mujoco.mj_step(m, d)
                work += float(d.actuator_force @ d.actuator_velocity) * m.opt.timestep
            if not np.all(np.isfinite(d.qvel)):
                raise SimulationError("diverged")
            rolls.append(float(np.degrees(fl.reduced_state()[1])))
    except SimulationError:
        return {"push_n": push_n, "diverged": True, "roll_deg": rolls}
    finally:
        d.xfrc_applied[trunk, :] = 0.0
    return {"push_n": push_n, "roll_deg": rolls, "largest_input_steps": us,
            "drift_m": float(d.qpos[1] - y0), "height_change_m": float(d.qpos[2] - z0),
            "speed_m_s": float(np.linalg.norm(d.qvel[:3])),
            "servo_power_w": work / (float(d.time) - t0)}


def parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--dove", default="cruise", choices=("cruise", "robofly"))
    ap.add_argument("--push", default="3,8", help="sideways pushes to fly, N (comma list)")
    ap.add_argument("--wingbeats", type=int, default=10, help="wingbeats flown per push")
    ap.add_argument("--r-weight", type=float, default=1.0,
                    help="LQR cost of one difference step of an input against the state's scales")
    ap.add_argument("--q-scale", default="10,0.5,1,1",
                    help="LQR state scales: roll deg, v_y m/s, roll rate and yaw rate rad/s")
    ap.add_argument("--u-max", type=float, default=10.0,
                    help="largest input, in difference steps (2 %% of scale, 1 deg of shift)")
    ap.add_argument("--json", default=None)
    return ap


def main(argv: list[str] | None = None) -> None:
    a = parser().parse_args(argv)
    fl, P, cfg = dove(a.dove)
    names, E = inputs()
    fl.reset(cfg, P)
    for _ in range(SETTLE):
        fl.run_cycle(P, record=False)
    start = Snapshot(fl)
    A, B = linearise(fl, P, start, E)
    lam = np.linalg.eigvals(A)
    lam = lam[np.argsort(-np.abs(lam))]
    print(f"{a.dove} dove, lateral wingbeat map at {np.linalg.norm(fl.data.qvel[:3]):.2f} m/s")
    print("A (rows and columns " + ", ".join(LATERAL_NAMES) + "; rad, m/s, rad/s):")
    print(np.array2string(A[:4, :4], precision=3, suppress_small=True))
    print("eigenvalues per wingbeat (largest 6): " + ", ".join(f"{x:.3f}" for x in lam[:6])
          + f"  (largest |lambda| {np.abs(lam).max():.2f})")
    gain = np.linalg.norm(B, axis=0)
    for i in np.argsort(-gain)[:6]:
        print(f"  input {names[i]:22s} moves the trunk's by {np.array2string(B[:4, i], precision=3)}")
    q_scale = np.array([float(v) for v in a.q_scale.split(",")])
    q_scale[0] = np.radians(q_scale[0])
    K = lqr(A, B, q_scale, a.r_weight)
    lam_cl = np.linalg.eigvals(A - B @ K)
    lam_cl = lam_cl[np.argsort(-np.abs(lam_cl))]
    print("closed loop eigenvalues: " + ", ".join(f"{x:.3f}" for x in lam_cl[:6]))
    runs = []
    for push in (float(v) for v in a.push.split(",")):
        for label, k in (("open loop", None), ("LQR", K)):
            r = fly(fl, P, cfg, E, k, push, a.wingbeats, a.u_max)
            r["controller"] = label
            runs.append(r)
            if r.get("diverged"):
                print(f"{push:4.1f} N {label:9s}: diverged after {len(r['roll_deg'])} wingbeats")
                continue
            print(f"{push:4.1f} N {label:9s}: roll " + " ".join(f"{x:+.0f}" for x in r["roll_deg"])
                  + f" deg; drift {r['drift_m']:+.2f} m, height {r['height_change_m']:+.2f} m, "
                  f"{r['speed_m_s']:.1f} m/s, servos {r['servo_power_w']:.1f} W, largest input "
                  f"{max(r['largest_input_steps']):.1f} steps", flush=True)
    if a.json:
        write_json(a.json, {"dove": a.dove, "A": A.tolist(), "B": B.tolist(), "inputs": names,
                            "eigenvalues": [[x.real, x.imag] for x in lam],
                            "closed_loop_eigenvalues": [[x.real, x.imag] for x in lam_cl],
                            "K": K.tolist(), "runs": runs})


if __name__ == "__main__":
    main()
