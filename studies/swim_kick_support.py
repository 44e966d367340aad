"""What a treading kick holds up, and at what cost: the mean vertical water force on the legs
(and on the arms) over one cycle of a stroke, with the water work they do, the trunk held still
upright with the head's centre at the surface and the limbs moving through the stroke's targets
at its period (:meth:`flapsim.fluid.surfaces.SurfaceForces.evaluate` on each sampled pose; the
polygons' velocities from the poses' differences). With ``--search``, an eggbeater kick is
searched (differential evolution) for the least water power that holds ``--target`` N up:
thighs at a fixed flexion and abduction, each shank circling by hip rotation a quarter cycle
(``--lag``) from the knee's flexion, the ankle's flexion and inversion cycling, the legs half a
cycle apart (the stroke file's mirror), the mean forward force and pitching moment about the
centre of mass held near zero.

    python studies/swim_kick_support.py --stroke treading                   # the scull alone
    python studies/swim_kick_support.py --search --target 15 --json k.json  # an eggbeater kick

Kinematic, not dynamic: the trunk does not move and the water is still, so it says what the
limbs' motion can give, not what a free swimmer gets from it (``flapsim swim --stroke FILE``:
free in the water the body moves with a kick, and the feet lose much of their speed).
"""

from __future__ import annotations

import argparse
import copy
import time
import tomllib
from collections.abc import Sequence

import mujoco
import numpy as np
from scipy.optimize import differential_evolution

from flapsim.core.io import write_json
from flapsim.swim.model import Swimmer
from flapsim.swim.strokes import parse_stroke, stroke_path, stroke_tables

#: the searched kick: (name, low, high); angles in deg, lags in cycles
KICK = (
    ("hip_flex_deg", 30.0, 100.0), ("hip_abd_deg", 20.0, 80.0),
    ("hip_rot_amp_deg", 20.0, 45.0), ("hip_rot_lag", 0.65, 0.85),
    ("knee_mean_deg", 40.0, 110.0), ("knee_amp_deg", 20.0, 45.0),
    ("ankle_plantar_mean_deg", -30.0, 60.0), ("ankle_plantar_amp_deg", 0.0, 40.0),
    ("ankle_plantar_lag", 0.0, 1.0),
    ("ankle_inversion_mean_deg", -35.0, 35.0), ("ankle_inversion_amp_deg", 0.0, 35.0),
    ("ankle_inversion_lag", 0.0, 1.0),
)
#: the hip's ball joint allows 130 deg from the standing pose; candidates past 125 pay
HIP_CONE_DEG = 125.0
LEGS = ("thigh", "shank", "foot")
ARMS = ("upper_arm", "forearm", "hand")


def _sine(mean: float, amp: float, lag: float, lo: float = -np.inf, hi: float = np.inf) -> list:
    phase = np.arange(8) / 8
    return [[float(p), float(np.clip(mean + amp * np.sin(2 * np.pi * (p - lag)), lo, hi))]
            for p in phase]


def kick_stroke(raw: dict, x: Sequence[float]) -> dict:
    """The stroke file ``raw`` with its left leg's keys replaced by the kick ``x`` (see
    :data:`KICK`); the right leg follows by the file's mirror."""
    (flex, abd, rot_amp, rot_lag, knee_mean, knee_amp, pl_mean, pl_amp, pl_lag, inv_mean,
     inv_amp, inv_lag) = x
    out = copy.deepcopy(raw)
    for dof in [d for d in out.get("pose", {}) if d.split(".")[0] in ("hip_l", "knee_l", "ankle_l")]:
        del out["pose"][dof]
    keys = out.setdefault("keys", {})
    keys["hip_l"] = {"flex": [[0.0, float(flex)]], "abd": [[0.0, float(abd)]],
                     "rot": _sine(0.0, rot_amp, rot_lag)}
    keys["knee_l"] = {"flex": _sine(knee_mean, knee_amp, 0.0, 0.0, 150.0)}
    keys["ankle_l"] = {"plantar": _sine(pl_mean, pl_amp, pl_lag, -30.0, 70.0),
                       "inversion": _sine(inv_mean, inv_amp, inv_lag, -35.0, 35.0)}
    return out


class KickMeter:
    """One swimmer, measuring strokes' limb forces kinematically."""

    def __init__(self) -> None:
        self.sw = Swimmer()
        m = self.sw.model
        body = np.asarray(self.sw.hydro.polygons.body)
        ids = {g: [m.body(f"{s}_{side}").id for s in segs for side in "lr"]
               for g, segs in (("legs", LEGS), ("arms", ARMS))}
        self.masks = {g: np.isin(body, v) for g, v in ids.items()}
        self.hips = [m.joint(f"hip_{s}").qposadr[0] for s in "lr"]

    def measure(self, raw: dict, samples: int = 32) -> dict:
        """Cycle means: each limb group's vertical force [N] and the water work it does [W],
        the legs' forward force [N] and pitching moment about the centre of mass [N m], and
        the hips' largest angle from the standing pose [deg]."""
        sw, m, d = self.sw, self.sw.model, self.sw.data
        stroke = parse_stroke(raw, "<kick>")
        tab = stroke_tables(stroke, sw.joints, nsamp=samples)
        period = stroke.period_s
        sw.reset("upright")
        root = d.qpos[:7].copy()
        forces = {g: [] for g in self.masks}
        points = {g: [] for g in self.masks}
        com, cone = [], 0.0
        for k in range(samples):
            d.qpos[:7] = root
            d.qpos[7:] = tab.q[k]
            d.qvel[:] = 0.0
            d.qvel[6:] = tab.v[k] / period
            mujoco.mj_forward(m, d)
            rep = sw.hydro.evaluate(d)
            for g, mask in self.masks.items():
                forces[g].append(rep.force[mask])
                points[g].append(rep.points[mask])
            com.append(sw.com())
            for a in self.hips:
                cone = max(cone, 2.0 * np.degrees(np.arccos(min(1.0, abs(d.qpos[a])))))
        out = {"period_s": period, "hip_cone_deg": cone}
        c = np.array(com)
        for g in self.masks:
            f, p = np.array(forces[g]), np.array(points[g])
            v = (np.roll(p, -1, 0) - np.roll(p, 1, 0)) * (samples / 2.0) / period
            out[f"{g}_up_n"] = float(f[:, :, 2].sum(1).mean())
            out[f"{g}_water_power_w"] = float(-(f * v).sum(2).sum(1).mean())
            if g == "legs":
                out["legs_forward_n"] = float(f[:, :, 0].sum(1).mean())
                out["legs_pitch_moment_n_m"] = float(
                    np.cross(p - c[:, None, :], f).sum(1).mean(0)[1])
        return out


def parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--stroke", default="treading", help="stroke name or file (default treading)")
    ap.add_argument("--search", action="store_true", help="search an eggbeater kick")
    ap.add_argument("--target", type=float, default=15.0, help="search: the legs' support, N")
    ap.add_argument("--maxiter", type=int, default=60)
    ap.add_argument("--popsize", type=int, default=10)
    ap.add_argument("--seed", type=int, default=2)
    ap.add_argument("--json", help="write the measures (and the kick found) here")
    return ap


def _print(label: str, r: dict) -> None:
    print(f"{label}: legs hold {r['legs_up_n']:+.1f} N up on {r['legs_water_power_w']:.1f} W of "
          f"water work, arms {r['arms_up_n']:+.1f} N on {r['arms_water_power_w']:.1f} W; legs' "
          f"forward force {r['legs_forward_n']:+.1f} N, pitching moment "
          f"{r['legs_pitch_moment_n_m']:+.2f} N m; hips up to {r['hip_cone_deg']:.0f} deg")


def main(argv: Sequence[str] | None = None) -> int:
    a = parser().parse_args(argv)
    raw = tomllib.loads(stroke_path(a.stroke).read_text())
    meter = KickMeter()
    out = {"stroke": a.stroke, "stroke_measures": meter.measure(raw, samples=96)}
    _print(a.stroke, out["stroke_measures"])
    if a.search:
        def cost(x: np.ndarray) -> float:
            r = meter.measure(kick_stroke(raw, x))
            return (r["legs_water_power_w"] + 30.0 * max(0.0, a.target - r["legs_up_n"])
                    + 10.0 * max(0.0, r["hip_cone_deg"] - HIP_CONE_DEG)
                    + 3.0 * abs(r["legs_forward_n"]) + 10.0 * abs(r["legs_pitch_moment_n_m"]))

        t0 = time.perf_counter()
        res = differential_evolution(cost, [(lo, hi) for _, lo, hi in KICK], maxiter=a.maxiter,
                                     popsize=a.popsize, seed=a.seed, polish=False, tol=1e-7)
        found = meter.measure(kick_stroke(raw, res.x), samples=96)
        _print(f"kick for {a.target:g} N", found)
        kick = {name: float(v) for (name, _, _), v in zip(KICK, res.x, strict=True)}
        for name, v in kick.items():
            print(f"  {name:26s} {v:8.2f}")
        out.update({"target_n": a.target, "kick": kick, "kick_measures": found,
                    "evaluations": int(res.nfev), "wall_s": time.perf_counter() - t0})
    if a.json:
        write_json(a.json, out)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
