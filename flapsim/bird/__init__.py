"""System 1: data-driven flapping flight of a collared dove (Ju et al., ACM TOG 2013).

The dove's body (:mod:`flapsim.bird.body`), open-loop flight (:mod:`flapsim.bird.flight`),
the learned wingbeat controller (:mod:`flapsim.bird.control`), its training
(:mod:`flapsim.bird.training`) and the tasks it flies (:mod:`flapsim.bird.tasks`). The names
below are the short public API; everything else is reached through those subpackages.

Example: ten wingbeats of level cruise under the learned controller and the bundled
database::
    from flapsim.bird import (CruiseTarget, Dove, DoveFlight, FlightConfig, fly_controlled,
                              load_controller, start_cruise, trim_of_base_flight)

    flight = DoveFlight(Dove.load())
    controller = load_controller(flight)
    cfg = FlightConfig()
    trim = trim_of_base_flight(flight, controller.P0, cfg)
    start_cruise(flight, controller.P0, cfg)
    result = fly_controlled(controller, CruiseTarget(trim, altitude=cfg.height), 10)
"""

from flapsim.bird.body.model import Dove
from flapsim.bird.body.params import DoveParams
from flapsim.bird.control.controller import (
    WingbeatController,
    fly_controlled,
    load_controller,
    start_cruise,
)
from flapsim.bird.control.targets import CruiseTarget, trim_of_base_flight
from flapsim.bird.flight.dove_flight import DoveFlight, FlightConfig
from flapsim.bird.flight.wingbeat import ReferenceWingbeat, reference_wingbeat
from flapsim.bird.tasks.flight_tasks import Task, TaskResult, fly_task

__all__ = [
    "CruiseTarget",
    "Dove",
    "DoveFlight",
    "DoveParams",
    "FlightConfig",
    "ReferenceWingbeat",
    "Task",
    "TaskResult",
    "WingbeatController",
    "fly_controlled",
    "fly_task",
    "load_controller",
    "reference_wingbeat",
    "start_cruise",
    "trim_of_base_flight",
]
