"""`jointangle bench compare`: every method on every scenario (table, JSON, Markdown report)."""

from __future__ import annotations

import argparse
import json
import os
import sys
from pathlib import Path
from typing import Any

from rich.console import Console
from rich.table import Table

from jointangle.bench.compare import losses, run_compare, write_report
from jointangle.cli.common import pair_progress, parse_names, positive_int
from jointangle.estimators.registry import ESTIMATORS
from jointangle.sim.scenarios import scenario_names


def register(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    p = sub.add_parser(
        "compare", help="every method (paper, ours, neighbours) on every scenario, with report",
        description="Run the paper's filters, ours and the neighbouring methods (incl-kf: "
        "accelerometers + gyro; madgwick-array: redundant-array pseudoinverse; array-ekf-rom: "
        "El-Gohary ROM + stationary updates) on every scenario with BNO055 rigs (gyro output "
        "with bias drift). Prints a table, one JSON object with --json, and with --report DIR "
        "writes report.md with error-over-time and error-vs-speed plots.")
    p.add_argument("--json", action="store_true", help="print one JSON object on stdout")
    p.add_argument("--report", metavar="DIR", help="write report.md and PNGs into DIR")
    p.add_argument("--seeds", type=positive_int, default=20, help="noise seeds (default 20)")
    p.add_argument("--scenarios", help="comma-separated scenario names (default: all)")
    p.add_argument("--methods", help="comma-separated methods (default: all of "
                   f"{', '.join(ESTIMATORS)})")
    p.add_argument("--jobs", type=positive_int, default=min(os.cpu_count() or 1, 4),
                   help="worker processes (default: CPU count, at most 4)")
    p.set_defaults(func=run)


def _table(doc: dict[str, Any], console: Console) -> None:
    scenarios = list(doc["methods"][0]["scenarios"])
    table = Table(title=f"bench compare: steady RMS θ error (°), {doc['seeds']} seeds",
                  title_justify="left")
    table.add_column("method", no_wrap=True)
    for sc in scenarios:
        table.add_column(sc.replace("paper-table2-", "").replace("gravity-", "g-"),
                         justify="right")
    for m in doc["methods"]:
        table.add_row(m["name"], *[
            "n/a" if m["scenarios"][sc]["theta_rms_deg"] is None
            else f"{m['scenarios'][sc]['theta_rms_deg']:.3f}" for sc in scenarios])
    console.print(table)
    for line in losses(doc):
        console.print(f"ours loses: {line}")


def run(args: argparse.Namespace) -> int:
    scenarios = parse_names(args.scenarios, scenario_names(), "--scenarios")
    methods = parse_names(args.methods, list(ESTIMATORS), "--methods")
    n_tasks = len(scenarios or scenario_names()) * len(methods or ESTIMATORS)
    with pair_progress("bench compare", n_tasks) as tick:
        doc = run_compare(scenarios, methods, args.seeds, max(1, args.jobs), tick)
    if args.report:
        argv = ["jointangle bench compare", f"--seeds {args.seeds}", f"--report {args.report}"]
        if args.scenarios:
            argv.append(f"--scenarios {args.scenarios}")
        if args.methods:
            argv.append(f"--methods {args.methods}")
        path = write_report(doc, Path(args.report), " ".join(argv))
        Console(stderr=True).print(f"wrote {path}")
    doc.pop("_traces", None)
    if args.json:
        json.dump(doc, sys.stdout)
        sys.stdout.write("\n")
    else:
        out = Console()
        _table(doc, out if out.is_terminal else Console(width=140))
    return 0
