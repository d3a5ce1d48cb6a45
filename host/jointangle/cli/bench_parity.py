"""`jointangle bench parity`: the firmware core (x86 replay) against `mirror`, every scenario."""

from __future__ import annotations

import argparse
import json
import sys

from rich.console import Console
from rich.table import Table

from jointangle.bench.accuracy import DEFAULT_SEEDS
from jointangle.bench.parity import SENSORS_PER_LINK_CHOICES, run_parity
from jointangle.cli.common import positive_int
from jointangle.errors import InputError
from jointangle.sim.scenarios import scenario_names


def register(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    p = sub.add_parser(
        "parity", help="firmware fixed-point core vs the float64 mirror (docs/design.md §5)",
        description="Replays every scenario's quantised readings through the firmware core "
        "(fixed point, x86 build of firmware/core) and through `mirror` (float64), both "
        "open-loop, and reports their largest differences against the docs/design.md §5 targets.")
    p.add_argument("--json", action="store_true", help="print one JSON object on stdout")
    p.add_argument("--seeds", type=positive_int, default=DEFAULT_SEEDS,
                   help=f"number of noise seeds (default {DEFAULT_SEEDS})")
    p.add_argument("--scenarios", help="comma-separated scenario names (default: all)")
    p.add_argument("--sensors-per-link", type=int, choices=SENSORS_PER_LINK_CHOICES,
                   help="re-build every scenario's rig with this many sensors per link, spread "
                   "over the same span (default: the scenario's own, 2)")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    scenarios = None
    if args.scenarios:
        scenarios = [s.strip() for s in args.scenarios.split(",") if s.strip()]
        for s in scenarios:
            if s not in scenario_names():
                raise InputError(f"unknown scenario {s!r}; known: {', '.join(scenario_names())}",
                                 field="--scenarios")
    doc = run_parity(scenarios, args.seeds, args.sensors_per_link)
    if args.json:
        json.dump(doc, sys.stdout)
        sys.stdout.write("\n")
        return 0
    t = doc["targets"]
    table = Table(title=f"firmware core vs mirror ({doc['seeds']} seeds; from "
                  f"{doc['from_s']:g} s unless stated)", title_justify="left")
    for col in ("scenario", "max |Δθ| °", "RMS Δθ °", "max |Δω| °/s", "start-up |Δθ| °",
                "saturations", "ok"):
        table.add_column(col, justify="left" if col == "scenario" else "right")
    for sc in doc["scenarios"]:
        table.add_row(sc["name"], f"{sc['max_abs_dtheta_deg']:.5f}",
                      f"{sc['rms_dtheta_deg']:.5f}", f"{sc['max_abs_domega_dps']:.4f}",
                      f"{sc['startup_max_abs_dtheta_deg']:.4f}", str(sc["saturations"]),
                      "yes" if sc["within_targets"] else "NO")
    table.add_row("target", f"{t['max_abs_dtheta_deg']}", f"{t['rms_dtheta_deg']}",
                  f"{t['max_abs_domega_dps']}", f"{t['startup_max_abs_dtheta_deg']}", "", "")
    Console().print(table)
    return 0
