"""`jointangle simulate`: run a named scenario and write the accelerations CSV (with truth)."""

from __future__ import annotations

import argparse
import json
import sys

from jointangle.cli.common import nonnegative_int, positive_float, refuse_overwrite
from jointangle.errors import InputError
from jointangle.io.atomic import check_output_paths
from jointangle.io.csv_formats import AccelData, Truth, write_accel_csv
from jointangle.io.rig_file import load_rig, write_rig
from jointangle.sim.gyro import gyro_readings, with_gyros
from jointangle.sim.scenarios import (
    DEFAULT_RATE_HZ,
    DEFAULT_SECONDS,
    all_scenario_names,
    get_scenario,
    scenario_names,
    simulate,
)

MAX_SAMPLES = 10_000_000  # per run (28 h at 100 Hz): ~1.3 GB for each float64 copy of 16 columns


def register(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    p = sub.add_parser(
        "simulate", help="simulate a rig and write an accelerations CSV with truth columns",
        description="Simulate one of the named scenarios (docs/design.md §5; motion parameters in "
        "the README) and write every sensor's specific force (m/s², sensor frame) plus the "
        "truth columns theta, omega_a, omega_b.")
    p.add_argument("--scenario", required=True, choices=all_scenario_names(), metavar="NAME",
                   help=f"one of: {', '.join(scenario_names())}; gravity-free-motion: both "
                   "links swinging freely, a motion for `calibrate --method motion`; "
                   "NAME-as-built simulates the "
                   "rig as built (positions and joints ±2 mm, mountings ±0.2°, the board's read "
                   "skew; drawn from --seed; --rig-out writes them as sim_* fields, which the "
                   "estimators ignore), NAME-as-built-uncal the same with mountings ±1°, "
                   "NAME-as-built-clocks as NAME-as-built with each part converting on its "
                   "own clock (any phase, ±2 percent; docs/as-built.md)")
    p.add_argument("--seed", type=nonnegative_int, default=0, help="noise seed (default 0)")
    p.add_argument("--rate", type=positive_float, default=DEFAULT_RATE_HZ,
                   help=f"sample rate in Hz (default {DEFAULT_RATE_HZ:g})")
    p.add_argument("--seconds", type=positive_float, default=DEFAULT_SECONDS,
                   help=f"duration in seconds (default {DEFAULT_SECONDS:g})")
    p.add_argument("--rig", help="use this rig file's sensors instead of the scenario's own "
                   "(same mechanism and motion)")
    p.add_argument("--gyros", action="store_true",
                   help="make every sensor a BNO055 (accelerometer + gyro at the same place) and "
                   "write its gyro columns a.0.gx,… too (rigs with BNO055s always get them)")
    p.add_argument("--out", required=True, help="accelerations CSV to write")
    p.add_argument("--rig-out", help="also write the rig file describing the simulated build")
    p.add_argument("--json", action="store_true",
                   help="print a one-line JSON summary on stdout")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    outputs = {"--out": args.out, "--rig-out": args.rig_out}
    refuse_overwrite({"--rig": args.rig}, outputs)
    check_output_paths(outputs)  # both writable, before either is written
    samples = args.rate * args.seconds
    if samples < 2:
        raise InputError(f"--rate x --seconds gives {samples:g} samples: at least 2 are needed",
                         field="--seconds")
    if samples > MAX_SAMPLES:
        raise InputError(f"--rate x --seconds gives {samples:.3g} samples, more than the "
                         f"{MAX_SAMPLES:,} this command holds in memory; simulate shorter runs",
                         field="--seconds")
    rig = load_rig(args.rig).with_sample_rate(args.rate) if args.rig else None
    if args.gyros:
        rig = with_gyros(rig if rig is not None else get_scenario(args.scenario).rig(args.rate))
    sim = simulate(args.scenario, seed=args.seed, rate_hz=args.rate, seconds=args.seconds,
                   rig=rig)
    data = AccelData(t=sim.t, readings=sim.readings,
                     gyro=gyro_readings(sim.rig, sim.mechanism, args.seed),
                     truth=Truth(sim.theta, sim.omega_a, sim.omega_b))
    write_accel_csv(args.out, sim.rig, data)
    if args.rig_out:
        write_rig(sim.rig, args.rig_out)
    print(f"wrote {len(sim.t)} samples of {len(sim.rig.all_sensors())} sensors to {args.out}"
          + (f" and the rig to {args.rig_out}" if args.rig_out else ""), file=sys.stderr)
    if args.json:
        print(json.dumps({"out": args.out, "rig_out": args.rig_out, "samples": len(sim.t),
                          "sensors": len(sim.rig.all_sensors()), "rate_hz": args.rate,
                          "gyro_columns": data.gyro is not None}))
    return 0
