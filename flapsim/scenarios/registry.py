"""The registry of evaluation scenarios for every animal (``flapsim eval``).

A :class:`Scenario` is a named task with a runner: ``runner(scenario, options) -> dict``.
Families register theirs in their own module (``flapsim/scenarios/flight.py``,
``flapsim/scenarios/swim.py``, ...), which :func:`load_all` imports by name (the registry
reads them, they import it); names are unique and
start with the family's prefix where it is not flight (``swim-...``).

A runner returns a JSON-able dict with at least::
    {"status": "completed" | "lost" | "failed" | ..., "ok": bool, "reason": str,
     "metrics": {name: number, ...}, "files": [paths written]}

:func:`run_scenario` adds the name, family, wall time, and turns a
:class:`~flapsim.core.errors.FlapsimError` (bad database, diverged simulation) into a failed
result with its one-line reason, so that one broken run never hides the others
(:mod:`flapsim.scenarios.runner` runs many in parallel).
"""

from __future__ import annotations

import importlib
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass, field

import numpy as np

from flapsim.bird.control.config import ControllerConfig
from flapsim.bird.tasks.config import PathControlConfig
from flapsim.core.errors import FlapsimError, InputError

#: The modules that register scenarios, in listing order.
FAMILY_MODULES: tuple[str, ...] = ("flapsim.scenarios.flight", "flapsim.scenarios.swim")


@dataclass(frozen=True)
class Scenario:
    """A named evaluation task."""

    name: str
    family: str
    """``flight`` or ``swim``."""
    summary: str
    """One line for ``flapsim eval --list``."""
    runner: Callable[[Scenario, EvalOptions], dict]
    params: dict = field(default_factory=dict)
    """The scenario's own settings, passed to the runner (and reported)."""
    in_all: bool = True
    """Part of ``--scenario all``."""
    cost: float = 1.0
    """Rough wall seconds it takes: parallel runs start with the dearest (a long run started
    last would keep one worker busy alone at the end)."""


@dataclass
class EvalOptions:
    """What every scenario run may use (from the command line)."""

    db: str | None = None
    """Flight: controller database (None: the bundled one)."""
    method: str = "lwlr"
    """Flight: the wingbeat controller's regression, ``lwlr`` or ``knn``."""
    k: int | None = None
    """Flight: the regression's neighbours (None: a share of the samples searched,
    :data:`flapsim.bird.control.regression.DEFAULT_K_SHARE`)."""
    mirror: bool = True
    """Flight: the regression also searches the samples' mirror images."""
    predict: str = "simulate"
    """Flight: how the controller finds S0 (:func:`flapsim.bird.control.controller.load_controller`)."""
    controller: ControllerConfig | None = None
    """Flight: the wingbeat controller's tuning (None: the dove's defaults without the
    look-ahead thread, :func:`flapsim.bird.control.controller.load_controller`). Its
    ``lookahead`` changes the wall time only, so a journal's runs are resumed whatever it is."""
    path_control: PathControlConfig | None = None
    """Flight: the path target's tuning (None: the dove's defaults,
    :meth:`flapsim.bird.tasks.config.PathControlConfig.for_dove`)."""
    speed: float | None = None
    """Flight: the speed asked of every flight, m/s (None: each task's own, 7)."""
    start_speed_change: float | None = None
    """Flight: added to each path's start speed, m/s (None: the task's, 0; a perturbation
    within +-1 m/s for verdict-spread studies,
    :attr:`flapsim.bird.tasks.flight_tasks.Task.start_speed_change`)."""
    layers: str = "all"
    """Swim: control layers (basic, cycle, all)."""
    body: str = "box"
    """Swim: the hydrodynamic surface, ``box`` or ``rounded``
    (:attr:`flapsim.swim.model.SwimmerParams.body_shape`); the rounded body swims its own
    tuning of a stroke where there is one (:func:`flapsim.swim.strokes.stroke_for_body`)."""
    feathers: str = "rigid"
    """Flight: feather model."""
    plots_dir: str | None = None
    video_dir: str | None = None
    seed: int = 0
    path_file: str | None = None
    """A user's path file (the ``path`` scenario)."""
    quick: bool = False
    """Shorter variants (tests, smoke runs)."""
    fps: float = 60.0
    size: tuple[int, int] = (640, 480)
    slowmo: float | None = None
    """Videos: slow motion factor (None: real time)."""
    camera: str = "chase"
    """Videos: camera mode (:data:`flapsim.render.video.CAMERAS`)."""

    def to_dict(self) -> dict:
        return asdict(self)


_REGISTRY: dict[str, Scenario] = {}
_LOADED = False


def register(scenario: Scenario) -> Scenario:
    """Add ``scenario`` (a name may be registered once)."""
    if scenario.name in _REGISTRY and _REGISTRY[scenario.name] is not scenario:
        raise ValueError(f"scenario {scenario.name!r} is registered twice")
    _REGISTRY[scenario.name] = scenario
    return scenario


def load_all() -> None:
    """Import every family module (each registers its scenarios); a family whose module
    does not exist yet is skipped."""
    global _LOADED
    if _LOADED:
        return
    for mod in FAMILY_MODULES:
        try:
            importlib.import_module(mod)
        except ModuleNotFoundError as exc:
            if exc.name != mod:
                raise
    _LOADED = True


def names(family: str | None = None, all_only: bool = False) -> list[str]:
    """Registered scenario names (of one family), in registration order."""
    load_all()
    return [n for n, s in _REGISTRY.items()
            if (family is None or s.family == family) and (not all_only or s.in_all)]


def get(name: str) -> Scenario:
    """The scenario called ``name``; a one-line error listing the names otherwise."""
    load_all()
    try:
        return _REGISTRY[name]
    except KeyError:
        raise InputError(f"no scenario {name!r}; known: {', '.join(names())} "
                         "(flapsim eval --list)") from None


def run_scenario(name: str, options: EvalOptions) -> dict:
    """Run one scenario; never raises for a failure of the run itself (see module doc)."""
    sc = get(name)
    t0 = time.perf_counter()
    try:
        out = dict(sc.runner(sc, options))
    except FlapsimError as exc:
        out = {"status": "failed", "ok": False, "reason": str(exc), "metrics": {}, "files": []}
    out.setdefault("files", [])
    out.setdefault("reason", "")
    return {"scenario": name, "family": sc.family, "summary": sc.summary, **out,
            "wall_s": time.perf_counter() - t0}


def start_speed_changes(n: int, jitter_m_s: float, seed: int = 0) -> list[float]:
    """The starts of a verdict spread (``flapsim eval --starts N``): 0, the start as it is,
    then ``n - 1`` changes of its forward speed drawn uniformly within +-``jitter_m_s`` (m/s),
    the same for the same ``seed``. Near its limits a controlled flight is chaotic, and one
    start's verdict says little; a completion rate over starts under 1 mm/s apart says whether
    a path is within reach, at its edge or beyond it."""
    draws = np.random.default_rng(seed).uniform(-jitter_m_s, jitter_m_s, max(n - 1, 0))
    return [0.0] + [float(x) for x in draws]


def completion_interval(k: int, n: int, z: float = 1.96) -> tuple[float, float]:
    """Wilson's score interval for a completion rate of ``k`` of ``n`` starts (95 % with the
    default ``z``): unlike k/n +- z sqrt(p(1-p)/n) it stays within [0, 1] and is not empty at
    0 or n of n, where a spread's counts often are."""
    if not 0 <= k <= n or n < 1:
        raise InputError(f"a completion rate needs 0 <= k <= n and n >= 1, got {k} of {n}")
    z2 = z * z
    centre = (k + z2 / 2) / (n + z2)
    half = z * (k * (n - k) / n + z2 / 4) ** 0.5 / (n + z2)
    return max(0.0, centre - half), min(1.0, centre + half)
