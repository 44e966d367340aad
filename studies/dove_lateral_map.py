"""How unstable is a dove's lateral motion from one wingbeat to the next, and can wingbeats
chosen once a beat hold it?

The learned controller picks one wingbeat per beat. Whether any once-a-beat choice of
wingbeats can hold a pushed dove is a property of the wingbeat-to-wingbeat map, which this
study measures around the reference wingbeat flown in cruise (`flapsim.bird.control.lateral`:
the lateral state is the trunk's roll, body-frame sideways velocity, roll and yaw rate, and
each wing DOF pair's angle and rate difference; the inputs are the 12 antisymmetric scales and
translations of the wing DOFs). It prints A's eigenvalues (|lambda| > 1: a lateral disturbance
grows every wingbeat), the inputs that move the trunk most, and the closed loop of the
discrete LQR on (A, B). Then, on the nonlinear dove, it pushes sideways for 0.1 s at the
third wingbeat's start (the flight suite's push) and prints the trunk's roll at every
wingbeat's end, the sideways drift and the height change, open loop and
regulated (toward level, no path). Every force is the feathers' and the body's; the wingbeats
are the paper's 29-number family, changed once a beat (nothing on the trunk).

    python studies/dove_lateral_map.py --dove cruise --push 1,3,8
    python studies/dove_lateral_map.py --dove robofly --r-weight 0.3
"""

from __future__ import annotations

import argparse

import mujoco
import numpy as np

from flapsim.bird.body.model import Dove
from flapsim.bird.control import lateral
from flapsim.bird.flight import cycle
from flapsim.bird.flight.dove_flight import CRUISE, DoveFlight, FlightConfig
from flapsim.bird.flight.wingbeat import p0, reference_wingbeat, with_tail_bias
from flapsim.core.errors import SimulationError
from flapsim.core.io import write_json

PUSH_S, PUSH_WINGBEAT = 0.1, 2


def dove(kind: str) -> tuple[DoveFlight, np.ndarray, FlightConfig]:
    """The flight, its reference parameters and its start: the cruise dove (bird wing, induced
    flow, cruise wingbeat) or the default robofly dove."""
    if kind == "cruise":
        fl = DoveFlight(Dove.load(induced=True), ref=reference_wingbeat("cruise"),
                        table="bird_wing")
        cfg = CRUISE
    else:
        fl, cfg = DoveFlight(Dove.load()), FlightConfig()
    return fl, with_tail_bias(p0(), cfg.tail_bias_deg), cfg


def fly(fl: DoveFlight, P: np.ndarray, cfg: FlightConfig, reg: lateral.LateralRegulator | None,
        push_n: float, wingbeats: int) -> dict:
    """``wingbeats`` from the settled start, pushed ``push_n`` N along +y for :data:`PUSH_S`
    at wingbeat :data:`PUSH_WINGBEAT`; ``reg`` None: the reference wingbeat every beat."""
    m, d = fl.model, fl.data
    trunk = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, "trunk")
    steps = int(round(PUSH_S / m.opt.timestep))
    fl.reset(cfg, P)
    for _ in range(lateral.SETTLE):
        cycle.fly_cycle(fl, None, P)
    y0, z0 = float(d.qpos[1]), float(d.qpos[2])
    x_ref = np.zeros(lateral.N_STATE)
    rolls, steps_used = [], []
    try:
        for wb in range(wingbeats):
            dP = np.zeros_like(P) if reg is None else reg.offset(lateral.lateral_state(fl), x_ref)
            u = np.abs(reg.K @ lateral.lateral_state(fl)).max() if reg is not None else 0.0
            steps_used.append(float(min(u, lateral.U_MAX)))
            push = (cycle.Push(trunk, np.array([0.0, push_n, 0.0]), steps)
                    if wb == PUSH_WINGBEAT else None)
            cycle.fly_cycle(fl, None, P + dP, push=push)
            rolls.append(float(np.degrees(fl.reduced_state()[1])))
    except SimulationError:
        return {"push_n": push_n, "diverged": True, "roll_deg": rolls}
    return {"push_n": push_n, "roll_deg": rolls, "largest_input_steps": steps_used,
            "drift_m": float(d.qpos[1] - y0), "height_change_m": float(d.qpos[2] - z0),
            "speed_m_s": float(np.linalg.norm(d.qvel[:3]))}


def parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--dove", default="cruise", choices=("cruise", "robofly"))
    ap.add_argument("--push", default="3,8", help="sideways pushes to fly, N (comma list)")
    ap.add_argument("--wingbeats", type=int, default=12, help="wingbeats flown per push")
    ap.add_argument("--r-weight", type=float, default=0.3,
                    help="LQR cost of one input step (lateral.STATE_SCALE weighs the state)")
    ap.add_argument("--json", default=None)
    return ap


def main(argv: list[str] | None = None) -> None:
    a = parser().parse_args(argv)
    fl, P, cfg = dove(a.dove)
    reg = lateral.build_regulator(fl, P, cfg, a.r_weight)
    names, _ = lateral.input_directions(len(P))
    lam = np.linalg.eigvals(reg.A)
    lam = lam[np.argsort(-np.abs(lam))]
    lam_cl = np.linalg.eigvals(reg.A - reg.B @ reg.K)
    lam_cl = lam_cl[np.argsort(-np.abs(lam_cl))]
    print(f"{a.dove} dove, lateral wingbeat map (trunk block: roll, v_y, omega_x, omega_z):")
    print(np.array2string(reg.A[:4, :4], precision=3, suppress_small=True))
    print("eigenvalues per wingbeat (largest 4): " + ", ".join(f"{x:.3f}" for x in lam[:4]))
    for i in np.argsort(-np.linalg.norm(reg.B[:4], axis=0))[:4]:
        print(f"  one step of {names[i]:22s} moves the trunk's by "
              + np.array2string(reg.B[:4, i], precision=3))
    print(f"closed loop (r {a.r_weight:g}), largest 4: " + ", ".join(f"{x:.3f}" for x in lam_cl[:4]))
    runs = []
    for push in (float(v) for v in a.push.split(",")):
        for label, r in (("open loop", None), ("regulated", reg)):
            out = fly(fl, P, cfg, r, push, a.wingbeats)
            out["controller"] = label
            runs.append(out)
            if out.get("diverged"):
                print(f"{push:4.1f} N {label:9s}: diverged after {len(out['roll_deg'])} wingbeats")
                continue
            print(f"{push:4.1f} N {label:9s}: roll " + " ".join(f"{x:+.0f}" for x in out["roll_deg"])
                  + f" deg; drift {out['drift_m']:+.2f} m, height {out['height_change_m']:+.2f} m, "
                  f"{out['speed_m_s']:.1f} m/s, largest input {max(out['largest_input_steps']):.1f} "
                  "steps", flush=True)
    if a.json:
        write_json(a.json, {"dove": a.dove, "r": a.r_weight, "A": reg.A.tolist(),
                            "B": reg.B.tolist(), "inputs": names,
                            "eigenvalues": [[x.real, x.imag] for x in lam],
                            "closed_loop_eigenvalues": [[x.real, x.imag] for x in lam_cl],
                            "K": reg.K.tolist(), "runs": runs})


if __name__ == "__main__":
    main()
