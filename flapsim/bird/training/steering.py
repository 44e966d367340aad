"""One-wingbeat steering: how well a controller reaches a commanded state change.

Two measurements the training issue asks for:

* :func:`steering_table`: from random start states (drawn as in phase 1: a random pre-state
  and a random pre-simulation wingbeat), the controller is asked to steer by alpha and
  climb by beta in one wingbeat (:class:`~flapsim.bird.control.targets.SteerTarget`); the error
  between the state it reaches and the target state is compared with the base
  controller's (P0 from the same state).
* :func:`steering_range`: from steady cruise, the largest heading change per wingbeat the
  controller achieves to either side when asked for more than it can do (the paper's
  "steering range per wingbeat": -8.0..8.9 deg after phase 1, -38.2..29.2 after phase 2).
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np

from flapsim.bird.control.controller import WingbeatController, start_cruise
from flapsim.bird.control.regression import PAPER_WEIGHTS, weight_vector
from flapsim.bird.control.targets import PathTurnTarget, SignatureTarget, SteerTarget, Trim
from flapsim.bird.flight import cycle
from flapsim.bird.training.sampling import SampleWorker
from flapsim.core.errors import SimulationError


def state_error(S: np.ndarray, S_target: np.ndarray) -> float:
    """sqrt((S - S_t) W (S - S_t)^T) with the paper's W (eq. 3) in SI units."""
    d = np.asarray(S) - np.asarray(S_target)
    return float(np.sqrt(d @ (weight_vector(PAPER_WEIGHTS) * d)))


@dataclass
class SteeringRow:
    """One command over all start states."""

    alpha_deg: float
    beta_deg: float
    error_controller: float
    """Mean state error of the controller's wingbeat (weighted, see :func:`state_error`)."""
    error_base: float
    """Mean state error of P0 from the same states."""
    achieved_alpha_deg: float
    """Mean achieved steering (heading change of the centre-of-mass velocity vs P0), deg."""
    achieved_beta_deg: float
    """Mean achieved elevation change vs P0, deg."""
    better: float
    """Share of start states where the controller's error is below the base's."""
    error_controller_db: float
    """Mean state error in the regression's own metric (the paper's weights over each
    dimension's spread in the database)."""
    error_base_db: float
    """... of P0."""
    n: int
    """Start states that did not diverge."""


def steering_table(controller: WingbeatController, sampler: SampleWorker, trim: Trim,
                   commands_deg: list[tuple[float, float]], n_states: int = 20,
                   seed: int = 0, target: str = "turn", start: str = "cruise",
                   signature: np.ndarray | None = None) -> list[SteeringRow]:
    """Controller vs base on one-wingbeat commands from ``n_states`` start states.

    ``target``: ``turn`` (:class:`SteerTarget`, a coordinated turn), ``path``
    (:class:`PathTurnTarget`) or ``signature`` (:class:`SignatureTarget` with
    ``signature``); ``start``: ``cruise`` (steady flight tilted by up to 5 deg in pitch and
    roll, two base wingbeats) or ``random`` (phase-1 pre-states and wingbeats)."""
    fl = controller.flight
    starts = []
    for i in range(n_states):
        rng = np.random.default_rng([seed, i])
        if start == "cruise":
            # near steady flight: the cruise start tilted by up to 5 deg, two base wingbeats
            start_cruise(fl, controller.P0, roll_deg=float(rng.uniform(-5, 5)))
            d = fl.data

            q = d.qpos[3:7].copy()
            th = np.radians(rng.uniform(-5, 5))
            mujoco.mju_mulQuat(d.qpos[3:7], q, np.array([np.cos(-th / 2), 0, np.sin(-th / 2), 0]))
            mujoco.mj_forward(fl.model, d)
            try:
                for _ in range(2):
                    cycle.fly_cycle(fl, None, controller.P0)
            except SimulationError:
                continue
            starts.append(cycle.snapshot(fl))
            continue
        pre = sampler.pre_state(rng)
        dP = sampler.draw_wingbeat(rng)
        if dP is None:
            continue
        try:
            starts.append(cycle.fly_cycle(fl, pre, sampler.P0 + dP, sampler.ref).snapshot)
        except SimulationError:
            continue
    rows = []
    for a_deg, b_deg in commands_deg:
        ec, eb, aa, bb, win, ecn, ebn = [], [], [], [], [], [], []
        wdb = controller.regressor.w
        for snap in starts:
            if target == "path":
                tgt = PathTurnTarget(np.radians(a_deg), np.radians(b_deg))
            elif target == "signature":
                tgt = SignatureTarget(signature, np.radians(a_deg), np.radians(b_deg))
            else:
                tgt = SteerTarget(trim, np.radians(a_deg), np.radians(b_deg))
            try:
                step = controller.choose(tgt, snap)
            except SimulationError:
                continue
            e_c = state_error(step.end.S, step.S_target)
            e_b = state_error(step.reference.S, step.S_target)
            h0, c0 = cycle.heading_and_climb(step.reference.com_vel)
            h1, c1 = cycle.heading_and_climb(step.end.com_vel)
            ecn.append(float(np.sqrt(np.sum(wdb * (step.end.S - step.S_target) ** 2))))
            ebn.append(float(np.sqrt(np.sum(wdb * (step.reference.S - step.S_target) ** 2))))
            ec.append(e_c)
            eb.append(e_b)
            aa.append(np.degrees(cycle.wrap(h1 - h0)))
            bb.append(np.degrees(c1 - c0))
            win.append(e_c < e_b)
        rows.append(SteeringRow(a_deg, b_deg, float(np.mean(ec)), float(np.mean(eb)),
                                float(np.mean(aa)), float(np.mean(bb)), float(np.mean(win)),
                                float(np.mean(ecn)), float(np.mean(ebn)), len(ec)))
    return rows


def steering_range(controller: WingbeatController, trim: Trim, ask_deg: float = 30.0,
                   wingbeats: int = 12, settle_wingbeats: int = 3) -> dict:
    """Sustained steering from steady cruise: the controller is asked to steer by
    +-``ask_deg`` every wingbeat (:class:`SteerTarget`) for ``wingbeats`` wingbeats, as in
    the paper's rapid side-to-side turns; returns the largest heading change per wingbeat
    it achieved to each side (deg, right negative) and whether it stayed in control
    (|roll| < 80 deg, no divergence)."""
    fl = controller.flight
    out = {}
    for side, a in (("right", -ask_deg), ("left", ask_deg)):
        start_cruise(fl, controller.P0)
        for _ in range(settle_wingbeats):
            cycle.fly_cycle(fl, None, controller.P0)
        h_prev, _ = cycle.heading_and_climb(_com_vel(fl, cycle.snapshot(fl)))
        per_wb, ok = [], True
        for _ in range(wingbeats):
            try:
                step = controller.choose(SteerTarget(trim, np.radians(a), 0.0))
            except SimulationError:
                ok = False
                break
            h, _ = cycle.heading_and_climb(step.end.com_vel)
            per_wb.append(float(np.degrees(cycle.wrap(h - h_prev))))
            h_prev = h
            if abs(step.end.S[1]) > np.radians(80):
                ok = False
                break
        best = (min(per_wb) if a < 0 else max(per_wb)) if per_wb else float("nan")
        out[side] = {"best_deg_per_wingbeat": best, "per_wingbeat_deg": per_wb, "in_control": ok}
    out["range_deg"] = [out["right"]["best_deg_per_wingbeat"], out["left"]["best_deg_per_wingbeat"]]
    return out


def _com_vel(fl, snap: cycle.Snapshot) -> np.ndarray:
    cycle.restore(fl, snap)
    mujoco.mj_subtreeVel(fl.model, fl.data)
    return fl.data.subtree_linvel[fl.dove.trunk].copy()
