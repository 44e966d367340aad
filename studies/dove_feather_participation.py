"""How much each feather mode carries in flight, and what dropping modes changes.

    python studies/dove_feather_participation.py [--wingbeats 10] [--json out.json]

Flies the base controller (10 wingbeats, as the dove acceptance) with 4, 2 and 1 modes per
feather; reports each mode's share of the shaft-tip deflection and tip twist (RMS over the
flight, all feathers pooled, 4-mode run), and for each mode count: lift/weight, the
primaries' RMS tip deflection and twist, and the cost per step (bare ``mj_step``).
The modes ride MuJoCo joints here (``ModalParams(integration="joints")``: their coordinates
are in the recorded ``qpos``); the engine's integration gives the same shares (its tip
deflections follow the joints', ``tests/bird/body/test_feather_dynamics.py``).
"""

from __future__ import annotations

import argparse
import json
import time

import mujoco
import numpy as np

from flapsim.bird.body.feather_dynamics import dove_feather_modes
from flapsim.bird.body.feather_modes import ModalParams
from flapsim.bird.body.model import Dove
from flapsim.bird.flight.dove_flight import flight_metrics, fly


def tip_series(dove: Dove, qpos: np.ndarray) -> tuple[np.ndarray, np.ndarray, list[str]]:
    """(steps, feathers, K) shaft-tip deflection and tip twist contributed by each mode."""
    modes = dove_feather_modes(dove.params, dove.modal)
    m = dove.model
    defl, twist = [], []
    for fm in modes:
        a = m.jnt_qposadr[mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, f"{fm.name}_mode1")]
        q = qpos[:, a:a + fm.omega.size]
        tip = np.flatnonzero(fm.vert_station == fm.stations - 1)
        defl.append(q * fm.shape[tip].mean(axis=0))  # mean of the two tip vertices: the shaft
        twist.append(q * fm.twist[-1])
    return np.stack(defl, 1), np.stack(twist, 1), [fm.name for fm in modes]


def bare_us(m: mujoco.MjModel, n: int = 3000) -> float:
    d = mujoco.MjData(m)
    mujoco.mj_step(m, d, nstep=100)
    t = time.perf_counter()
    mujoco.mj_step(m, d, nstep=n)
    return 1e6 * (time.perf_counter() - t) / n


def parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--wingbeats", type=int, default=10, help="wingbeats flown per mode count")
    ap.add_argument("--json", default=None, help="write every number here")
    return ap


def main(argv: list[str] | None = None) -> dict:
    ap = parser()
    a = ap.parse_args(argv)
    out: dict = {"runs": {}}
    rigid = Dove.load()
    out["rigid_bare_us"] = bare_us(rigid.model)
    for K in (4, 2, 1):
        dove = Dove.load(feathers="modal", modal=ModalParams(modes=K, integration="joints"))
        f = fly(dove, a.wingbeats)
        met = flight_metrics(f)
        dfl, tw, names = tip_series(dove, f.qpos)
        prim = np.array([n[2] == "p" for n in names])
        r = {"lift_over_weight": met["mean_lift_per_weight"], "metrics": met,
             "primary_tip_rms_mm": 1e3 * float(np.sqrt(np.mean(dfl[:, prim].sum(-1) ** 2))),
             "primary_twist_rms_deg": float(np.degrees(np.sqrt(np.mean(tw[:, prim].sum(-1) ** 2)))),
             "bare_us": bare_us(dove.model), "nv": int(dove.model.nv)}
        if K > 1:
            # share of each mode: RMS of its contribution over the RMS of the total, pooled
            tot_d = np.sqrt(np.mean(dfl.sum(-1) ** 2))
            tot_t = np.sqrt(np.mean(tw.sum(-1) ** 2))
            r["deflection_share"] = [float(np.sqrt(np.mean(dfl[..., k] ** 2)) / tot_d) for k in range(K)]
            r["twist_share"] = [float(np.sqrt(np.mean(tw[..., k] ** 2)) / tot_t) for k in range(K)]
        out["runs"][K] = r
        print(f"K={K}: lift/weight {r['lift_over_weight']:.4f}, vertical dev "
              f"{met['max_vertical_deviation']:.3f} m, primary tip RMS {r['primary_tip_rms_mm']:.2f} mm,"
              f" twist RMS {r['primary_twist_rms_deg']:.3f} deg, bare {r['bare_us']:.1f} us "
              f"(rigid {out['rigid_bare_us']:.1f}), shares {r.get('deflection_share')} "
              f"{r.get('twist_share')}", flush=True)
    if a.json:
        with open(a.json, "w") as fh:
            json.dump(out, fh, indent=1, default=float)
    return out


if __name__ == "__main__":
    main()
