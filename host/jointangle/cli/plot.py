"""`jointangle plot`: estimates against truth and the error over time, as an image (PNG, ...)."""

from __future__ import annotations

import argparse
import json
import sys

import numpy as np

from jointangle.cli.common import nonnegative_int, refuse_overwrite
from jointangle.errors import InputError
from jointangle.estimators.base import Estimates, sensor_to_link
from jointangle.estimators.inputs import check_inputs, run_estimator
from jointangle.estimators.registry import ESTIMATORS, get_estimator
from jointangle.io.atomic import check_output_paths
from jointangle.io.csv_formats import Truth, read_accel_csv, read_estimates_csv
from jointangle.io.rig_file import load_rig
from jointangle.plotting import image_format, plot_estimates
from jointangle.sim.scenarios import scenario_names, simulate

DEFAULT_FILTERS = "smooth,ekf,array-fls"


def register(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    p = sub.add_parser(
        "plot", help="plot estimates against truth and the error over time (PNG)",
        description="Plot θ, ω_a, ω_b of one or more estimators against the truth, and the θ "
        "error over time (the paper's Figs. 3–4). The data come from a scenario (simulated "
        "on the spot) or from --rig and --input; estimates are computed with --filters "
        "and/or read from estimates CSVs with --estimates.")
    src = p.add_mutually_exclusive_group(required=True)
    src.add_argument("--scenario", choices=scenario_names(), metavar="NAME",
                     help=f"simulate one of: {', '.join(scenario_names())}")
    src.add_argument("--input", help="accelerations CSV (with truth columns for the error)")
    p.add_argument("--rig", help="rig file for --input (a --scenario has its own)")
    p.add_argument("--seed", type=nonnegative_int, default=0, help="noise seed for --scenario")
    p.add_argument("--filters", default=DEFAULT_FILTERS,
                   help=f"comma-separated estimators to run (default {DEFAULT_FILTERS}; "
                   "'' for none)")
    p.add_argument("--estimates", nargs="*", default=[], metavar="EST.csv",
                   help="estimates CSVs to overlay (from `jointangle estimate`)")
    p.add_argument("--out", required=True,
                   help="image to write; its extension gives the format (.png, .pdf, .svg, ...)")
    p.add_argument("--json", action="store_true",
                   help="print a one-line JSON summary on stdout")
    p.set_defaults(func=run)


def _check_command_line(args: argparse.Namespace) -> None:
    """What can be refused before any data is read or any estimator runs."""
    if args.scenario and args.rig:
        raise InputError("--rig is for --input: a --scenario simulates its own rig (run "
                         "`simulate --rig` and plot its CSV with --input)", field="--rig")
    if args.input and not args.rig:
        raise InputError("--input needs --rig", field="--rig")
    refuse_overwrite({"--input": args.input, "--rig": args.rig}, {"--out": args.out})
    for path in args.estimates:
        refuse_overwrite({"--estimates": path}, {"--out": args.out})
    image_format(args.out, "--out")
    check_output_paths({"--out": args.out})


def run(args: argparse.Namespace) -> int:
    _check_command_line(args)
    if args.scenario:
        sim = simulate(args.scenario, seed=args.seed)
        rig, t, readings, gyro = sim.rig, sim.t, sim.readings, None
        truth: Truth | None = Truth(sim.theta, sim.omega_a, sim.omega_b)
        title = f"{args.scenario}, seed {args.seed}"
    else:
        rig = load_rig(args.rig)
        data = read_accel_csv(args.input, rig)
        t, readings, gyro, truth = data.t, data.readings, data.gyro, data.truth
        title = args.input
    names = [n.strip() for n in args.filters.split(",") if n.strip()]
    for n in names:
        if n not in ESTIMATORS:
            raise InputError(f"unknown filter {n!r}; choose from {', '.join(ESTIMATORS)}",
                             field="--filters")
    acc = sensor_to_link(rig, readings)[None]
    estimators = {n: get_estimator(n) for n in names}
    for est in estimators.values():  # refused before any runs, as estimate does
        check_inputs(est, rig, readings, gyro)
    results: dict[str, Estimates] = {
        n: run_estimator(est, rig, acc, None if gyro is None else gyro[None])
        for n, est in estimators.items()}
    for path in args.estimates:
        table = read_estimates_csv(path)
        if len(table.t) != len(t) or not np.allclose(table.t, t, atol=1e-6):
            raise InputError("its time column does not match the accelerations'", path=path,
                             field="t")
        results[path] = Estimates(np.radians(table.theta_deg)[None],
                                  np.radians(table.omega_a_dps)[None],
                                  np.radians(table.omega_b_dps)[None])
    if not results:
        raise InputError("nothing to plot: give --filters or --estimates", field="--filters")
    plot_estimates(args.out, t, results, truth, title)
    print(f"wrote {args.out}", file=sys.stderr)
    if args.json:
        print(json.dumps({"out": args.out, "series": list(results)}))
    return 0
