"""System 2: layered swimming (Yang, Laszlo, Singh 2004).

The swimmer's body and water (:mod:`flapsim.swim.model`), stroke files
(:mod:`flapsim.swim.strokes`), the three control layers (:mod:`flapsim.swim.layers`,
:mod:`flapsim.swim.per_cycle`, :mod:`flapsim.swim.continuous`), where to go
(:mod:`flapsim.swim.goals`) and the simulation that measures a swim
(:mod:`flapsim.swim.simulate`). The names below are the short public API.

Example: five seconds of front crawl toward a point 10 m ahead and 3 m to the left::
    from flapsim.swim import Point, swim

    result = swim("crawl", seconds=5.0, target=Point(10.0, 3.0))
    print(result.cycles, result.com[-1])
"""

from flapsim.swim.goals import Heading, Path, Point, Trajectory, Waypoints, figure_eight, load_path
from flapsim.swim.model import Swimmer, SwimmerParams
from flapsim.swim.simulate import SwimResult, swim
from flapsim.swim.strokes import Stroke, load_stroke

__all__ = [
    "Heading",
    "Path",
    "Point",
    "Stroke",
    "SwimResult",
    "Swimmer",
    "SwimmerParams",
    "Trajectory",
    "Waypoints",
    "figure_eight",
    "load_path",
    "load_stroke",
    "swim",
]
