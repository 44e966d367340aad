"""``flapsim train``: build the dove's wingbeat-controller sample database (phase 1:
perturbed wingbeats around the reference; phase 2: from a phase-1 database) on local
worker processes or a Ray cluster. Rerunning the same command after an interruption
resumes it; the finished file is the same whatever the workers, backend or
interruptions."""

from __future__ import annotations

import argparse
import json
import math
import os
from pathlib import Path
from typing import Any

from flapsim.bird.control.database import merge_databases, read_header
from flapsim.bird.flight.dove_flight import CRUISE
from flapsim.bird.training.discovery import DiscoveryConfig, DiscoveryWorker
from flapsim.bird.training.sampling import SampleWorker, SamplingConfig
from flapsim.bird.training.train import check_out, train
from flapsim.core.errors import InputError
from flapsim.core.io import write_problem
from flapsim.core.validate import address_problem, require_finite
from flapsim.fluid.coefficients import get_table

HELP = ("train the dove's controller database: sample wingbeats in parallel (local processes "
        "or Ray), resumable, into one database file")


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--samples", type=int, default=None, metavar="N",
                   help="accepted samples to collect (the first N by sample index; required "
                        "unless --merge)")
    p.add_argument("--phase", type=int, choices=(1, 2), default=1,
                   help="1: perturbations of the reference wingbeat; 2: refine from --from DB")
    p.add_argument("--sigma", type=float, default=None,
                   help="perturbation scale (default: the sampler's, from the paper)")
    p.add_argument("--workers", type=int, default=None,
                   help="parallel workers (default: one per CPU core)")
    p.add_argument("--backend", choices=("local", "ray"), default="local",
                   help="local processes, or Ray actors (pip install 'flapsim[cluster]')")
    p.add_argument("--address", default=None,
                   help="Ray cluster to join (default: start a private local Ray instance)")
    p.add_argument("--out", required=True, metavar="DB",
                   help="the database file to create, or to resume if it exists")
    p.add_argument("--from", dest="from_db", default=None, metavar="DB",
                   help="phase 2 only: the phase-1 database to start from")
    p.add_argument("--discovery", type=int, default=None, metavar="M",
                   help="phase 2: steering tasks the phase-1 controller flies first (default 2 x "
                        "--samples; written to OUT.discovery.db, resumable too)")
    p.add_argument("--extrapolate", type=float, default=0.25,
                   help="phase 2: share of samples drawn along the discovered control manifold "
                        "beyond its steering/elevation extremes (default 0.25; 0 = none)")
    p.add_argument("--method", choices=("knn", "lwlr"), default="lwlr",
                   help="phase 2: regression of the phase-1 controller that discovers (default lwlr)")
    p.add_argument("--alpha-max-deg", type=float, default=30.0,
                   help="phase 2: steering asked within +-this per wingbeat (default 30)")
    p.add_argument("--beta-max-deg", type=float, default=15.0,
                   help="phase 2: elevation asked within +-this per wingbeat (default 15)")
    p.add_argument("--pre-pitch-deg", type=float, default=None,
                   help="phase 1: pre-state pitch within +-this (default 45, the paper's)")
    p.add_argument("--pre-pitch-centre-deg", type=float, default=None, metavar="DEG",
                   help="phase 1: the pre-state pitch range's centre, deg, with a level cruise "
                        "velocity (default 0, the paper's; the cruise dove's trunk starts its "
                        "trimmed wingbeats at 18: docs/design/flight.md)")
    p.add_argument("--pre-roll-deg", type=float, default=None,
                   help="phase 1: pre-state roll within +-this (default 45, the paper's)")
    p.add_argument("--pre-velocity", type=float, default=None, metavar="M_S",
                   help="phase 1: pre-state linear velocity within +-this per body axis around cruise, "
                        "m/s (default 0.3, the paper's)")
    p.add_argument("--pre-angvel", type=float, default=None, metavar="DEG_S",
                   help="phase 1: pre-state angular velocity within +-this per body axis, deg/s "
                        "(default 4, the paper's)")
    p.add_argument("--pre-speed", type=float, default=None, metavar="M_S",
                   help="phase 1: the cruise speed pre-states are drawn around, m/s (default 7, "
                        "the paper's)")
    p.add_argument("--centre-flap-scale", type=float, default=None, metavar="S",
                   help="phase 1: draw the wingbeats around P0 with both shoulder-flap strokes "
                        "scaled by S (default 1: around P0)")
    p.add_argument("--centre-timewarp", type=float, default=None, metavar="W",
                   help="phase 1: ... and the cycle's duration times W (< 1: a faster beat; "
                        "default 1). See studies/dove_turn_limit.py for the wingbeats tight turns need")
    p.add_argument("--centre-wingbeat", default=None, metavar="FILE",
                   help="phase 1: draw the wingbeats around this wingbeat instead of P0: a JSON "
                        "file with its 29 parameters under \"wingbeat\" (as "
                        "studies/dove_wingbeat_search.py writes them) or as a bare list")
    p.add_argument("--reference-wingbeat", default=None, metavar="FILE",
                   help="phase 1: the reference wingbeat P0 itself (biases included), in the "
                        "same JSON as --centre-wingbeat: a gait the capture does not hold, "
                        "such as a slow-flight wingbeat trimmed by studies/dove_trim_power.py; "
                        "the controller then predicts with it and measures its trim")
    p.add_argument("--merge", nargs="+", default=None, metavar="DB",
                   help="instead of training: write the samples of these finished databases (of "
                        "the same dove and reference wingbeat) into one database --out, with "
                        "every source's provenance")
    p.add_argument("--chunk-size", type=int, default=None, metavar="C",
                   help="samples per work unit (default 16, or the resumed file's)")
    p.add_argument("--feathers", choices=("rigid", "modal"), default="rigid",
                   help="phase 1: the dove's feathers, rigid (default) or modal (bending; ~1.4x "
                        "slower); the database only serves a dove with the same feathers")
    p.add_argument("--table", default=None, metavar="NAME",
                   help="phase 1: the feather coefficient table the samples are flown with (default "
                        "dickinson1999_profile; dove_revolving: fitted to revolving dove wings, see "
                        "docs/flight.md); the database's controller flies with it")
    p.add_argument("--cruise", action="store_true",
                   help="phase 1: the cruise dove (a bird wing's section, its induced flow, the "
                        "cruise capture, its tail bias and 8.5 m/s; docs/flight.md); options given "
                        "beside it win")
    p.add_argument("--induced", action="store_true", default=None,
                   help="phase 1: the wings see the air their own lift pushes down (rigid "
                        "feathers; --cruise sets it)")
    p.add_argument("--tail-bias-deg", type=float, default=None,
                   help="phase 1: tail bend added to the reference wingbeat, deg (default 17, the "
                        "paper's)")
    p.add_argument("--twist-bias-deg", type=float, default=None,
                   help="phase 1: shoulder twist added to the reference wingbeat on both sides, deg "
                        "(default 0; - supinates: more lift, less thrust)")
    p.add_argument("--float32", action="store_true",
                   help="store the finished database's samples in single precision (half the "
                        "size: the bundled database is stored so)")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")


def _writable_file(path: str, flag: str) -> Path:
    p = Path(path)
    if p.is_dir():
        raise InputError(f"{flag} {path} is a folder; name a file")
    if p.exists() and not p.is_file():  # a device (/dev/full) is no database
        raise InputError(f"{flag} {path} is not a regular file (a device, pipe or socket); "
                         "name a file")
    parent = p.parent if str(p.parent) else Path(".")
    if not parent.is_dir():
        raise InputError(f"{flag} {path}: folder {parent} does not exist (create it first)")
    if not os.access(parent, os.W_OK | os.X_OK):
        raise InputError(f"{flag} {path}: folder {parent} is not writable")
    problem = write_problem(p)  # the permission bits can say yes where no file can be made
    if problem is not None:
        raise InputError(f"{flag} {path}: cannot create a file in {parent} ({problem})")
    if p.exists() and not os.access(p, os.R_OK | os.W_OK):
        raise InputError(f"{flag} {path} exists but is not readable and writable")
    return p


def validate(args: argparse.Namespace) -> None:
    """Check every argument before any work (one-line InputError)."""
    if getattr(args, "merge", None) is not None:
        validate_merge(args)
        return
    if args.samples is None:
        raise InputError("--samples N is required (unless --merge)")
    if not (1 <= args.samples <= 10**9):
        raise InputError(f"--samples must be 1..1e9, got {args.samples}")
    if args.workers is not None and not (1 <= args.workers <= 4096):
        raise InputError(f"--workers must be 1..4096, got {args.workers}")
    if args.sigma is not None and not (math.isfinite(args.sigma) and args.sigma > 0):
        raise InputError(f"--sigma must be a finite number > 0, got {args.sigma}")
    if args.chunk_size is not None and not (1 <= args.chunk_size <= 10**6):
        raise InputError(f"--chunk-size must be 1..1e6, got {args.chunk_size}")
    if args.address is not None and args.backend != "ray":
        raise InputError("--address is only for --backend ray")
    if args.backend == "ray":
        try:
            import ray  # noqa: F401
        except ImportError:
            raise InputError("--backend ray needs Ray: pip install 'flapsim[cluster]'") from None
        problem = address_problem(args.address) if args.address else None
        if problem:
            raise InputError(problem)
    out = _writable_file(args.out, "--out")
    if args.json:
        js = _writable_file(args.json, "--json")
        if js.resolve() == out.resolve():
            raise InputError("--json and --out name the same file")
    if args.phase == 1 and args.from_db is not None:
        raise InputError("--from is only for --phase 2")
    if args.discovery is not None and not (1 <= args.discovery <= 10**9):
        raise InputError(f"--discovery must be 1..1e9, got {args.discovery}")
    if not (math.isfinite(args.extrapolate) and 0 <= args.extrapolate <= 1):
        raise InputError(f"--extrapolate must be a share 0..1, got {args.extrapolate}")
    for flag, v, hi in (("--alpha-max-deg", args.alpha_max_deg, 90), ("--beta-max-deg",
                        args.beta_max_deg, 60), ("--pre-pitch-deg", args.pre_pitch_deg, 80),
                        ("--pre-roll-deg", args.pre_roll_deg, 80),
                        ("--pre-velocity", getattr(args, "pre_velocity", None), 10),
                        ("--pre-angvel", getattr(args, "pre_angvel", None), 720)):
        # (--pre-speed, --centre-flap-scale and --centre-timewarp: SamplingConfig.validate)
        if v is not None and not (math.isfinite(v) and 0 <= v <= hi):
            raise InputError(f"{flag} must be 0..{hi}, got {v}")
    if args.phase == 2 and any(getattr(args, k, None) is not None for k in (
            "pre_velocity", "pre_angvel", "pre_speed", "centre_flap_scale", "centre_timewarp",
            "centre_wingbeat", "pre_pitch_centre_deg", "reference_wingbeat")):
        raise InputError("--pre-velocity, --pre-angvel, --pre-speed, --centre-flap-scale, "
                         "--centre-timewarp, --centre-wingbeat and --reference-wingbeat are for "
                         "phase 1; phase 2 keeps "
                         "its --from database's pre-states and samples around its discovered "
                         "wingbeats")
    if args.phase == 2 and getattr(args, "feathers", "rigid") != "rigid":
        raise InputError("--feathers is for phase 1; phase 2 flies the dove of its --from database")
    if args.phase == 2 and (getattr(args, "table", None) or getattr(args, "tail_bias_deg", None) is not None
                            or getattr(args, "twist_bias_deg", None) is not None
                            or getattr(args, "cruise", False) or getattr(args, "induced", None)):
        raise InputError("--table, --tail-bias-deg, --twist-bias-deg, --induced and --cruise are "
                         "for phase 1; "
                         "phase 2 keeps its --from database's")
    if args.phase == 2:
        if args.from_db is None:
            raise InputError("--phase 2 needs --from DB (a phase-1 database)")
        src = Path(args.from_db)
        if not src.is_file():
            raise InputError(f"--from {args.from_db} does not exist or is not a file")
        if src.resolve() == out.resolve():
            raise InputError("--from and --out name the same file; choose another --out")


def read_centre_wingbeat(path: str, flag: str = "--centre-wingbeat") -> tuple[float, ...]:
    """--centre-wingbeat's (or ``flag``'s) file: a JSON list of numbers, or an object with one
    under ``wingbeat``; its length and values are checked with the rest of the configuration."""

    try:
        data = json.loads(Path(path).read_text())
    except FileNotFoundError:
        raise InputError(f"{flag} {path} does not exist") from None
    except (OSError, UnicodeDecodeError, ValueError) as exc:
        raise InputError(f"{flag} {path} is not a JSON file ({type(exc).__name__}): give "
                         "the JSON that studies/dove_wingbeat_search.py writes") from None
    if isinstance(data, dict):
        data = data.get("wingbeat")
    if not isinstance(data, list) or not all(
            isinstance(x, (int, float)) and not isinstance(x, bool) for x in data):
        raise InputError(f"{flag} {path} holds no list of numbers (a list, or one "
                         "under \"wingbeat\")")
    require_finite(data, f"{flag} {path}", "wingbeat")
    return tuple(float(x) for x in data)


def phase1(args: argparse.Namespace) -> tuple[Any, type]:
    """The phase-1 sampler: (config, worker class)."""
    kwargs: dict[str, Any] = {"seed": args.seed}
    if getattr(args, "cruise", False):
        if getattr(args, "feathers", "rigid") != "rigid":
            raise InputError("--cruise needs rigid feathers (modal ones do not see the induced "
                             "flow yet): drop --feathers modal")
        kwargs.update(table=CRUISE.table, tail_bias_deg=CRUISE.tail_bias_deg,
                      cruise_speed=CRUISE.speed, capture_preset="cruise", induced=True)
    if args.sigma is not None:
        kwargs["sigma"] = args.sigma
    if getattr(args, "pre_pitch_deg", None) is not None:
        kwargs["pitch_deg"] = args.pre_pitch_deg
    if getattr(args, "pre_pitch_centre_deg", None) is not None:
        kwargs["pitch_centre_deg"] = float(args.pre_pitch_centre_deg)
    if getattr(args, "pre_roll_deg", None) is not None:
        kwargs["roll_deg"] = args.pre_roll_deg
    if getattr(args, "pre_velocity", None) is not None:
        kwargs["linvel"] = args.pre_velocity
    if getattr(args, "pre_angvel", None) is not None:
        kwargs["angvel_deg_s"] = args.pre_angvel
    for arg, key in (("pre_speed", "cruise_speed"), ("centre_flap_scale", "centre_flap_scale"),
                     ("centre_timewarp", "centre_timewarp")):
        if getattr(args, arg, None) is not None:
            kwargs[key] = float(getattr(args, arg))
    if getattr(args, "centre_wingbeat", None) is not None:
        kwargs["centre_wingbeat"] = read_centre_wingbeat(args.centre_wingbeat)
    if getattr(args, "reference_wingbeat", None) is not None:
        if any(getattr(args, k, None) is not None for k in ("tail_bias_deg", "twist_bias_deg")):
            raise InputError("--reference-wingbeat gives the whole reference, its biases included: "
                             "leave out --tail-bias-deg and --twist-bias-deg")
        if getattr(args, "cruise", False):
            raise InputError("--reference-wingbeat replaces the capture's reference: leave out "
                             "--cruise (give its table and --induced instead)")
        kwargs["reference_wingbeat"] = read_centre_wingbeat(args.reference_wingbeat,
                                                            "--reference-wingbeat")
    if getattr(args, "feathers", "rigid") != "rigid":
        kwargs["feathers"] = args.feathers
    if getattr(args, "table", None):
        kwargs["table"] = get_table(args.table).name  # an unknown name: one-line error here
    if getattr(args, "twist_bias_deg", None) is not None:
        kwargs["twist_bias_deg"] = float(args.twist_bias_deg)
    if getattr(args, "tail_bias_deg", None) is not None:
        kwargs["tail_bias_deg"] = float(args.tail_bias_deg)
    if getattr(args, "induced", None):
        if kwargs.get("feathers", "rigid") != "rigid":
            raise InputError("--induced needs rigid feathers (modal ones do not see the induced "
                             "flow yet): drop --feathers modal")
        kwargs["induced"] = True
    config = SamplingConfig(**kwargs)
    config.validate()  # here, one line: in a worker it would only kill the pool
    return config, SampleWorker


def discovery_path(out: str | Path) -> Path:
    """Where phase 2 keeps its discovered samples: next to ``--out``."""
    out = Path(out)
    return out.with_name(out.name + ".discovery.db")


#: Phase 2's ellipse scale: the discovered wingbeats already spread along the control
#: manifold, so the lower end of the paper's 2..4 keeps the new samples on it.
PHASE2_SIGMA = 2.0


def run_phase2(args: argparse.Namespace) -> tuple[Any, type]:
    """Phase 2 (the paper's sec. 5.2): the phase-1 controller flies ``--discovery`` random
    steering tasks into ``OUT.discovery.db`` (step 1, trained and resumable like any
    database); returns the resampling step's (config, worker class): phase-1 sampling
    around the discovered wingbeats, with ``--extrapolate`` of the samples along the
    discovered manifold beyond its extremes."""

    src = Path(args.from_db).resolve()
    base = read_header(src).get("config") or {}
    disc_out = discovery_path(args.out)
    n_disc = args.discovery or 2 * args.samples
    dcfg = DiscoveryConfig(seed=args.seed, db=str(src), method=args.method,
                           alpha_max_deg=args.alpha_max_deg, beta_max_deg=args.beta_max_deg)
    cfg = SamplingConfig.from_dict({**base, "seed": args.seed,
                                    "sigma": args.sigma if args.sigma is not None else PHASE2_SIGMA,
                                    "source": str(disc_out.resolve()),
                                    "extrapolate": args.extrapolate})
    # both files are checked before step 1 flies (a minute or more): the final --out too
    workers = args.workers or os.cpu_count() or 1
    for c, w, o, n, kind in ((dcfg, DiscoveryWorker, disc_out, n_disc, "dove-discovery"),
                             (cfg, SampleWorker, Path(args.out), args.samples, "dove-phase2")):
        check_out(c, o, n, w, workers, args.backend, args.address, args.chunk_size, kind)
    print(f"phase 2, step 1: {n_disc} steering tasks with the controller of {src.name} "
          f"-> {disc_out}")
    step1 = train_from_args(args, dcfg, DiscoveryWorker, kind="dove-discovery", out=disc_out,
                            n_samples=n_disc)
    args._phase2_discovery = step1
    print(f"phase 2, step 2: {args.samples} samples around the discovered wingbeats -> {args.out}")
    return cfg, SampleWorker


def train_from_args(args: argparse.Namespace, config: Any, worker_cls: type, kind: str,
                    out: str | Path | None = None, n_samples: int | None = None) -> dict:
    """Run :func:`flapsim.bird.training.train.train` for parsed arguments and print the summary."""

    workers = args.workers or os.cpu_count() or 1
    s = train(config, out or args.out, n_samples or args.samples, worker_cls, workers=workers,
              backend=args.backend,
              address=args.address, chunk_size=args.chunk_size,
              progress=not getattr(args, "no_progress", False), kind=kind,
              float32=getattr(args, "float32", False))
    rej = ", ".join(f"{k} {v}" for k, v in s["rejected"].items()) or "none"
    if s["already_complete"]:
        print(f"{s['out']} is already complete: {s['samples']} samples ({s['examined']} examined, "
              f"rejected: {rej})")
    else:
        resumed = f", resumed at {s['resumed_samples']}" if s["resumed_samples"] else ""
        print(f"{s['out']}: {s['samples']} samples from {s['examined']} examined "
              f"(acceptance {s['acceptance']:.1%}; rejected: {rej}){resumed}")
        print(f"  {s['wall_s']:.1f} s, {s['samples_per_s']:.1f} samples/s on {s['workers']} "
              f"{s['backend']} worker{'s' if s['workers'] != 1 else ''} "
              f"(start-up {s['startup_s']:.1f} s), model {s['model_hash']}, seed {s['seed']}")
    return {"phase": args.phase, **s}


#: Training options that mean nothing to --merge (it refuses them rather than ignore them).
_NOT_FOR_MERGE = (("samples", None, "--samples"), ("phase", 1, "--phase"), ("sigma", None, "--sigma"),
                  ("from_db", None, "--from"), ("discovery", None, "--discovery"),
                  ("pre_pitch_deg", None, "--pre-pitch-deg"), ("pre_roll_deg", None, "--pre-roll-deg"),
                  ("pre_pitch_centre_deg", None, "--pre-pitch-centre-deg"),
                  ("pre_velocity", None, "--pre-velocity"), ("pre_angvel", None, "--pre-angvel"),
                  ("pre_speed", None, "--pre-speed"), ("centre_flap_scale", None, "--centre-flap-scale"),
                  ("centre_timewarp", None, "--centre-timewarp"),
                  ("centre_wingbeat", None, "--centre-wingbeat"),
                  ("reference_wingbeat", None, "--reference-wingbeat"),
                  ("chunk_size", None, "--chunk-size"), ("feathers", "rigid", "--feathers"),
                  ("float32", False, "--float32"), ("table", None, "--table"),
                  ("tail_bias_deg", None, "--tail-bias-deg"), ("twist_bias_deg", None, "--twist-bias-deg"))


def validate_merge(args: argparse.Namespace) -> None:
    for name, default, flag in _NOT_FOR_MERGE:
        if getattr(args, name, default) != default:
            raise InputError(f"{flag} is for training; --merge only joins finished databases")
    if len(args.merge) < 2:
        raise InputError(f"--merge needs at least two databases, got {len(args.merge)}")
    out = _writable_file(args.out, "--out")
    if out.exists() and not any(Path(s).resolve() == out.resolve() for s in args.merge):
        raise InputError(f"--out {args.out} exists; --merge writes a new database: choose "
                         "another --out, or delete it first")
    for src in args.merge:
        p = Path(src)
        if p.resolve() == out.resolve():
            raise InputError(f"--merge {src} and --out name the same file; choose another --out")
        if not p.is_file():
            raise InputError(f"--merge {src} does not exist or is not a file")
    if len({Path(s).resolve() for s in args.merge}) != len(args.merge):
        raise InputError("--merge names the same database twice")
    if args.json:
        js = _writable_file(args.json, "--json")
        if js.resolve() == out.resolve():
            raise InputError("--json and --out name the same file")


def run_merge(args: argparse.Namespace) -> dict:
    db = merge_databases(args.merge, args.out)
    parts = db.header["provenance"]["parts"]
    print(f"{args.out}: {db.n} samples from {len(parts)} databases ("
          + ", ".join(f"{Path(p['path']).name}: {p['samples']}" for p in parts)
          + f"), model {db.header['model_hash']}")
    return {"merged": [str(s) for s in args.merge], "out": str(args.out), "samples": db.n,
            "parts": [{"path": p["path"], "samples": p["samples"], "sha256": p["sha256"]} for p in parts],
            "model_hash": db.header["model_hash"]}


def run(args: argparse.Namespace) -> dict:
    validate(args)
    if getattr(args, "merge", None) is not None:
        return run_merge(args)
    if args.phase == 1:
        config, worker_cls = phase1(args)
    else:
        config, worker_cls = run_phase2(args)
    result = train_from_args(args, config, worker_cls, kind=f"dove-phase{args.phase}")
    if args.phase == 2:
        result["discovery"] = args._phase2_discovery
    return result


def resume_hint(args: argparse.Namespace) -> str:
    """What an interrupted (Ctrl-C) or terminated (SIGTERM) training tells the user."""
    return "" if getattr(args, "merge", None) else "; run the same command again to resume"
