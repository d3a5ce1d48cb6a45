"""Entry point of the `jointangle` console script.

Each subcommand lives in its own module exposing `register(subparsers)`, which adds its parser and
sets `func` to a `run(args) -> int`. Bad input (`InputError`) prints one clear line and exits 2;
so does a command line argparse refuses (`cli.common.Parser`: a bad option value, a missing option).
"""

from __future__ import annotations

import argparse
import importlib
import os
import sys
from collections.abc import Sequence

from jointangle import __version__
from jointangle.cli.common import Parser, UsageError
from jointangle.errors import InputError

# Subcommand name -> module that implements it; build_parser imports each one to register its
# parser.
SUBCOMMANDS: dict[str, str] = {
    "simulate": "jointangle.cli.simulate",
    "estimate": "jointangle.cli.estimate",
    "bench": "jointangle.cli.bench",
    "plot": "jointangle.cli.plot",
    "design": "jointangle.cli.design",
    "replay": "jointangle.cli.replay",
    "calibrate": "jointangle.cli.calibrate",
    "info": "jointangle.cli.info",
    "configure": "jointangle.cli.configure",
    "record": "jointangle.cli.record",
    "live": "jointangle.cli.live",
    "flash": "jointangle.cli.flash",
    "doctor": "jointangle.cli.doctor",
}


def build_parser() -> argparse.ArgumentParser:
    parser = Parser(
        prog="jointangle",
        description="Joint angles from accelerometer arrays: simulate rigs, run the reference "
        "estimators, benchmark them, and talk to the jointangle firmware.",
    )
    parser.add_argument("--version", action="version", version=f"jointangle {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    sub.required = True
    for module_name in SUBCOMMANDS.values():
        importlib.import_module(module_name).register(sub)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    try:
        args = parser.parse_args(argv)
    except UsageError as exc:
        print(f"{exc.prog}: error: {exc}", file=sys.stderr)
        return 2
    try:
        return int(args.func(args))
    except InputError as exc:
        print(f"jointangle {args.command}: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return 130
    except BrokenPipeError:
        # The reader went away (`... --json-lines | head`): stop quietly, and keep Python's
        # final flush of stdout from raising again.
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        return 0
    except OSError as exc:
        # A file this command could not open or write (missing folder, no permission, ...):
        # one line naming it, like every other bad input.
        where = f"{exc.filename}: " if exc.filename else ""
        print(f"jointangle {args.command}: error: {where}{exc.strerror or exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    raise SystemExit(main())
