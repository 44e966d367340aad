"""``flapsim bench TARGET``: speed benchmarks that report ratios measured in one run."""

from __future__ import annotations

import argparse
import importlib

from flapsim.core.errors import InputError
from flapsim.core.validate import add_input_arg, integer, integer_list, quantity

HELP = "run a speed benchmark (forces, ...) and report ratios measured in the same run"
SEED_HELP = "random seed of the benchmark's polygons ('forces'); the other targets ignore it"

# name -> "module:function"; each function takes the parsed args and returns a dict.
BENCHES: dict[str, str] = {
    "forces": "flapsim.bench.forces:run",
    "modal": "flapsim.bench.modal:run_modal",
    "creatures": "flapsim.bench.modal:run_creatures",
    "swimmer": "flapsim.bench.swimmer:run",
    "dove": "flapsim.bench.dove:run",
    "train": "flapsim.bench.dove:run_train",
    "controller": "flapsim.bench.dove:run_controller",
    "eval": "flapsim.bench.dove:run_eval",
}

# --quick: the settings of a smoke run, for the options the user left unset
QUICK: dict[str, object] = {"seconds": 0.2, "polygons": [50], "workers": 1, "samples": 2,
                            "wingbeats": 1}


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("target", help=f"what to benchmark: {', '.join(BENCHES)}")
    p.add_argument(
        "--seconds", type=quantity("seconds"), default=None,
        help="wall seconds per measurement (default: per target)"
    )
    p.add_argument(
        "--polygons",
        default=None,
        type=integer_list(1, 100_000, "polygons"),
        help="comma-separated polygon counts for 'forces' (default 50,300,1000; each 1..100000)",
    )
    p.add_argument("--workers", type=integer(1, 4096), default=None,
                   help="worker processes for 'train' and 'eval' (default 2, or fewer CPU cores)")
    p.add_argument("--samples", type=integer(1, 100000), default=None,
                   help="samples for 'train' (default 48 per worker)")
    p.add_argument("--wingbeats", type=integer(1, 100000), default=None,
                   help="wingbeats for 'controller' (default 20)")
    p.add_argument("--feathers", choices=("rigid", "modal"), default="rigid",
                   help="'dove': rigid feathers (default) or modal ones (measured with rigid in "
                        "the same run, for the cost ratio); 'controller': the dove flown (and "
                        "its bundled database)")
    add_input_arg(p, "--db", default=None,
                  help="database for 'controller' (default: the bundled one of --feathers)")
    p.add_argument("--predict", choices=("simulate", "coarse", "regression"), default="simulate",
                   help="'eval': how the controller finds S0 (default simulate; see flapsim fly "
                        "--help)")
    p.add_argument("--quick", action="store_true",
                   help="a smoke run at the smallest settings (numbers not comparable): the options "
                        "left unset become --seconds 0.2 --polygons 50 --workers 1 --samples 2 "
                        "--wingbeats 1, and 'eval' flies only the suite's two cheapest scenarios in "
                        "their short variants")


def run(args: argparse.Namespace) -> dict:
    for flag in ("workers", "samples", "wingbeats"):
        v = getattr(args, flag, None)
        if v is not None and not (1 <= v <= 100000):
            raise InputError(f"--{flag} must be 1..100000, got {v}")
    if args.target not in BENCHES:
        raise InputError(f"unknown benchmark {args.target!r}; choose one of {', '.join(BENCHES)}")
    if getattr(args, "quick", False):
        for flag, value in QUICK.items():
            if getattr(args, flag, None) is None:
                setattr(args, flag, value)
    if isinstance(args.polygons, list):  # parsed and bounded by its type; the bench reads text
        args.polygons = ",".join(str(n) for n in args.polygons)
    module_name, func = BENCHES[args.target].split(":")
    return getattr(importlib.import_module(module_name), func)(args)
