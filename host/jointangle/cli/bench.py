"""`jointangle bench KIND`: the project's benchmarks, as a table or `--json`."""

from __future__ import annotations

import argparse
import json
import os
import sys
from typing import Any

from rich.console import Console
from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn
from rich.table import Table

from jointangle.bench.accuracy import DEFAULT_SEEDS, run_accuracy
from jointangle.errors import InputError
from jointangle.estimators.registry import ESTIMATORS
from jointangle.sim.scenarios import scenario_names

KINDS = ("accuracy",)


def register(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    p = sub.add_parser(
        "bench", help="run a benchmark (accuracy of every estimator, ...)",
        description="Run one of the project's benchmarks. `accuracy`: every estimator on the "
        "DESIGN.md §5 scenarios over noise seeds 0..N-1, steady (t ≥ 5 s) and start-up RMS "
        "θ error, side by side with the paper's published figures.")
    p.add_argument("kind", choices=KINDS, help="which benchmark")
    p.add_argument("--json", action="store_true", help="print one JSON object on stdout")
    p.add_argument("--seeds", type=int, default=DEFAULT_SEEDS,
                   help=f"number of noise seeds (default {DEFAULT_SEEDS})")
    p.add_argument("--scenarios", help="comma-separated scenario names (default: all of "
                   f"{', '.join(scenario_names())})")
    p.add_argument("--filters", help="comma-separated estimators (default: all of "
                   f"{', '.join(ESTIMATORS)})")
    p.add_argument("--jobs", type=int, default=min(os.cpu_count() or 1, 4),
                   help="worker processes (default: CPU count, at most 4)")
    p.set_defaults(func=run)


def _names(value: str | None, known: list[str], option: str) -> list[str] | None:
    if not value:
        return None
    names = [v.strip() for v in value.split(",") if v.strip()]
    for n in names:
        if n not in known:
            raise InputError(f"unknown name {n!r}; known: {', '.join(known)}", field=option)
    return names


def _fmt(v: float | None, digits: int = 2) -> str:
    return "—" if v is None else f"{v:.{digits}f}"


def print_accuracy(doc: dict[str, Any], console: Console) -> None:
    for sc in doc["scenarios"]:
        paper = sc["paper"].get("theta_rms_deg", {})
        table = Table(title=f"{sc['name']}  ({doc['seeds']} seeds; RMS θ error, degrees)",
                      title_justify="left")
        for col in ("filter", "steady", "worst seed", "start-up", "× ekf steady",
                    "× ekf start-up", "ω_a °/s", "ω_b °/s", "lag ms", "paper"):
            table.add_column(col, justify="left" if col == "filter" else "right")
        for name, f in sc["filters"].items():
            lat = f["latency_ms"]
            table.add_row(
                name, _fmt(f["theta_rms_deg"]), _fmt(f["theta_worst_seed_deg"]),
                _fmt(f["theta_rms_startup_deg"]), _fmt(f["theta_ratio_to_ekf"]),
                _fmt(f["startup_ratio_to_ekf"]), _fmt(f["omega_a_rms_dps"]),
                _fmt(f["omega_b_rms_dps"]), "offline" if lat is None else f"{lat:g}",
                _fmt(paper.get(name)))
        console.print(table)


def run(args: argparse.Namespace) -> int:
    if args.seeds < 1:
        raise InputError("must be at least 1", field="--seeds")
    scenarios = _names(args.scenarios, scenario_names(), "--scenarios")
    filters = _names(args.filters, list(ESTIMATORS), "--filters")
    n_tasks = len(scenarios or scenario_names()) * len(set((filters or list(ESTIMATORS))
                                                            + ["ekf"]))
    err = Console(stderr=True)
    with Progress(TextColumn("[progress.description]{task.description}"), BarColumn(),
                  MofNCompleteColumn(), TimeElapsedColumn(), console=err, transient=True,
                  disable=not err.is_terminal) as progress:
        task = progress.add_task("bench accuracy", total=n_tasks)

        def tick(scenario: str, name: str) -> None:
            progress.update(task, advance=1, description=f"{scenario} {name}")

        doc = run_accuracy(scenarios, filters, args.seeds, max(1, args.jobs), tick)
    if args.json:
        json.dump(doc, sys.stdout)
        sys.stdout.write("\n")
    else:
        print_accuracy(doc, Console())
    return 0
