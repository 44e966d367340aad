"""The learned wingbeat controller's tuning: one frozen dataclass, loadable from TOML.

:class:`ControllerConfig` holds what :func:`~flapsim.bird.control.controller.load_controller`
tunes beyond the database, the regression method, k, the mirror images and the way S0 is
found (those are the command line's ``--db``, ``--method``, ``--k``, ``--no-mirror`` and
``--predict``). Its field defaults are the rigid dove's; :meth:`ControllerConfig.for_dove`
gives each dove's own (the modal-feather dove was measured with other values). A TOML file's
``[controller]`` table overrides the fields it names (``flapsim eval|fly|view --config
FILE.toml``; ``flapsim list config`` prints the defaults to copy); in code, override with
:func:`dataclasses.replace`.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from pathlib import Path

from flapsim.bird.control.prediction import PREDICT_MODES
from flapsim.bird.control.regression import DEFAULT_CLIP_REQUEST, DEFAULT_K_DENSE_SHARE
from flapsim.core.config import from_table, read_toml, to_toml
from flapsim.core.errors import InputError

#: The tables of a control configuration file, in order: this module's ``[controller]`` and
#: the path target's ``[path]`` (:class:`flapsim.bird.tasks.config.PathControlConfig`).
TABLES = ("controller", "path")

#: The most simulated corrections per wingbeat (:attr:`ControllerConfig.refine`).
MAX_REFINE = 5

#: What :attr:`ControllerConfig.refine` aims its corrections at and ranks the wingbeats it
#: simulates by (:attr:`ControllerConfig.refine_goal`): ``reachable``, the target with each
#: component's change from P0's end clipped as the request is (the database's [q, 1 - q]
#: quantiles, ``clip_request``), or ``full``, the target itself.
REFINE_GOALS = ("reachable", "full")

#: The learned controller's default :attr:`ControllerConfig.carry`, per dove (docs/design/flight.md,
#: "Carrying the last wingbeat"): measured over five databases each; with modal feathers
#: 0.4 follows the figure of eight closer but survives fewer pushes, so they keep 0.
DEFAULT_CARRY = {"rigid": 0.4, "modal": 0.0}

#: Simulated corrections per wingbeat (:attr:`ControllerConfig.refine`) by dove (docs/design/flight.md,
#: "Wingbeats checked by simulation"): 2 for rigid feathers,
#: measured over five databases at 7 m/s (level circles of 3-8 m both ways followed 31 of 50
#: times against 8; 6 and 8 N pushes from four sides survived 40 of 40 against 36; the suite
#: 17 of 22 against 15 on the bundled database) at half the real-time factor; 0 for modal
#: ones (their bundled database: the same verdicts on 5-8 m circles both ways and 8 N pushes
#: from the left and below, the figure of eight's Ef 0.231 against 0.240 m, at 0.64x the
#: speed).
DEFAULT_REFINE = {"rigid": 2, "modal": 0}

#: :attr:`ControllerConfig.refine_stop` by dove (docs/design/flight.md, "The corrections stop
#: at the first answer near enough"): in cruise the first answer ends 0.03-0.08 from the target
#: and the corrections gain little, so a cruising wingbeat simulates one candidate instead of
#: three; the flight suite's verdicts are those of every correction simulated (0.1 lost the 12 N
#: push from the front). The modal dove has no corrections.
DEFAULT_REFINE_STOP = {"rigid": 0.09, "modal": 0.0}

#: :attr:`ControllerConfig.reference_hz` by dove (docs/design/flight.md, "S0 simulated at
#: 1600 Hz"): the rigid dove's reference wingbeat costs 2/3 of a wingbeat's steps, its S0 off
#: by 1-3 % of the database's spread, the suite's verdicts unchanged; the modal dove's was not
#: measured under its defaults and keeps its flight's rate.
DEFAULT_REFERENCE_HZ = {"rigid": 1600.0, "modal": 0.0}

#: The lowest :attr:`ControllerConfig.reference_hz`, the lowest measured: there S0 misses by
#: 5-10x more than at 1600 Hz and the rising figure of eight is lost (docs/design/flight.md).
MIN_REFERENCE_HZ = 1200.0

#: :attr:`ControllerConfig.refine_goal` by dove. ``reachable`` was measured on the rigid dove
#: and not made its default (docs/design/flight.md, "Corrections aimed at what a wingbeat can
#: reach: not kept": 17 of the 22 scenarios as ``full``, but 8 N rather than 10 N pushes from
#: all six directions, and 76 of 100 user-path starts against 83).
DEFAULT_REFINE_GOAL = {"rigid": "full", "modal": "full"}

#: :attr:`ControllerConfig.lookahead`'s modes.
LOOKAHEAD_MODES = ("auto", "on", "off")
#: :attr:`ControllerConfig.lateral`'s modes.
LATERAL_MODES = ("auto", "on", "off", "banked")
#: The banked lateral regulator's integral scale, deg: the roll error summed over the
#: wingbeats that costs as much as 10 deg of roll now (docs/design/flight.md, "A regulator for
#: a banking dove").
DEFAULT_LATERAL_INTEGRAL_DEG = 40.0
#: The lateral regulator's input cost: the cruise dove completes 8 of the 22 flight scenarios
#: with it, 4 without (docs/design/flight.md, "The lateral wingbeat map, and a once-a-beat
#: regulator on it").
DEFAULT_LATERAL_R = 0.01
#: :attr:`ControllerConfig.longitudinal`'s modes.
LONGITUDINAL_MODES = ("auto", "on", "off")
#: The longitudinal regulator's input cost (docs/design/flight.md, "A longitudinal regulator
#: beside it").
DEFAULT_LONGITUDINAL_R = 0.1


@dataclass(frozen=True)
class ControllerConfig:
    """The wingbeat controller's tuning (defaults: the rigid dove's; :meth:`for_dove`)."""

    carry: float = DEFAULT_CARRY["rigid"]
    """Share 0..1 of the last wingbeat's change from the reference wingbeat that the next one
    starts from (0: the reference every wingbeat, the paper's; docs/flight.md)."""
    refine: int = DEFAULT_REFINE["rigid"]
    """Simulated corrections per wingbeat, 0..5: where the answer would end short of the target
    it is asked again for the shortfall and the nearest is flown (0: flown as answered, the
    paper's; docs/flight.md)."""
    refine_goal: str = DEFAULT_REFINE_GOAL["rigid"]
    """What the corrections aim at and rank by: "full", the target itself, or "reachable", the
    target clipped as clip_request clips the request (measured in docs/flight.md)."""
    refine_stop: float = DEFAULT_REFINE_STOP["rigid"]
    """The corrections stop at the first candidate that ends within this of the target (the
    regression's metric over pitch, roll and velocity; 0: all refine corrections simulated)."""
    reference_hz: float = DEFAULT_REFERENCE_HZ["rigid"]
    """Step rate, Hz, at which the reference wingbeat is simulated for S0 with --predict simulate,
    on a copy of the flight (0: the flight's own rate, the paper's; the wingbeat flown is always
    stepped at the flight's rate; --predict coarse: 1600 whatever this says)."""
    lookahead: str = "auto"
    """Simulate the next wingbeat's reference in a second thread while the corrections run:
    "on", "off" or "auto" (where it can and two cores are free); the same flight to the bit,
    ~1.2x faster with every correction simulated; needs reference_hz = 0."""
    k_dense_share: float = DEFAULT_K_DENSE_SHARE["rigid"]
    """LWLR's neighbours where a request lies among densely packed samples, as a share of the
    samples searched, at most k, growing to k where they are sparse (0: always k, the paper's
    fixed neighbourhood; k-NN: always 0; docs/flight.md)."""
    clip_request: float = DEFAULT_CLIP_REQUEST
    """The regression clips each component of a requested state change to the [q, 1-q] quantiles
    of the database's, a share 0 <= q < 0.5 (0: no clip, the paper's; docs/flight.md)."""
    state_weight: float = 0.0
    """Weight 0..1000 of the wingbeat's start state beside dS in the regression's choice of
    neighbours (0: dS only, the paper's eq. 3; for databases that mix cruise and disturbed pre-
    states)."""
    lateral: str = "auto"
    """The once-a-beat lateral regulator added to each wingbeat's reference (an LQR on the
    lateral wingbeat map measured at load, flapsim.bird.control.lateral): "on", "off" (the
    paper's) or "auto": on for a database sampled around the cruise capture (train --cruise),
    whose dove spirals without it, off otherwise; "banked": the regulator for a banking dove
    (:attr:`lateral_integral_deg`; the cruise dove only, whose turn trims are bundled;
    docs/flight.md)."""
    lateral_r: float = DEFAULT_LATERAL_R
    """The lateral regulator's input cost, > 0 (smaller: stronger; docs/flight.md)."""
    lateral_integral_deg: float = DEFAULT_LATERAL_INTEGRAL_DEG
    """``lateral = "banked"``: the regulator's gains are designed on the lateral maps around
    the dove's turn trims and scheduled on its bank, it sums the roll error over the wingbeats
    (this, deg, costs as much as 10 deg of roll now; > 0), and the learned regression's answer
    is made left-right symmetric: the regulator flies the bank, the regression the rest
    (docs/flight.md)."""
    longitudinal: str = "off"
    """The once-a-beat longitudinal regulator beside it (an LQR on the longitudinal wingbeat
    map, flapsim.bird.control.longitudinal: pitch, forward and normal velocity, pitch rate):
    "on", "off" (the paper's) or "auto", as lateral (docs/flight.md)."""
    longitudinal_r: float = DEFAULT_LONGITUDINAL_R
    """The longitudinal regulator's input cost, > 0 (smaller: stronger)."""

    def __post_init__(self) -> None:
        c = self.carry
        if not (math.isfinite(c) and 0.0 <= c <= 1.0):
            raise InputError(f"controller carry must be a share 0..1, got {c}")
        n = self.refine
        if isinstance(n, bool) or not isinstance(n, int) or not 0 <= n <= MAX_REFINE:
            raise InputError(f"controller refine must be 0..{MAX_REFINE} simulated corrections per "
                             f"wingbeat, got {n!r}")
        if self.refine_goal not in REFINE_GOALS:
            raise InputError(f"controller refine_goal must be one of {', '.join(REFINE_GOALS)}, "
                             f"got {self.refine_goal!r}")
        r = self.refine_stop
        if isinstance(r, bool) or not (math.isfinite(r) and r >= 0.0):
            raise InputError(f"controller refine_stop must be a refine error >= 0 (0: off), got {r!r}")
        h = self.reference_hz
        if isinstance(h, bool) or not (math.isfinite(h) and (h == 0.0 or h >= MIN_REFERENCE_HZ)):
            raise InputError(f"controller reference_hz must be 0 (the flight's own rate) or a step "
                             f"rate of at least {MIN_REFERENCE_HZ:g} Hz, got {h!r}")
        if self.lookahead not in LOOKAHEAD_MODES:
            raise InputError(f"controller lookahead must be one of {', '.join(LOOKAHEAD_MODES)}, "
                             f"got {self.lookahead!r}")
        s = self.k_dense_share
        if not (math.isfinite(s) and 0.0 <= s <= 1.0):
            raise InputError(f"controller k_dense_share must be a share 0..1 (0: off), got {s}")
        q = self.clip_request
        if not (math.isfinite(q) and 0.0 <= q < 0.5):
            raise InputError(f"controller clip_request must be a share 0 <= q < 0.5, got {q}")
        w = self.state_weight
        if not (math.isfinite(w) and 0.0 <= w <= 1e3):
            raise InputError(f"controller state_weight must be 0..1000, got {w}")
        if self.lateral not in LATERAL_MODES:
            raise InputError(f"controller lateral must be one of {', '.join(LATERAL_MODES)}, "
                             f"got {self.lateral!r}")
        lr = self.lateral_r
        if isinstance(lr, bool) or not (math.isfinite(lr) and lr > 0.0):
            raise InputError(f"controller lateral_r must be an input cost > 0 (lateral = \"off\" "
                             f"turns the regulator off), got {lr!r}")
        zi = self.lateral_integral_deg
        if isinstance(zi, bool) or not (math.isfinite(zi) and zi > 0.0):
            raise InputError(f"controller lateral_integral_deg must be > 0 deg, got {zi!r}")
        if self.longitudinal not in LONGITUDINAL_MODES:
            raise InputError(f"controller longitudinal must be one of "
                             f"{', '.join(LONGITUDINAL_MODES)}, got {self.longitudinal!r}")
        gr = self.longitudinal_r
        if isinstance(gr, bool) or not (math.isfinite(gr) and gr > 0.0):
            raise InputError(f"controller longitudinal_r must be an input cost > 0 (longitudinal = "
                             f"\"off\" turns the regulator off), got {gr!r}")

    @classmethod
    def for_dove(cls, feathers: str = "rigid", predict: str = "simulate") -> ControllerConfig:
        """The defaults for the ``rigid`` or ``modal``-feather dove; with S0 predicted by
        regression (``predict="regression"``, which predicts the reference wingbeat's end
        only) nothing is carried."""
        if feathers not in DEFAULT_CARRY:
            raise InputError(f"feathers must be 'rigid' or 'modal', got {feathers!r}")
        if predict not in PREDICT_MODES:
            raise InputError(f"S0 prediction must be one of {', '.join(PREDICT_MODES)}, got {predict!r}")
        return cls(carry=0.0 if predict == "regression" else DEFAULT_CARRY[feathers],
                   refine=DEFAULT_REFINE[feathers], refine_goal=DEFAULT_REFINE_GOAL[feathers],
                   refine_stop=DEFAULT_REFINE_STOP[feathers],
                   reference_hz=DEFAULT_REFERENCE_HZ[feathers], k_dense_share=DEFAULT_K_DENSE_SHARE[feathers])

    @classmethod
    def from_toml(cls, path: str | Path, base: ControllerConfig | None = None) -> ControllerConfig:
        """``base`` (default: the rigid dove's) with the fields of ``path``'s ``[controller]``
        table; an unknown key or a value of the wrong type is a one-line
        :class:`~flapsim.core.errors.DataFileError`, a value out of range an
        :class:`~flapsim.core.errors.InputError`."""
        return from_table(base or cls(), read_toml(path, TABLES)["controller"], f"{path} [controller]")

    def to_dict(self) -> dict:
        return dataclasses.asdict(self)

    def to_toml(self) -> str:
        """The ``[controller]`` table, each field under its meaning; the modal dove's default
        is noted where it is not the rigid one's."""
        rigid, modal = ControllerConfig.for_dove("rigid"), ControllerConfig.for_dove("modal")
        notes = {f.name: f"modal dove: {getattr(modal, f.name)}" for f in dataclasses.fields(self)
                 if getattr(modal, f.name) != getattr(rigid, f.name)}
        return to_toml(self, "controller", notes)
