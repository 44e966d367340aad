"""``flapsim view``: steer the dove (learned controller) in MuJoCo's viewer, paced to real
time. The swimmer's viewer is ``flapsim swim --viewer``; both use ``flapsim.render.viewer``."""

from __future__ import annotations

import argparse

from flapsim.bird.tasks.interactive import view_flight
from flapsim.bird.tasks.path_control import load_path
from flapsim.cli.options import add_controller_arguments, controller_options
from flapsim.core.errors import InputError
from flapsim.core.validate import add_input_arg
from flapsim.render.viewer import check_display

HELP = ("steer the dove in MuJoCo's viewer: arrows steer and climb, double-click flies toward "
        "a point, PgUp/PgDn speed, Insert push, Delete gust, Home camera (needs a display or Xvfb)")
SEED_HELP = "ignored: the interactive flight draws nothing at random"


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--seconds", type=float, default=600.0,
                   help="simulated seconds before the viewer closes by itself (default 600)")
    add_input_arg(p, "--path", metavar="FILE",
                  help="follow and draw a path file (CSV header x,y,z or JSON list of [x,y,z])")
    add_controller_arguments(p)
    p.add_argument("--feathers", choices=("rigid", "modal"), default="rigid",
                   help="rigid feather plates (default) or modal feathers, drawn bent (their own "
                        "bundled database, or --db: one trained with flapsim train --feathers modal)")


def run(args: argparse.Namespace) -> dict:
    if not (0.0 < args.seconds <= 86400.0):
        raise InputError(f"--seconds must be within 0..86400, got {args.seconds}")
    controller, path_control = controller_options(args)
    path = load_path(args.path) if args.path else None
    check_display()
    r = view_flight(args.seconds, args.db, args.method, args.k, path, feathers=args.feathers,
                    path_control=path_control, mirror=args.mirror, predict=args.predict,
                    config=controller)
    print(f"dove viewer: {r['simulated_s']:.1f} s flown in {r['wall_s']:.1f} s ({r['status']}); "
          f"turned {r['heading_change_deg']:+.0f} deg, climbed {r['altitude_change_m']:+.1f} m, "
          f"{r['distance_m']:.0f} m flown; {len(r['events'])} key commands, {r['pushes']} pushes, "
          f"{r['gusts']} gusts")
    return {"viewer": r, "path": args.path, "db": args.db or "bundled", "method": args.method,
            "mirror": args.mirror, "predict": args.predict, "feathers": args.feathers,
            "controller_config": controller.to_dict(), "path_control": path_control.to_dict()}
