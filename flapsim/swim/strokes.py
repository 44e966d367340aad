"""Stroke files: per-joint keyframed pose cycles (the paper's pose control graph).

A stroke is a TOML file (``flapsim/swim/data/strokes/<name>.toml``, or any path) that keys
each joint's anatomical angles separately over one cycle (phase 0..1), as the paper
does ("key poses are defined for each joint separately"), in degrees::
    name = "breaststroke"
    period_s = 1.4            # cycle time at the default stroke rate
    posture = "prone"         # starting posture: prone (face down) or upright
    interpolation = "pchip"   # pchip (smooth, no overshoot) or linear

    [pose]                    # constant angles for dofs that are not keyed
    "ankle_l.plantar" = 60

    [keys.shoulder_l]         # [[phase, degrees], ...] per anatomical dof
    flex = [[0.0, 178], [0.3, 110], [0.6, 178]]

    [mirror]                  # copy a joint to the other side, shifted in phase
    shoulder_r = { from = "shoulder_l", shift = 0.0 }   # (scale = -1: opposite angles)

    [perturb.lean]            # optional: a perturbation the feedback layer weighs
    description = "scull further forwards (w > 0) or backwards (w < 0)"
    feedback = { tilt_x = 6.0 }   # w = bias + sum(gain * signal), clipped to -1..1
    [perturb.lean.keys.shoulder_l]  # offsets [deg] added to the keys at weight w = 1
    flex = [[0.0, 10], [0.5, -10]]

Perturbations are named offset cycles (mirrored like the keys) blended into the
stroke with weights that a feedback rule sets from the swimmer's state 50 times a
second (signals: :data:`flapsim.swim.feedback.SIGNALS`): continuous-layer rules such as
treading water's balance.

The paper's per-cycle layer (its sec. 4.3) uses up to six sequences, offsets relative to
the basic stroke like the perturbations but without a feedback rule, named by the
rotation they make::
    [cycle.yaw_left]          # pitch_up, pitch_down, yaw_left, yaw_right,
    description = "..."       # roll_left (left side down), roll_right
    [cycle.yaw_left.keys.neck]
    bend = [[0.0, 40]]

``hand_rule_phases = [[0.0, 0.4]]`` (top level, optional) limits the continuous layer's
hand rules to those parts of the cycle (default: all of it); a table limits each rule
on its own (a rule it does not name acts all cycle)::
    hand_rule_phases = { palm = [[0.1, 0.4]], reach = [[0.0, 0.4]] }

``hand_rule_aim = 5.0`` (top level, optional, prone strokes) turns the hand rules'
desired direction from the body line towards a target's aim by this times the aim's
bearing (at most 90 deg; default 0: forwards).

Three top-level settings (optional) shape the per-cycle layer's steering, for a body whose
turn keeps building for cycles after a yaw sequence starts (docs/design/swimming.md, "A turn
that builds up: the held calibration")::
    cycle_hold = 3      # the calibration holds each yaw sequence this many cycles and
                        # records the mean turn per cycle after the first (default 1)
    cycle_gain = 0.5    # times the heading error asked of one cycle (default 1)
    cycle_lead = 1      # aim at the heading this many cycles ahead at the last cycle's
                        # turn rate (default 0: the heading now)

At the start of every cycle :class:`flapsim.swim.per_cycle.CycleLayer` scales them by
weights read from the stroke's calibration table (``<name>.cycle.json``, made by
``flapsim swim --calibrate``).

Anatomical dofs (standing frame: x anterior, y left, z up; positive as named):
lumbar/thoracic/neck: flex (forward), bend (to the left), twist (to the left);
shoulder_*/hip_*: flex (limb forward), abd (limb out), rot (internal rotation);
elbow_*: flex, pronation (0 = palm facing the body); wrist_*: flex (towards the palm);
knee_*: flex; ankle_*: plantar (toes down), inversion (sole inwards).
A ball joint's target is the rotation flex (about the side axis), then abduction
(about the new forward axis), then rotation (about the limb's own axis).
"""

from __future__ import annotations

import tomllib
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from scipy.interpolate import PchipInterpolator

from flapsim.core.errors import DataFileError, InputError
from flapsim.core.validate import require_finite
from flapsim.swim.feedback import SIGNALS
from flapsim.swim.model import JointInfo

STROKE_DIR = Path(__file__).resolve().parent / "data" / "strokes"
STROKES = ("breaststroke", "crawl", "treading")
#: the largest key angle a stroke file may give, deg (a windmilling arm needs one turn)
MAX_KEY_DEG = 1080.0
#: the continuous layer's hand rules (:mod:`flapsim.swim.continuous`)
HAND_RULES = ("palm", "reach")
#: the per-cycle layer's sequence names -> (rotation axis, sign of the change it makes
#: in the angle of :func:`flapsim.swim.per_cycle.attitude`: yaw + = left, pitch + = up,
#: roll + = left side up)
CYCLE_SEQUENCES: dict[str, tuple[str, int]] = {
    "yaw_left": ("yaw", 1), "yaw_right": ("yaw", -1),
    "pitch_up": ("pitch", 1), "pitch_down": ("pitch", -1),
    "roll_left": ("roll", -1), "roll_right": ("roll", 1),
}

_BALL_LIMB = ("flex", "abd", "rot")
#: anatomical joint -> (kind, mujoco joint(s), dof names, signs)
ANATOMY: dict[str, tuple] = {
    "lumbar": ("ball", "lumbar", ("flex", "bend", "twist"), (1, -1, 1)),
    "thoracic": ("ball", "thoracic", ("flex", "bend", "twist"), (1, -1, 1)),
    "neck": ("ball", "neck", ("flex", "bend", "twist"), (1, -1, 1)),
}
for _s, _sign in (("l", 1), ("r", -1)):
    # flexion turns a hanging limb forward: a rotation about -y on both sides
    ANATOMY[f"shoulder_{_s}"] = ("ball", f"shoulder_{_s}", _BALL_LIMB, (-1, _sign, -_sign))
    ANATOMY[f"hip_{_s}"] = ("ball", f"hip_{_s}", _BALL_LIMB, (-1, _sign, -_sign))
    ANATOMY[f"elbow_{_s}"] = ("hinge", {"flex": f"elbow_flex_{_s}",
                                        "pronation": f"elbow_pron_{_s}"})
    ANATOMY[f"wrist_{_s}"] = ("hinge", {"flex": f"wrist_{_s}"})
    ANATOMY[f"knee_{_s}"] = ("hinge", {"flex": f"knee_{_s}"})
    ANATOMY[f"ankle_{_s}"] = ("hinge", {"plantar": f"ankle_flex_{_s}",
                                        "inversion": f"ankle_inv_{_s}"})


def dof_names() -> list[str]:
    """Every ``joint.dof`` a stroke file may key."""
    out = []
    for joint, spec in ANATOMY.items():
        dofs = spec[2] if spec[0] == "ball" else tuple(spec[1])
        out += [f"{joint}.{d}" for d in dofs]
    return out


@dataclass(frozen=True)
class Perturbation:
    """A named offset cycle [deg per dof] that a feedback layer blends into a stroke."""

    name: str
    #: ``joint.dof`` -> keyframes as in :attr:`Stroke.keys` (offsets, mirrored)
    keys: dict
    #: feedback rule: signal name -> gain (weight per unit signal)
    gains: dict = field(default_factory=dict)
    #: weight with every signal at zero
    bias: float = 0.0
    description: str = ""
    #: time constant of a first-order low-pass on the weight [s] (0 = none): lets a
    #: rule ignore what swings within a stroke cycle (a crawler's yaw with each arm)
    smooth_s: float = 0.0


@dataclass(frozen=True)
class Stroke:
    """A parsed stroke file: one periodic curve (degrees over phase) per anatomical dof."""

    #: stroke name
    name: str
    #: cycle time at the default stroke rate [s]
    period_s: float
    #: starting posture ("prone" or "upright")
    posture: str
    #: "pchip" or "linear"
    interpolation: str
    #: ``joint.dof`` -> (phases, degrees[, turn]) keyframes, phases in [0, 1); ``turn``
    #: [deg, a multiple of 360] is what the angle gains per cycle (default 0)
    keys: dict
    #: free text: what the stroke is based on
    description: str = ""
    #: file it came from
    path: str = ""
    #: named perturbations with feedback rules (continuous layer), may be empty
    perturbations: dict = field(default_factory=dict)
    #: the per-cycle layer's sequences (:data:`CYCLE_SEQUENCES` names), may be empty
    cycle: dict = field(default_factory=dict)
    #: per hand rule (:data:`HAND_RULES`): the phase intervals [start, end) of the cycle
    #: in which the continuous layer applies it (:mod:`flapsim.swim.continuous`); a rule
    #: not named here acts all cycle
    hand_rule_phases: dict = field(default_factory=dict)
    #: prone strokes with a target: the hand rules' desired direction turns from the
    #: body line towards the aim by this times the aim's bearing (at most 90 deg); 0:
    #: forwards (:meth:`flapsim.swim.continuous.HandRules.direction`)
    hand_rule_aim: float = 0.0
    #: cycles each yaw sequence is held in the calibration; the table records the mean
    #: turn per cycle after the first (1: the one cycle swum, the paper's calibration)
    cycle_hold: int = 1
    #: factor on the heading error the per-cycle layer asks of one cycle [-]
    cycle_gain: float = 1.0
    #: cycles ahead the per-cycle layer aims: the heading compared with the target's is
    #: the one measured plus this times the last cycle's turn [cycles]
    cycle_lead: float = 0.0

    def rule_acts(self, rule: str, phase: float) -> bool:
        """Whether the hand rule ``rule`` acts at ``phase`` (:attr:`hand_rule_phases`)."""
        phases = self.hand_rule_phases.get(rule)
        return not phases or any(a <= phase < b for a, b in phases)

    @property
    def rate_hz(self) -> float:
        """Default stroke rate [cycles/s]."""
        return 1.0 / self.period_s

    def curve(self, dof: str, phase: np.ndarray, weights: dict | None = None) -> np.ndarray:
        """Angle [deg] of ``joint.dof`` at the given phases (periodic), plus each named
        perturbation's offset times its weight in ``weights``."""
        out = _curve(self.keys.get(dof), phase, self.interpolation)
        for name, w in (weights or {}).items():
            if w != 0.0:
                p = self.perturbations.get(name) or self.cycle[name]
                out = out + w * _curve(p.keys.get(dof), phase, self.interpolation)
        return out


def _curve(key: tuple | None, phase: np.ndarray, interpolation: str) -> np.ndarray:
    """A keyed periodic curve [deg] at ``phase``; zero where there are no keys."""
    ph, val, turn = _unpack(key if key is not None else (np.zeros(1), np.zeros(1)))
    x = np.mod(np.asarray(phase, dtype=float), 1.0)
    if len(ph) == 1:
        return np.full_like(x, val[0])
    # periodic up to whole turns: f(x + 1) = f(x) + turn (a limb circling its joint)
    xs = np.concatenate([ph - 1.0, ph, ph + 1.0])
    ys = np.concatenate([val - turn, val, val + turn])
    if interpolation == "linear":
        return np.interp(x, xs, ys)
    return PchipInterpolator(xs, ys)(x)


def stroke_path(name_or_path: str) -> Path:
    """A bundled stroke by name, or a TOML file path."""
    p = Path(name_or_path)
    if p.suffix == ".toml":
        if not p.exists():
            raise DataFileError(f"stroke file {p} does not exist")
        return p
    q = STROKE_DIR / f"{name_or_path}.toml"
    if not q.exists():
        avail = sorted(x.stem for x in STROKE_DIR.glob("*.toml"))
        raise InputError(f"unknown stroke {name_or_path!r}; choose one of {', '.join(avail)} "
                         "or give a .toml file")
    return q


def stroke_for_body(name_or_path: str, body_shape: str = "box") -> str:
    """The stroke to swim on ``body_shape``: a bundled stroke's own tuning for that body
    (``data/strokes/<body_shape>/<name>.toml``) where there is one, else ``name_or_path``
    itself (a stroke file is swum as given)."""
    if body_shape == "box" or Path(name_or_path).suffix == ".toml":
        return name_or_path
    q = STROKE_DIR / body_shape / f"{name_or_path}.toml"
    return str(q) if q.is_file() else name_or_path


def _pairs(where: str, raw: object) -> tuple[np.ndarray, np.ndarray]:
    try:
        arr = np.asarray(raw, dtype=float)
    except (TypeError, ValueError):
        raise DataFileError(f"{where}: keys must be [[phase, degrees], ...]") from None
    if arr.ndim != 2 or arr.shape[1] != 2 or arr.shape[0] < 1 or not np.all(np.isfinite(arr)):
        raise DataFileError(f"{where}: keys must be a non-empty list of [phase, degrees] pairs")
    big = arr[np.abs(arr[:, 1]) > MAX_KEY_DEG, 1]
    if big.size:
        raise DataFileError(f"{where}: a key of {big[0]:g} deg: angles are degrees within "
                            f"+-{MAX_KEY_DEG:g}")
    outside = arr[(arr[:, 0] < 0.0) | (arr[:, 0] > 1.0), 0]
    if outside.size:
        raise DataFileError(f"{where}: a key at phase {outside[0]:g}: phases are fractions of "
                            "the cycle, 0..1")
    turn = 0.0
    at_one = np.abs(arr[:, 0] - 1.0) < 1e-12
    if np.any(at_one):
        # a key at phase 1 closes a cycle that gains whole turns (a crawl arm's windmill)
        at_zero = np.abs(arr[:, 0]) < 1e-12
        if not np.any(at_zero):
            raise DataFileError(f"{where}: a key at phase 1 needs a key at phase 0")
        turn = float(arr[at_one, 1][0] - arr[at_zero, 1][0])
        if abs(turn / 360.0 - round(turn / 360.0)) > 1e-9:
            raise DataFileError(f"{where}: the phase-1 key must differ from the phase-0 key by "
                                f"whole turns (360 deg), got {turn:g}")
        arr = arr[~at_one]
    ph = np.mod(arr[:, 0], 1.0)
    order = np.argsort(ph, kind="stable")
    ph, val = ph[order], arr[order, 1]
    if np.any(np.diff(ph) <= 1e-9):
        raise DataFileError(f"{where}: two keys at the same phase")
    return ph, val, turn


def _unpack(key: tuple) -> tuple[np.ndarray, np.ndarray, float]:
    """(phases, degrees, turn per cycle) from a stored key (turn 0 when absent)."""
    return (key[0], key[1], key[2]) if len(key) == 3 else (key[0], key[1], 0.0)


def _shifted(key: tuple, shift: float) -> tuple[np.ndarray, np.ndarray, float]:
    """The curve g(x) = f(x - shift): keys move by ``shift``; those that wrap past the
    cycle end lose one turn."""
    ph, val, turn = _unpack(key)
    x = ph + shift
    wraps = np.floor(x)
    x = x - wraps
    val = val - wraps * turn
    order = np.argsort(x, kind="stable")
    return x[order], val[order], turn


def load_stroke(name_or_path: str) -> Stroke:
    """Parse and check a stroke file (one-line errors naming the bad entry)."""
    path = stroke_path(name_or_path)
    try:
        data = path.read_bytes()
    except OSError as exc:
        raise DataFileError(f"cannot read stroke file {path}: {exc.strerror or exc}") from None
    if b"\0" in data:
        raise DataFileError(f"{path}: a binary file, not a TOML stroke file")
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise DataFileError(f"{path}: not UTF-8 text (byte {exc.start}); save it as UTF-8") from None
    try:
        raw = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise DataFileError(f"{path}: not valid TOML ({exc})") from None
    return parse_stroke(raw, path)


def parse_stroke(raw: dict, path: str | Path = "<stroke>") -> Stroke:
    """A :class:`Stroke` from the parsed contents of a stroke file (a dict laid out as
    the TOML files are); ``path`` names it in error messages."""
    require_finite(raw, path)
    valid = set(dof_names())
    try:
        period = float(raw.get("period_s", 1.0))
    except (TypeError, ValueError):
        raise DataFileError(f"{path}: period_s must be a number of seconds") from None
    if not (0.2 <= period <= 10.0):
        raise DataFileError(f"{path}: period_s must be 0.2..10 s, got {period}")
    posture = raw.get("posture", "prone")
    if posture not in ("prone", "upright"):
        raise DataFileError(f"{path}: posture must be 'prone' or 'upright', got {posture!r}")
    interp = raw.get("interpolation", "pchip")
    if interp not in ("pchip", "linear"):
        raise DataFileError(f"{path}: interpolation must be 'pchip' or 'linear'")
    for section in ("pose", "keys", "mirror", "perturb"):
        if not isinstance(raw.get(section, {}), dict):
            raise DataFileError(f"{path}: [{section}] must be a table, got "
                                f"{type(raw[section]).__name__}")
    keys: dict[str, tuple] = {}
    for dof, value in raw.get("pose", {}).items():
        if dof not in valid:
            raise DataFileError(f"{path}: [pose] names unknown dof {dof!r}; valid: "
                                f"{', '.join(sorted(valid))}")
        if isinstance(value, bool) or not isinstance(value, int | float) \
                or not np.isfinite(value) or abs(value) > MAX_KEY_DEG:
            raise DataFileError(f"{path}: [pose] {dof} must be an angle in degrees within +-{MAX_KEY_DEG:g}, "
                                f"got {value!r}")
        keys[dof] = (np.zeros(1), np.array([float(value)]))
    mirror = raw.get("mirror", {})
    keys = _parse_keys(raw.get("keys", {}), mirror, path, "keys", keys)
    if not keys:
        raise DataFileError(f"{path}: no keys: a stroke needs [pose] angles or [keys.<joint>] "
                            "key lists (see the bundled strokes in flapsim/swim/data/strokes/)")
    perturbations = {}
    for name, spec in raw.get("perturb", {}).items():
        perturbations[name] = _parse_perturbation(name, spec, mirror, path)
    cycle = {}
    table = raw.get("cycle", {})
    if not isinstance(table, dict):
        raise DataFileError(f"{path}: [cycle] must be a table of sequences")
    for name, spec in table.items():
        if name not in CYCLE_SEQUENCES:
            raise DataFileError(f"{path}: unknown per-cycle sequence [cycle.{name}]; valid: "
                                f"{', '.join(CYCLE_SEQUENCES)}")
        if isinstance(spec, dict) and ("feedback" in spec or "smooth_s" in spec):
            raise DataFileError(f"{path}: [cycle.{name}] takes keys, mirror and description; "
                                "its weights come from the calibration table, not a feedback rule")
        cycle[name] = _parse_perturbation(name, spec, mirror, path, section="cycle")
    clash = set(cycle) & set(perturbations)
    if clash:
        raise DataFileError(f"{path}: {sorted(clash)} named both in [perturb] and [cycle]")
    return Stroke(str(raw.get("name", Path(path).stem)), period, posture, interp, keys,
                  str(raw.get("description", "")), str(path), perturbations, cycle,
                  _parse_phases(raw.get("hand_rule_phases", []), path),
                  _parse_aim(raw.get("hand_rule_aim", 0.0), path),
                  *_parse_steering(raw, path))


#: bounds of the per-cycle steering settings (what a stroke file may ask)
CYCLE_HOLD_MAX = 10
CYCLE_GAIN_RANGE = (0.05, 5.0)
CYCLE_LEAD_MAX = 5.0


def steering_problem(hold: object, gain: object, lead: object) -> str | None:
    """What is wrong with the per-cycle steering settings :attr:`Stroke.cycle_hold`,
    :attr:`Stroke.cycle_gain`, :attr:`Stroke.cycle_lead` (None: nothing)."""
    if isinstance(hold, bool) or not isinstance(hold, int) or not 1 <= hold <= CYCLE_HOLD_MAX:
        return f"cycle_hold must be a whole number of cycles 1..{CYCLE_HOLD_MAX}, got {hold!r}"
    for key, v, (lo, hi) in (("cycle_gain", gain, CYCLE_GAIN_RANGE),
                             ("cycle_lead", lead, (0.0, CYCLE_LEAD_MAX))):
        # NaN fails the range test too
        if isinstance(v, bool) or not isinstance(v, int | float) or not lo <= v <= hi:
            return f"{key} must be a number in [{lo:g}, {hi:g}], got {v!r}"
    return None


def _parse_steering(raw: dict, path: str | Path) -> tuple[int, float, float]:
    """``cycle_hold``, ``cycle_gain`` and ``cycle_lead`` (:func:`steering_problem`)."""
    hold, gain, lead = (raw.get("cycle_hold", 1), raw.get("cycle_gain", 1.0),
                        raw.get("cycle_lead", 0.0))
    problem = steering_problem(hold, gain, lead)
    if problem:
        raise DataFileError(f"{path}: {problem}")
    return hold, float(gain), float(lead)


def _parse_aim(raw: object, path: str | Path) -> float:
    """``hand_rule_aim``: a number >= 0."""
    if isinstance(raw, bool) or not isinstance(raw, int | float) or not 0.0 <= raw <= 10.0:
        raise DataFileError(f"{path}: hand_rule_aim must be a number in [0, 10], got {raw!r}")
    return float(raw)


def _parse_phases(raw: object, path: str | Path) -> dict:
    """``hand_rule_phases``: a list of [start, end] phase pairs, 0 <= start < end <= 1
    (every hand rule), or a table of such lists by rule (:data:`HAND_RULES`)."""
    if isinstance(raw, dict):
        bad = sorted(set(raw) - set(HAND_RULES))
        if bad:
            raise DataFileError(f"{path}: hand_rule_phases names unknown rules {bad}; valid: "
                                f"{', '.join(HAND_RULES)}")
        return {r: _parse_pairs(v, path, f"hand_rule_phases.{r}") for r, v in raw.items()}
    pairs = _parse_pairs(raw, path, "hand_rule_phases")
    return {r: pairs for r in HAND_RULES} if pairs else {}


def _parse_pairs(raw: object, path: str | Path, what: str) -> tuple:
    msg = f"{path}: {what} must be a list of [start, end] phases, 0 <= start < end <= 1"
    if not isinstance(raw, list):
        raise DataFileError(msg)
    out = []
    for pair in raw:
        if not (isinstance(pair, list) and len(pair) == 2
                and all(isinstance(x, int | float) and not isinstance(x, bool) for x in pair)
                and 0.0 <= pair[0] < pair[1] <= 1.0):
            raise DataFileError(f"{msg}, got {pair!r}")
        out.append((float(pair[0]), float(pair[1])))
    return tuple(out)


def _parse_keys(table: object, mirror: dict, path: str | Path, where: str,
                initial: dict | None = None) -> dict:
    """``[keys.<joint>]`` tables (over ``initial``, e.g. the [pose] entries), and the
    mirrored joints, as ``joint.dof`` -> keys."""
    valid = set(dof_names())
    if not isinstance(table, dict):
        raise DataFileError(f"{path}: [{where}] must be a table of joints")
    keys: dict[str, tuple] = dict(initial or {})
    for joint, dofs in table.items():
        if not isinstance(dofs, dict):
            raise DataFileError(f"{path}: [{where}.{joint}] must be a table of dofs")
        for dof, pairs in dofs.items():
            full = f"{joint}.{dof}"
            if full not in valid:
                raise DataFileError(f"{path}: unknown dof {full!r} in [{where}]; valid: "
                                    f"{', '.join(sorted(valid))}")
            keys[full] = _pairs(f"{path} {where}.{full}", pairs)
    for target, spec in mirror.items():
        src = spec.get("from") if isinstance(spec, dict) else None
        if target not in ANATOMY or src not in ANATOMY:
            raise DataFileError(f"{path}: mirror {target} = {spec!r} must name two joints")
        try:
            shift = float(spec.get("shift", 0.0))
            scale = float(spec.get("scale", 1.0))
        except (TypeError, ValueError):
            raise DataFileError(f"{path}: mirror {target}: shift and scale must be numbers"
                                ) from None
        for full in [k for k in list(keys) if k.startswith(src + ".")]:
            dof = full.split(".", 1)[1]
            ph, val, turn = _shifted(keys[full], shift)
            keys[f"{target}.{dof}"] = (ph, scale * val, scale * turn)
    return keys


def _parse_perturbation(name: str, spec: object, mirror: dict, path: str | Path,
                        section: str = "perturb") -> Perturbation:

    where = f"{section}.{name}"
    if not isinstance(spec, dict):
        raise DataFileError(f"{path}: [{where}] must be a table")
    unknown = set(spec) - {"keys", "feedback", "description", "mirror", "smooth_s"}
    if unknown:
        raise DataFileError(f"{path}: [{where}] has unknown entries {sorted(unknown)}; "
                            "allowed: keys, feedback, description, mirror, smooth_s")
    try:
        smooth = float(spec.get("smooth_s", 0.0))
    except (TypeError, ValueError):
        smooth = -1.0
    if not (0.0 <= smooth <= 60.0):
        raise DataFileError(f"{path}: {where}.smooth_s must be 0..60 s")
    # its own [perturb.NAME.mirror] (e.g. scale = -1: the other side does the opposite)
    # replaces the stroke's mirror table for this perturbation
    keys = _parse_keys(spec.get("keys", {}), spec.get("mirror", mirror), path, f"{where}.keys")
    if not keys:
        raise DataFileError(f"{path}: [{where}] needs [{where}.keys.<joint>] offsets")
    for full, key in keys.items():
        if len(key) == 3 and key[2] != 0.0:
            raise DataFileError(f"{path}: {where}.{full}: offsets cannot gain whole turns")
    gains = dict(spec.get("feedback", {}))
    try:
        bias = float(gains.pop("bias", 0.0))
        gains = {k: float(v) for k, v in gains.items()}
    except (TypeError, ValueError):
        raise DataFileError(f"{path}: {where}.feedback gains must be numbers") from None
    bad = [k for k in gains if k not in SIGNALS]
    if bad:
        raise DataFileError(f"{path}: {where}.feedback names unknown signals {bad}; valid: "
                            f"{', '.join(SIGNALS)} (and bias)")
    if not all(np.isfinite(list(gains.values()) + [bias])):
        raise DataFileError(f"{path}: {where}.feedback gains must be finite")
    return Perturbation(name, keys, gains, bias, str(spec.get("description", "")), smooth)


# -- joint targets ---------------------------------------------------------------------
def _quat_axis(axis: int, angle: np.ndarray) -> np.ndarray:
    q = np.zeros((angle.size, 4))
    q[:, 0] = np.cos(angle / 2)
    q[:, 1 + axis] = np.sin(angle / 2)
    return q


def _quat_mul(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    w1, x1, y1, z1 = a.T
    w2, x2, y2, z2 = b.T
    return np.column_stack([
        w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2,
        w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2,
        w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2,
        w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2,
    ])


def ball_quat(flex_deg: np.ndarray, abd_deg: np.ndarray, rot_deg: np.ndarray,
              signs: tuple[int, int, int]) -> np.ndarray:
    """Ball-joint target quaternions (n, 4): about y, then x, then z (intrinsic)."""
    r = np.deg2rad
    qy = _quat_axis(1, signs[0] * r(np.atleast_1d(flex_deg)))
    qx = _quat_axis(0, signs[1] * r(np.atleast_1d(abd_deg)))
    qz = _quat_axis(2, signs[2] * r(np.atleast_1d(rot_deg)))
    return _quat_mul(_quat_mul(qy, qx), qz)


@dataclass(frozen=True)
class StrokeTables:
    """Sampled joint targets over one cycle, in the swimmer's joint order."""

    #: targets (nsamp, nqj): hinge angles [rad], ball quaternions
    q: np.ndarray
    #: phase derivatives (nsamp, nvj): hinge [rad/cycle], ball local angular velocity
    #: [rad/cycle]
    v: np.ndarray
    #: the stroke they came from
    stroke: Stroke


def stroke_tables(stroke: Stroke, joints: JointInfo, nsamp: int = 240,
                  weights: dict | None = None) -> StrokeTables:
    """Sample ``stroke`` (with its perturbations at ``weights``) into per-joint target
    tables for :func:`flapsim.swim.muscles.pd_controls`."""
    phase = np.arange(nsamp) / nsamp
    by_joint: dict[str, np.ndarray] = {}  # mujoco joint -> (nsamp, 1 or 4)
    for joint, spec in ANATOMY.items():
        if spec[0] == "ball":
            _, mj, dofs, signs = spec
            ang = [stroke.curve(f"{joint}.{d}", phase, weights) for d in dofs]
            q = ball_quat(*ang, signs)
            for i in range(1, nsamp):  # one hemisphere, so that nlerp between samples works
                if q[i] @ q[i - 1] < 0:
                    q[i] = -q[i]
            by_joint[mj] = q
        else:
            for dof, mj in spec[1].items():
                by_joint[mj] = np.deg2rad(stroke.curve(f"{joint}.{dof}", phase, weights))[:, None]
    missing = [n for n in joints.names if n not in by_joint]
    if missing:
        raise InputError(f"stroke tables: no anatomy for joints {missing}")
    qcols, vcols = [], []
    for name in joints.names:
        tab = by_joint[name]
        qcols.append(tab)
        if tab.shape[1] == 1:
            vcols.append((np.roll(tab, -1, 0) - np.roll(tab, 1, 0)) * (nsamp / 2.0))
        else:
            # local angular velocity: 2 vec(conj(q) dq/dphase), central differences
            dq = (np.roll(tab, -1, 0) - np.roll(tab, 1, 0)) * (nsamp / 2.0)
            # hemisphere jumps at the wrap
            fix = np.einsum("ij,ij->i", np.roll(tab, -1, 0), np.roll(tab, 1, 0)) < 0
            if np.any(fix):
                nxt = np.roll(tab, -1, 0)
                nxt[fix] *= -1
                dq = (nxt - np.roll(tab, 1, 0)) * (nsamp / 2.0)
            conj = tab * np.array([1, -1, -1, -1])
            vcols.append(2.0 * _quat_mul(conj, dq)[:, 1:])
    return StrokeTables(np.ascontiguousarray(np.hstack(qcols)),
                        np.ascontiguousarray(np.hstack(vcols)), stroke)


def pose_at(tables: StrokeTables, phase: float) -> np.ndarray:
    """Target non-root qpos at a phase (nearest sample; for initial poses and plots)."""
    n = tables.q.shape[0]
    return tables.q[int(round((phase % 1.0) * n)) % n].copy()
