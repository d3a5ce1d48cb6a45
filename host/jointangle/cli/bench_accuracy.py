"""`jointangle bench accuracy`: every estimator on every scenario (table, JSON, Markdown)."""

from __future__ import annotations

import argparse
import json
import os
import sys
from typing import Any

from rich.console import Console
from rich.table import Table

from jointangle.bench.accuracy import DEFAULT_SEEDS, default_filters, run_accuracy
from jointangle.cli.common import pair_progress, parse_names, positive_int
from jointangle.estimators.registry import ESTIMATORS
from jointangle.sim.scenarios import scenario_names


def register(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    p = sub.add_parser(
        "accuracy", help="every estimator on every scenario (DESIGN.md §5)",
        description="Every estimator on the DESIGN.md §5 scenarios over noise seeds 0..N-1: "
        "steady (t ≥ 5 s) and start-up RMS θ error, ratios to `ekf` (per seed, averaged), ω "
        "errors and latency, side by side with the paper's published figures.")
    out = p.add_mutually_exclusive_group()
    out.add_argument("--json", action="store_true", help="print one JSON object on stdout")
    out.add_argument("--markdown", action="store_true",
                     help="print Markdown tables (for reports and the README)")
    p.add_argument("--seeds", type=positive_int, default=DEFAULT_SEEDS,
                   help=f"number of noise seeds (default {DEFAULT_SEEDS})")
    p.add_argument("--scenarios", help="comma-separated scenario names (default: all of "
                   f"{', '.join(scenario_names())})")
    p.add_argument("--filters", help="comma-separated estimators (default: all of "
                   f"{', '.join(ESTIMATORS)})")
    p.add_argument("--jobs", type=positive_int, default=min(os.cpu_count() or 1, 4),
                   help="worker processes (default: CPU count, at most 4)")
    p.set_defaults(func=run)


def _fmt(v: float | None, digits: int = 2) -> str:
    return "—" if v is None else f"{v:.{digits}f}"


def print_accuracy(doc: dict[str, Any], console: Console) -> None:
    for sc in doc["scenarios"]:
        paper = sc["paper"].get("theta_rms_deg", {})
        table = Table(title=f"{sc['name']}  ({doc['seeds']} seeds; RMS θ error, degrees)",
                      title_justify="left")
        for col in ("filter", "steady", "worst", "start-up", "×ekf", "×ekf st", "ω_a °/s",
                    "ω_b °/s", "lag ms", "paper"):
            if col == "filter":
                table.add_column(col, no_wrap=True, min_width=16)
            else:
                table.add_column(col, justify="right")
        for name, f in sc["filters"].items():
            lat = f["latency_ms"]
            table.add_row(
                name, _fmt(f["theta_rms_deg"], 3), _fmt(f["theta_worst_seed_deg"], 3),
                _fmt(f["theta_rms_startup_deg"], 3), _fmt(f["theta_ratio_to_ekf"], 3),
                _fmt(f["startup_ratio_to_ekf"], 3), _fmt(f["omega_a_rms_dps"]),
                _fmt(f["omega_b_rms_dps"]), "offline" if lat is None else f"{lat:g}",
                _fmt(paper.get(name)))
        console.print(table)


def markdown_accuracy(doc: dict[str, Any]) -> str:
    """The accuracy document as Markdown: one row per scenario and estimator."""
    lines = [
        f"Steady = RMS θ error over t ≥ {doc['startup_s']:g} s, mean over {doc['seeds']} seeds "
        f"(worst seed in brackets); start-up = RMS over t < {doc['startup_s']:g} s; ratios to "
        "`ekf` taken per seed, then averaged.",
        "",
        "| scenario | estimator | lag | steady θ (°) | × ekf | start-up θ (°) | × ekf "
        "| ω_a (°/s) | ω_b (°/s) | paper θ (°) |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    for sc in doc["scenarios"]:
        paper = sc["paper"].get("theta_rms_deg", {})
        for name, f in sc["filters"].items():
            lat = f["latency_ms"]
            lag = "offline" if lat is None else f"{lat:g} ms"
            lines.append(
                f"| {sc['name']} | `{name}` | {lag} | {_fmt(f['theta_rms_deg'])} "
                f"({_fmt(f['theta_worst_seed_deg'])}) | {_fmt(f['theta_ratio_to_ekf'], 3)} | "
                f"{_fmt(f['theta_rms_startup_deg'])} | {_fmt(f['startup_ratio_to_ekf'], 3)} | "
                f"{_fmt(f['omega_a_rms_dps'])} | {_fmt(f['omega_b_rms_dps'])} | "
                f"{_fmt(paper.get(name))} |")
    return "\n".join(lines)


def run(args: argparse.Namespace) -> int:
    scenarios = parse_names(args.scenarios, scenario_names(), "--scenarios")
    filters = parse_names(args.filters, list(ESTIMATORS), "--filters")
    n_tasks = len(scenarios or scenario_names()) * len(set((filters or default_filters())
                                                            + ["ekf"]))
    with pair_progress("bench accuracy", n_tasks) as tick:
        doc = run_accuracy(scenarios, filters, args.seeds, max(1, args.jobs), tick)
    if args.json:
        json.dump(doc, sys.stdout)
        sys.stdout.write("\n")
    elif args.markdown:
        print(markdown_accuracy(doc))
    else:
        out = Console()
        print_accuracy(doc, out if out.is_terminal else Console(width=120))
    return 0
