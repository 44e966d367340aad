"""``flapsim list [WHAT]``: what can be named on the command line: strokes, coefficient
tables, models and creatures, gaits, benchmarks and evaluation scenarios; and the learned
controller's default configuration (``flapsim list config``: a TOML file to copy and pass
with ``--config``)."""

from __future__ import annotations

import argparse

from flapsim.bird.control.config import ControllerConfig
from flapsim.bird.tasks.config import PathControlConfig, control_toml
from flapsim.cli.commands.bench import BENCHES
from flapsim.core.errors import FlapsimError
from flapsim.fluid.coefficients import TABLES
from flapsim.modal.creatures import CREATURES
from flapsim.modal.gaits import GAITS, MODELS
from flapsim.scenarios import get, names
from flapsim.swim.strokes import STROKE_DIR, load_stroke

HELP = ("list the strokes, coefficient tables, models, gaits, benchmarks and scenarios by name; "
        "'list config' prints the controller's defaults as TOML for --config")
SEED_HELP = "accepted for uniformity; listing uses no random numbers, --seed changes nothing"

KINDS = ("strokes", "tables", "models", "gaits", "benchmarks", "scenarios", "config")


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("what", nargs="?", default="all", choices=("all",) + KINDS,
                   help="what to list (default all)")


def strokes() -> dict:
    out = {}
    for f in sorted(STROKE_DIR.glob("*.toml")):
        try:
            s = load_stroke(str(f))
            out[f.stem] = {"description": s.description.strip().splitlines()[0] if s.description
                           else "", "period_s": s.period_s, "posture": s.posture}
        except FlapsimError as exc:  # a bundled file being edited: say so, list the rest
            out[f.stem] = {"description": f"(cannot load: {exc})"}
    return out


def tables() -> dict:
    out = {}
    for name, make in TABLES.items():
        t = make()
        src = " ".join((getattr(t, "source", "") or "").split())
        out[name] = {"description": src if len(src) <= 100 else src[:97] + "..."}
    return out


def models() -> dict:
    out = {"dove": {"description": "collared dove, 14 actuated DOF, feathers (flapsim fly, train)"},
           "swimmer": {"description": "human swimmer, 16 boxes, 39 DOF (flapsim swim, sweep)"}}
    for name, spec in CREATURES.items():
        shape = "ring" if spec.closed_loop else "chain"
        out[name] = {"description": f"{spec.filename}: modal creature, a {shape} driven by its two "
                     "lowest modes (flapsim creature --model)"}
    for name, xml in MODELS.items():
        out[name] = {"description": f"{xml}: modal gaits (flapsim animate --model)"}
    return out


def gaits() -> dict:
    return {g.name: {"description": f"{g.model}: {g.description}", "model": g.model}
            for g in GAITS.values()}


def benchmarks() -> dict:
    return {name: {"description": f"flapsim bench {name} ({target.split(':')[0]})"}
            for name, target in BENCHES.items()}


def scenarios() -> dict:
    out = {}
    for name in names():
        try:
            s = get(name)
            out[name] = {"description": s.summary, "family": s.family}
        except Exception as exc:  # noqa: BLE001 - a broken family must not hide the others
            out[name] = {"description": f"(cannot load: {exc})"}
    return out


def config() -> dict:
    """The rigid dove's controller configuration, by table (the modal dove's defaults differ
    where :func:`~flapsim.bird.tasks.config.control_toml` notes it)."""
    return {"controller": ControllerConfig().to_dict(), "path": PathControlConfig().to_dict()}


def run(args: argparse.Namespace) -> dict:
    kinds = KINDS if args.what == "all" else (args.what,)
    result = {}
    for kind in kinds:
        if kind == "config":  # a file to copy, not a list of names
            result[kind] = config()
            if len(kinds) > 1:
                print("config (flapsim list config; pass a copy with --config FILE.toml):")
            print(control_toml(), end="")
            continue
        items = globals()[kind]()
        result[kind] = items
        print(f"{kind}:" if items else f"{kind}: (none)")
        width = max((len(n) for n in items), default=0)
        for name, info in items.items():
            print(f"  {name:<{width}}  {info.get('description', '')}")
    return result
