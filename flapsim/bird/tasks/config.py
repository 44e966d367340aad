"""The path controller's tuning, and the control configuration file that holds it beside the
wingbeat controller's.

:class:`PathControlConfig` holds what the path target
(:class:`~flapsim.bird.tasks.path_control.PathTarget`) asks of the wingbeat controller in
turns and climbs: the bank, how far ahead it is asked, the angle of attack per g, speed
first, slowing for tight turns. It is its own dataclass rather than part of
:class:`~flapsim.bird.control.config.ControllerConfig` because it tunes another loop: the
wingbeat controller answers a target state whatever asks for it (a cruise has no path), and
the path target is built above it. One file holds both, as two tables::
    [controller]   # ControllerConfig
    carry = 0.4
    [path]         # PathControlConfig
    max_bank_deg = 60.0

(:func:`load_control_config`; ``flapsim list config`` prints the defaults, :func:`control_toml`).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from pathlib import Path

from flapsim.bird.control.config import TABLES, ControllerConfig
from flapsim.bird.tasks.flight_tasks import (
    DEFAULT_AOA_PER_G_DEG,
    DEFAULT_BANK_LEAD_S,
    DEFAULT_CLIMB_PER_SPEED_DEFICIT,
    DEFAULT_MAX_BANK_DEG,
    Task,
)
from flapsim.bird.tasks.path_control import PathTarget
from flapsim.core.config import from_table, read_toml, to_toml
from flapsim.core.errors import InputError


@dataclass(frozen=True)
class PathControlConfig:
    """The path target's tuning (defaults: the rigid dove's; :meth:`for_dove`)."""

    max_bank_deg: float = DEFAULT_MAX_BANK_DEG["rigid"]
    """The largest bank the path target asks, 10..80 deg (the paper gives none; docs/flight.md)."""
    bank_lead_s: float = DEFAULT_BANK_LEAD_S["rigid"]
    """The path target asks the bank its recovery curve has this long after the wingbeat's end,
    0..1 s (0: at the end, the paper's; docs/flight.md)."""
    aoa_per_g_deg: float = DEFAULT_AOA_PER_G_DEG["rigid"]
    """More angle of attack asked per g of a turn's load factor, 0..90 deg (0: the level trim's,
    the paper's; docs/flight.md)."""
    climb_per_speed_deficit: float = DEFAULT_CLIMB_PER_SPEED_DEFICIT["rigid"]
    """Speed first: the climb asked drops this much per m/s of airspeed below the speed asked,
    0..1 rad s/m (0: independent speed and height loops, the paper's; docs/design/flight.md, "Speed
    first: off")."""
    max_climb_deg: float = float(PathTarget.max_climb_deg)
    """The steepest climb or descent the path target asks, 5..60 deg. The default, 15, is below
    the 30 and 45 deg climbing circles' own climbs: on them it leaves even a bird that flies
    every climb asked 1.2 and 2.5 m below the path by the climb's top (docs/flight.md)."""
    turn_load_factor: float = float(PathTarget.turn_load_factor)
    """Slow down ahead of turns that would need more than this load factor at the speed asked,
    to the speed where they need it, 0 or above 1 and at most 5 g (0: never, the paper's;
    docs/design/flight.md, "Slowing for tight turns: off")."""
    turn_speed_floor: float = float(PathTarget.turn_speed_floor)
    """With turn_load_factor, the lowest speed asked for a turn, 3..12 m/s, never above the
    speed asked (the bundled database's dove loses 6 m circles at 6 m/s)."""

    def __post_init__(self) -> None:
        def check(ok: bool, key: str, what: str) -> None:
            if not ok:
                raise InputError(f"path {key} must be {what}, got {getattr(self, key)}")

        f = math.isfinite
        check(f(self.max_bank_deg) and 10.0 <= self.max_bank_deg <= 80.0, "max_bank_deg", "10..80 deg")
        check(f(self.bank_lead_s) and 0.0 <= self.bank_lead_s <= PathTarget.lookahead_s, "bank_lead_s",
              f"0..{PathTarget.lookahead_s:g} s (within the look-ahead)")
        check(f(self.aoa_per_g_deg) and 0.0 <= self.aoa_per_g_deg <= 90.0, "aoa_per_g_deg", "0..90 deg")
        check(f(self.climb_per_speed_deficit) and 0.0 <= self.climb_per_speed_deficit <= 1.0,
              "climb_per_speed_deficit", "0..1 rad per m/s")
        check(f(self.max_climb_deg) and 5.0 <= self.max_climb_deg <= 60.0, "max_climb_deg",
              "5..60 deg")
        n = self.turn_load_factor
        check(f(n) and (n == 0.0 or 1.0 < n <= 5.0), "turn_load_factor",
              "0 (no slowing) or above 1 and at most 5 g")
        check(f(self.turn_speed_floor) and 3.0 <= self.turn_speed_floor <= 12.0, "turn_speed_floor",
              "3..12 m/s")

    @classmethod
    def for_dove(cls, feathers: str = "rigid") -> PathControlConfig:
        """The defaults for the ``rigid`` or ``modal``-feather dove."""
        if feathers not in DEFAULT_MAX_BANK_DEG:
            raise InputError(f"feathers must be 'rigid' or 'modal', got {feathers!r}")
        return cls(max_bank_deg=DEFAULT_MAX_BANK_DEG[feathers], bank_lead_s=DEFAULT_BANK_LEAD_S[feathers],
                   aoa_per_g_deg=DEFAULT_AOA_PER_G_DEG[feathers],
                   climb_per_speed_deficit=DEFAULT_CLIMB_PER_SPEED_DEFICIT[feathers])

    @classmethod
    def from_toml(cls, path: str | Path, base: PathControlConfig | None = None) -> PathControlConfig:
        """``base`` (default: the rigid dove's) with the fields of ``path``'s ``[path]`` table
        (errors as :meth:`flapsim.bird.control.config.ControllerConfig.from_toml`)."""
        return from_table(base or cls(), read_toml(path, TABLES)["path"], f"{path} [path]")

    def target_settings(self, speed: float) -> dict:
        """:class:`~flapsim.bird.tasks.path_control.PathTarget`'s keyword arguments for a flight
        asked ``speed`` m/s."""
        return {**dataclasses.asdict(self), "turn_speed_floor": min(speed, self.turn_speed_floor)}

    def apply(self, task: Task) -> Task:
        """``task`` flown under these settings (its own path-target fields replaced)."""
        return dataclasses.replace(task, **self.target_settings(task.speed))

    def to_dict(self) -> dict:
        return dataclasses.asdict(self)

    def to_toml(self) -> str:
        """The ``[path]`` table, each field under its meaning; the modal dove's default is
        noted where it is not the rigid one's."""
        rigid, modal = PathControlConfig.for_dove("rigid"), PathControlConfig.for_dove("modal")
        notes = {f.name: f"modal dove: {getattr(modal, f.name)}" for f in dataclasses.fields(self)
                 if getattr(modal, f.name) != getattr(rigid, f.name)}
        return to_toml(self, "path", notes)


def load_control_config(path: str | Path | None, feathers: str = "rigid", predict: str = "simulate"
                        ) -> tuple[ControllerConfig, PathControlConfig]:
    """The wingbeat and path controllers' configurations: the ``feathers`` dove's defaults
    (:meth:`ControllerConfig.for_dove <flapsim.bird.control.config.ControllerConfig.for_dove>`,
    :meth:`PathControlConfig.for_dove`) with the keys of the TOML file ``path`` (None: the
    defaults) over them."""
    controller = ControllerConfig.for_dove(feathers, predict)
    path_control = PathControlConfig.for_dove(feathers)
    if path is None:
        return controller, path_control
    tables = read_toml(path, TABLES)
    return (from_table(controller, tables["controller"], f"{path} [controller]"),
            from_table(path_control, tables["path"], f"{path} [path]"))


def control_toml(controller: ControllerConfig | None = None,
                 path_control: PathControlConfig | None = None) -> str:
    """A control configuration file (default: the rigid dove's defaults), ready to copy."""
    controller = controller or ControllerConfig()
    path_control = path_control or PathControlConfig()
    head = ("# flapsim control configuration: flapsim eval|fly|view --config FILE.toml.\n"
            "# Keys left out keep their defaults (the dove flown's: --feathers modal has its own,\n"
            "# noted beside a value); a key that is not listed here is an error.\n\n")
    return head + controller.to_toml() + "\n" + path_control.to_toml()
