"""Pieces the subcommands share: the parser whose usage errors are one line, the argparse types
of numeric options, the check that no output overwrites an input, comma-separated name options
and the progress bar of the benchmarks that run every (scenario, estimator) pair."""

from __future__ import annotations

import argparse
import math
import os
import re
from collections.abc import Callable, Iterator, Mapping
from contextlib import contextmanager
from pathlib import Path
from typing import NoReturn

from rich.console import Console
from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn

from jointangle.errors import InputError


class UsageError(InputError):
    """A command line argparse refused (a bad option value, a missing option); `prog` is the
    (sub)command it belongs to, e.g. "jointangle simulate"."""

    def __init__(self, message: str, *, prog: str, field: str | None = None) -> None:
        self.prog = prog
        super().__init__(message, field=field)


class Parser(argparse.ArgumentParser):
    """argparse whose errors are one line and exit 2 like every other bad input: `error`
    raises UsageError (main prints it) instead of printing the usage and exiting. Subparsers
    made with `add_subparsers` are of the same class."""

    def error(self, message: str) -> NoReturn:
        m = re.fullmatch(r"argument (\S+): (.*)", message, flags=re.DOTALL)
        if m is None:
            raise UsageError(f"{message} (see {self.prog} --help)", prog=self.prog)
        raise UsageError(m.group(2), prog=self.prog, field=m.group(1))


# argparse types of numeric options: a refused value is reported by the parser as one line
# naming the option (`field '--seed': must be an integer ≥ 0, got '-1'`).


def _number(text: str, kind: type[int] | type[float], what: str) -> float:
    try:
        value = kind(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"must be {what}, got {text!r}") from None
    if not math.isfinite(value):
        raise argparse.ArgumentTypeError(f"must be {what}, got {text!r}")
    return value


def positive_float(text: str) -> float:
    """A finite number > 0 (durations, rates, lengths, timeouts, gravity, noise density)."""
    value = _number(text, float, "a finite number > 0")
    if not value > 0:
        raise argparse.ArgumentTypeError(f"must be a finite number > 0, got {text!r}")
    return value


def nonnegative_float(text: str) -> float:
    """A finite number ≥ 0 (delays, margins)."""
    value = _number(text, float, "a finite number ≥ 0")
    if not value >= 0:
        raise argparse.ArgumentTypeError(f"must be a finite number ≥ 0, got {text!r}")
    return value


def positive_int(text: str) -> int:
    """An integer ≥ 1 (counts: seeds, jobs, frames, baud rate)."""
    value = int(_number(text, int, "an integer ≥ 1"))
    if value < 1:
        raise argparse.ArgumentTypeError(f"must be an integer ≥ 1, got {text!r}")
    return value


MAX_EVERY = 255  # start_stream.every is a byte


def every_count(text: str) -> int:
    """--every: an integer 1..255 (start_stream.every)."""
    value = positive_int(text)
    if value > MAX_EVERY:
        raise argparse.ArgumentTypeError(f"must be at most {MAX_EVERY}, got {text!r}")
    return value


def nonnegative_int(text: str) -> int:
    """An integer ≥ 0 (noise seeds: numpy's are non-negative; retry counts)."""
    value = int(_number(text, int, "an integer ≥ 0"))
    if value < 0:
        raise argparse.ArgumentTypeError(f"must be an integer ≥ 0, got {text!r}")
    return value


def add_stream_options(p: argparse.ArgumentParser) -> None:
    """--stream full|estimates and --every N (live, record)."""
    p.add_argument("--stream", choices=("full", "estimates"), default="full",
                   help="what the board streams: full = every sensor's raw counts with the "
                   "estimate (needed by the firmware-vs-mirror divergence, host filters and "
                   "replay --verify); estimates = the estimate, its health and which sensors are "
                   "at fault only (27 bytes a frame instead of ~70: fits 115 200 baud and "
                   "Bluetooth serial links at the board's rate). Default: full")
    p.add_argument("--every", type=every_count, default=1, metavar="N",
                   help="the board sends its per-loop frame every Nth loop, 1..255 (status "
                   "frames are not thinned); above 1 the host cannot follow the board's filter "
                   "(no divergence, host filter or verification). Default: 1")


def stream_checks(args: argparse.Namespace) -> bool:
    """True when the stream carries what a host-side filter needs (full frames,
    every loop). Otherwise a --host-filter asked for by name is refused and the default one
    switched off (args.host_filter = "none")."""
    if args.stream == "full" and args.every == 1:
        return True
    if args.host_filter not in (None, "none"):
        raise InputError(f"--host-filter {args.host_filter} needs the raw readings of every "
                         "loop: --stream full --every 1", field="--host-filter")
    args.host_filter = "none"
    return False


def _same_file(a: str | Path, b: str | Path) -> bool:
    try:
        return os.path.samefile(a, b)
    except OSError:  # one of them does not exist (yet): the same path is still the same file
        return Path(a).resolve() == Path(b).resolve()


def refuse_overwrite(inputs: Mapping[str, str | Path | None],
                     outputs: Mapping[str, str | Path | None]) -> None:
    """Refuse, before anything is written, an output path that is the same file as an input
    (or as another output): {option: path} of each, None for an option not given."""
    given_out = [(o, p) for o, p in outputs.items() if p is not None]
    for k, (out_opt, out) in enumerate(given_out):
        for in_opt, src in inputs.items():
            if src is not None and _same_file(out, src):
                raise InputError(f"is the same file as {in_opt} ({src}): refusing to overwrite "
                                 "an input; write to another file", field=out_opt)
        for other_opt, other in given_out[:k]:
            if _same_file(out, other):
                raise InputError(f"is the same file as {other_opt} ({other}): each output "
                                 "needs its own file", field=out_opt)


def parse_names(value: str | None, known: list[str], option: str) -> list[str] | None:
    """Names from a comma-separated option, each checked against `known`; None when empty."""
    if not value:
        return None
    names = [v.strip() for v in value.split(",") if v.strip()]
    for n in names:
        if n not in known:
            raise InputError(f"unknown name {n!r}; known: {', '.join(known)}", field=option)
    return names


@contextmanager
def pair_progress(description: str, total: int) -> Iterator[Callable[[str, str], None]]:
    """A progress bar on stderr (only on a terminal) over `total` (scenario, name) tasks;
    yields the callback that marks one done."""
    err = Console(stderr=True)
    with Progress(TextColumn("[progress.description]{task.description}"), BarColumn(),
                  MofNCompleteColumn(), TimeElapsedColumn(), console=err, transient=True,
                  disable=not err.is_terminal) as progress:
        task = progress.add_task(description, total=total)

        def tick(scenario: str, name: str) -> None:
            progress.update(task, advance=1, description=f"{scenario} {name}")

        yield tick
