"""Tune a stroke's keyframes by pre-simulation (the layered-swimming paper found its
per-cycle weight tables the same way: by simulating the swimmer and keeping what works).

Only joint-angle keyframes move, each within a stated band around the hand-designed
value and inside the joint's range; the body, the fluid coefficients, the stroke rate
and the muscles' torque limits stay as they are. The objective is the forward speed
over a short swim from rest, less penalties for sinking the head and for muscle power
above a cap (so the optimiser cannot buy speed with superhuman effort), and optionally
for a coach's faults: a stroke rate outside a band, a trunk inclined more than a limit,
hips rolling more than the shoulders.

    python studies/swim_tune_stroke.py crawl --generations 25 --out /tmp/crawl_tuned.toml
    python studies/swim_tune_stroke.py crawl --body rounded --power-cap 150 --rate 0.5,0.7 \
        --incline-max 10 --roll 40,55 --out /tmp/crawl_rounded.toml

The result is written as the starting stroke file with the tuned period and keys in
place (comments and other sections kept: update the comments that describe numbers). Resumable: every
generation is checkpointed to ``--out`` + ``.state.npz``.
"""

from __future__ import annotations

import argparse
import contextlib
import copy
import json
import logging
import math
import os
import re
import sys
import time
import tomllib
from concurrent.futures import ProcessPoolExecutor

import numpy as np

from flapsim.core.errors import FlapsimError
from flapsim.core.io import atomic_path
from flapsim.swim.model import Swimmer, SwimmerParams
from flapsim.swim.simulate import swim
from flapsim.swim.strokes import parse_stroke, stroke_path

# (kind, dof, index, half-width [deg]); kinds: "key" moves one keyframe value, "all"
# shifts every key of a dof, "amp" scales a dof's keys about their mean and "warp" retimes
# the arms' time under water (half-width as a fraction for both); "legs" moves one of the
# breaststroke legs' timing marks (:data:`LEG_MARKS`, half-width in phase) and "phase" moves
# one key's phase (half-width in phase, kept between its neighbours' phases)
_CRAWL = (
    [("key", f"shoulder_l.{d}", i, 25.0) for d in ("flex", "abd", "rot") for i in range(1, 6)]
    + [("key", "elbow_l.flex", i, 25.0) for i in range(1, 6)]
    + [("key", "elbow_l.pronation", i, 30.0) for i in range(1, 6)]
    + [("all", "neck.flex", 0, 20.0), ("all", "lumbar.flex", 0, 10.0),
       ("all", "thoracic.flex", 0, 15.0),
       ("amp", "hip_l.flex", 0, 0.8), ("all", "hip_l.flex", 0, 10.0),
       ("amp", "knee_l.flex", 0, 0.8), ("all", "ankle_l.plantar", 0, 15.0),
       # -1..3 x the written twist: reversed, the upper trunk rolls with the hips, so the
       # shoulders roll more than the hips as swimmers' do (Psycharakis & Sanders 2008)
       ("amp", "thoracic.twist", 0, 2.0), ("period", "", 0, 0.2),
       # the arms' share of the cycle under water (entry to exit), +-35 %: swimmers pull
       # for ~60-70 % of the cycle and recover over the water in the rest
       ("warp", "arms", 0, 0.35)]
    # the recovery: how far the arm swings out and how the elbow folds (a recovery that
    # drags the upper arm through the water pays for it: studies/swim_power_budget.py)
    + [("key", "shoulder_l.abd", i, 20.0) for i in range(6, 9)]
    + [("key", "shoulder_l.rot", 6, 25.0)]
    + [("key", "elbow_l.flex", i, 25.0) for i in range(6, 8)]
)
#: the crawl's arm joints whose keys the "warp" parameter retimes, and the key of the
#: shoulder's flexion at which the hand leaves the water
WARP_JOINTS = ("shoulder_l", "elbow_l", "wrist_l", "neck")
WARP_EXIT = ("shoulder_l", "flex", 5)
_BREAST = (
    [("key", f"shoulder_l.{d}", i, 25.0) for d in ("flex", "abd") for i in range(1, 6)]
    + [("key", "elbow_l.flex", i, 25.0) for i in range(1, 5)]
    + [("key", "elbow_l.pronation", i, 30.0) for i in range(1, 4)]
    # the hips' flexion +-40 deg: the knees can drop in the recovery so that the heels
    # stay under water and the shanks behind the thighs; the soles +-35 deg, so that they
    # can face backwards in the kick (dorsiflexed)
    + [("key", "hip_l.flex", i, 40.0) for i in range(2, 4)]
    + [("key", "hip_l.abd", i, 15.0) for i in range(2, 4)]
    + [("key", "hip_l.rot", i, 20.0) for i in range(2, 4)]
    + [("key", "knee_l.flex", i, 35.0) for i in range(2, 4)]
    + [("key", "ankle_l.plantar", i, 35.0) for i in range(2, 5)]
    + [("all", "neck.flex", 0, 15.0), ("period", "", 0, 0.3)]
    + [("key", "hip_l.flex", 4, 10.0), ("key", "knee_l.flex", 4, 10.0),
       ("key", "shoulder_l.flex", 6, 10.0)]
    + [("key", "neck.flex", i, 20.0) for i in range(1, 4)]
    + [("key", "thoracic.flex", 1, 15.0)]
    # the legs' timing: the recovery's start and the kick's start and end (the shanks
    # dragged forward in a short recovery, and a kick driving the feet back at 4 m/s, cost
    # most of the box breaststroke's leg power for little thrust: studies/swim_power_budget.py)
    + [("legs", "start", 0, 0.12), ("legs", "kick", 0, 0.12), ("legs", "end", 0, 0.10)]
    # the soles turned out in the kick (eversion), and the inward sweep's end (the hips'
    # adduction and rotation at the kick's close: the feet sweeping in push sideways, the
    # two sides' forces cancelling)
    + [("key", "ankle_l.inversion", i, 20.0) for i in range(1, 4)]
    + [("key", "hip_l.abd", 4, 15.0), ("key", "hip_l.rot", 4, 30.0)]
    # ... and when the legs close: the inward sweep slower, into the glide
    + [("phase", "hip_l.abd", 4, 0.12), ("phase", "hip_l.rot", 4, 0.12)]
)
#: the breaststroke legs' timing marks that the "legs" parameters move, each the phase of
#: one of the knee's keys: the recovery's start (the legs begin to bend), the kick's start
#: (the knees most bent), its end (the legs straight). Every key of :data:`LEG_JOINTS` is
#: retimed by the piecewise-linear map through the marks (phases 0 and 1 fixed), so the keys
#: keep their order.
LEG_MARKS = {"start": ("knee_l", "flex", 1), "kick": ("knee_l", "flex", 2),
             "end": ("knee_l", "flex", 4)}
LEG_JOINTS = ("hip_l", "knee_l", "ankle_l")
#: the least phase between two timing marks (and between the first mark and 0, the last
#: and 1) after a move
LEG_GAP = 0.04
# treading: the arms' scull, and the legs' eggbeater kick as a whole (where the thighs sit,
# how far the shanks circle, how the soles are set): its keys trace one circle, which
# moving single keys would break
_TREAD = (
    [("all", "shoulder_l.flex", 0, 30.0), ("all", "shoulder_l.abd", 0, 30.0)]
    + [("key", "shoulder_l.rot", i, 40.0) for i in range(2)]
    + [("all", "elbow_l.flex", 0, 30.0)]
    + [("all", "elbow_l.pronation", 0, 35.0)]
    + [("all", "hip_l.flex", 0, 25.0), ("all", "hip_l.abd", 0, 25.0),
       ("amp", "hip_l.rot", 0, 0.6), ("all", "knee_l.flex", 0, 25.0),
       ("amp", "knee_l.flex", 0, 0.6), ("all", "ankle_l.plantar", 0, 25.0),
       ("all", "ankle_l.inversion", 0, 20.0)]
    + [("all", "neck.flex", 0, 20.0), ("all", "lumbar.flex", 0, 20.0),
       ("period", "", 0, 0.3)]
)
#: stroke period bounds [s]: the acceptance's human stroke rates (crawl 0.6-1.0 cycles/s,
#: breaststroke 0.4-1.1); treading: 0.6-1.5 s (eggbeater ~1-1.7 cycles/s)
PERIODS = {"crawl": (1.0, 1.67), "breaststroke": (0.91, 2.5), "treading": (0.6, 1.5)}

#: stroke -> (parameters, objective): "speed" = forward speed, "float" = head height
SPECS: dict[str, tuple[list[tuple[str, str, int, float]], str]] = {
    "crawl": (_CRAWL, "speed"),
    "breaststroke": (_BREAST, "speed"),
    "treading": (_TREAD, "float"),
}


def _dof_keys(raw: dict, dof: str) -> list:
    joint, name = dof.split(".")
    keys = raw.setdefault("keys", {}).setdefault(joint, {})
    if name not in keys:
        pose = raw.get("pose", {}).pop(dof, 0.0)
        keys[name] = [[0.0, float(pose)]]
    return keys[name]


def apply_params(raw: dict, spec: list, x: np.ndarray,
                 periods: tuple[float, float] | None = None) -> dict:
    """A copy of the stroke file contents with the parameters ``x`` (in [-1, 1]) applied.
    ``periods`` [s]: the period parameter spans this band (x = -1: the shortest) instead
    of moving the file's period within its stroke's bounds."""
    out = copy.deepcopy(raw)
    for (kind, _, _, width), xi in zip(spec, x, strict=True):
        if kind == "period":
            if periods is not None:
                out["period_s"] = float(periods[0] + 0.5 * (xi + 1.0) * (periods[1] - periods[0]))
                continue
            lo, hi = PERIODS[out.get("name", "")]
            out["period_s"] = float(np.clip(out["period_s"] + width * xi, lo, hi))
    legs: dict[str, float] = {}
    for (kind, dof, idx, width), xi in zip(spec, x, strict=True):
        if kind in ("period", "phase"):
            continue
        if kind == "warp":
            _warp(out, 1.0 + width * xi)
            continue
        if kind == "legs":
            legs[dof] = legs.get(dof, 0.0) + width * float(xi)
            continue
        keys = _dof_keys(out, dof)
        lo, hi = RANGES.get(dof, (-math.inf, math.inf))
        if kind == "key":
            keys[idx][1] += width * xi
        elif kind == "all":
            for k in keys:
                k[1] += width * xi
        elif kind == "amp":
            mean = float(np.mean([k[1] for k in keys]))
            for k in keys:
                k[1] = mean + (k[1] - mean) * (1.0 + width * xi)
        for k in keys:
            k[1] = float(np.clip(k[1], lo, hi))
    if legs:
        retime_legs(out, legs)
    for (kind, dof, idx, width), xi in zip(spec, x, strict=True):
        if kind == "phase":
            keys = _dof_keys(out, dof)
            lo = keys[idx - 1][0] + LEG_GAP / 2 if idx > 0 else 0.0
            hi = keys[idx + 1][0] - LEG_GAP / 2 if idx + 1 < len(keys) else 1.0
            keys[idx][0] = float(np.clip(keys[idx][0] + width * xi, lo, hi))
    return out


def leg_phase_map(marks: list[float], shifts: list[float]):
    """The piecewise-linear phase map that moves each of the increasing timing ``marks``
    by its shift (each moved mark kept :data:`LEG_GAP` from its neighbours, the first from
    0 and the last from 1, so that the map increases), phases 0 and 1 fixed. Returns
    ``(map, moved marks)``."""
    moved: list[float] = []
    n = len(marks)
    for i, (m, s) in enumerate(zip(marks, shifts, strict=True)):
        lo = (moved[-1] if moved else 0.0) + LEG_GAP
        hi = 1.0 - LEG_GAP * (n - i)
        moved.append(float(np.clip(m + s, lo, hi)))
    src, dst = [0.0, *marks, 1.0], [0.0, *moved, 1.0]
    if moved == list(marks):  # no move: the phases as written (interpolation may round)
        return float, moved

    def g(ph: float) -> float:
        return float(np.interp(ph, src, dst))

    return g, moved


def retime_legs(raw: dict, shifts: dict[str, float]) -> None:
    """Retime the breaststroke legs' keys in place: each timing mark of :data:`LEG_MARKS`
    moved by ``shifts[name]`` (phase), the keys between marks spread linearly."""
    names = list(LEG_MARKS)
    marks = [float(raw["keys"][j][d][i][0]) for j, d, i in LEG_MARKS.values()]
    g, _ = leg_phase_map(marks, [shifts.get(n, 0.0) for n in names])
    for j in LEG_JOINTS:
        for keys in raw["keys"].get(j, {}).values():
            for k in keys:
                k[0] = g(float(k[0]))


def _warp(raw: dict, factor: float) -> None:
    """Retime the arms' keys in place: the phases from the entry (0) to the exit key
    (:data:`WARP_EXIT`) stretched by ``factor``, the recovery's squeezed into the rest of
    the cycle (piecewise linear, so every key keeps its order)."""
    joint, dof, idx = WARP_EXIT
    a = float(raw["keys"][joint][dof][idx][0])
    b = float(np.clip(a * factor, 0.2, 0.8))

    def g(ph: float) -> float:
        return ph * b / a if ph <= a else b + (ph - a) * (1.0 - b) / (1.0 - a)

    for j in WARP_JOINTS:
        for keys in raw["keys"].get(j, {}).values():
            for k in keys:
                k[0] = g(float(k[0]))


#: joint ranges the keys are clipped to [deg] (swimmer.xml)
RANGES = {"elbow_l.flex": (0.0, 150.0), "elbow_l.pronation": (-90.0, 90.0),
          "knee_l.flex": (0.0, 150.0), "ankle_l.plantar": (-30.0, 70.0),
          "ankle_l.inversion": (-35.0, 35.0)}


#: cost per W of mean muscle power over the cap (default: 200 W over costs 1 m/s)
POWER_SLOPE_W = 200.0
#: cost per deg of trunk incline over --incline-max: 3 deg over costs as much as 0.1 m/s
#: (a coach's limit, ~5-12 deg in crawl, Zamparo et al. 2009; a steeper trunk is drag the
#: swimmer pays for, but a small excess should not outweigh a faster stroke)
INCLINE_COST = 0.1 / 3.0
#: cost per deg of roll out of order (shoulders below the hips + ROLL_MARGIN_DEG) or out of
#: the shoulders' band: 10 deg cost as much as 0.1 m/s (roll is how a coach sees the stroke,
#: Psycharakis & Sanders 2008: shoulders 45-60 > hips 35-45 deg, not a speed the stroke has)
ROLL_COST = 0.01
#: cost per m that a hand's or a foot's centre rises above --limbs-top: a limb lifted out
#: of the water meets no drag in its recovery (a free ride that swimmers do not get in the
#: breaststroke, whose recovery is under water), so 5 cm cost as much as 0.5 m/s
LIMBS_COST = 10.0
ROLL_MARGIN_DEG = 5.0


#: one swimmer per body in each worker process: building one (its model and rounded
#: surface) costs more than a 12 s trial; a reused one swims the same to the bit
_SWIMMERS: dict[str, Swimmer] = {}


def _evaluate(args: tuple) -> tuple[float, dict]:
    (raw, seconds, head_min, power_cap, drift_weight, objective, breathe, breath_height,
     body, power_slope, incline_max, roll, limbs_top) = args
    # a trial stroke has no per-cycle table (the layer is off): not worth a warning each
    logging.getLogger("flapsim").setLevel(logging.ERROR)
    try:
        if body not in _SWIMMERS:
            _SWIMMERS[body] = Swimmer(SwimmerParams(body_shape=body))
        s = swim(parse_stroke(raw, "<tuned>"), seconds, swimmer=_SWIMMERS[body]).summary()
    except FlapsimError:
        return 1e3, {}
    if objective == "speed":
        cost = -s["speed_m_s"]
        cost += 5.0 * max(0.0, head_min - s["head_height_mean_m"])
        # a swimmer breathes: the head's centre (eye level) clears the water in most
        # cycles, and by breath_height on average at each cycle's highest point
        cost += breathe * max(0.0, 0.9 - s["breathing_cycles_fraction"])
        cost += 5.0 * breathe * max(0.0, breath_height - s["head_height_cycle_peak_mean_m"])
    else:  # keep the head as high as possible, the lowest moment counting as much as the mean
        cost = -0.5 * (s["head_height_mean_m"] + s["head_height_min_m"])
        cost += 0.5 * max(0.0, s["head_horizontal_drift_max_m"] - 0.2)
    cost += max(0.0, s["muscle_power_mean_w"] - power_cap) / power_slope
    if incline_max is not None:
        cost += INCLINE_COST * max(0.0, s["trunk_incline_deg"] - incline_max)
    if limbs_top is not None:
        top = max(s["hands_height_max_m"], s["feet_height_max_m"])
        cost += LIMBS_COST * max(0.0, top - limbs_top)
    if roll is not None:
        sh, hips = s["roll_shoulders_deg"], s["roll_hips_deg"]
        cost += ROLL_COST * (max(0.0, roll[0] - sh) + max(0.0, sh - roll[1])
                             + max(0.0, hips + ROLL_MARGIN_DEG - sh))
    # the basic layer cannot steer: a stroke that veers is a worse stroke
    cost += drift_weight * abs(s["lateral_drift_m"]) / s["seconds"]
    return cost, s


def _closing(text: str, i: int) -> int:
    """Index just past the bracket that closes the one opening at ``text[i]``."""
    depth = 0
    for j in range(i, len(text)):
        depth += {"[": 1, "]": -1}.get(text[j], 0)
        if depth == 0:
            return j + 1
    raise ValueError("unbalanced brackets")


def merge_toml(text: str, raw: dict) -> str:
    """The stroke file ``text`` with the period and every key list of ``raw`` written in
    place (its comments, per-cycle sequences and other sections kept); a dof the file
    does not list is added at the end of its joint's section."""
    text = re.sub(r"(?m)^period_s = [0-9.eE+-]+", f"period_s = {raw['period_s']:.3f}", text)
    for joint, dofs in raw.get("keys", {}).items():
        head = re.search(rf"(?m)^\[keys\.{re.escape(joint)}\]\s*$", text)
        for dof, keys in dofs.items():
            pairs = ", ".join(f"[{q:.3f}, {v:.0f}]" for q, v in keys)
            if head is None:
                text += f"\n[keys.{joint}]\n"
                head = re.search(rf"(?m)^\[keys\.{re.escape(joint)}\]\s*$", text)
            nxt = re.search(r"(?m)^\[", text[head.end():])
            end = head.end() + (nxt.start() if nxt else len(text) - head.end())
            m = re.search(rf"(?m)^{re.escape(dof)} = \[", text[head.end():end])
            if m is None:
                text = text[:end].rstrip("\n") + f"\n{dof} = [{pairs}]\n\n" + text[end:]
            else:
                i = head.end() + m.end() - 1
                text = text[:i] + f"[{pairs}]" + text[_closing(text, i):]
            head = re.search(rf"(?m)^\[keys\.{re.escape(joint)}\]\s*$", text)
    return text


def parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("stroke", choices=sorted(SPECS))
    ap.add_argument("--generations", type=int, default=25)
    ap.add_argument("--popsize", type=int, default=16)
    ap.add_argument("--seconds", type=float, default=10.0, help="simulated seconds per trial")
    ap.add_argument("--head-min", type=float, default=-0.10,
                    help="mean head-centre height below which a trial is penalised [m]")
    ap.add_argument("--power-cap", type=float, default=450.0,
                    help="mean muscle power above which a trial is penalised [W]")
    ap.add_argument("--power-slope", type=float, default=POWER_SLOPE_W,
                    help="watts over the cap that cost as much as 1 m/s of speed")
    ap.add_argument("--body", choices=("box", "rounded"), default="box",
                    help="the swimmer's hydrodynamic surface (flapsim swim --body)")
    ap.add_argument("--rate", metavar="LO,HI", default=None,
                    help="stroke-rate band [cycles/s]: the period parameter spans it (default: "
                         "the file's period +- a band, within the stroke's human bounds)")
    ap.add_argument("--incline-max", type=float, default=None,
                    help="trunk incline above which a trial is penalised [deg] (off by default)")
    ap.add_argument("--limbs-top", type=float, default=None,
                    help="height relative to the surface that the centres of the hands and "
                         "feet are not to rise above [m] (off by default; the breaststroke's "
                         "recovery under water: e.g. -0.03)")
    ap.add_argument("--roll", metavar="LO,HI", default=None,
                    help="the shoulders' roll band [deg]; also penalised: the hips rolling "
                         f"within {ROLL_MARGIN_DEG:g} deg of the shoulders (off by default)")
    ap.add_argument("--drift-weight", type=float, default=0.5,
                    help="cost per m/s of sideways drift")
    ap.add_argument("--breathe", type=float, default=1.0,
                    help="cost when fewer than 90 %% of the cycles lift the head out, per "
                         "missing fraction")
    ap.add_argument("--breath-height", type=float, default=0.0,
                    help="mean per-cycle peak of the head centre wanted above water [m] "
                         "(breaststroke, face forwards: ~0.06 puts the mouth out)")
    ap.add_argument("--start", help="start from this stroke file (e.g. an earlier result) "
                    "instead of the bundled one; it must have the same keys")
    ap.add_argument("--sigma", type=float, default=0.3, help="initial step (fraction of band)")
    ap.add_argument("--workers", type=int, default=os.cpu_count() or 1)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--out", required=True)
    return ap


def main(argv: list[str] | None = None) -> int:
    ap = parser()
    a = ap.parse_args(argv)
    periods = roll = None
    try:
        if a.rate is not None:
            lo, hi = (float(v) for v in a.rate.split(","))
            if not 0.0 < lo <= hi:
                raise ValueError
            periods = (1.0 / hi, 1.0 / lo)
        if a.roll is not None:
            roll = tuple(float(v) for v in a.roll.split(","))
            if len(roll) != 2 or roll[0] > roll[1]:
                raise ValueError
    except ValueError:
        ap.error("--rate and --roll take LO,HI with 0 < LO <= HI, e.g. --rate 0.5,0.7")
    text = stroke_path(a.start or a.stroke).read_text()
    raw = tomllib.loads(text)
    spec, objective = SPECS[a.stroke]
    n = len(spec)
    rng = np.random.default_rng(a.seed)
    state_path = a.out + ".state.npz"
    mean, sigma, gen0 = np.zeros(n), a.sigma, 0
    best = (math.inf, np.zeros(n), {})
    if os.path.exists(state_path):
        st = np.load(state_path, allow_pickle=False)
        if str(st["stroke"]) != a.stroke or st["mean"].shape != (n,):
            sys.exit(f"{state_path} belongs to a {st['stroke']} run with {st['mean'].size} "
                     f"parameters: delete it or choose another --out")
        mean, sigma, gen0 = st["mean"], float(st["sigma"]), int(st["gen"])
        best = (float(st["best_cost"]), st["best_x"], json.loads(str(st["best_summary"])))
        rng = np.random.default_rng([a.seed, gen0])
        print(f"resuming at generation {gen0} (best speed {best[2].get('speed_m_s')})")
    # a (mu/mu_w, lambda) evolution strategy with cumulative step-size adaptation
    # (Hansen's CSA, isotropic): robust, needs no gradient, a few hundred trials
    mu = a.popsize // 2
    w = np.log(mu + 0.5) - np.log(np.arange(1, mu + 1))
    w /= w.sum()
    mu_eff = 1.0 / float(w @ w)
    c_s = (mu_eff + 2.0) / (n + mu_eff + 5.0)
    d_s = 1.0 + c_s + 2.0 * max(0.0, math.sqrt((mu_eff - 1.0) / (n + 1.0)) - 1.0)
    chi_n = math.sqrt(n) * (1.0 - 1.0 / (4.0 * n) + 1.0 / (21.0 * n * n))
    p_s = np.zeros(n) if gen0 == 0 else st["p_s"]
    # one worker: evaluate in this process (no second process on a shared machine)
    with (ProcessPoolExecutor(a.workers) if a.workers > 1 else contextlib.nullcontext()) as pool:
        for gen in range(gen0, a.generations):
            t0 = time.perf_counter()
            z = rng.standard_normal((a.popsize, n))
            xs = np.clip(mean + sigma * z, -1, 1)
            if gen == 0:
                xs[0] = mean  # the starting stroke itself
            jobs = [(apply_params(raw, spec, x, periods), a.seconds, a.head_min, a.power_cap,
                     a.drift_weight, objective, a.breathe, a.breath_height, a.body,
                     a.power_slope, a.incline_max, roll, a.limbs_top) for x in xs]
            res = list((pool.map if pool is not None else map)(_evaluate, jobs))
            costs = np.array([c for c, _ in res])
            order = np.argsort(costs)
            if costs[order[0]] < best[0]:
                best = (float(costs[order[0]]), xs[order[0]].copy(), res[order[0]][1])
            new_mean = w @ xs[order[:mu]]
            p_s = (1 - c_s) * p_s + math.sqrt(c_s * (2 - c_s) * mu_eff) * (new_mean - mean) / sigma
            sigma *= math.exp((c_s / d_s) * (np.linalg.norm(p_s) / chi_n - 1.0))
            sigma = float(np.clip(sigma, 0.02, 0.8))
            mean = new_mean
            s = best[2]
            print(f"gen {gen + 1}/{a.generations}: best cost {best[0]:.3f} speed "
                  f"{s.get('speed_m_s', float('nan')):.3f} m/s head "
                  f"{s.get('head_height_mean_m', float('nan')):.3f} m power "
                  f"{s.get('muscle_power_mean_w', float('nan')):.0f} W rate "
                  f"{s.get('stroke_rate_hz', float('nan')):.2f} Hz incline "
                  f"{s.get('trunk_incline_deg', float('nan')):.1f} roll shoulders/hips "
                  f"{s.get('roll_shoulders_deg', float('nan')):.0f}/"
                  f"{s.get('roll_hips_deg', float('nan')):.0f} deg limbs top "
                  f"{s.get('hands_height_max_m', float('nan')):+.2f}/"
                  f"{s.get('feet_height_max_m', float('nan')):+.2f} m; gen median "
                  f"{np.median(costs):.3f}; sigma {sigma:.2f}; {time.perf_counter() - t0:.1f} s",
                  flush=True)
            np.savez(state_path + ".tmp.npz", stroke=a.stroke, mean=mean, sigma=sigma,
                     gen=gen + 1, p_s=p_s,
                     best_cost=best[0], best_x=best[1], best_summary=json.dumps(best[2]))
            os.replace(state_path + ".tmp.npz", state_path)
            with atomic_path(a.out) as tmp:
                tmp.write_text(merge_toml(text, apply_params(raw, spec, best[1], periods)))
    print(json.dumps({"best_x": [round(v, 3) for v in best[1]], **best[2]}, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
