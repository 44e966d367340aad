"""Options shared by several commands: the learned controller's (``fly``, ``eval``, ``view``)
and the folders a command writes into.

The learned controller takes from the command line what a user chooses (the database, the
regression method and k, the mirror images, how S0 is found) and the rest of its tuning from
one TOML file, ``--config FILE.toml``: the wingbeat controller's ``[controller]`` table and the
path target's ``[path]`` table (:func:`flapsim.bird.tasks.config.load_control_config`;
``flapsim list config`` prints the defaults to copy).
"""

from __future__ import annotations

import argparse
import os
from pathlib import Path

from flapsim.bird.control.config import ControllerConfig
from flapsim.bird.tasks.config import PathControlConfig, load_control_config
from flapsim.core.errors import InputError
from flapsim.core.io import write_problem
from flapsim.core.validate import add_input_arg, quantity
from flapsim.render.video import CAMERAS


def add_controller_arguments(p: argparse.ArgumentParser) -> None:
    """``--db``, ``--method``, ``--k``, ``--no-mirror``, ``--predict`` and ``--config``."""
    add_input_arg(p, "--db", metavar="DB", help="controller database (default: the bundled one "
                                                "of the dove flown)")
    p.add_argument("--method", choices=("knn", "lwlr"), default="lwlr",
                   help="regression of the wingbeat controller: lwlr (default; locally weighted "
                        "linear regression) or knn (the paper's k-NN average; see docs/flight.md)")
    p.add_argument("--k", type=int, default=None,
                   help="neighbours of the regression (default: 2%% of the samples searched for "
                        "lwlr, 0.5%% for knn)")
    p.add_argument("--no-mirror", dest="mirror", action="store_false",
                   help="the regression searches the database's samples only, not also their mirror "
                        "images (the default searches both: the dove is symmetric)")
    p.add_argument("--predict", choices=("simulate", "coarse", "regression"), default="simulate",
                   help="how the learned controller finds S0, where the reference wingbeat would "
                        "end: simulate it every wingbeat (default; the paper), simulate it at a "
                        "coarser step (coarse: 1600 Hz against 2400, ~1.25x faster, the same "
                        "verdicts on the figures of eight and in wind) or predict it from the "
                        "database's (S, S0) pairs, simulating only some wingbeats to correct its "
                        "bias (regression, EXPERIMENTAL: 1.4-1.6x faster; loses the rising figure "
                        "of eight on 3 of 7 asked speeds)")
    add_input_arg(p, "--config", metavar="FILE.toml",
                  help="the controller's tuning: a TOML file with a [controller] table (carry, "
                       "simulated corrections, look-ahead, the regression's dense neighbourhood, "
                       "request clip, state weight) and a [path] table (the path target's bank, "
                       "bank lead, angle of attack per g, speed first, slowing for turns); keys "
                       "left out keep the dove's defaults ('flapsim list config' prints them)")


def controller_options(args: argparse.Namespace) -> tuple[ControllerConfig, PathControlConfig]:
    """Checks ``--k`` and reads ``--config`` over the flown dove's defaults (``--feathers``,
    ``--predict``): the wingbeat controller's and the path target's configurations."""
    if args.k is not None and args.k < 1:
        raise InputError(f"--k must be >= 1, got {args.k}")
    controller, path = load_control_config(args.config, getattr(args, "feathers", "rigid"),
                                            args.predict)
    if controller.carry and args.predict == "regression":
        raise InputError(f"{args.config} [controller]: carry needs S0 simulated (--predict "
                         "simulate or coarse): --predict regression predicts the reference "
                         "wingbeat's end only; set carry = 0")
    return controller, path


def writable_dir(flag: str, value: str | None) -> str | None:
    """``value`` as a folder the command may create and write into (None stays None); a file
    there, a missing parent, or a parent in which no file can be created (tried) is a
    one-line error."""
    if value is None:
        return None
    p = Path(value)
    if p.exists() and not p.is_dir():
        raise InputError(f"{flag} {value} is a file; name a folder (it is created if missing)")
    parent = p if p.exists() else p.parent
    if not parent.exists():
        raise InputError(f"{flag} {value}: folder {parent} does not exist (create it first)")
    if not os.access(parent, os.W_OK | os.X_OK):
        raise InputError(f"{flag} {value}: folder {parent} is not writable")
    problem = write_problem(parent / ".flapsim")  # the permission bits can say yes where no file can be made
    if problem is not None:
        raise InputError(f"{flag} {value}: cannot create a file in {parent} ({problem})")
    return str(p)


def add_video_arguments(p: argparse.ArgumentParser, slowmo_default: str = "1") -> None:
    """``--fps``, ``--size``, ``--slowmo`` and ``--camera`` of the dove's videos."""
    p.add_argument("--fps", type=quantity("fps"), default=60.0,
                   help="video frames per second (default 60: ~6 frames per wingbeat)")
    p.add_argument("--size", default="640x480", help="video size WxH (default 640x480)")
    p.add_argument("--slowmo", type=float, default=None, metavar="F",
                   help=f"slow motion: the video lasts F times the flight (default {slowmo_default}); "
                        "e.g. 8 shows ~50 frames per wingbeat")
    p.add_argument("--camera", choices=CAMERAS, default="chase",
                   help="chase (default: behind the bird along its heading, above it, the path "
                        "ahead in view), side, top or orbit")


def video_options(args: argparse.Namespace) -> dict:
    """The keyword arguments of :func:`flapsim.bird.flight.video.dove_video` from
    :func:`add_video_arguments`' options."""
    return {"slowmo": args.slowmo, "camera": args.camera}


def video_size(args: argparse.Namespace) -> tuple[int, int]:
    """``--size WxH`` as (width, height) pixels, checked."""
    try:
        width, height = (int(v) for v in args.size.lower().split("x"))
    except ValueError:
        raise InputError(f"--size must look like 640x480, got {args.size!r}") from None
    if not (16 <= width <= 4096 and 16 <= height <= 4096):
        raise InputError(f"--size must be 16..4096 pixels each way, got {args.size!r}")
    return width, height
