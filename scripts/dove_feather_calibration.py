"""Feather calibration scene (the flight paper, sec. 7 and Fig. 3/12): the modal dove's trunk
fixed in a headwind, the wings on the reference wingbeat; tip deflection and twist of a
primary, a secondary and a rectrix over one wingbeat.

    PYTHONPATH=. python scripts/dove_feather_calibration.py --out calib [--speed 7]

Writes ``calib/feathers.png`` (deflection and twist against the wingbeat phase, downstroke
shaded) and ``calib/feathers.json`` (per feather: mean and extreme tip deflection and twist in
the downstroke and the upstroke, and the fixed-trunk lift/weight with rigid and modal
feathers). What the paper shows: the feathers bend at the downstroke and the primaries twist
open at the upstroke.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import mujoco
import numpy as np

from flapsim.bird.feather_modes import ModalParams
from flapsim.bird.flight import DoveFlight, FlightConfig, wind_tunnel
from flapsim.bird.model import DOF_NAMES, Dove, DoveParams, build_xml
from flapsim.bird.wingbeat import control_table, p0, reference_wingbeat, with_tail_bias
from flapsim.sim.loading import load_model

FEATHERS = ("l_p8", "l_p3", "l_s5", "l_r3")


def record(speed: float, pitch_deg: float, cycles: int = 3, integration: str = "engine") -> dict:
    params = DoveParams.load()
    mp = ModalParams(integration=integration)
    model = load_model(build_xml(params, fixed_trunk_pitch_deg=pitch_deg, modal=mp), is_xml=True)
    dove = Dove.from_model(model, params, mp)
    P = with_tail_bias(p0(), FlightConfig.tail_bias_deg)
    fl = DoveFlight(dove, reference_wingbeat(), wind=(-speed, 0.0, 0.0), use_rollout=False)
    try:
        fl.reset(FlightConfig(speed=0.0), P)
        m, d = fl.model, fl.data
        ctrl, _, _ = control_table(fl.ref, P, m.opt.timestep, fl.kp, fl.kv)
        idx = [fl.modal.feather_index(n) for n in FEATHERS]
        hinge = {n: m.jnt_qposadr[mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, f"{n}_twist")]
                 for n in FEATHERS if n.startswith("l_p")}
        flap = dove.qadr[DOF_NAMES.index("l_shoulder_flap")]
        for _ in range(cycles - 1):
            for k in range(len(ctrl)):
                d.ctrl[:] = ctrl[k]
                mujoco.mj_step(m, d)
        rows = []
        for k in range(len(ctrl)):
            d.ctrl[:] = ctrl[k]
            mujoco.mj_step(m, d)
            row = [d.qpos[flap]]
            for n, i in zip(FEATHERS, idx, strict=True):
                defl, tw = fl.modal.tip(d, i)
                row += [defl, tw, d.qpos[hinge[n]] if n in hinge else 0.0]
            rows.append(row)
    finally:
        fl.close()
    a = np.array(rows)
    phase = np.arange(len(a)) / len(a)
    flap_angle = a[:, 0]
    down = np.gradient(flap_angle) < 0  # the wing descends
    out = {"speed": speed, "pitch_deg": pitch_deg, "phase": phase, "flap": flap_angle,
           "down": down, "feathers": {}}
    for j, n in enumerate(FEATHERS):
        defl, tw, hin = a[:, 1 + 3 * j], a[:, 2 + 3 * j], a[:, 3 + 3 * j]
        out["feathers"][n] = {"deflection": defl, "elastic_twist": tw, "hinge_twist": hin}
    return out


def summary(rec: dict) -> dict:
    down = rec["down"]
    res = {}
    for n, r in rec["feathers"].items():
        total_twist = r["elastic_twist"] + r["hinge_twist"]
        res[n] = {
            "downstroke_mean_deflection_mm": 1e3 * float(np.mean(r["deflection"][down])),
            "upstroke_mean_deflection_mm": 1e3 * float(np.mean(r["deflection"][~down])),
            "max_abs_deflection_mm": 1e3 * float(np.abs(r["deflection"]).max()),
            "downstroke_mean_twist_deg": float(np.degrees(np.mean(total_twist[down]))),
            "upstroke_mean_twist_deg": float(np.degrees(np.mean(total_twist[~down]))),
            "max_twist_deg": float(np.degrees(total_twist.max())),
        }
    return res


def plot(rec: dict, path: Path) -> None:
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(8, 6))
    FigureCanvasAgg(fig)
    ax1, ax2 = fig.subplots(2, 1, sharex=True)
    ph, down = rec["phase"], rec["down"]
    for ax in (ax1, ax2):
        ax.fill_between(ph, 0, 1, where=down, color="0.9", transform=ax.get_xaxis_transform(),
                        label="downstroke")
    for n, r in rec["feathers"].items():
        ax1.plot(ph, 1e3 * r["deflection"], label=n)
        ax2.plot(ph, np.degrees(r["elastic_twist"] + r["hinge_twist"]), label=n)
    ax1.set_ylabel("tip deflection, mm (+ dorsal)")
    ax2.set_ylabel("twist, deg (+ trailing edge down)")
    ax2.set_xlabel("wingbeat phase (0 = top of the stroke)")
    ax1.legend(fontsize=8)
    ax1.set_title(f"modal feathers, trunk fixed at {rec['pitch_deg']:g} deg in a "
                  f"{rec['speed']:g} m/s headwind")
    fig.tight_layout()
    fig.savefig(path, dpi=110)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--out", default="dove_feather_calibration", help="output folder")
    ap.add_argument("--speed", type=float, default=7.0, help="headwind, m/s")
    ap.add_argument("--pitch-deg", type=float, default=5.0, help="trunk pitch, deg")
    ap.add_argument("--no-tunnel", action="store_true", help="skip the rigid/modal lift/weight")
    ap.add_argument("--integration", choices=("engine", "joints"), default="engine",
                    help="who integrates the modes (ModalParams.integration)")
    args = ap.parse_args()
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    rec = record(args.speed, args.pitch_deg, integration=args.integration)
    res = {"speed": args.speed, "pitch_deg": args.pitch_deg, "integration": args.integration,
           "feathers": summary(rec)}
    if not args.no_tunnel:
        params = DoveParams.load()
        P = with_tail_bias(p0(), FlightConfig.tail_bias_deg)
        for name, modal in (("rigid", None), ("modal", ModalParams(integration=args.integration))):
            t = wind_tunnel(params, P, args.speed, args.pitch_deg, modal=modal)
            res[f"{name}_lift_per_weight"] = float(t.lift_per_weight)
            res[f"{name}_thrust_per_weight"] = float(t.thrust_per_weight)
    plot(rec, out / "feathers.png")
    (out / "feathers.json").write_text(json.dumps(res, indent=1))
    print(json.dumps(res, indent=1))


if __name__ == "__main__":
    main()
