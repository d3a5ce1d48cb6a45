"""`jointangle design`: where to put the sensors, and what error to expect."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

import numpy as np
from rich.console import Console
from rich.table import Table

from jointangle.cli.common import nonnegative_float, positive_float, positive_int
from jointangle.design import (
    MAX_BUS_SENSORS,
    build_rig,
    count_gain,
    crb0_theta,
    pcrb_theta,
    rank_placements,
    reference_motion,
    simulate_errors,
    steady_rms,
)
from jointangle.design_figures import write_placement_report
from jointangle.errors import InputError
from jointangle.estimators.registry import ESTIMATORS
from jointangle.io.rig_file import write_rig
from jointangle.sensors import SENSOR_MODELS
from jointangle.sim.scenarios import scenario_names

COUNT_NOTE = ("Extra sensors cut the steady error as √κ for every estimator, the filters "
              "included, but not the start-up of `ekf`/`ukf` from x₀ = 0, which dominates a "
              "whole-run score (the paper's 'minimal benefit'; reports/placement/placement.md).")


def register(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    p = sub.add_parser(
        "design", help="recommend sensor positions and predict the joint-angle error",
        description="Rank sensor placements for two links of given lengths by the posterior "
        "Cramér–Rao bound of the array model (no noise drawn, fast), then check the best and "
        "the paper's placement (sensors at 0 and L/2 from the joint) by simulation over noise "
        "seeds with the chosen filters. With --paper-figures, redo the paper's Figs. 5–7 "
        "(error vs number of sensors, vs l and d, the l/d floor) as PNGs and Markdown.")
    p.add_argument("--la", type=positive_float, default=0.30, help="length of link a in metres "
                   "(default 0.30)")
    p.add_argument("--lb", type=positive_float, default=0.30, help="length of link b in metres "
                   "(default 0.30; the slider-crank motion needs lb > la)")
    p.add_argument("--model", default="adxl345", choices=list(SENSOR_MODELS),
                   help="accelerometer model (default adxl345; its datasheet noise and LSB)")
    p.add_argument("--noise-ug", type=positive_float, help="noise density in µg/√Hz instead of the "
                   "datasheet's")
    p.add_argument("--n", type=positive_int, default=2, help="sensors per link (default 2)")
    p.add_argument("--rate", type=positive_float, default=100.0,
                   help="sample rate in Hz, 10-1000 as the board (default 100)")
    p.add_argument("--motion", default="gravity-slow-periodic", choices=scenario_names(),
                   metavar="SCENARIO", help="reference motion: a scenario name; paper-* is "
                   "the slider-crank on these links, gravity-* link b moving on a clamped "
                   "link a (default gravity-slow-periodic)")
    p.add_argument("--margin", type=nonnegative_float, default=0.01,
                   help="keep sensors this far (m) from the joint and the link end "
                   "(default 0.01)")
    p.add_argument("--filters", default="ekf,array-ekf",
                   help="filters to simulate (default ekf,array-ekf)")
    p.add_argument("--seeds", type=positive_int, default=4, help="noise seeds (default 4)")
    p.add_argument("--rig-out", help="write the recommended rig file here")
    p.add_argument("--paper-figures", metavar="DIR",
                   help="instead, redo the paper's Figs. 5–7 into DIR (slow: minutes)")
    p.add_argument("--json", action="store_true", help="print one JSON object on stdout")
    p.set_defaults(func=run)


DESIGN_RATE_HZ = (10.0, 1000.0)  # the firmware's set_rate range (APP.md)


def _check(args: argparse.Namespace) -> list[str]:
    if args.n < 2:
        raise InputError("each link needs at least two sensors", field="--n")
    if not DESIGN_RATE_HZ[0] <= args.rate <= DESIGN_RATE_HZ[1]:
        raise InputError(f"{args.rate:g} Hz is outside {DESIGN_RATE_HZ[0]:g}-"
                         f"{DESIGN_RATE_HZ[1]:g} Hz, the rates the board samples at",
                         field="--rate")
    if args.rig_out and 2 * args.n > MAX_BUS_SENSORS:
        raise InputError(f"a rig file addresses at most {MAX_BUS_SENSORS} sensors (8 mux "
                         f"channels × 2 addresses), {2 * args.n} asked; simulate without "
                         "--rig-out", field="--n")
    if not args.margin < min(args.la, args.lb) / 2:
        raise InputError("must be ≥ 0 and less than half the shorter link", field="--margin")
    if args.motion.startswith("paper-") and args.lb <= args.la:
        raise InputError("the slider-crank needs link b longer than link a", field="--lb")
    filters = [f.strip() for f in args.filters.split(",") if f.strip()]
    for f in filters:
        if f not in ESTIMATORS:
            raise InputError(f"unknown filter {f!r}; choose from {', '.join(ESTIMATORS)}",
                             field="--filters")
        if f == "incl-kf":
            raise InputError("incl-kf needs gyro data, which design does not simulate",
                             field="--filters")
    return filters


def run(args: argparse.Namespace) -> int:
    if args.paper_figures:
        doc = write_placement_report(Path(args.paper_figures), args.seeds)
        if args.json:
            json.dump(doc, sys.stdout)
            sys.stdout.write("\n")
        else:
            print((Path(args.paper_figures) / "placement.md").read_text(encoding="utf-8"))
        return 0
    filters = _check(args)
    motion = reference_motion(args.motion, args.la, args.lb, args.rate)
    quantize = args.noise_ug is None
    ranked = rank_placements(args.la, args.lb, args.n, motion, args.model, args.rate,
                             args.noise_ug, args.margin)
    best = ranked[0]
    t = motion.mech.t
    seeds = range(args.seeds)

    def evaluate(da: list[float], db: list[float], label: str) -> dict[str, Any]:
        rig = build_rig(args.la, args.lb, da, db, args.model, args.rate, args.noise_ug,
                        quantize)
        sims = simulate_errors(rig, motion, filters, seeds)
        return {
            "label": label,
            "positions_a_m": [round(x, 4) for x in da],
            "positions_b_m": [round(x, 4) for x in db],
            "pcrb_deg": round(float(np.degrees(steady_rms(pcrb_theta(rig, motion), t))), 4),
            "crb_per_sample_deg": round(float(np.degrees(steady_rms(crb0_theta(rig, motion),
                                                                    t))), 4),
            "simulated_deg": {f: {"mean": round(float(np.mean(v)), 4),
                                  "worst": round(float(np.max(v)), 4)}
                              for f, v in sims.items()},
        }

    rec = evaluate(list(best.dist_a), list(best.dist_b), "recommended")
    paper = evaluate([0.0, args.la / 2] if args.n == 2 else list(np.linspace(0, args.la / 2,
                                                                             args.n)),
                     [0.0, args.lb / 2] if args.n == 2 else list(np.linspace(0, args.lb / 2,
                                                                             args.n)),
                     "paper (0 and L/2)")
    gain = count_gain(args.la, args.lb, best.dist_a, best.dist_b)
    doc = {"la_m": args.la, "lb_m": args.lb, "model": args.model, "n_per_link": args.n,
           "rate_hz": args.rate, "motion": args.motion, "seeds": args.seeds,
           "candidates_ranked": len(ranked), "recommended": rec, "paper_placement": paper,
           "more_sensors": {"error_factor_vs_two": gain, "note": COUNT_NOTE},
           "note": "positions are distances from the joint along each link (m)"}
    if args.rig_out:
        write_rig(build_rig(args.la, args.lb, list(best.dist_a), list(best.dist_b),
                            args.model, args.rate, args.noise_ug, quantize), args.rig_out)
    if args.json:
        json.dump(doc, sys.stdout)
        sys.stdout.write("\n")
        return 0
    con = Console()
    table = Table(title=f"design: L_a={args.la:g} m, L_b={args.lb:g} m, {args.n}× {args.model} "
                  f"per link, {args.rate:g} Hz, motion {args.motion} ({args.seeds} seeds)",
                  title_justify="left")
    for col in ("placement", "link a (m from joint)", "link b (m from joint)", "PCRB °",
                "per-sample bound °", *[f"{f} ° (worst)" for f in filters]):
        table.add_column(col, justify="left" if "link" in col or col == "placement"
                         else "right")
    for row in (rec, paper):
        table.add_row(row["label"], ", ".join(f"{x:.3f}" for x in row["positions_a_m"]),
                      ", ".join(f"{x:.3f}" for x in row["positions_b_m"]),
                      f"{row['pcrb_deg']:.3f}", f"{row['crb_per_sample_deg']:.2f}",
                      *[f"{row['simulated_deg'][f]['mean']:.3f} "
                        f"({row['simulated_deg'][f]['worst']:.3f})" for f in filters])
    con.print(table)
    con.print("More sensors on the recommended spans (noise-limited error × "
              "√(κ(N)/κ(2)), evenly over the span / stacked at its ends): "
              + "; ".join(f"N = {g['n']}: ×{g['even']:.2f} / ×{g['ends']:.2f}" for g in gain)
              + ". " + COUNT_NOTE)
    con.print("Put the sensors as far apart as the link allows (large d) and keep the array's "
              "mean close to the joint relative to d (small l/d); give both links a similar "
              "l/d — the worse link sets the floor.")
    return 0
