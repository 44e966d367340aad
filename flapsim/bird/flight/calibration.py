"""The feather calibration scene (the flight paper, sec. 7 and Fig. 3/12): the modal dove's
trunk fixed in a headwind, the wings on the reference wingbeat; tip deflection and twist of a
primary, a secondary and a rectrix over one wingbeat. What the paper shows: the feathers bend
at the downstroke and the primaries twist open at the upstroke.
``studies/dove_feather_calibration.py`` plots it and adds the fixed-trunk lift/weight.
"""

from __future__ import annotations

import mujoco
import numpy as np

from flapsim.bird.body.feather_modes import ModalParams
from flapsim.bird.body.model import Dove, build_xml
from flapsim.bird.body.params import DOF_NAMES, DoveParams
from flapsim.bird.flight.dove_flight import DoveFlight, FlightConfig
from flapsim.bird.flight.wingbeat import control_table, p0, reference_wingbeat, with_tail_bias
from flapsim.core.loading import load_model

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
