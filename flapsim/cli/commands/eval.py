"""``flapsim eval``: run evaluation scenarios (the flight paper's sec. 7 suite, the
swimmer's tasks) in parallel, print a table like the paper's Table I, write JSON, plots
and videos. ``--table1`` reproduces Table I itself: database sizes and neighbour counts."""

from __future__ import annotations

import argparse
import math
from pathlib import Path

from flapsim import scenarios
from flapsim.bird.tasks.path_control import load_path
from flapsim.cli.options import (
    add_controller_arguments,
    add_video_arguments,
    controller_options,
    video_size,
    writable_dir,
)
from flapsim.core.errors import InputError
from flapsim.core.parallel import usable_cores
from flapsim.core.validate import add_input_arg, address_problem, require_gl
from flapsim.scenarios import runner
from flapsim.scenarios.journal import journal_path
from flapsim.scenarios.runner import TABLE1_K_PERCENT, TABLE1_SCENARIO, TABLE1_SIZES

HELP = ("evaluate controllers on named scenarios (figure of eight, pushes, forest, flock, "
        "swimming tasks, ...): metrics table, JSON, plots, videos")
EXIT_STATUS = ("  1    a scenario failed or its animal got lost (the table and JSON still say which)\n"
               "  130, 143: with --json PATH the runs finished so far stay in PATH.partial, and\n"
               "       the same command again resumes from them")
SEED_HELP = ("random seed of the scenarios that draw (forest trees, flock perturbations) and of "
             "--starts' speed changes (default 0)")

DEFAULT_SCENARIO = "figure8-level"


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


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--scenario", default=None, metavar="NAME",
                   help=f"scenario name, several comma-separated, 'all', or one family's part of "
                        f"it: 'flight' or 'swim' (default {DEFAULT_SCENARIO}; --list shows them)")
    p.add_argument("--list", action="store_true", help="list the scenarios and exit")
    add_input_arg(p, "--path", metavar="FILE",
                  help="fly a path file of yours (CSV with header x,y,z, or JSON list of [x,y,z])")
    add_controller_arguments(p)
    p.add_argument("--speed", type=float, default=None, metavar="M_S",
                   help="flight: the speed asked of every flight, m/s (default 7, the paper's; the "
                        "bundled database was sampled at 7: slower flight needs a database sampled "
                        "there, see docs/flight.md)")
    p.add_argument("--layers", choices=("basic", "cycle", "all"), default="all",
                   help="swimming scenarios: control layers (default all)")
    p.add_argument("--body", choices=("box", "rounded"), default="box",
                   help="swimming scenarios: the paper's boxes (default) or the rounded body, "
                        "which swims its own crawl")
    p.add_argument("--feathers", choices=("rigid", "modal"), default="rigid",
                   help="flight scenarios: feather model (default rigid)")
    p.add_argument("--workers", type=int, default=None,
                   help="parallel workers (default: one per CPU core, at most one per run)")
    p.add_argument("--backend", choices=("local", "ray"), default="local",
                   help="local processes, or Ray actors (pip install 'flapsim[cluster]')")
    p.add_argument("--address", default=None, help="Ray cluster to join")
    p.add_argument("--plots", metavar="DIR", default=None,
                   help="write a PNG per run: path against flown trajectory, metrics per wingbeat")
    p.add_argument("--video", metavar="DIR", default=None,
                   help="write an mp4 per run: the path drawn, the flight as a fading trail, "
                        "trees and flock mates, an overlay (see --camera, --fps, --slowmo)")
    add_video_arguments(p, slowmo_default="1: real time")
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
    if args.path:
        if args.scenario not in (None, "path"):
            raise InputError("--path flies your path file (scenario 'path'); drop --scenario")
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


#: Options only --table1 reads (dest, flag, default).
_TABLE1_ONLY = (("sizes", "--sizes", None), ("table1_seed", "--table1-seed", None),
                ("cache", "--cache", "table1_dbs"))


#: Options that mean nothing to --list (dest, flag, default).
_NOT_FOR_LIST = (("scenario", "--scenario", None), ("path", "--path", None),
                 ("table1", "--table1", False), ("db", "--db", None), ("plots", "--plots", None),
                 ("video", "--video", None))


def check_conflicts(args: argparse.Namespace) -> None:
    """Options that the run asked for would ignore are refused before any work (--table1
    trains for hours: it must not start on a command line it does not follow)."""
    if args.list:
        given = [flag for dest, flag, default in _NOT_FOR_LIST
                 if getattr(args, dest, default) != default]
        if given:
            raise InputError(f"--list only lists the scenarios; drop {', '.join(given)}")
        return
    if args.table1:
        if args.path:
            raise InputError("--table1 flies one of the suite's scenarios with its own databases; "
                             "drop --path (or --table1)")
        if args.db:
            raise InputError("--table1 trains and flies its own databases; drop --db")
        if args.starts != 1:
            raise InputError("--table1 flies one start per database; drop --starts")
        return
    given = [flag for dest, flag, default in _TABLE1_ONLY if getattr(args, dest, default) != default]
    if given:
        raise InputError(f"{', '.join(given)} {'is' if len(given) == 1 else 'are'} for --table1; "
                         "add --table1, or drop them")


def run(args: argparse.Namespace) -> dict:
    check_conflicts(args)
    if args.address is not None:
        if args.backend != "ray":
            raise InputError("--address is only for --backend ray")
        problem = address_problem(args.address)
        if problem:
            raise InputError(problem)
    if args.list:
        return _list()
    if args.workers is not None and not (1 <= args.workers <= 4096):
        raise InputError(f"--workers must be 1..4096, got {args.workers}")
    plots, video = writable_dir("--plots", args.plots), writable_dir("--video", args.video)
    if video:
        require_gl()
    controller, path_control = controller_options(args)
    speed = args.speed
    if speed is not None and not (math.isfinite(speed) and 3.0 <= speed <= 12.0):
        raise InputError(f"--speed must be 3..12 m/s, got {speed}")
    opts = scenarios.EvalOptions(db=args.db, method=args.method, k=args.k, mirror=args.mirror,
                                 predict=args.predict, controller=controller,
                                 path_control=path_control, speed=speed, layers=args.layers, body=args.body,
                                 feathers=args.feathers, plots_dir=plots, video_dir=video,
                                 seed=args.seed, path_file=args.path, quick=args.quick,
                                 fps=args.fps, size=video_size(args), slowmo=args.slowmo,
                                 camera=args.camera)
    if args.table1:
        if args.starts != 1:
            raise InputError("--table1 flies one start per database; drop --starts")
        return _table1(args, opts)
    runs = runner.start_runs(_names(args), opts, args.starts, args.start_jitter, args.seed)
    runs = runner.lookahead_runs(runs, args.workers, args.backend)
    if args.db and any(scenarios.get(n).family == "flight" for n, _ in runs):
        runner.check_database(args.db, args.feathers)
    for d in (plots, video):
        if d:
            Path(d).mkdir(exist_ok=True)
    journal = args._journal = runner.open_journal(args.json, runs)
    results = runner.execute(runs, args.workers, args.backend, args.address, journal, say=print)
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


def print_spread(results: list[dict], n: int, jitter: float, seed: int) -> dict:
    """Completion over the starts of each scenario (``--starts``), with Wilson's 95 % interval
    and the spread of the largest distance from the path (:func:`flapsim.scenarios.runner.
    spread`); the JSON's ``starts``."""
    rows = runner.spread(results)
    print(f"\ncompleted over {n} starts (the first as it is, the others up to {jitter * 1e3:g} mm/s "
          f"faster or slower; seed {seed}):")
    for name, row in rows.items():
        k, m = row["completed"], row["starts"]
        lo, hi = row["rate_95"]
        far = row["max_path_distance_range_m"]
        span = f"; largest distance {far[0]:.2f}-{far[1]:.2f} m" if far else ""
        print(f"  {name:<22} {k:>4} of {m:<4} ({100 * lo:.0f}-{100 * hi:.0f} % at 95 %){span}")
    return {"n": n, "jitter_m_s": jitter, "seed": seed, "scenarios": rows}


def finished(args: argparse.Namespace) -> None:
    """Called once ``--json PATH`` is written: the finished runs' journal goes, unless it
    holds runs of other evals (never deleted unasked)."""
    journal = getattr(args, "_journal", None)
    if journal is not None and journal.finish():
        print(f"{journal.path} is kept: it holds {len(journal.kept)} finished runs of another "
              "eval (the same command as that eval resumes from them)")


def resume_hint(args: argparse.Namespace) -> str:
    """What an interrupted eval tells the user about its finished runs."""
    if args.json and args.json != "-" and journal_path(args.json).exists():
        return (f"; the finished runs are kept in {journal_path(args.json)}: run the same "
                "command again to resume")
    if getattr(args, "table1", False) and args.cache and any(Path(args.cache).glob("phase1_*.db")):
        return (f"; the samples trained so far are kept in {args.cache}: run the same command "
                "again to resume")
    return ""


def _fmt(v, digits: int = 3) -> str:
    if v is None:
        return "-"
    if isinstance(v, float):
        return f"{v:.{digits}f}"
    return str(v)


def _beyond_wing(m: dict) -> str:
    """Where a path's held turn asks more lift than the wing holds at the speed asked, say so:
    the dove can follow it only by slowing into the turn, and near that limit it is lost from
    some starts (docs/flight.md)."""
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
    rows = []
    names = scenarios.names()
    width = max(len(n) for n in names)  # the columns line up whatever the longest name
    for name in names:
        sc = scenarios.get(name)
        rows.append({"name": name, "family": sc.family, "summary": sc.summary, "in_all": sc.in_all})
        print(f"{name:<{width}} {sc.family:<7} {sc.summary}")
    return {"scenarios": rows}


# -- Table I --------------------------------------------------------------------------------

def _table1(args: argparse.Namespace, opts: scenarios.EvalOptions) -> dict:
    """Train (or reuse) the phase-1 databases and fly the scenario with each
    (:mod:`flapsim.scenarios.runner`'s Table I)."""
    name = args.scenario or TABLE1_SCENARIO
    if "," in name or name in ("all", "path"):
        raise InputError("--table1 flies one scenario: --scenario NAME")
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
    cache = Path(writable_dir("--cache", args.cache))
    made = not cache.exists()
    cache.mkdir(exist_ok=True)
    # the bundled database's sampling (phase 1, pre-states within 10 deg) and, unless asked
    # otherwise, its seed: one draw of the databases, whose spread docs/design/flight.md
    # measures ("How much the database's random draw matters")
    seed = (args.table1_seed if args.table1_seed is not None
            else runner.bundled_seed(opts.feathers))
    try:
        dbs = runner.table1_databases(sizes, cache, seed, opts.feathers,
                                      workers=args.workers or usable_cores(),
                                      backend=args.backend, address=args.address, say=print)
    except BaseException:
        if made and not any(cache.iterdir()):  # stopped before a sample was kept
            cache.rmdir()
        raise
    runs, labels = runner.table1_runs(name, opts, dbs, sizes)
    runs = runner.lookahead_runs(runs, args.workers, args.backend)
    journal = args._journal = runner.open_journal(args.json, runs)
    results = runner.execute(runs, args.workers, args.backend, args.address, journal, say=print)
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
            "databases": {str(k): str(v) for k, v in dbs.items()},
            "options": opts.to_dict()}
