"""``flapsim eval``: run evaluation scenarios (the flight paper's sec. 7 suite, the
swimmer's tasks) in parallel, print a table like the paper's Table I, write JSON, plots
and videos. ``--table1`` reproduces Table I itself: database sizes and neighbour counts."""

from __future__ import annotations

import argparse
import math
import os
from pathlib import Path

from flapsim.cli.commands.fly import add_regression_arguments
from flapsim.core.errors import InputError
from flapsim.core.validate import add_input_arg

HELP = ("evaluate controllers on named scenarios (figure of eight, pushes, forest, flock, "
        "swimming tasks, ...): metrics table, JSON, plots, videos")
EXIT_STATUS = ("  1    a scenario failed or its animal got lost (the table and JSON still say which)\n"
               "  130, 143: with --json PATH the runs finished so far stay in PATH.partial, and\n"
               "       the same command again resumes from them")
SEED_HELP = ("random seed of the scenarios that draw (forest trees, flock perturbations) and of "
             "--starts' speed changes (default 0)")

TABLE1_SIZES = (2000, 5000, 10000, 20000)
TABLE1_K_PERCENT = (2.0, 1.0, 0.5, 0.3)
DEFAULT_SCENARIO = "figure8-level"
TABLE1_SCENARIO = "figure8"
"""The paper's Table I path: a figure of eight with ascending and descending turns."""


def push_note(table: list[dict]) -> str:
    """One line for a push scenario's forces: survived, completed but ended off the path
    (how far), lost."""
    ok = [f"{r['newtons']:g}" for r in table if r["survived"]]
    off = [f"{r['newtons']:g} ({r['final_path_distance']:.1f} m)" for r in table
           if not r["survived"] and r["status"] == "completed"]
    lost = [f"{r['newtons']:g}" for r in table if not r["survived"] and r["status"] != "completed"]
    parts = [f"survived {', '.join(ok)} N" if ok else "survived none"]
    if off:
        parts.append(f"ended off the path: {', '.join(off)}")
    if lost:
        parts.append(f"lost at {', '.join(lost)} N")
    return "; ".join(parts)


def check_regression_options(args: argparse.Namespace) -> None:
    """--clip-request, --state-weight, --k-dense, --carry and --refine (fly, eval, view):
    one-line errors."""
    import math

    q, w = args.clip_request, args.state_weight
    if not (math.isfinite(q) and 0.0 <= q < 0.5):
        raise InputError(f"--clip-request must be a share 0 <= Q < 0.5, got {q}")
    if not (math.isfinite(w) and 0.0 <= w <= 1e3):
        raise InputError(f"--state-weight must be 0..1000, got {w}")
    kd = getattr(args, "k_dense", None)
    if kd is not None and kd < 0:
        raise InputError(f"--k-dense must be 0 (off) or >= 1, got {kd}")
    c = getattr(args, "carry", None)
    if c is not None and not (math.isfinite(c) and 0.0 <= c <= 1.0):
        raise InputError(f"--carry must be a share 0..1, got {c}")
    if c and getattr(args, "predict", "simulate") == "regression":
        raise InputError("--carry needs S0 simulated (--predict simulate or coarse)")
    n = getattr(args, "refine", None)
    from flapsim.bird.control.controller import MAX_REFINE

    if n is not None and not 0 <= n <= MAX_REFINE:
        raise InputError(f"--refine must be 0..{MAX_REFINE} simulated corrections per wingbeat, got {n}")


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--scenario", default=None, metavar="NAME",
                   help=f"scenario name, several comma-separated, 'all', or one family's part of "
                        f"it: 'flight' or 'swim' (default {DEFAULT_SCENARIO}; --list shows them)")
    p.add_argument("--list", action="store_true", help="list the scenarios and exit")
    add_input_arg(p, "--path", metavar="FILE",
                  help="fly a path file of yours (CSV with header x,y,z, or JSON list of [x,y,z])")
    add_input_arg(p, "--db", metavar="DB", help="controller database (default: the bundled one)")
    p.add_argument("--method", choices=("knn", "lwlr"), default="lwlr",
                   help="regression of the wingbeat controller (default lwlr; knn: the paper's)")
    p.add_argument("--k", type=int, default=None,
                   help="neighbours (default: 2%% of the samples searched for lwlr, 0.5%% for knn)")
    add_regression_arguments(p)
    p.add_argument("--max-bank", type=float, default=None, metavar="DEG",
                   help="flight: the largest bank the path target asks, 10..80 deg (default 60 "
                        "for the rigid dove, 45 with modal feathers; the paper gives none; at 45 "
                        "sinusoid-sharp steers no wider than the capture set to the right, see "
                        "docs/flight.md)")
    p.add_argument("--bank-lead", type=float, default=None, metavar="S",
                   help="flight: the path target asks the bank its recovery curve has S seconds "
                        "after the wingbeat's end (default 0.2 for the rigid dove, 0.3 with modal "
                        "feathers; 0: at the end, the paper's; "
                        "--table1 uses 0)")
    p.add_argument("--speed", type=float, default=None, metavar="M_S",
                   help="flight: the speed asked of every flight, m/s (default 7, the paper's; the "
                        "bundled database was sampled at 7: slower flight needs a database sampled "
                        "there, see docs/flight.md)")
    p.add_argument("--aoa-per-g", type=float, default=None, metavar="DEG",
                   help="flight: the path target asks DEG more angle of attack per g of a turn's "
                        "load factor (default 40 for rigid feathers, 0 for modal ones; 0: the "
                        "paper's; see docs/flight.md)")
    p.add_argument("--speed-first", type=float, default=None, metavar="K",
                   help="flight: the climb asked drops K rad per m/s of airspeed below the speed "
                        "asked (default 0: independent speed and height loops, the paper's; "
                        "see docs/flight_log.md, \"Speed first\")")
    p.add_argument("--turn-g", type=float, default=None, metavar="N",
                   help="flight: slow down ahead of turns that would need more than N g at the "
                        "speed asked, to the speed where they need N (0: never, the paper's; "
                        "default 0; see docs/flight_log.md, \"Slowing for tight turns\")")
    p.add_argument("--turn-speed-floor", type=float, default=None, metavar="M_S",
                   help="flight: with --turn-g, the lowest speed asked for a turn (default 6.5 m/s)")
    p.add_argument("--layers", choices=("basic", "cycle", "all"), default="all",
                   help="swimming scenarios: control layers (default all)")
    p.add_argument("--feathers", choices=("rigid", "modal"), default="rigid",
                   help="flight scenarios: feather model (default rigid)")
    p.add_argument("--workers", type=int, default=None,
                   help="parallel workers (default: one per CPU core, at most one per run)")
    p.add_argument("--backend", choices=("local", "ray"), default="local",
                   help="local processes, or Ray actors (pip install 'flapsim[cluster]')")
    p.add_argument("--address", default=None, help="Ray cluster to join")
    p.add_argument("--plots", metavar="DIR", default=None,
                   help="write a PNG per run: path against flown trajectory, metrics per wingbeat")
    p.add_argument("--video", metavar="DIR", default=None, help="write an mp4 per run (chase camera)")
    p.add_argument("--quick", action="store_true",
                   help="short variants of every scenario (smoke runs; numbers not comparable)")
    p.add_argument("--starts", type=int, default=1, metavar="N",
                   help="flight: fly each scenario from N starts, the first as it is and the others "
                        "with its forward speed changed by at most --start-jitter, and report how "
                        "many complete (default 1). Near its limits a controlled flight is chaotic "
                        "and one verdict says little; plots and videos: the first start's")
    p.add_argument("--start-jitter", type=float, default=0.001, metavar="M_S",
                   help="with --starts: the largest change of the start's speed, m/s (default "
                        "0.001: far below anything physical)")
    p.add_argument("--table1", action="store_true",
                   help="reproduce the paper's Table I on --scenario (default figure8, with ascending "
                        "and descending turns): "
                        f"phase-1 databases of {'/'.join(map(str, TABLE1_SIZES))} samples (trained "
                        "into --cache if missing, resumable) with k = 0.5%%, and k = "
                        f"{'/'.join(f'{k:g}' for k in TABLE1_K_PERCENT)}%% on 10,000")
    p.add_argument("--cache", metavar="DIR", default="table1_dbs",
                   help="--table1: folder of the trained databases (default ./table1_dbs)")
    p.add_argument("--table1-seed", type=int, default=None, metavar="SEED",
                   help="--table1: the databases' sampling seed (default: the bundled database's, "
                        "so its size is copied rather than trained)")
    p.add_argument("--sizes", default=None,
                   help="--table1: database sizes to use instead of the paper's, comma-separated")


def _dir(flag: str, value: str | None) -> str | None:
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
    return str(p)


def _wider(m: dict) -> str:
    """The table's word on the steering range against the capture's, per side."""
    w = m.get("steering_wider_than_capture")
    if not w:
        return ""
    sides = [side for side in ("right", "left") if w[side]]
    if len(sides) == 1:
        return f": wider on the {sides[0]} only"
    return ": wider on both sides" if sides else ": wider on neither side"


def _names(args: argparse.Namespace) -> list[str]:
    from flapsim import scenarios

    if args.path:
        if args.scenario not in (None, "path"):
            raise InputError("--path flies your path file (scenario 'path'); drop --scenario")
        from flapsim.bird.tasks.path_control import load_path

        # a bad file is the user's input error (exit 2, one line), as for fly and view, not a
        # failed run in the table after the workers have started
        load_path(args.path)
        return ["path"]
    spec = args.scenario or DEFAULT_SCENARIO
    if spec == "all":
        return scenarios.names(all_only=True)
    if spec in ("flight", "swim"):  # one family's part of 'all'
        return scenarios.names(family=spec, all_only=True)
    out = []
    for name in (s.strip() for s in spec.split(",")):
        scenarios.get(name)  # one-line error naming the known ones
        if name == "path":
            raise InputError("scenario 'path' needs --path FILE")
        out.append(name)
    return out


def run(args: argparse.Namespace) -> dict:
    from flapsim import scenarios

    if args.list:
        return _list()
    if args.k is not None and args.k < 1:
        raise InputError(f"--k must be >= 1, got {args.k}")
    if args.workers is not None and not (1 <= args.workers <= 4096):
        raise InputError(f"--workers must be 1..4096, got {args.workers}")
    plots, video = _dir("--plots", args.plots), _dir("--video", args.video)
    if video:
        from flapsim.core.validate import require_gl

        require_gl()
    check_regression_options(args)
    if args.bank_lead is not None and not (math.isfinite(args.bank_lead) and 0.0 <= args.bank_lead <= 1.0):
        raise InputError(f"--bank-lead must be 0..1 s (within the 1 s look-ahead), got {args.bank_lead}")
    speed = getattr(args, "speed", None)
    if speed is not None and not (math.isfinite(speed) and 3.0 <= speed <= 12.0):
        raise InputError(f"--speed must be 3..12 m/s, got {speed}")
    max_bank = getattr(args, "max_bank", None)
    if max_bank is not None and not (math.isfinite(max_bank) and 10.0 <= max_bank <= 80.0):
        raise InputError(f"--max-bank must be 10..80 deg, got {max_bank}")
    aoa = getattr(args, "aoa_per_g", None)
    if aoa is not None and not (math.isfinite(aoa) and 0.0 <= aoa <= 90.0):
        raise InputError(f"--aoa-per-g must be 0..90 deg, got {aoa}")
    speed_first = getattr(args, "speed_first", None)
    if speed_first is not None and not (math.isfinite(speed_first) and 0.0 <= speed_first <= 1.0):
        raise InputError(f"--speed-first must be 0..1 rad per m/s, got {speed_first}")
    turn_g = getattr(args, "turn_g", None)
    if turn_g is not None and not (math.isfinite(turn_g) and (turn_g == 0.0 or 1.0 < turn_g <= 5.0)):
        raise InputError(f"--turn-g must be 0 (no slowing) or above 1 and at most 5 g, got {turn_g}")
    floor = getattr(args, "turn_speed_floor", None)
    if floor is not None and not (math.isfinite(floor) and 3.0 <= floor <= (speed or 7.0)):
        raise InputError(f"--turn-speed-floor must be 3 m/s..the speed asked ({speed or 7.0:g}), "
                         f"got {floor}")
    opts = scenarios.EvalOptions(db=args.db, method=args.method, k=args.k, k_dense=args.k_dense,
                                 carry=args.carry, refine=args.refine,
                                 refine_goal=args.refine_goal,
                                 mirror=args.mirror,
                                 clip_request=args.clip_request, state_weight=args.state_weight,
                                 predict=args.predict, lookahead=args.lookahead,
                                 bank_lead_s=args.bank_lead,
                                 speed=speed, aoa_per_g_deg=aoa, turn_load_factor=turn_g,
                                 max_bank_deg=max_bank,
                                 climb_per_speed_deficit=speed_first,
                                 turn_speed_floor=floor, layers=args.layers,
                                 feathers=args.feathers, plots_dir=plots, video_dir=video,
                                 seed=args.seed, path_file=args.path, quick=args.quick)
    if args.table1:
        if args.starts != 1:
            raise InputError("--table1 flies one start per database; drop --starts")
        return _table1(args, opts)
    runs = start_runs(_names(args), opts, args)
    runs = lookahead_runs(runs, args.lookahead, args.workers, args.backend)
    if args.db and any(scenarios.get(n).family == "flight" for n, _ in runs):
        _check_db_model(args.db, args.feathers)
    for d in (plots, video):
        if d:
            Path(d).mkdir(exist_ok=True)
    journal = open_journal(args, runs)
    results = execute(runs, args.workers, args.backend, args.address, journal)
    for r, (_, o) in zip(results, runs, strict=True):
        if args.starts > 1:
            r["start_speed_change_m_s"] = o.start_speed_change
    print_table(results)
    failed = [r["scenario"] for r in results if not r.get("ok")]
    out = {"scenarios": results, "runs": len(results), "failed": failed,
           "exit_status": 1 if failed else 0,
           "resumed_runs": journal.resumed if journal is not None else 0,
           "options": opts.to_dict()}
    if args.starts > 1:
        out["starts"] = print_spread(results, args.starts, args.start_jitter, args.seed)
    return out


def start_runs(names: list[str], opts, args: argparse.Namespace) -> list[tuple[str, object]]:
    """``(scenario, options)`` for each scenario and start (``--starts``, ``--start-jitter``):
    the start as it is, then its forward speed changed (:func:`flapsim.scenarios.start_speed_changes`);
    only the first start writes plots and videos (they would overwrite each other)."""
    import dataclasses

    from flapsim import scenarios

    n, jitter = args.starts, args.start_jitter
    if not 1 <= n <= 1000:
        raise InputError(f"--starts must be 1..1000, got {n}")
    if not (math.isfinite(jitter) and 0.0 < jitter <= 0.1):
        raise InputError(f"--start-jitter must be above 0 and at most 0.1 m/s (a perturbation far "
                         f"below the flight's speed), got {jitter}")
    if n == 1:
        return [(name, opts) for name in names]
    other = [name for name in names if scenarios.get(name).family != "flight"]
    if other:
        raise InputError(f"--starts perturbs the dove's start: flight scenarios only, not "
                         f"{', '.join(other)} (--scenario flight: the flight part of 'all')")
    runs = []
    for name in names:
        for i, dv in enumerate(scenarios.start_speed_changes(n, jitter, args.seed)):
            o = dataclasses.replace(opts, start_speed_change=dv)
            if i:
                o = dataclasses.replace(o, plots_dir=None, video_dir=None)
            runs.append((name, o))
    return runs


def print_spread(results: list[dict], n: int, jitter: float, seed: int) -> dict:
    """Completion over the starts of each scenario (``--starts``), with Wilson's 95 % interval
    and the spread of the largest distance from the path; the JSON's ``starts``."""
    from flapsim.scenarios import completion_interval

    by: dict[str, list[dict]] = {}
    for r in results:
        by.setdefault(r["scenario"], []).append(r)
    rows = {}
    print(f"\ncompleted over {n} starts (the first as it is, the others up to {jitter * 1e3:g} mm/s "
          f"faster or slower; seed {seed}):")
    for name, rs in by.items():
        k = sum(r["status"] == "completed" for r in rs)
        lo, hi = completion_interval(k, len(rs))
        far = [r.get("metrics", {}).get("max_path_distance") for r in rs]
        far = [f for f in far if f is not None]
        rows[name] = {"completed": k, "starts": len(rs), "rate": k / len(rs),
                      "rate_95": [lo, hi],
                      "max_path_distance_range_m": [min(far), max(far)] if far else None}
        span = f"; largest distance {min(far):.2f}-{max(far):.2f} m" if far else ""
        print(f"  {name:<22} {k:>4} of {len(rs):<4} ({100 * lo:.0f}-{100 * hi:.0f} % at 95 %){span}")
    return {"n": n, "jitter_m_s": jitter, "seed": seed, "scenarios": rows}


def _check_db_model(db: str, feathers: str) -> None:
    """A database of another dove is a one-line error before any worker starts (each run
    would fail alike)."""
    from flapsim.bird.body.model import Dove
    from flapsim.bird.control.database import read_header

    have, want = read_header(db).get("model_hash"), Dove.load(feathers=feathers).hash()
    if have != want:
        other = "modal" if feathers == "rigid" else "rigid"
        hint = (f"fly it with --feathers {other}" if have == Dove.load(feathers=other).hash()
                else f"train one for this dove: flapsim train --feathers {feathers} --out NEW.db")
        raise InputError(f"{db} was built for model {have}, not the {feathers}-feather dove "
                         f"({want}): {hint}")


def open_journal(args: argparse.Namespace, runs: list[tuple[str, object]]):
    """The journal of ``--json PATH``'s finished runs (:mod:`flapsim.scenarios.journal`),
    or None without a file to write (no ``--json``, or ``--json -``)."""
    from flapsim.core import environment
    from flapsim.scenarios.journal import RunJournal, fingerprint, journal_path

    if not args.json or args.json == "-":
        return None
    # the packages too: the same runs flown with another numpy may end otherwise (environment)
    return RunJournal(journal_path(args.json), fingerprint(runs, environment.tag()), len(runs))


def finished(args: argparse.Namespace) -> None:
    """Called once ``--json PATH`` is written: the finished runs' journal goes."""
    from flapsim.scenarios.journal import journal_path

    if args.json and args.json != "-" and not args.list:
        journal_path(args.json).unlink(missing_ok=True)


def resume_hint(args: argparse.Namespace) -> str:
    """What an interrupted eval tells the user about its finished runs."""
    from flapsim.scenarios.journal import journal_path

    if args.json and args.json != "-" and journal_path(args.json).exists():
        return (f"; the finished runs are kept in {journal_path(args.json)}: run the same "
                "command again to resume")
    return ""


def lookahead_runs(runs: list[tuple[str, object]], mode: str, workers: int | None,
                   backend: str = "local") -> list[tuple[str, object]]:
    """``--lookahead`` for each run: ``auto`` becomes ``on`` only where the local runs leave
    this machine a second core per worker (one scenario on two cores, say), else ``off``: the
    suite's runs already fill the cores, and a third thread would slow them."""
    import dataclasses

    from flapsim.bird.control.controller import usable_cores

    if mode == "auto":
        n = workers or max(1, min(len(runs), usable_cores()))
        n = min(n, len(runs)) if runs else 1
        mode = "on" if backend == "local" and usable_cores() >= 2 * n else "off"
        # "on" is an error where a run cannot look ahead (--refine 0, say): auto stays quiet
        mode = "auto" if mode == "on" else "off"
    return [(name, dataclasses.replace(o, lookahead=mode) if hasattr(o, "lookahead") else o)
            for name, o in runs]


def execute(runs: list[tuple[str, object]], workers: int | None, backend: str = "local",
            address: str | None = None, journal=None) -> list[dict]:
    """Run ``(scenario name, options)`` pairs on the training executor; results in order.
    ``journal`` (a :class:`~flapsim.scenarios.journal.RunJournal`): the runs it holds are
    taken from it, not flown again, and each run flown is added to it as it finishes."""
    from tqdm import tqdm

    from flapsim.core.parallel import ChunkExecutor
    from flapsim.scenarios import EvalWorker, RunsConfig

    n = len(runs)
    out: list[dict | None] = [None] * n
    if journal is not None:
        done = journal.load()
        if journal.stale:
            print(f"{journal.path} holds the runs of another eval (other options, databases, "
                  "path files or flapsim version): starting afresh")
        for i, r in done.items():
            out[i] = r
        if done:
            print(f"resuming: {len(done)} of {n} runs finished before, read from {journal.path}")
        journal.open(done)
    from flapsim.scenarios import get

    todo = [i for i in range(n) if out[i] is None]
    # dearest first: the longest run must not be the one that starts last
    order = sorted(todo, key=lambda i: -get(runs[i][0]).cost)
    try:
        if order:
            workers = workers or max(1, min(len(order), os.cpu_count() or 1))
            workers = min(workers, len(order))
            with ChunkExecutor(EvalWorker, RunsConfig(list(runs)), workers=workers, backend=backend,
                               address=address) as ex, \
                    tqdm(total=n, initial=n - len(order), desc="scenarios", unit="run") as bar:
                for chunk in ex.map_unordered([(i, i + 1) for i in order]):
                    for i, r in chunk:
                        out[i] = r
                        if journal is not None:
                            journal.add(i, r)
                        bar.set_postfix_str(f"{r['scenario']}: {r['status']}")
                        bar.update(1)
            missing = [runs[i][0] for i in order if out[i] is None]
            if missing:  # never a table that silently lacks a run
                from flapsim.core.parallel import WorkerError

                raise WorkerError(f"no result came back for {', '.join(missing)}; run the same "
                                  "command again to resume")
    finally:
        if journal is not None:
            journal.close()
    return [r for r in out if r is not None]


def _fmt(v, digits: int = 3) -> str:
    if v is None:
        return "-"
    if isinstance(v, float):
        return f"{v:.{digits}f}"
    return str(v)


def _beyond_wing(m: dict) -> str:
    """Where a path's held turn asks more lift than the wing holds at the speed asked, say so:
    the dove can follow it only by slowing into the turn, and near that limit it is lost from
    some starts (docs/flight.md, "Flight tasks (issue #14): where they stand")."""
    n = m.get("wing_load_factor")
    if n is None or m["sustained_turn_load_factor"] <= n:
        return ""
    return (f"; the wing holds {n:.2f} g there, turns of {m['wing_min_turn_radius_m']:.1f} m and "
            f"wider: the dove must slow into it")


def print_table(results: list[dict]) -> None:
    """One row per run: the paper's per-wingbeat Ep, Er, Eo, Ef (flight), or the swimmer's
    distances to target, and the verdict."""
    flight = [r for r in results if r["family"] == "flight"]
    other = [r for r in results if r["family"] != "flight"]
    if flight:
        head = (f"{'scenario':<16} {'status':<10} {'Ep m':>7} {'Er rad':>7} {'Eo rad':>7} {'Ef m':>7} "
                f"{'max m':>7} {'wb':>5}  note")
        print(head)
        print("-" * len(head))
        for r in flight:
            m = r.get("metrics", {})
            note = r.get("reason", "")
            if "table" in m:
                note = push_note(m["table"])
            elif "steering_range_deg" in m and r["scenario"].startswith("sinusoid"):
                lo, hi = m.get("steering_range_both_ways_deg") or m["steering_range_deg"]
                asked = m.get("path_steering_range_deg")
                tube = (m.get("steering_range_in_tube_both_ways_deg")
                        or m.get("steering_range_in_tube_deg"))
                note = (f"steering {lo:+.1f}..{hi:+.1f} deg/wingbeat"
                        + (" (both ways)" if m.get("steering_range_both_ways_deg") else "")
                        + (f", {tube[0]:+.1f}..{tube[1]:+.1f} in the tube"
                           if tube and r.get("status") != "completed" else "")
                        + (f" (path {asked[0]:+.1f}..{asked[1]:+.1f})" if asked else "")
                        + (f" (capture {m['capture_steering_range_deg'][0]:+.1f}.."
                           f"{m['capture_steering_range_deg'][1]:+.1f}{_wider(m)})"
                           if m.get("capture_steering_range_deg") else "") + (f"; {note}" if note else ""))
            elif "min_separation_m" in m:
                note = f"closest birds {m['min_separation_m']:.2f} m" + (f"; {note}" if note else "")
            elif r["scenario"] == "path" and m.get("path_geometry"):
                g = m["path_geometry"]
                radius = "straight" if g["min_radius_m"] is None else f"radius >= {g['min_radius_m']:.1f} m"
                if m.get("sustained_turn_load_factor") is not None:
                    radius += (f" (held over 2 m: {g['sustained_radius_m']:.1f} m, "
                               f"{m['sustained_turn_load_factor']:.2f} g at {m['speed_asked']:g} m/s"
                               + _beyond_wing(m) + ")")
                note = (f"{radius}, climbs <= {g['max_climb_deg']:.1f} deg, descents <= "
                        f"{g['max_descent_deg']:.1f} deg" + (f"; {note}" if note else ""))
                if m.get("way_speed_m_s") is not None and m.get("speed_asked"):
                    # a dove slows into tight turns and up climbs: say how much
                    note += (f"; {m['way_speed_m_s']:.1f} m/s made good along the path "
                             f"({m['speed_asked']:g} asked)")
            elif "collisions" in m and r["scenario"] == "forest":
                note = f"{m['collisions']} collisions" + (f"; {note}" if note else "")
            if r.get("start_speed_change_m_s") is not None:
                note = f"start {1e3 * r['start_speed_change_m_s']:+.3f} mm/s" + (f"; {note}" if note else "")
            print(f"{r['scenario']:<16} {r['status']:<10} {_fmt(m.get('Ep_per_wingbeat')):>7} "
                  f"{_fmt(m.get('Er_per_wingbeat')):>7} {_fmt(m.get('Eo_per_wingbeat')):>7} "
                  f"{_fmt(m.get('Ef_per_wingbeat')):>7} {_fmt(m.get('max_path_distance'), 2):>7} "
                  f"{_fmt(m.get('wingbeats')):>5}  {note}")
        print("per wingbeat: Ep, Ef in m; Er, Eo = ||log(q^-1 q')|| in rad (the paper's eq. 12-15)")
    if other:
        if flight:
            print()
        cols = (("distance_to_target_mean_m", "mean m", 2), ("distance_to_target_max_m", "max m", 2),
                ("heading_error_mean_deg", "heading deg", 1), ("distance_swum_m", "swum m", 1),
                ("time_to_reach_s", "reached s", 1))
        head = f"{'scenario':<26} {'status':<10} " + " ".join(f"{c[1]:>11}" for c in cols) + "  note"
        print(head)
        print("-" * len(head))
        for r in other:
            m = r.get("metrics", {})
            print(f"{r['scenario']:<26} {r['status']:<10} "
                  + " ".join(f"{_fmt(m.get(k), d):>11}" for k, _, d in cols) + f"  {r.get('reason', '')}")
        print("distance to the target (to the path for the figure of eight), mean heading error, "
              "distance swum, time the target was first reached")


def _list() -> dict:
    from flapsim import scenarios

    rows = []
    names = scenarios.names()
    width = max(len(n) for n in names)  # the columns line up whatever the longest name
    for name in names:
        sc = scenarios.get(name)
        rows.append({"name": name, "family": sc.family, "summary": sc.summary, "in_all": sc.in_all})
        print(f"{name:<{width}} {sc.family:<7} {sc.summary}")
    return {"scenarios": rows}


# -- Table I --------------------------------------------------------------------------------

def _bundled_seed(feathers: str = "rigid") -> int:
    from flapsim.bird.control.controller import bundled_database_path
    from flapsim.bird.control.database import load_database

    return int(load_database(bundled_database_path(feathers), require_finalized=True).header["seed"])


def _is_bundled_run(config, n: int) -> bool:
    """True when the bundled database holds exactly ``n`` samples of this configuration's
    run (``train`` still checks the copy's header before accepting it)."""
    from flapsim.bird.control.controller import bundled_database_path
    from flapsim.bird.control.database import load_database
    from flapsim.bird.training.sampling import SampleWorker
    from flapsim.bird.training.train import run_header

    db = load_database(bundled_database_path(config.feathers), require_finalized=True)
    ident = run_header(config, SampleWorker, "dove-phase1")
    return db.n == n and all(db.header.get(k) == ident.get(k)
                             for k in ("kind", "worker", "config_class", "config", "seed"))


def _paper_protocol(o) -> None:
    """Table I's runs fly the paper's controller whatever else was asked: k fixed (the sweep is
    over k itself), the bank of the wingbeat's end, P0 every wingbeat, the trim's angle of
    attack in turns, the speed asked everywhere, independent speed and height loops and the
    regression's answer flown as it is, with the dove's default bank cap (Table I's figure of
    eight flies the same at 45 and 60 deg: docs/flight_log.md, "A 60 deg bank by default")."""
    o.k_dense, o.bank_lead_s, o.carry, o.refine, o.max_bank_deg = 0, 0.0, 0.0, 0, None
    o.aoa_per_g_deg, o.speed, o.turn_load_factor, o.climb_per_speed_deficit = 0.0, None, 0.0, 0.0


def _table1(args: argparse.Namespace, opts) -> dict:
    """Train (or reuse) the phase-1 databases and fly the scenario with each."""
    import copy

    from flapsim.bird.training.sampling import SampleWorker, SamplingConfig
    from flapsim.bird.training.train import train

    name = args.scenario or TABLE1_SCENARIO
    if "," in name or name in ("all", "path"):
        raise InputError("--table1 flies one scenario: --scenario NAME")
    from flapsim import scenarios

    if scenarios.get(name).family != "flight":
        raise InputError(f"--table1 needs a flight scenario, got {name!r}")
    sizes = TABLE1_SIZES
    if args.sizes:
        try:
            sizes = tuple(int(s) for s in args.sizes.split(","))
        except ValueError:
            raise InputError(f"--sizes must be integers separated by commas, got {args.sizes!r}") \
                from None
        if any(not (100 <= s <= 10**6) for s in sizes):
            raise InputError(f"--sizes must each be 100..1e6, got {args.sizes}")
    cache = Path(_dir("--cache", args.cache))
    cache.mkdir(exist_ok=True)
    # the bundled database's sampling (phase 1, pre-states within 10 deg) and, unless asked
    # otherwise, its seed: one draw of the databases, whose spread docs/flight_log.md measures
    seed = (args.table1_seed if getattr(args, "table1_seed", None) is not None
            else _bundled_seed(opts.feathers))
    config = SamplingConfig(seed=seed, pitch_deg=10.0, roll_deg=10.0, feathers=opts.feathers)
    dbs = {}
    for n in sorted(set(sizes)):
        out = cache / f"phase1_{n}.db"
        if not out.exists() and _is_bundled_run(config, n):
            # the bundled database is this very run: copy it rather than train it again
            import shutil

            from flapsim.bird.control.controller import bundled_database_path

            shutil.copyfile(bundled_database_path(config.feathers), out)
            print(f"database of {n} samples: {out} (the bundled one)")
        else:
            print(f"database of {n} samples: {out}")
        train(config, out, n, SampleWorker, workers=args.workers or (os.cpu_count() or 1),
              backend=args.backend, address=args.address, kind="dove-phase1")
        dbs[n] = out
    runs, labels = [], []
    # k is a share of the samples the regression searches: with the mirror images, twice the
    # database's
    per = 2 if opts.mirror else 1
    for n in sizes:
        o = copy.copy(opts)
        o.db, o.k = str(dbs[n]), max(1, round(0.005 * per * n))
        _paper_protocol(o)
        runs.append((name, o))
        labels.append({"samples": n, "k_percent": 0.5, "k": o.k})
    base = 10000 if 10000 in dbs else max(dbs)
    for kp in TABLE1_K_PERCENT:
        if kp == 0.5:
            continue
        o = copy.copy(opts)
        o.db, o.k = str(dbs[base]), max(1, round(kp / 100 * per * base))
        _paper_protocol(o)
        runs.append((name, o))
        labels.append({"samples": base, "k_percent": kp, "k": o.k})
    runs = lookahead_runs(runs, args.lookahead, args.workers, args.backend)
    journal = open_journal(args, runs)
    results = execute(runs, args.workers, args.backend, args.address, journal)
    print(f"\nTable I on {name} ({opts.method}{', samples and their mirror images' if opts.mirror else ''}; "
          f"databases of sampling seed {seed}): per-wingbeat means")
    head = (f"{'samples':>8} {'k %':>5} {'k':>5} {'status':<10} {'Ep m':>7} {'Er rad':>7} "
            f"{'Eo rad':>7} {'Ef m':>7}")
    print(head)
    print("-" * len(head))
    rows = []
    for lab, r in zip(labels, results, strict=True):
        m = r.get("metrics", {})
        print(f"{lab['samples']:>8} {lab['k_percent']:>5g} {lab['k']:>5} {r['status']:<10} "
              f"{_fmt(m.get('Ep_per_wingbeat')):>7} {_fmt(m.get('Er_per_wingbeat')):>7} "
              f"{_fmt(m.get('Eo_per_wingbeat')):>7} {_fmt(m.get('Ef_per_wingbeat')):>7}")
        rows.append({**lab, **r})
    print("the paper (k-NN, its figure of eight): 10,000 samples, k = 0.5 %: Ep 0.039, Er 0.062, "
          "Eo 0.111, Ef 0.145")
    failed = [f"{row['samples']}/{row['k_percent']}%" for row in rows if not row.get("ok")]
    return {"table1": rows, "scenario": name, "seed": seed, "failed": failed,
            "exit_status": 1 if failed else 0,
            "resumed_runs": journal.resumed if journal is not None else 0,
            "databases": {str(k): str(v) for k, v in dbs.items()}}
