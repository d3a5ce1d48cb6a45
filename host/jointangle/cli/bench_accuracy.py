"""`jointangle bench accuracy`: every estimator on every scenario (table, JSON, Markdown)."""

from __future__ import annotations

import argparse
import json
import os
import sys
from typing import Any

from rich.console import Console
from rich.table import Table

from jointangle.bench.accuracy import DEFAULT_SEEDS, count_tasks, run_accuracy
from jointangle.bench.report import report_footer, report_header
from jointangle.cli.common import pair_progress, parse_names, positive_int
from jointangle.errors import InputError
from jointangle.estimators.registry import ESTIMATORS
from jointangle.sim.as_built import AS_BUILT_LEVELS
from jointangle.sim.scenarios import scenario_names


def register(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    p = sub.add_parser(
        "accuracy", help="every estimator on every scenario (docs/design.md §5)",
        description="Every estimator on the docs/design.md §5 scenarios over noise seeds 0..N-1: "
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
    levels = ", ".join(f"{k}: {v.description}" for k, v in AS_BUILT_LEVELS.items())
    p.add_argument("--as-built", nargs="?", const=",".join(AS_BUILT_LEVELS), metavar="LEVELS",
                   help="also run every scenario on rigs as built (seed s = build s; the "
                   "estimators read the nominal rig) and show each figure next to the ideal "
                   "geometry's, with the ratio as built / ideal (per seed, averaged); JSON: an "
                   "'as_built' object in each scenario. LEVELS: comma-separated, default all "
                   f"({levels}; docs/as-built.md)")
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


def _levels(doc: dict[str, Any]) -> list[str]:
    return list(doc.get("as_built_levels", {}))


def print_as_built(doc: dict[str, Any], console: Console) -> None:
    levels = _levels(doc)
    for sc in doc["scenarios"]:
        table = Table(title=f"{sc['name']} as built ({doc['seeds']} seeds, one build each; RMS "
                      "θ error, degrees; × = as built / ideal)", title_justify="left")
        table.add_column("filter", no_wrap=True, min_width=16)
        table.add_column("ideal", justify="right")
        for lv in levels:
            table.add_column(lv, justify="right")
            table.add_column("×", justify="right")
        table.add_column("start-up ideal", justify="right")
        for lv in levels:
            table.add_column(lv, justify="right")
        for name, f in sc["filters"].items():
            row = [name, _fmt(f["theta_rms_deg"], 3)]
            for lv in levels:
                g = sc["as_built"][lv]["filters"][name]
                row += [_fmt(g["theta_rms_deg"], 3), _fmt(g["theta_ratio_to_ideal"], 2)]
            row.append(_fmt(f["theta_rms_startup_deg"], 3))
            row += [_fmt(sc["as_built"][lv]["filters"][name]["theta_rms_startup_deg"], 3)
                    for lv in levels]
            table.add_row(*row)
        console.print(table)


def markdown_as_built(doc: dict[str, Any]) -> str:
    """Ideal vs as-built figures as one Markdown table."""
    levels = _levels(doc)
    head = " | ".join(f"{lv} steady (× ideal)" for lv in levels)
    head_st = " | ".join(f"{lv} start-up" for lv in levels)
    lines = [
        f"Steady RMS θ error (t ≥ {doc['startup_s']:g} s) and start-up RMS (t < "
        f"{doc['startup_s']:g} s), degrees, mean over {doc['seeds']} seeds; as built, seed s "
        "is build s; × ideal = as built / ideal geometry, per seed, then averaged. Levels: "
        + "; ".join(f"`{k}` {v}" for k, v in doc.get("as_built_levels", {}).items()) + ".",
        "",
        f"| scenario | estimator | ideal steady | {head} | ideal start-up | {head_st} |",
        "|---|---|---|" + "---|" * len(levels) + "---|" + "---|" * len(levels),
    ]
    for sc in doc["scenarios"]:
        for name, f in sc["filters"].items():
            cells = [f"{_fmt(f['theta_rms_deg'], 3)}"]
            for lv in levels:
                g = sc["as_built"][lv]["filters"][name]
                cells.append(f"{_fmt(g['theta_rms_deg'], 3)} "
                             f"({_fmt(g['theta_ratio_to_ideal'], 1)}×)")
            cells.append(_fmt(f["theta_rms_startup_deg"], 3))
            cells += [_fmt(sc["as_built"][lv]["filters"][name]["theta_rms_startup_deg"], 3)
                      for lv in levels]
            lines.append(f"| {sc['name']} | `{name}` | " + " | ".join(cells) + " |")
    return "\n".join(lines)


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


def _command(args: argparse.Namespace, as_built: list[str]) -> str:
    """The run's command without --jobs (which does not change a figure)."""
    parts = ["jointangle bench accuracy --markdown", f"--seeds {args.seeds}"]
    if args.scenarios:
        parts.append(f"--scenarios {args.scenarios}")
    if args.filters:
        parts.append(f"--filters {args.filters}")
    if as_built:
        parts.append(f"--as-built {','.join(as_built)}")
    return " ".join(parts)


def run(args: argparse.Namespace) -> int:
    scenarios = parse_names(args.scenarios, scenario_names(), "--scenarios")
    filters = parse_names(args.filters, list(ESTIMATORS), "--filters")
    as_built: list[str] = []
    if args.as_built is not None:
        as_built = [x.strip() for x in args.as_built.split(",") if x.strip()]
        unknown = [x for x in as_built if x not in AS_BUILT_LEVELS]
        if unknown or not as_built:
            raise InputError(f"unknown as-built level {', '.join(unknown) or '(none)'!s}; "
                             f"choose from {', '.join(AS_BUILT_LEVELS)}", field="--as-built")
    n_tasks = count_tasks(scenarios, filters, as_built)
    with pair_progress("bench accuracy", n_tasks) as tick:
        doc = run_accuracy(scenarios, filters, args.seeds, max(1, args.jobs), tick,
                           as_built=as_built)
    if args.json:
        json.dump(doc, sys.stdout)
        sys.stdout.write("\n")
    elif args.markdown:
        # A generated report: the command and a fingerprint of its sources open it, so a test
        # can tell when it is stale (bench/report.py; reports/accuracy.md).
        print(report_header(_command(args, as_built)))
        print("\n# Accuracy: every estimator on every scenario\n")
        print(markdown_accuracy(doc))
        if as_built:
            print()
            print(markdown_as_built(doc))
        print()
        print(report_footer())
    else:
        out = Console()
        console = out if out.is_terminal else Console(width=120)
        print_accuracy(doc, console)
        if as_built:
            print_as_built(doc, console)
    return 0
