"""``flapsim <command>``: the command-line entry point.

Each command lives in ``flapsim/cli/commands/<name>.py`` and defines ``HELP`` (one line),
``add_arguments(parser)`` and ``run(args) -> dict``. ``run`` prints a readable summary
and returns the machine-readable result that ``--json PATH`` writes (atomically).
Every command gets ``--json`` (``-``: stdout, the readable summary then goes to stderr)
and ``--seed``. A module may also define ``SEED_HELP`` (say so when ``--seed`` changes
nothing) and ``EXIT_STATUS`` (extra exit-status lines for its ``--help``).

Before ``run``, :func:`flapsim.core.validate.check_outputs` checks every input file and output
path the command declared with :mod:`flapsim.core.validate`'s helpers (numbers are checked by
their argparse types while parsing), so nothing is simulated on arguments that would fail.

Exit statuses (:data:`EXIT_STATUS`): 0 done; 1 some runs of a batch failed, or the system
refused a write (disk full); 2 bad input or a diverged simulation, one line naming it;
130 Ctrl-C, 143 SIGTERM (no partial file is left: outputs are written to a temporary file
and renamed).
"""

from __future__ import annotations

import argparse
import contextlib
import importlib
import json
import logging
import signal
import sys
import threading
import time
from collections.abc import Sequence

import mujoco

from flapsim import __version__
from flapsim.core import environment, interrupts
from flapsim.core.errors import FlapsimError, OutputError
from flapsim.core.io import _jsonable, write_json
from flapsim.core.validate import add_output_arg, check_outputs, declare_options, guard_gl

# Order is the order ``flapsim --help`` lists them in.
COMMANDS: tuple[str, ...] = ("fly", "eval", "view", "train", "swim", "sweep", "modes", "creature",
                             "animate", "demo", "bench", "list")


#: Exit statuses every command shares (each command's ``--help`` lists them).
EXIT_STATUS = """exit status:
  0    done
  2    bad input (a one-line message names it), or the simulation diverged
  130  interrupted by Ctrl-C, 143 by SIGTERM (no partial output file is left)"""


Terminated = interrupts.Terminated


def _on_sigterm(signum, frame):  # noqa: ARG001 - signal handler API
    interrupts.signalled(Terminated)


def _on_sigint(signum, frame):  # noqa: ARG001 - signal handler API
    # Python's own handler raises KeyboardInterrupt; recorded too, for where it gets dropped
    interrupts.signalled(KeyboardInterrupt)


class _Parser(argparse.ArgumentParser):
    """argparse with a one-line error (no usage dump) and exit status 2."""

    def error(self, message: str) -> None:  # noqa: D401 - argparse API
        self.exit(2, f"{self.prog}: error: {message} (see '{self.prog} --help')\n")


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(
        prog="flapsim",
        description="Simulate birds, swimmers and modal creatures in MuJoCo.",
        epilog="'flapsim COMMAND --help' describes a command; 'flapsim list' names what they "
               "accept.\n\n" + EXIT_STATUS.replace("  2    bad", "  1    some runs of a batch "
                                                      "failed (sweep, eval)\n  2    bad"),
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    # the packages too: a bug report (or a flight near the limits) depends on them
    parser.add_argument("--version", action="version",
                        version=f"flapsim {__version__} ({environment.tag().split(', ', 1)[1]})")
    parser.add_argument("-v", "--verbose", action="store_true", help="log progress details")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser)
    for name in COMMANDS:
        module = importlib.import_module(f"flapsim.cli.commands.{name}")
        extra = getattr(module, "EXIT_STATUS", "")
        epilog = EXIT_STATUS + ("\n" + extra if extra else "")
        p = sub.add_parser(name, help=module.HELP, description=module.HELP, epilog=epilog,
                           formatter_class=argparse.RawDescriptionHelpFormatter)
        add_output_arg(p, "--json", stdout=True,
                       help="write the results as JSON to PATH ('-': to stdout)")
        p.add_argument("--seed", type=int, default=0,
                       help=getattr(module, "SEED_HELP", "random seed (default 0)"))
        module.add_arguments(p)
        declare_options(p)
        p.set_defaults(_module=module)
    return parser


def _route_mujoco_warnings() -> None:
    """MuJoCo writes its warnings (an unstable simulation, a full contact buffer) to
    ``MUJOCO_LOG.TXT`` in the working directory. In the CLI's own process send them to
    the log on stderr instead, each message text once. (Library users keep MuJoCo's
    default: the handler is process-wide, so flapsim does not set it on import.)"""
    seen: set[str] = set()
    log = logging.getLogger("flapsim.mujoco")

    def warn(message: str) -> None:
        if message not in seen:
            seen.add(message)
            log.warning("%s", message.strip())

    mujoco.set_mju_user_warning(warn)


def _stopped(args: argparse.Namespace, by: type[BaseException]) -> int:
    """The one line and exit status of a command stopped by SIGINT (130) or SIGTERM (143),
    with the command's hint on how to resume."""
    hint = args._module.resume_hint(args) if hasattr(args._module, "resume_hint") else ""
    if by is KeyboardInterrupt:
        print(f"flapsim {args.command}: interrupted{hint}", file=sys.stderr)
        return 130
    print(f"flapsim {args.command}: terminated (SIGTERM){hint}", file=sys.stderr)
    return 143


def main(argv: Sequence[str] | None = None) -> int:
    guard_gl()  # also done on importing flapsim.cli, before mujoco: see flapsim/cli/__init__.py
    parser = build_parser()
    try:
        args = parser.parse_args(argv)
    except SystemExit as exc:  # --help, --version, or a one-line argparse error (status 2)
        return exc.code if isinstance(exc.code, int) else 2
    if args.command is None:
        parser.print_help()
        return 2
    logging.basicConfig(
        level=logging.INFO if args.verbose else logging.WARNING,
        format="%(levelname)s %(name)s: %(message)s",
    )
    _route_mujoco_warnings()

    to_stdout = args.json == "-"
    handlers = {}  # the signals' previous handlers, restored at the end
    interrupts.clear()
    if threading.current_thread() is threading.main_thread():
        for sig, handler in ((signal.SIGTERM, _on_sigterm), (signal.SIGINT, _on_sigint)):
            handlers[sig] = signal.signal(sig, handler)
    t0 = time.perf_counter()
    status = 0
    try:
        check_outputs(args)
        # with --json -, stdout carries the JSON alone: the readable summary goes to stderr
        with contextlib.redirect_stdout(sys.stderr) if to_stdout else contextlib.nullcontext():
            result = args._module.run(args)
        status = int(result.get("exit_status", 0) or 0) if isinstance(result, dict) else 0
        if args.json:
            result = dict(result)
            result.setdefault("command", args.command)
            result.setdefault("flapsim_version", __version__)
            result.setdefault("environment", environment.versions())  # see flapsim.core.environment
            result.setdefault("seed", args.seed)
            result.setdefault("wall_time_s", time.perf_counter() - t0)
            if to_stdout:
                print(json.dumps(_jsonable(result), indent=2))
            else:
                write_json(args.json, result)
                print(f"results written to {args.json}")
                if hasattr(args._module, "finished"):
                    args._module.finished(args)  # e.g. eval's journal of finished runs
    except OutputError as exc:  # the system refused a write: not the user's input
        print(f"flapsim {args.command}: error: {exc}", file=sys.stderr)
        return 1
    except FlapsimError as exc:
        print(f"flapsim {args.command}: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        return _stopped(args, KeyboardInterrupt)
    except Terminated:
        return _stopped(args, Terminated)
    except Exception as exc:
        # a signal raised inside a C call that turned it into an error of its own (SIGTERM in
        # the EGL context's ctypes call while a video renders: ctypes.ArgumentError
        # "argument 1: Terminated"): the signal it recorded says what stopped the command
        signalled = interrupts.pending()
        if signalled in (KeyboardInterrupt, Terminated):
            return _stopped(args, signalled)
        if isinstance(exc, OSError):  # the system refused a read or write the checks could not foresee
            what = f"{exc.strerror or exc}" + (f": {exc.filename}" if exc.filename else "")
            print(f"flapsim {args.command}: error: {what}", file=sys.stderr)
            return 1
        raise
    finally:
        for sig, old in handlers.items():
            # None: the handler was set outside Python; Python's defaults stand in for it
            default = signal.default_int_handler if sig == signal.SIGINT else signal.SIG_DFL
            signal.signal(sig, default if old is None else old)
        interrupts.clear()
    return status


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
