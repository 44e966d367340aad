"""``flapsim sweep``: swim one stroke at several values of one parameter (in parallel
processes) and print a table of the results."""

from __future__ import annotations

import argparse
import time

from tqdm import tqdm

from flapsim.cli.commands.swim import add_target_arguments, target_from_args
from flapsim.core.errors import InputError
from flapsim.core.io import atomic_path
from flapsim.core.validate import RANGES, add_input_arg, add_output_arg, integer, quantity
from flapsim.swim.goals import Waypoints
from flapsim.swim.plots import sweep_plot
from flapsim.swim.sweep import PARAMETERS, sweep, table

HELP = ("batch-evaluate the swimmer: one stroke over several water densities, lung "
        "volumes, stroke rates, frictions or cross currents; a table of the results")
SEED_HELP = "accepted for uniformity; swimming is deterministic, --seed changes nothing"
EXIT_STATUS = ("  1    at least one run failed (diverged): the table, --csv and --json are still "
               "written,\n       each failed run with its error")


def add_arguments(p: argparse.ArgumentParser) -> None:
    add_input_arg(p, "--stroke", may_be_name=True, default="crawl",
                  help="breaststroke, crawl, treading, or a stroke .toml file (default crawl)")
    p.add_argument("--vary", required=True, choices=sorted(PARAMETERS),
                   help="the parameter to sweep: " + ", ".join(
                       f"{k} [{v[1]}]" for k, v in PARAMETERS.items())
                   + " (current: a cross current along +y)")
    p.add_argument("--values", required=True, metavar="V1,V2,...",
                   help="the values to try, comma-separated")
    p.add_argument("--seconds", type=quantity("seconds"), default=20.0,
                   help="simulated time per run [s]")
    add_target_arguments(p)
    p.add_argument("--no-feedback", action="store_true", help="basic stroke layer only")
    p.add_argument("--workers", type=integer(1, 256), default=None,
                   help="parallel processes (default: one per CPU core, at most one per value)")
    add_output_arg(p, "--csv", kinds=(".csv",), help="also write the table as CSV")
    add_output_arg(p, "--plot", kinds=(".png",),
                   help="also plot speeds and heights against the parameter (PNG)")


def run(args: argparse.Namespace) -> dict:
    try:
        values = [float(v) for v in args.values.split(",") if v.strip()]
    except ValueError:
        raise InputError(f"--values must be comma-separated numbers, got {args.values!r}") from None
    rng = RANGES[args.vary]
    bad = [f"{v:g}" for v in values if not rng.contains(v)]
    if bad:  # the same ranges as flapsim swim's options
        raise InputError(f"--values: {args.vary} values must be within {rng.describe()}, "
                         f"got {', '.join(bad)}")
    if not values:
        raise InputError("--values: give at least one value")
    target = target_from_args(args)
    if isinstance(target, Waypoints):
        raise InputError("flapsim sweep swims on the surface: a --target depth below it (a "
                         "surface dive) is flapsim swim's; give --target X,Y")

    t0 = time.perf_counter()
    with tqdm(total=len(values), unit="run", desc=f"{args.stroke} x {args.vary}") as bar:
        rows = sweep(args.stroke, args.vary, values, args.seconds, target,
                     feedback=not args.no_feedback, workers=args.workers,
                     on_done=lambda _: bar.update(1))
    wall = time.perf_counter() - t0
    text = table(rows, args.vary)
    print(f"{args.stroke}, {args.seconds:g} s per run, varying {args.vary} "
          f"({len(rows)} runs in {wall:.1f} s):")
    print(text)
    if args.csv:
        keys = sorted({k for r in rows for k, v in r.items() if not isinstance(v, (dict, list))},
                      key=lambda k: (k != "value", k == "error", k))
        with atomic_path(args.csv) as tmp:
            lines = [",".join(keys)]
            for r in rows:
                lines.append(",".join("" if r.get(k) is None else _csv_cell(r.get(k))
                                      for k in keys))
            tmp.write_text("\n".join(lines) + "\n")
        print(f"table written to {args.csv}")
    if args.plot:
        sweep_plot(rows, args.vary, PARAMETERS[args.vary][1], args.plot, args.stroke)
        print(f"plot written to {args.plot}")
    failed = [r for r in rows if "error" in r]
    if failed:
        print(f"{len(failed)} of {len(rows)} runs failed: "
              + "; ".join(f"{args.vary} {r['value']:g}: {r['error']}" for r in failed))
    return {"stroke": args.stroke, "vary": args.vary, "unit": PARAMETERS[args.vary][1],
            "seconds": args.seconds, "target": target.describe() if target else None,
            "rows": rows, "failed_runs": len(failed), "exit_status": 1 if failed else 0,
            "wall_s": wall}


def _csv_cell(v: object) -> str:
    """A CSV cell: text with commas or quotes quoted (an error message)."""
    text = str(v)
    if any(c in text for c in ',"\n'):
        text = '"' + text.replace('"', '""').replace("\n", " ") + '"'
    return text
