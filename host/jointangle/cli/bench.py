"""`jointangle bench KIND`: the project's benchmarks (docs/design.md §4).

Each kind lives in its own module exposing `register(subparsers)`; add a line to `BENCH_KINDS`
to add one. Every kind prints a table by default and one JSON object with `--json`.
"""

from __future__ import annotations

import argparse
import importlib

BENCH_KINDS: dict[str, str] = {
    "accuracy": "jointangle.cli.bench_accuracy",
    "compare": "jointangle.cli.bench_compare",
    "protocol": "jointangle.cli.bench_protocol",
    "calibration": "jointangle.cli.bench_calibration",
    "parity": "jointangle.cli.bench_parity",
    "firmware": "jointangle.cli.bench_firmware",
    "host": "jointangle.cli.bench_host",
}


def register(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    p = sub.add_parser(
        "bench", help="run a benchmark: " + ", ".join(BENCH_KINDS),
        description="Run one of the project's benchmarks. Speed figures are ratios measured "
        "side by side in one run; accuracy figures come from several noise seeds.")
    kinds = p.add_subparsers(dest="kind", metavar="KIND")
    kinds.required = True
    for module_name in BENCH_KINDS.values():
        importlib.import_module(module_name).register(kinds)
