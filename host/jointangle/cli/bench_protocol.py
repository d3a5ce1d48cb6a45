"""`jointangle bench protocol`: the bulk, streaming and construct decoders timed on one log.

Implementation: jointangle.bench.protocol.run_protocol_bench (see its docstring for what is timed).
"""

from __future__ import annotations

import argparse
import json
import sys

from jointangle.bench.protocol import DEFAULT_FRAMES, describe_protocol, run_protocol_bench
from jointangle.cli.common import nonnegative_int, positive_int
from jointangle.errors import InputError


def register(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    p = sub.add_parser(
        "protocol", help="decoder speed: numpy bulk vs streaming vs per-frame construct",
        description="Time the three host decoders on the same synthetic 500 Hz log (four "
        "sensors, the high-rate frame) after checking that the bulk and streaming decoders agree "
        "on it and on a corrupted copy.")
    p.add_argument("--json", action="store_true", help="print one JSON object on stdout")
    p.add_argument("--frames", type=positive_int, default=DEFAULT_FRAMES,
                   help=f"high-rate frames in the log (default {DEFAULT_FRAMES})")
    p.add_argument("--seed", type=nonnegative_int, default=0, help="seed of the synthetic log")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    if args.frames < 1000:
        raise InputError("use at least 1000 frames for a meaningful timing", field="--frames")
    doc = run_protocol_bench(args.frames, seed=args.seed)
    sys.stdout.write((json.dumps(doc) if args.json else describe_protocol(doc)) + "\n")
    return 0
