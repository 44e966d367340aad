"""The paper's continuous perturbation layer (its sec. 4.4): two rules applied 50 times
a second from the local relative flow at each hand.

* **Palm orientation**: the palms face into the flow when more force is wanted in the
  desired direction, and slice through it when less is wanted.
* **Arm reach**: the arms reach out further when more force is wanted in the desired
  direction, and come closer to the torso when less is wanted.

"More force in the desired direction" is read from the flow itself: a flat hand's
drag acts along the water's velocity relative to the hand, ``v_rel = v_water -
v_hand``, so a hand whose ``v_rel`` points along the desired direction ``d``
(:meth:`HandRules.direction`: forwards for prone strokes, tilted towards a target's
depth, or turned towards the aim by the stroke's ``hand_rule_aim`` times its bearing;
towards the target for treading water) can push the swimmer that way
(``c = v_rel . d / |v_rel| > 0``: more force wanted: face the flow, reach out), and one
whose ``v_rel`` points against ``d`` holds it back (``c < 0``: less force wanted:
slice, fold in). The rules scale with ``|c|``. With a target, ``d`` is scaled by how much
forward force is wanted (:attr:`HandRules.need`): the cosine of the aim's bearing, and,
continuously, less where the aim asks for a sharper turn than the stroke can make
(:attr:`HandRuleParams.curvature_slowdown`; the slower swimmer turns in a smaller circle).

The palm's normal ``n`` is the hand box's thin (local y) axis, outward from the palm
(:data:`PALM_SIDE`). The palm rule asks for the normal ``n*``: ``-v_rel`` (the palm,
not the back of the hand, faces the water coming at it) to face the flow, ``n`` with
its ``v_rel`` part removed to slice; the turns of the forearm rotation (elbow pronation)
and the wrist that bring ``n`` towards ``n*`` come from the two joints' axes (damped
least squares on ``d n = sum_j (a_j x n) d theta_j``) and are integrated into the two
joints' offsets from the stroke's pose (``palm_gain`` of the remaining turn per update,
at most ``palm_max_deg``): an integral, because the weak forearm and wrist muscles
yield to the water's torque on the hand (up to ~70 deg on the crawl's pull), so that
aiming at "where the joint is now plus the turn" would follow that yielding instead of
correcting it. The reach rule offsets elbow flexion by ``-reach_max_deg * c``
(extension for more force), low-passed. Offsets act on the PD's targets as motor
torques ``kp * offset`` (:attr:`flapsim.swim.layers.BasicStrokeLayer.extra`). Hands out
of the water (no flow force), in a weak flow, or outside the stroke's
``hand_rule_phases`` (per rule or for both; the breaststroke: its arm pull, the palm
rule not in the outsweep; see its file) relax that rule's offsets.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass

import mujoco
import numpy as np

from flapsim.core.errors import InputError
from flapsim.swim.feedback import wrap_angle
from flapsim.swim.layers import BasicStrokeLayer
from flapsim.swim.strokes import HAND_RULES

RULES = HAND_RULES
#: the palm's outward normal is the hand box's local y axis times this (the boxes are
#: mirrored): on the crawl's basic stroke the pull's relative flow has
#: y . v_rel/|v_rel| = +0.65 at the left hand and -0.63 at the right (speed-weighted,
#: tests/swim/test_continuous.py), and a pulling palm faces the water
#: coming at it
PALM_SIDE = {"l": -1.0, "r": 1.0}
#: version of the hand rules' behaviour in still water, stored with the per-cycle
#: calibration tables made with them (2: the palm, not the nearer face, faces the flow;
#: 3: the "all" tables start from straight swimming with the rules on, and the rules act
#: only in the stroke's hand_rule_phases)
RULES_VERSION = 3
#: the HandRuleParams that act while calibrating (still water, no target)
STILL_WATER_SETTINGS = ("palm_max_deg", "reach_max_deg", "min_flow", "smooth_s", "palm_gain",
                        "min_alignment")


@dataclass(frozen=True)
class HandRuleParams:
    """Settings of the continuous layer's hand rules."""

    #: largest palm turn from the stroke's pose [deg] (forearm rotation and wrist each)
    palm_max_deg: float = 45.0
    #: largest elbow offset of the reach rule [deg]
    reach_max_deg: float = 20.0
    #: below this relative flow speed at a hand the rules rest [m/s]
    min_flow: float = 0.1
    #: time constant of the reach offset's low-pass, and of the relaxation of offsets
    #: where the rules rest [s]
    smooth_s: float = 0.06
    #: fraction of the palm's remaining turn added to its offsets per update [-]
    palm_gain: float = 0.1
    #: the rules act only where the flow is clearly with or against the desired
    #: direction: strength (|c| - c0) / (1 - c0), c0 = this [-]
    min_alignment: float = 0.0
    #: prone strokes with a target: while the per-cycle layer's yaw weight is w, at most
    #: 1 - turn_slowdown w of the force along d is wanted (negative: the palms slice, a
    #: slower swimmer turns in a smaller circle). Off by default: coupled to a
    #: once-a-cycle weight it pulses on the 5 m figure of eight (brake and turn, then
    #: sprint straight, every ~10 s); curvature_slowdown replaces it
    turn_slowdown: float = 0.0
    #: prone strokes with a target, continuously: pure pursuit to an aim point L ahead
    #: at bearing e asks for the curvature 2 sin|e| / L; the stroke turns at most W (its
    #: per-cycle table's largest yaw turn per cycle at this speed x the stroke rate), so
    #: speeds up to v_ok = W / curvature can follow the aim. Above v_ok at most
    #: 1 - k (v / v_ok - 1) of the force along d is wanted, k = this (2: the rules are
    #: neutral at 1.5 v_ok, the palms slice and the arms fold fully at 2 v_ok); 0: off
    curvature_slowdown: float = 2.0
    #: prone strokes: the reach rule's strength times 1 - tuck_in_turns w (arms kept in
    #: while the per-cycle layer turns). Measured, not on by default: reaching out adds
    #: no speed to the crawl but damps its yaw (12.2 -> 9.7 deg/s at full yaw weight);
    #: tucking helps the breaststroke's 5 m figure of eight (0.26 -> 0.19 m) but costs
    #: the chases a little (cross current 1.59 -> 1.79 m, trajectory 3.64 -> 4.14 m)
    tuck_in_turns: float = 0.0


def calibration_settings() -> dict:
    """What the per-cycle calibration's "all" tables depend on: the rules' version and
    the default settings that act in still water without a target (stored in a table's
    provenance, checked when it is loaded)."""
    p = asdict(HandRuleParams())
    return {"version": RULES_VERSION, **{k: p[k] for k in STILL_WATER_SETTINGS}}


class HandRules:
    """Call :meth:`update` at the control rate (after the per-cycle layer, if any)."""

    def __init__(self, basic: BasicStrokeLayer, target: object | None = None,
                 rules: tuple[str, ...] = RULES, params: HandRuleParams | None = None) -> None:
        bad = [r for r in rules if r not in RULES]
        if bad:
            raise InputError(f"unknown continuous rules {bad}; choose from {', '.join(RULES)}")
        self.basic = basic
        self.target = target
        self.rules = tuple(rules)
        self.params = params or HandRuleParams()
        sw = basic.swimmer
        m = sw.model
        self.root = sw.body["pelvis"]
        self.head = sw.body["head"]
        self.level = sw.params.water_level
        j = sw.joints
        # per joint: index into the PD's per-dof gains, its actuator, its qpos address and
        # the index of its target in BasicStrokeLayer.target
        where: dict[str, tuple[int, int, int, int, int]] = {}
        dof = tq = 0
        for k, (name, t) in enumerate(zip(j.names, j.types, strict=True)):
            jid = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, name)
            where[name] = (dof, int(j.actuator[k]), int(j.qadr[k]), tq, jid)
            dof += 3 if t == 1 else 1
            tq += 4 if t == 1 else 1
        self.hands = []
        for s in ("l", "r"):
            need = (f"elbow_pron_{s}", f"wrist_{s}", f"elbow_flex_{s}")
            if not all(n in where for n in need):
                raise InputError("the continuous layer needs elbow_pron, wrist and elbow_flex joints")
            gid = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, f"hand_{s}")
            self.hands.append({"side": s, "geom": gid, "pron": where[need[0]],
                               "wrist": where[need[1]], "elbow": where[need[2]],
                               "off": np.zeros(3)})
        self.t_last: float | None = None
        #: how much force along d is wanted, -1..1 (1; prone strokes with a target: the
        #: cosine of the angle between the body line and the target's direction, less
        #: where the aim asks for a sharper turn than the stroke can make
        #: (curvature_slowdown), and at most 1 - turn_slowdown w, w the per-cycle layer's
        #: yaw weight this cycle)
        self.need = 1.0
        #: the per-cycle layer (its yaw weights), if any: set by whoever stacks the layers
        self.cycle = None
        self._vel = np.zeros(6)
        #: per update: mean c over the wet hands, and the offsets [rad] (pron, wrist,
        #: elbow) of each hand
        self.history: list[list[float]] = []
        basic.extra_on = True

    def direction(self, data: mujoco.MjData) -> np.ndarray | None:
        """The desired direction ``d`` (unit, world), or None: no force wanted anywhere.

        Prone strokes: forwards, the body line's heading (pelvis to head; steering is
        the per-cycle layer's job, the paper's Fig. 8c: "maximize forward thrust"),
        tilted towards a target's depth; with a target and the stroke's
        ``hand_rule_aim`` k > 0, turned from the body line towards the aim by k times
        the aim's bearing (at most 90 deg: the breaststroke's sweeping hands push
        sideways into the turn). Upright (treading water): towards the target,
        horizontally; without a target nowhere (the rules rest)."""
        sw = self.basic.swimmer
        mujoco.mj_subtreeVel(sw.model, data)
        com = data.subtree_com[self.root].copy()
        t = float(data.time)
        self.need = 1.0
        #: the reach rule's share while turning (prone: 1 - tuck_in_turns w)
        self.reach_scale = 1.0
        if self.basic.stroke.posture == "prone":
            line = data.xpos[self.head] - data.xpos[self.root]
            h = math.atan2(line[1], line[0])
            if self.target is not None:  # forward force is wanted as far as the target
                # lies ahead: more on course, less while the aim is beside or behind ...
                aim = self.target.heading(com[:2], data.subtree_linvel[self.root][:2].copy(), t)
                self.need = math.cos(aim - h)
                cyc = self.cycle
                if cyc is not None and self.params.curvature_slowdown > 0:  # ... and less
                    # while the aim asks for a sharper turn than the stroke can make
                    self.need = min(self.need, self._curvature_need(data, com, aim - h, t))
                if cyc is not None and cyc.weights:  # ... and less while the per-cycle
                    # layer turns hard (turn_slowdown; arms in: tuck_in_turns)
                    w = max(cyc.weights.get("yaw_left", 0.0), cyc.weights.get("yaw_right", 0.0))
                    if self.params.turn_slowdown > 0:
                        self.need = min(self.need, 1.0 - self.params.turn_slowdown * w)
                    self.reach_scale = max(0.0, 1.0 - self.params.tuck_in_turns * w)
                k = self.basic.stroke.hand_rule_aim
                if k > 0:  # towards the aim, by k times its bearing
                    h += float(np.clip(k * wrap_angle(aim - h), -math.pi / 2, math.pi / 2))
        elif self.target is None:
            return None
        else:
            h = self.target.heading(com[:2], data.subtree_linvel[self.root][:2].copy(), t)
        e = self.target.elevation(com, t) if getattr(self.target, "is_3d", False) else 0.0
        return np.array([math.cos(e) * math.cos(h), math.cos(e) * math.sin(h), math.sin(e)])

    def _curvature_need(self, data: mujoco.MjData, com: np.ndarray, err: float, t: float) -> float:
        """Forward force wanted [-1, 1] so that the aim's turn stays within the stroke's
        turn rate (:attr:`HandRuleParams.curvature_slowdown`). The aim point is the
        target's look-ahead away (paths) or the target itself (points, trajectories)."""
        tgt = self.target
        if hasattr(tgt, "lookahead"):
            dist = float(tgt.lookahead)
        elif hasattr(tgt, "position"):
            dist = float(np.linalg.norm(np.asarray(tgt.position(t))[:2] - com[:2]))
        else:
            return 1.0
        kappa = 2.0 * abs(math.sin(err)) / max(dist, 0.5)
        table = getattr(self.cycle, "table", None)
        name = "yaw_left" if math.sin(err) > 0 else "yaw_right"
        if kappa < 1e-6 or table is None or name not in table.angles:
            return 1.0
        v = float(np.linalg.norm(data.subtree_linvel[self.root][:2]))
        rate = float(np.max(table.angle_curve(name, v))) * self.basic.rate_hz  # [rad/s]
        v_ok = rate / kappa
        if v <= v_ok:
            return 1.0
        return max(-1.0, 1.0 - self.params.curvature_slowdown * (v / v_ok - 1.0))

    def update(self, data: mujoco.MjData) -> None:
        sw = self.basic.swimmer
        m = sw.model
        p = self.params
        now = float(data.time)
        dt = 0.0 if self.t_last is None or now < self.t_last else now - self.t_last
        self.t_last = now
        alpha = 1.0 if p.smooth_s <= 0 else min(1.0, dt / p.smooth_s) if dt > 0 else 0.0
        d = self.direction(data)
        target = self.basic.target
        kp = self.basic.kp
        extra = self.basic.extra
        cs = []
        row = []
        for h in self.hands:
            want = np.zeros(3)
            palm_on = False
            pos = data.geom_xpos[h["geom"]]
            acts = [r for r in self.rules if self.acting(r)]
            if d is not None and pos[2] < self.level and acts:
                mujoco.mj_objectVelocity(m, data, mujoco.mjtObj.mjOBJ_GEOM, h["geom"], self._vel, 0)
                v_rel = sw.flow.velocity(pos[None, :], now)[0] - self._vel[3:]
                speed = float(np.linalg.norm(v_rel))
                if speed > p.min_flow:
                    u = v_rel / speed
                    c = float(np.clip(u @ d, -1.0, 1.0)) * self.need
                    cs.append(c)
                    if "palm" in acts:
                        want[:2] = self._palm(data, h, u, c, target)
                        palm_on = True
                    if "reach" in acts:
                        want[2] = -math.radians(p.reach_max_deg) * self.reach_scale * \
                            math.copysign(self._strength(c), c)
            if palm_on:  # integral: want holds the new palm offsets
                h["off"][:2] = want[:2]
            else:
                h["off"][:2] += alpha * (want[:2] - h["off"][:2])
            h["off"][2] += alpha * (want[2] - h["off"][2])
            for k, key in enumerate(("pron", "wrist", "elbow")):
                dof, act, _, _, _ = h[key]
                extra[act] = kp[dof] * h["off"][k]
            row += h["off"].tolist()
        self.history.append([float(np.mean(cs)) if cs else 0.0, *row])

    def acting(self, rule: str) -> bool:
        """Whether the stroke's phase is one in which ``rule`` acts (the stroke's
        ``hand_rule_phases``; the whole cycle if it names none for the rule)."""
        return self.basic.stroke.rule_acts(rule, self.basic.phase)

    def _strength(self, c: float) -> float:
        c0 = self.params.min_alignment
        return max(0.0, (abs(c) - c0) / (1.0 - c0))

    def _palm(self, data: mujoco.MjData, h: dict, u: np.ndarray, c: float,
              target: np.ndarray) -> np.ndarray:
        """New offsets [rad] of forearm rotation and wrist from the stroke's targets:
        the present ones plus a part of the turn towards the rule's normal."""
        n = data.geom_xmat[h["geom"]].reshape(3, 3)[:, 1] * PALM_SIDE[h["side"]]
        if c > 0:  # face the flow: the palm's normal against the water coming at it
            goal = -u
        else:  # slice: the normal across the flow
            goal = n - (n @ u) * u
            norm = float(np.linalg.norm(goal))
            if norm < 1e-6:
                return h["off"][:2].copy()
            goal = goal / norm
        goal = n + self._strength(c) * (goal - n)  # as much as the rule is wanted
        cols = []
        for key in ("pron", "wrist"):
            jid = h[key][4]
            cols.append(np.cross(data.xaxis[jid], n))
        jac = np.column_stack(cols)
        dtheta = np.linalg.solve(jac.T @ jac + 0.05 * np.eye(2), jac.T @ (goal - n))
        lim = math.radians(self.params.palm_max_deg)
        return np.clip(h["off"][:2] + self.params.palm_gain * dtheta, -lim, lim)

    def summary(self) -> dict:
        """Mean flow alignment c, mean |offset| [deg] per joint."""
        if not self.history:
            return {}
        a = np.asarray(self.history)
        offs = np.degrees(np.abs(a[:, 1:])).mean(axis=0)
        return {"rules": list(self.rules), "flow_alignment_mean": float(a[:, 0].mean()),
                "pronation_offset_mean_abs_deg": float((offs[0] + offs[3]) / 2),
                "wrist_offset_mean_abs_deg": float((offs[1] + offs[4]) / 2),
                "elbow_offset_mean_abs_deg": float((offs[2] + offs[5]) / 2)}
