"""``flapsim list [WHAT]``: what can be named on the command line: strokes, coefficient
tables, models and creatures, gaits, benchmarks and evaluation scenarios."""

from __future__ import annotations

import argparse

HELP = "list the strokes, coefficient tables, models, gaits, benchmarks and scenarios by name"
SEED_HELP = "accepted for uniformity; listing uses no random numbers, --seed changes nothing"

KINDS = ("strokes", "tables", "models", "gaits", "benchmarks", "scenarios")


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("what", nargs="?", default="all", choices=("all",) + KINDS,
                   help="what to list (default all)")


def strokes() -> dict:
    from flapsim.core.errors import FlapsimError
    from flapsim.swim.strokes import STROKE_DIR, load_stroke

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
    from flapsim.fluid.coefficients import TABLES

    out = {}
    for name, make in TABLES.items():
        t = make()
        src = " ".join((getattr(t, "source", "") or "").split())
        out[name] = {"description": src if len(src) <= 100 else src[:97] + "..."}
    return out


def models() -> dict:
    from flapsim.modal.creatures import CREATURES
    from flapsim.modal.gaits import MODELS

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
    from flapsim.modal.gaits import GAITS

    return {g.name: {"description": f"{g.model}: {g.description}", "model": g.model}
            for g in GAITS.values()}


def benchmarks() -> dict:
    from flapsim.cli.commands.bench import BENCHES

    return {name: {"description": f"flapsim bench {name} ({target.split(':')[0]})"}
            for name, target in BENCHES.items()}


def scenarios() -> dict:
    try:
        from flapsim.scenarios import get, names
    except ImportError:  # the evaluation scenarios are not built in this version
        return {}
    out = {}
    for name in names():
        try:
            s = get(name)
            out[name] = {"description": s.summary, "family": s.family}
        except Exception as exc:  # noqa: BLE001 - a broken family must not hide the others
            out[name] = {"description": f"(cannot load: {exc})"}
    return out


def run(args: argparse.Namespace) -> dict:
    kinds = KINDS if args.what == "all" else (args.what,)
    result = {}
    for kind in kinds:
        items = globals()[kind]()
        result[kind] = items
        print(f"{kind}:" if items else f"{kind}: (none)")
        width = max((len(n) for n in items), default=0)
        for name, info in items.items():
            print(f"  {name:<{width}}  {info.get('description', '')}")
    return result
