"""Evaluation scenarios for every animal (``flapsim eval``): a registry of named tasks
(:mod:`~flapsim.scenarios.registry`), the flight paper's suite (:mod:`~flapsim.scenarios.flight`)
and the swimmer's (:mod:`~flapsim.scenarios.swim`), and the parallel runner with its resume
journal (:mod:`~flapsim.scenarios.runner`, :mod:`~flapsim.scenarios.journal`)."""

from flapsim.scenarios.registry import (
    FAMILY_MODULES,
    EvalOptions,
    Scenario,
    completion_interval,
    get,
    load_all,
    names,
    register,
    run_scenario,
    start_speed_changes,
)

__all__ = ["FAMILY_MODULES", "EvalOptions", "Scenario", "completion_interval", "get", "load_all",
           "names", "register", "run_scenario", "start_speed_changes"]
