"""The paper's per-cycle perturbation layer (its sec. 4.3) and the pre-simulation that
calibrates it.

A stroke file names up to six sequences (``[cycle.yaw_left]``, ``yaw_right``,
``pitch_up``, ``pitch_down``, ``roll_left``, ``roll_right``: offsets relative to the
basic stroke, see :mod:`flapsim.swim.strokes`). At the start of every stroke cycle
:class:`CycleLayer` measures the swimmer's attitude and where the target is, asks the
stroke's :class:`CycleTable` which weight of each sequence turns the swimmer through
the wanted angle in one cycle at its present speed, and blends the weighted sequences
into the basic stroke for that cycle.

The tables come from pre-simulation in still water (:func:`calibrate`, ``flapsim swim
--calibrate --stroke NAME``): the swimmer starts from rest and its state is kept at the
start of several cycles (cycles 0, 1, 2, 4: speeds from rest to full speed); from each,
one cycle is swum with each sequence at each weight (0.25 .. 1), and the turn is the
attitude at the end of that cycle minus the attitude of the unperturbed cycle from the
same state. A stroke whose turn keeps building for cycles after its yaw sequence
starts (:attr:`flapsim.swim.strokes.Stroke.cycle_hold` N > 1) holds each yaw sequence,
and the reference, for N cycles; its yaw turn is the mean turn per cycle after the
first, ((end N - end 1) minus the reference's) / (N - 1): the neck bend that moves the
measured body line is there at both ends and cancels. Parallel
(:class:`flapsim.core.parallel.ChunkExecutor`), resumable (finished chunks are journalled
to ``OUT.partial.jsonl``), stored as JSON with provenance; bundled strokes ship theirs next
to the stroke file (``<name>.cycle.json``).

Attitude (:func:`attitude`) is that of the upper trunk (thorax): yaw = horizontal
direction of its forward axis (head-ward when prone, anterior when upright) [rad, +
= left], pitch = the forward axis's angle above the horizontal (+ = up), roll = the
angle of its left axis above the horizontal (+ = left side up). Because the crawl and
breaststroke rock within a cycle, the layer compares attitudes at the same phase: the
table also stores, per speed, how far the cycle-start attitude lies from the cycle's
mean (``offset_*``) and the mean pitch and roll of straight swimming.
"""

from __future__ import annotations

import hashlib
import json
import logging
import math
import os
from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from pathlib import Path

import mujoco
import numpy as np
from tqdm import tqdm

from flapsim import __version__
from flapsim.core.errors import DataFileError, InputError
from flapsim.core.io import read_regular, write_json
from flapsim.core.parallel import ChunkExecutor, WorkerError
from flapsim.core.validate import require_finite
from flapsim.swim.continuous import HandRules, calibration_settings
from flapsim.swim.feedback import wrap_angle
from flapsim.swim.layers import BasicStrokeLayer, FeedbackLayer
from flapsim.swim.model import Swimmer, SwimmerParams, check_diverged
from flapsim.swim.strokes import (
    CYCLE_SEQUENCES,
    STROKE_DIR,
    Stroke,
    load_stroke,
    steering_problem,
    stroke_tables,
)

log = logging.getLogger(__name__)

SCHEMA = 1
#: weights tried for every sequence (0 is the reference cycle)
WEIGHTS = (0.25, 0.5, 0.75, 1.0)
#: cycle starts (counted from rest) whose states are the calibration's starting points
SNAPSHOT_CYCLES = (0, 1, 2, 4)
#: the most the layer asks of one cycle [rad] (beyond the table, the largest weight)
MAX_PITCH = math.radians(40.0)
#: roll corrections start beyond this deviation from straight swimming [rad]
ROLL_DEADBAND = math.radians(10.0)
#: the attitude steered: the body line from the pelvis (the root of the body tree) to
#: the head, and the pelvis's roll (the thorax alone turns with every breath and bend,
#: and the pelvis alone counter-rotates when the trunk bends)
ATTITUDE_BODY = "pelvis"
ATTITUDE_HEAD = "head"


def attitude(data: mujoco.MjData, trunk: int, forward_axis: int, head: int | None = None
             ) -> np.ndarray:
    """(yaw, pitch, roll) [rad]: yaw and pitch of the body line from body ``trunk``'s
    origin to body ``head``'s (or of ``trunk``'s local axis ``forward_axis`` when no
    head is given), roll of ``trunk``'s left (local y) axis (see the module docstring)."""
    r = data.xmat[trunk].reshape(3, 3)
    f = (data.xpos[head] - data.xpos[trunk]) if head is not None else r[:, forward_axis]
    f = f / max(float(np.linalg.norm(f)), 1e-12)
    left = r[:, 1]
    return np.array([math.atan2(f[1], f[0]), math.asin(float(np.clip(f[2], -1, 1))),
                     math.asin(float(np.clip(left[2], -1, 1)))])


def _bundled(p: Path) -> bool:
    """Whether ``p`` lies in the package's own stroke folder (read-only once installed)."""
    try:
        return p.resolve().is_relative_to(STROKE_DIR.resolve())
    except OSError:
        return False


def user_table_dir() -> Path:
    """Where calibrations of the bundled strokes are written: the package is read-only
    (``$FLAPSIM_DATA``, else ``$XDG_DATA_HOME/flapsim``, else ``~/.local/share/flapsim``)."""
    base = os.environ.get("FLAPSIM_DATA") or os.path.join(
        os.environ.get("XDG_DATA_HOME") or os.path.join(os.path.expanduser("~"), ".local", "share"),
        "flapsim")
    return Path(base) / "tables"


def table_path(stroke: Stroke, body_shape: str = "box", for_writing: bool = False) -> Path:
    """Where a stroke's calibration table lives: next to its file (``NAME.cycle.json``
    for the box body, ``NAME.rounded.cycle.json`` for the rounded one); for a bundled
    stroke, a calibration of the user's (:func:`user_table_dir`) when there is one, else the
    bundled table. ``for_writing``: where a new calibration goes (never into the package)."""
    p = Path(stroke.path) if stroke.path else STROKE_DIR / f"{stroke.name}.toml"
    beside = p.with_name(p.stem + ("" if body_shape == "box" else f".{body_shape}") + ".cycle.json")
    if not _bundled(p):
        return beside
    # a body's own tuning of a stroke (data/strokes/<body>/) keeps its folder there too
    mine = user_table_dir() / p.resolve().parent.relative_to(STROKE_DIR.resolve()) / beside.name
    return mine if for_writing or mine.is_file() else beside


def stroke_hash(stroke: Stroke) -> str:
    """Hash of the stroke file's bytes (a table is valid for the file it was made from)."""
    p = Path(stroke.path)
    return hashlib.sha256(p.read_bytes()).hexdigest()[:16] if p.is_file() else ""


# ------------------------------------------------------------------ the table
@dataclass
class CycleTable:
    """Turn per cycle [rad] made by each sequence at each weight and speed."""

    stroke: str
    #: centre-of-mass speed at the start of the calibration cycles [m/s] (increasing)
    speeds: np.ndarray
    weights: np.ndarray
    #: sequence -> (n_speeds, n_weights) turn in the sequence's own direction [rad]
    angles: dict
    #: per speed: cycle-start attitude minus cycle mean (yaw, pitch, roll) [rad], (n, 3)
    offsets: np.ndarray
    #: per speed: mean pitch and roll of straight swimming [rad], (n, 2)
    level: np.ndarray
    provenance: dict = field(default_factory=dict)

    def _at(self, arr: np.ndarray, speed: float) -> np.ndarray:
        return np.array([np.interp(speed, self.speeds, arr[:, j]) for j in range(arr.shape[1])])

    def angle_curve(self, name: str, speed: float) -> np.ndarray:
        """The turn [rad] at each of :attr:`weights` at ``speed`` (interpolated)."""
        return self._at(np.asarray(self.angles[name]), speed)

    def weight_for(self, name: str, speed: float, angle: float) -> float:
        """The weight of sequence ``name`` that turns ``angle`` [rad, >= 0, in the
        sequence's direction] in one cycle at ``speed`` [m/s]: inverse interpolation of
        the table (its monotone envelope); the largest useful weight beyond its reach,
        0 where the sequence does not turn the swimmer its way at this speed."""
        if name not in self.angles or angle <= 0.0:
            return 0.0
        a = np.maximum.accumulate(np.concatenate([[0.0], self.angle_curve(name, speed)]))
        w = np.concatenate([[0.0], self.weights])
        keep = np.concatenate([[True], np.diff(a) > 1e-9])
        a, w = a[keep], w[keep]
        if len(a) < 2:
            return 0.0
        return float(np.interp(angle, a, w))

    def baseline(self, speed: float) -> tuple[np.ndarray, np.ndarray]:
        """(offsets (3,), level (2,)) at ``speed``."""
        return self._at(self.offsets, speed), self._at(self.level, speed)

    def to_dict(self) -> dict:
        return {"schema": SCHEMA, "stroke": self.stroke, "speeds_m_s": self.speeds,
                "weights": self.weights,
                "turn_per_cycle_deg": {k: np.degrees(v) for k, v in self.angles.items()},
                "cycle_start_offset_deg": np.degrees(self.offsets),
                "level_pitch_roll_deg": np.degrees(self.level), "provenance": self.provenance}

    @classmethod
    def from_dict(cls, d: dict, where: str = "<table>") -> CycleTable:
        # a NaN table was taken, and the swimmer never steered
        require_finite(d, where, fix="recalibrate (flapsim swim --calibrate)")
        try:
            if d.get("schema") != SCHEMA:
                raise DataFileError(f"{where}: schema {d.get('schema')!r}, expected {SCHEMA}; "
                                    "recalibrate (flapsim swim --calibrate)")
            speeds = np.asarray(d["speeds_m_s"], dtype=float)
            weights = np.asarray(d["weights"], dtype=float)
            angles = {k: np.radians(np.asarray(v, dtype=float))
                      for k, v in d["turn_per_cycle_deg"].items()}
            offsets = np.radians(np.asarray(d["cycle_start_offset_deg"], dtype=float))
            level = np.radians(np.asarray(d["level_pitch_roll_deg"], dtype=float))
        except (KeyError, TypeError, ValueError) as exc:
            raise DataFileError(f"{where}: not a per-cycle calibration table ({exc})") from None
        n = len(speeds)
        if (n < 1 or np.any(np.diff(speeds) <= 0) or offsets.shape != (n, 3)
                or level.shape != (n, 2)
                or any(a.shape != (n, len(weights)) for a in angles.values())):
            raise DataFileError(f"{where}: inconsistent table shapes; recalibrate")
        bad = set(angles) - set(CYCLE_SEQUENCES)
        if bad:
            raise DataFileError(f"{where}: unknown sequences {sorted(bad)}")
        return cls(str(d.get("stroke", "")), speeds, weights, angles, offsets, level,
                   dict(d.get("provenance", {})))


def load_table(stroke: Stroke, path: str | Path | None = None, check: bool = True,
               layers: str = "cycle", body_shape: str = "box") -> CycleTable:
    """The calibration table of ``stroke`` (default: next to its file) for swimming with
    ``layers`` ("cycle": basic + per-cycle; "all": the continuous layer running too,
    which changes how far a sequence turns the swimmer). ``check``: the table must have
    been made from this very file (its hash)."""
    p = Path(path) if path is not None else table_path(stroke, body_shape)
    cmd = f"flapsim swim --calibrate --stroke {stroke.path or stroke.name}" + \
        ("" if body_shape == "box" else f" --body {body_shape}")
    if not p.is_file():
        raise InputError(f"stroke {stroke.name!r} has no per-cycle calibration table ({p}); "
                         f"make it with: {cmd}")
    try:
        d = json.loads(p.read_text())
    except (OSError, ValueError) as exc:
        raise DataFileError(f"{p}: cannot read the calibration table ({exc})") from None
    modes = d.get("layers") if isinstance(d, dict) else None
    if not isinstance(modes, dict) or layers not in modes:
        raise DataFileError(f"{p}: no table for layers {layers!r}; recalibrate: {cmd}")
    table = CycleTable.from_dict({**modes[layers], "provenance": d.get("provenance", {})},
                                 f"{p} [{layers}]")
    if check and table.provenance.get("stroke_sha256") != stroke_hash(stroke):
        raise DataFileError(f"{p} was calibrated for another version of {stroke.path}; "
                            f"recalibrate: {cmd}")
    made_on = (table.provenance.get("swimmer_params") or {}).get("body_shape", "box")
    if check and made_on != body_shape:
        raise DataFileError(f"{p} was calibrated on the {made_on} body, not the {body_shape} "
                            f"one; recalibrate: {cmd}")
    made = (table.provenance.get("config") or {}).get("hand_rules")
    if check and layers == "all" and made != calibration_settings():
        raise DataFileError(f"{p}: its 'all' table was made with other continuous-layer rules "
                            f"({made}); recalibrate: {cmd}")
    return table


# ------------------------------------------------------------------ the layer
#: speeds that may be asked [m/s] (a slow recreational swim .. a fast one)
SPEED_RANGE = (0.5, 1.6)
#: stroke rates the speed control may set, as fractions of the stroke's own
RATE_RANGE = (0.35, 1.3)
#: exponent of the per-cycle rate correction (below 1: a cycle's speed lags its rate)
SPEED_GAIN = 0.7


class CycleLayer:
    """Call :meth:`update` at the control rate (it acts once per cycle).

    The heading error asked of a cycle is ``gain`` x the stroke's ``cycle_gain`` x (the
    target's heading minus the body line's, less ``cycle_lead`` x the turn the pelvis
    made over the last cycle); pitch and roll errors are asked at ``gain``."""

    def __init__(self, basic: BasicStrokeLayer, table: CycleTable, target: object | None = None,
                 feedback: object | None = None, gain: float = 1.0,
                 speed: float | None = None, plan: object | None = None) -> None:
        st = basic.stroke
        if not st.cycle:
            raise InputError(f"stroke {st.name!r} has no [cycle.*] sequences")
        if speed is not None and not (SPEED_RANGE[0] <= speed <= SPEED_RANGE[1]):
            raise InputError(f"the speed asked must be {SPEED_RANGE[0]:g}..{SPEED_RANGE[1]:g} "
                             f"m/s, got {speed:g}")
        if (speed is not None or plan is not None) and st.posture != "prone":
            raise InputError(f"stroke {st.name!r} swims on the spot: a speed is asked of the "
                             "prone strokes (crawl, breaststroke)")
        #: the speed asked [m/s] (None: the stroke's own rate); held by the stroke rate
        self.speed = speed
        #: something with ``asked_speed(com_xy, t, cruise) -> m/s`` that sets the speed
        #: asked of each cycle (:class:`flapsim.swim.arrival.Approach`: slow down for a
        #: target, match a moving one's speed); ``speed``, if given, is its cruise
        self.plan = plan
        #: the speed asked of the cycle being swum [m/s] (None: not holding a speed)
        self.asked: float | None = None
        self.rate0 = float(basic.rate_hz)
        self._last: tuple[float, np.ndarray] | None = None
        self.basic = basic
        self.table = table
        self.target = target
        #: the continuous FeedbackLayer to rebase on the blended tables, if any
        self.feedback = feedback
        #: fraction of the measured error asked of one cycle
        self.gain = float(gain)
        sw = basic.swimmer
        self.trunk = sw.body[ATTITUDE_BODY]
        self.head = sw.body[ATTITUDE_HEAD]
        self.root = sw.body["pelvis"]
        self.forward_axis = 2 if st.posture == "prone" else 0
        self._n = basic.tables.q.shape[0]
        self._base = basic.base_tables
        problem = steering_problem(st.cycle_hold, st.cycle_gain, st.cycle_lead)
        if problem:
            raise InputError(f"stroke {st.name!r}: {problem}")
        self._cycle = -1
        self.weights = {k: 0.0 for k in st.cycle}
        #: the pelvis axis's yaw at the last decision [rad] (None: none yet), for the
        #: stroke's ``cycle_lead``
        self._yaw_last: float | None = None
        #: per decision: time, speed, heading error, pitch error, roll error, weights
        self.history: list[dict] = []

    def reset(self) -> None:
        """Decide again at the next update (and weights back to 0 until then)."""
        self._cycle = -1
        self.weights = {k: 0.0 for k in self.basic.stroke.cycle}
        self._yaw_last = None
        # the next speed hold starts afresh: a cycle swum under other layers (a dive,
        # treading water) says nothing about this stroke's rate
        self._last = None

    def desired(self, data: mujoco.MjData) -> tuple[float | None, float | None]:
        """(heading or None, elevation or None) the target asks for now [rad]. Without
        a target a prone swimmer holds its start heading (+x); one treading water has
        nowhere to go (None)."""
        sw = self.basic.swimmer
        mujoco.mj_subtreeVel(sw.model, data)
        com = data.subtree_com[self.root].copy()
        vel = data.subtree_linvel[self.root].copy()
        t = float(data.time)
        if self.target is None:
            return (0.0 if self.basic.stroke.posture == "prone" else None), None
        elev = self.target.elevation(com, t) if getattr(self.target, "is_3d", False) else None
        return self.target.heading(com[:2], vel[:2], t), elev

    def update(self, data: mujoco.MjData) -> dict[str, float] | None:
        """At the first call of each cycle: choose and blend in the cycle's weights."""
        if self.basic.cycles == self._cycle:
            return None
        self._cycle = self.basic.cycles
        sw = self.basic.swimmer
        heading, elev = self.desired(data)
        speed = float(np.linalg.norm(data.subtree_linvel[self.root]))
        if self.speed is not None or self.plan is not None:
            self._hold_speed(data)
        off, level = self.table.baseline(speed)
        att = attitude(data, self.trunk, self.forward_axis, self.head) - off
        st = self.basic.stroke
        yaw_error = 0.0 if heading is None else wrap_angle(heading - att[0])
        if st.cycle_lead:
            # a turn that goes on building after its sequence: aim from where the last
            # cycle's turn carries the swimmer. That turn is measured on the pelvis's own
            # axis at the same phase of both cycles: a change of neck bend swings the body
            # line (pelvis to head) without turning the swimmer. Not wrapped again: a fast
            # turn the wrong way must not flip the error's sign past 180 deg
            yaw = float(attitude(data, self.trunk, self.forward_axis)[0])
            if self._yaw_last is not None and heading is not None:
                yaw_error -= st.cycle_lead * wrap_angle(yaw - self._yaw_last)
            self._yaw_last = yaw
        errors = {"yaw": yaw_error,
                  "pitch": 0.0 if elev is None else
                  float(np.clip(elev, -MAX_PITCH, MAX_PITCH)) - (att[1] - level[0]),
                  "roll": -(att[2] - level[1])}
        if abs(errors["roll"]) < ROLL_DEADBAND:
            errors["roll"] = 0.0
        else:
            errors["roll"] -= math.copysign(ROLL_DEADBAND, errors["roll"])
        w = {}
        for name in self.basic.stroke.cycle:
            axis, sign = CYCLE_SEQUENCES[name]
            want = self.gain * errors[axis] * sign * (st.cycle_gain if axis == "yaw" else 1.0)
            w[name] = self.table.weight_for(name, speed, want)
        self.weights = w
        active = {k: v for k, v in w.items() if v > 0.0}
        tables = (stroke_tables(self.basic.stroke, sw.joints, self._n, active) if active
                  else self._base)
        self.basic.set_tables(tables)
        if self.feedback is not None:
            self.feedback.rebase(tables)
        self.history.append({"t": float(data.time), "speed": speed,
                             **{f"{k}_error_deg": math.degrees(v) for k, v in errors.items()},
                             **w})
        return w

    def _hold_speed(self, data: mujoco.MjData) -> None:
        """Set the next cycle's stroke rate for the speed asked: at the first cycle from
        the stroke's full speed (the table's fastest), then from the speed of the cycle
        just swum (horizontal, centre of mass): distance per stroke hardly changes with the
        rate, so speed ~ rate, corrected by (asked / swum)^SPEED_GAIN each cycle."""
        t = float(data.time)
        xy = data.subtree_com[self.root][:2].copy()
        b = self.basic
        full = float(np.max(self.table.speeds))
        asked = self.speed if self.plan is None else \
            float(self.plan.asked_speed(xy, t, self.speed if self.speed is not None else full))
        self.asked = asked
        if self._last is None:
            rate = self.rate0 * asked / max(full, 0.1)
        else:
            t0, xy0 = self._last
            swum = float(np.linalg.norm(xy - xy0)) / max(t - t0, 1e-6)
            rate = b.rate_hz * (asked / max(swum, 0.05)) ** SPEED_GAIN
        b.rate_hz = float(np.clip(rate, RATE_RANGE[0] * self.rate0, RATE_RANGE[1] * self.rate0))
        self._last = (t, xy)

    def summary(self) -> dict:
        """Per sequence: mean weight and the fraction of cycles it was used."""
        if not self.history:
            return {}
        out = {}
        for name in self.basic.stroke.cycle:
            ws = np.array([h[name] for h in self.history])
            out[name] = {"mean": float(ws.mean()), "used_fraction": float((ws > 0).mean())}
        return out


# ------------------------------------------------------------------ calibration
@dataclass
class CalibrationConfig:
    """What one calibration runs (the journal's identity)."""

    stroke: str
    stroke_sha256: str
    snapshot_cycles: tuple = SNAPSHOT_CYCLES
    weights: tuple = WEIGHTS
    params: dict = field(default_factory=dict)
    #: the layer modes calibrated: "cycle" (basic stroke + sequence) and "all" (the
    #: continuous layer's hand rules and feedback rules running as well)
    layers: tuple = ("cycle", "all")
    #: the continuous layer's settings the "all" tables are made with
    #: (:func:`flapsim.swim.continuous.calibration_settings`)
    hand_rules: dict = field(default_factory=lambda: calibration_settings())
    #: cycles each yaw sequence (and the reference) is swum from a snapshot: the
    #: stroke's ``cycle_hold``; pitch and roll sequences are swum one cycle
    hold: int = 1

    def cycles_of(self, seq: str | None) -> int:
        """Cycles job ``seq`` swims (None: the reference)."""
        return self.hold if seq is None or CYCLE_SEQUENCES[seq][0] == "yaw" else 1

    def sequences(self) -> list[str]:
        return [n for n in CYCLE_SEQUENCES if n in load_stroke(self.stroke).cycle]

    def jobs(self) -> list[tuple[str, int, str | None, float]]:
        """(layers, snapshot index, sequence or None = reference, weight)."""
        out: list[tuple[str, int, str | None, float]] = []
        seqs = self.sequences()
        for mode in self.layers:
            for k in range(len(self.snapshot_cycles)):
                out.append((mode, k, None, 0.0))
                out += [(mode, k, s, float(w)) for s in seqs for w in self.weights]
        return out


def _swim_cycle(sw: Swimmer, layer: BasicStrokeLayer, trunk: int, fwd: int, head: int,
                fb: FeedbackLayer | None = None, hands: object | None = None
                ) -> tuple[np.ndarray, np.ndarray]:
    """Swim until the layer's cycle count goes up (running the feedback rules ``fb``, if
    any); (attitude at the end, cycle-mean attitude (yaw circular))."""
    m, d = sw.model, sw.data
    dt = m.opt.timestep
    c0 = layer.cycles
    every = max(1, int(round(0.02 / dt)))
    atts = []
    i = 0

    while layer.cycles == c0:
        if i % every == 0:
            sw.update_flow()
            if fb is not None:
                fb.update(d)
            if hands is not None:
                hands.update(d)
            atts.append(attitude(d, trunk, fwd, head))
        layer.apply(d, dt)
        mujoco.mj_step(m, d)
        i += 1
        if i % 500 == 0:
            check_diverged(m, d)
    check_diverged(m, d)
    a = np.asarray(atts)
    mean = np.array([math.atan2(np.sin(a[:, 0]).mean(), np.cos(a[:, 0]).mean()),
                     a[:, 1].mean(), a[:, 2].mean()])
    return attitude(d, trunk, fwd, head), mean


class CalibrationWorker:
    """A :class:`~flapsim.core.parallel.ChunkExecutor` worker: builds the swimmer and the
    starting states once, then runs jobs by index."""

    def __init__(self, config: CalibrationConfig) -> None:
        self.config = config
        self.stroke = load_stroke(config.stroke)
        self.sw = Swimmer(SwimmerParams(**config.params))
        self.layer = BasicStrokeLayer(self.sw, self.stroke)
        self.base = self.layer.base_tables
        self.trunk = self.sw.body[ATTITUDE_BODY]
        self.head = self.sw.body[ATTITUDE_HEAD]
        self.fwd = 2 if self.stroke.posture == "prone" else 0
        self.jobs = config.jobs()
        sw, layer = self.sw, self.layer
        sw.reset(self.stroke.posture, qpos_joints=layer.start_pose(0.0))
        # a stroke with balance rules (treading water) swims with them: without them it
        # tips over within a few cycles and no turn could be measured
        self.fb = FeedbackLayer(layer) if self.stroke.perturbations else None

        self.hands = HandRules(layer)
        layer.extra_on = False
        spec = mujoco.mjtState.mjSTATE_INTEGRATION
        self._spec = spec
        #: per layer mode: the states at the snapshot cycles of straight swimming from
        #: rest with that mode's layers (the "all" tables start from swimming with the
        #: hand rules on, as the continuous layer swims)
        self.snaps: dict[str, list[tuple]] = {}
        for mode in config.layers:
            sw.reset(self.stroke.posture, qpos_joints=layer.start_pose(0.0))
            layer.phase, layer.cycles = 0.0, 0
            layer.set_tables(self.base)
            if self.fb is not None:
                self.fb.reset()
            hands = self.hands if mode == "all" else None
            self._rules_off()
            layer.extra_on = hands is not None
            snaps = self.snaps[mode] = []
            with sw:
                for k in range(max(config.snapshot_cycles) + 1):
                    if k in config.snapshot_cycles:
                        st = np.empty(mujoco.mj_stateSize(sw.model, spec))
                        mujoco.mj_getState(sw.model, sw.data, st, spec)
                        fbw = dict(self.fb.weights) if self.fb is not None else {}
                        offs = [h["off"].copy() for h in self.hands.hands]
                        snaps.append((st, layer.phase, layer.cycles, fbw, offs, layer.extra.copy()))
                    _swim_cycle(sw, layer, self.trunk, self.fwd, self.head, self.fb, hands)
            layer.extra_on = False

    def _rules_off(self) -> None:
        self.layer.extra[:] = 0.0
        for h in self.hands.hands:
            h["off"][:] = 0.0
        self.hands.t_last = None

    def header(self) -> dict:
        return {"flapsim_version": __version__, "config": asdict(self.config)}

    def run_job(self, i: int) -> dict:
        mode, k, seq, w = self.jobs[i]
        st, phase, cycles, fbw, offs, extra = self.snaps[mode][k]
        sw, layer = self.sw, self.layer
        mujoco.mj_setState(sw.model, sw.data, st, self._spec)
        mujoco.mj_forward(sw.model, sw.data)
        layer.phase, layer.cycles = phase, cycles
        tables = self.base if seq is None else \
            stroke_tables(self.stroke, sw.joints, self.base.q.shape[0], {seq: w})
        layer.set_tables(tables)
        if self.fb is not None:
            self.fb.rebase(tables)
            self.fb.weights = dict(fbw)
            self.fb._last_t = None
        hands = self.hands if mode == "all" else None
        self._rules_off()
        if hands is not None:
            for h, o in zip(self.hands.hands, offs, strict=True):
                h["off"][:] = o
            layer.extra[:] = extra
            self.hands.t_last = float(sw.data.time)
        layer.extra_on = hands is not None
        start = attitude(sw.data, self.trunk, self.fwd, self.head)
        speed = float(np.linalg.norm(sw.com_velocity()))
        ends, means = [], []
        with sw:
            for _ in range(self.config.cycles_of(seq)):
                end, m = _swim_cycle(sw, layer, self.trunk, self.fwd, self.head, self.fb, hands)
                ends.append(end.tolist())
                means.append(m)
        mean = means[0]  # the first cycle's (the reference's offsets are one cycle's)
        layer.set_tables(self.base)
        layer.extra_on = False
        out = {"i": i, "layers": mode, "snapshot": k, "sequence": seq, "weight": w,
               "speed": speed, "start": start.tolist(), "end": ends[0], "mean": mean.tolist()}
        if len(ends) > 1:
            out["ends"] = ends
        return out

    def run_chunk(self, start: int, stop: int) -> list[dict]:
        return [self.run_job(i) for i in range(start, stop)]


def _assemble(config: CalibrationConfig, results: dict[int, dict], header: dict,
              mode: str) -> CycleTable:
    seqs = config.sequences()
    nk = len(config.snapshot_cycles)
    results = {i: r for i, r in results.items() if r["layers"] == mode}
    ref = {r["snapshot"]: r for r in results.values() if r["sequence"] is None}
    speeds = np.array([ref[k]["speed"] for k in range(nk)])
    order = np.argsort(speeds)
    angles = {s: np.zeros((nk, len(config.weights))) for s in seqs}
    for r in results.values():
        if r["sequence"] is None:
            continue
        axis, sign = CYCLE_SEQUENCES[r["sequence"]]
        j = ("yaw", "pitch", "roll").index(axis)
        n = config.cycles_of(r["sequence"])
        if n > 1:  # held: the mean turn per cycle after the first
            e, e0 = r["ends"][n - 1][j], r["ends"][0][j]
            f, f0 = ref[r["snapshot"]]["ends"][n - 1][j], ref[r["snapshot"]]["ends"][0][j]
            d = (wrap_angle(e - e0) - wrap_angle(f - f0)) / (n - 1)
        else:
            d = r["end"][j] - ref[r["snapshot"]]["end"][j]
        if axis == "yaw":
            d = wrap_angle(d)
        angles[r["sequence"]][r["snapshot"], config.weights.index(r["weight"])] = sign * d
    offsets = np.zeros((nk, 3))
    level = np.zeros((nk, 2))
    for k in range(nk):
        s, m = np.asarray(ref[k]["start"]), np.asarray(ref[k]["mean"])
        offsets[k] = [wrap_angle(s[0] - m[0]), s[1] - m[1], s[2] - m[2]]
        level[k] = m[1:]
    # speeds must increase for interpolation: nudge ties (two snapshots at rest)
    sp = speeds[order]
    for i in range(1, len(sp)):
        sp[i] = max(sp[i], sp[i - 1] + 1e-3)
    # the table records which stroke it was made from by the file's place in the package
    # (bundled strokes) so that a table reads the same on every machine; the hash identifies it
    header = {**header, "config": {**header.get("config", {}),
                                   "stroke": portable_stroke_name(config.stroke)}}
    prov = {**header, "stroke_sha256": config.stroke_sha256,
            "swimmer_params": asdict(SwimmerParams(**config.params)),
            "method": "one cycle from the state at each snapshot cycle start of straight "
                      "swimming from rest with the same layers, still water; turn = attitude "
                      "at the cycle's end minus the unperturbed cycle's" + (
                          "" if config.hold == 1 else
                          f"; yaw sequences held {config.hold} cycles, turn = the mean per "
                          "cycle after the first, minus the unperturbed cycles'"),
            "snapshot_cycles": list(config.snapshot_cycles)}
    return CycleTable(load_stroke(config.stroke).name, sp, np.asarray(config.weights, float),
                      {s: a[order] for s, a in angles.items()}, offsets[order], level[order], prov)


def portable_stroke_name(path: str | os.PathLike) -> str:
    """A bundled stroke file's path inside the package (``flapsim/swim/data/strokes/...``,
    the same on every machine); any other file's resolved path."""
    p = Path(path).resolve()
    try:
        return (Path("flapsim/swim/data/strokes") / p.relative_to(STROKE_DIR)).as_posix()
    except ValueError:
        return str(p)


def _finite_numbers(v: object) -> bool:
    """Whether ``v`` is a non-empty list of finite numbers (not booleans)."""
    return isinstance(v, list) and bool(v) and all(
        isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x) for x in v)


def _job_problem(r: object, jobs: list, cycles: Callable[[str | None], int]) -> str | None:
    """Why ``r`` is not the result of one of ``jobs``, or None; ``cycles(sequence)``: the
    cycles its job swims (:meth:`CalibrationConfig.cycles_of`: a held job records each
    cycle's end)."""
    if not isinstance(r, dict):
        return "a result is not a JSON object"
    i = r.get("i")
    if type(i) is not int or not 0 <= i < len(jobs):
        return f"result index {i!r} is not one of the {len(jobs)} cycles"
    if [r.get("layers"), r.get("snapshot"), r.get("sequence"), r.get("weight")] != \
            json.loads(json.dumps(list(jobs[i]))):
        return f"result {i} is not of cycle {i}'s job"
    for key in ("start", "end", "mean"):
        if not _finite_numbers(r.get(key)):
            return f"result {i} has no finite {key!r} numbers"
    n = cycles(jobs[i][2])
    if n > 1:
        ends = r.get("ends")
        if not (isinstance(ends, list) and len(ends) == n and all(map(_finite_numbers, ends))):
            return f"result {i} has no finite 'ends' numbers for its {n} cycles"
    return None


def _read_journal(path: Path, header: dict, jobs: list,
                  cycles: Callable[[str | None], int] = lambda seq: 1) -> dict[int, dict]:
    """Finished jobs from a journal started with the same ``header``; a journal of another
    run is an error. A line that holds no finished jobs (torn by an interruption, or edited)
    is skipped with a warning naming the file and line: its jobs are run again."""
    done: dict[int, dict] = {}
    lines = read_regular(path, "calibration journal").decode("utf-8", "replace").splitlines()
    if not lines:
        return done
    try:
        first = json.loads(lines[0])
    except ValueError:
        first = None
    if not isinstance(first, dict) or "header" not in first:
        raise DataFileError(f"{path}: not a calibration journal; delete it to start over")
    if first.get("header") != json.loads(json.dumps(header)):
        raise InputError(f"{path} belongs to another calibration (other stroke file, settings or "
                         "flapsim version); delete it to start over")
    for n, line in enumerate(lines[1:], start=2):
        try:
            rec = json.loads(line)
        except ValueError:
            rec, problem = None, "not JSON (torn by an interrupted write?)"
        else:
            results = rec.get("results") if isinstance(rec, dict) else None
            problem = None if isinstance(results, list) else "no list of results"
            for r in results if problem is None else ():
                problem = _job_problem(r, jobs, cycles)
                if problem:
                    break
        if problem is not None:
            log.warning("%s line %d: %s; its cycles are run again", path, n, problem)
            continue
        for r in rec["results"]:
            done[r["i"]] = r
    return done


def calibrate(stroke: str, out: str | os.PathLike | None = None, workers: int = 1,
              params: dict | None = None, snapshot_cycles: tuple = SNAPSHOT_CYCLES,
              weights: tuple = WEIGHTS, progress: bool = False, chunk_size: int = 4
              ) -> tuple[dict[str, CycleTable], Path]:
    """Pre-simulate ``stroke``'s per-cycle sequences and write its tables, one per layer
    mode (default: next to the stroke file). Re-running after an interruption resumes
    from the journal."""

    st = load_stroke(stroke)
    if not st.cycle:
        raise InputError(f"stroke {st.name!r} has no [cycle.*] sequences to calibrate")
    if workers < 1:
        raise InputError("workers must be >= 1")
    if not snapshot_cycles or any(int(c) != c or c < 0 for c in snapshot_cycles):
        raise InputError("snapshot cycles must be whole numbers >= 0")
    if not weights or any(not (0 < w <= 1) for w in weights):
        raise InputError("calibration weights must be in (0, 1]")
    out_p = Path(out) if out is not None else table_path(
        st, (params or {}).get("body_shape", "box"), for_writing=True)
    if out is None:
        out_p.parent.mkdir(parents=True, exist_ok=True)
    problem = steering_problem(st.cycle_hold, st.cycle_gain, st.cycle_lead)
    if problem:
        raise InputError(f"stroke {st.name!r}: {problem}")
    config = CalibrationConfig(str(Path(st.path).resolve()), stroke_hash(st),
                               tuple(int(c) for c in sorted(set(snapshot_cycles))),
                               tuple(float(w) for w in sorted(set(weights))), dict(params or {}),
                               hold=st.cycle_hold)
    jobs = config.jobs()
    journal = out_p.with_name(out_p.name + ".partial.jsonl")

    ident = {"flapsim_version": __version__, "config": asdict(config)}
    done = _read_journal(journal, ident, jobs, config.cycles_of) if journal.exists() else {}
    todo = [i for i in range(len(jobs)) if i not in done]
    # contiguous runs of todo indices, chunk_size at most
    chunks = []
    i = 0
    while i < len(todo):
        j = i
        while j + 1 < len(todo) and todo[j + 1] == todo[j] + 1 and j + 1 - i < chunk_size:
            j += 1
        chunks.append((todo[i], todo[j] + 1))
        i = j + 1

    if not journal.is_file():
        journal.write_text(json.dumps({"header": ident}) + "\n")
    with tqdm(total=len(jobs), initial=len(done), unit="cycle", desc=f"calibrating {st.name}",
              disable=not progress) as bar:
        if chunks:
            with ChunkExecutor(CalibrationWorker, config, workers=min(workers, len(chunks))) as ex, \
                    journal.open("a") as fj:
                for res in ex.map_unordered(chunks):
                    fj.write(json.dumps({"results": res}) + "\n")
                    fj.flush()
                    for r in res:
                        done[int(r["i"])] = r
                    bar.update(len(res))
    missing = [i for i in range(len(jobs)) if i not in done]
    if missing:  # a table assembled without them would hold zeros for their cycles

        raise WorkerError(f"no result came back for {len(missing)} of {len(jobs)} calibration "
                          f"cycles; run the same command again to resume ({journal} keeps the rest)")
    tables = {mode: _assemble(config, done, ident, mode) for mode in config.layers}
    first = tables[config.layers[0]]
    write_json(out_p, {"schema": SCHEMA, "stroke": first.stroke, "provenance": first.provenance,
                       "layers": {m: {k: v for k, v in t.to_dict().items() if k != "provenance"}
                                  for m, t in tables.items()}})
    journal.unlink(missing_ok=True)
    return tables, out_p
