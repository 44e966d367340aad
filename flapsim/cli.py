"""``flapsim <command>``: the command-line entry point.

Each command lives in ``flapsim/commands/<name>.py`` and defines ``HELP`` (one line),
``add_arguments(parser)`` and ``run(args) -> dict``. ``run`` prints a readable summary
and returns the machine-readable result that ``--json PATH`` writes (atomically).
Every command gets ``--json`` and ``--seed``. Errors that are the user's to fix
(:class:`flapsim.errors.FlapsimError`) print one line and exit with status 2.
"""

from __future__ import annotations

import argparse
import importlib
import logging
import sys
import time
from collections.abc import Sequence

from flapsim import __version__
from flapsim.errors import FlapsimError

# Order is the order ``flapsim --help`` lists them in.
COMMANDS: tuple[str, ...] = ("fly", "train", "swim", "sweep", "modes", "creature", "animate",
                             "demo", "bench")


class _Parser(argparse.ArgumentParser):
    """argparse with a one-line error (no usage dump) and exit status 2."""

    def error(self, message: str) -> None:  # noqa: D401 - argparse API
        self.exit(2, f"{self.prog}: error: {message} (see '{self.prog} --help')\n")


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(
        prog="flapsim",
        description="Simulate birds, swimmers and modal creatures in MuJoCo.",
    )
    parser.add_argument("--version", action="version", version=f"flapsim {__version__}")
    parser.add_argument("-v", "--verbose", action="store_true", help="log progress details")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser)
    for name in COMMANDS:
        module = importlib.import_module(f"flapsim.commands.{name}")
        p = sub.add_parser(name, help=module.HELP, description=module.HELP)
        p.add_argument("--json", metavar="PATH", help="write the results as JSON to PATH")
        p.add_argument("--seed", type=int, default=0, help="random seed (default 0)")
        module.add_arguments(p)
        p.set_defaults(_module=module)
    return parser


def _route_mujoco_warnings() -> None:
    """MuJoCo writes its warnings (an unstable simulation, a full contact buffer) to
    ``MUJOCO_LOG.TXT`` in the working directory. In the CLI's own process send them to
    the log on stderr instead, each message text once. (Library users keep MuJoCo's
    default: the handler is process-wide, so flapsim does not set it on import.)"""
    import mujoco

    seen: set[str] = set()
    log = logging.getLogger("flapsim.mujoco")

    def warn(message: str) -> None:
        if message not in seen:
            seen.add(message)
            log.warning("%s", message.strip())

    mujoco.set_mju_user_warning(warn)


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if args.command is None:
        parser.print_help()
        return 2
    logging.basicConfig(
        level=logging.INFO if args.verbose else logging.WARNING,
        format="%(levelname)s %(name)s: %(message)s",
    )
    from flapsim.io import write_json

    _route_mujoco_warnings()

    t0 = time.perf_counter()
    try:
        result = args._module.run(args)
        if args.json:
            result = dict(result)
            result.setdefault("command", args.command)
            result.setdefault("flapsim_version", __version__)
            result.setdefault("seed", args.seed)
            result.setdefault("wall_time_s", time.perf_counter() - t0)
            write_json(args.json, result)
            print(f"results written to {args.json}")
    except FlapsimError as exc:
        print(f"flapsim {args.command}: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        hint = "; run the same command again to resume" if args.command == "train" else ""
        print(f"flapsim {args.command}: interrupted{hint}", file=sys.stderr)
        return 130
    return 0


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
