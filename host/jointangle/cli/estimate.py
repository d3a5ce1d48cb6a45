"""`jointangle estimate`: run one estimator over an accelerations CSV."""

from __future__ import annotations

import argparse
import json
import sys

import numpy as np

from jointangle.cli.common import refuse_overwrite
from jointangle.errors import InputError
from jointangle.estimators.base import sensor_to_link
from jointangle.estimators.inputs import check_inputs, run_estimator
from jointangle.estimators.registry import ESTIMATORS, get_estimator
from jointangle.io.csv_formats import read_accel_csv, write_estimates_csv
from jointangle.io.rig_file import load_rig
from jointangle.model import rig_model
from jointangle.observability import observable
from jointangle.sim.sensor_timing import board_readings, parse_sensor_timing


def register(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    lines = "\n".join(f"  {name:18s} {f().description}" for name, f in ESTIMATORS.items())
    p = sub.add_parser(
        "estimate", help="estimate θ and ω from an accelerations CSV",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        description="Run an estimator on recorded or simulated accelerations. It reads only the "
        "rig file and the acceleration columns (never truth columns).\n\nfilters:\n" + lines)
    p.add_argument("--rig", required=True, help="rig file (TOML)")
    p.add_argument("--input", required=True, help="accelerations CSV")
    p.add_argument("--filter", required=True, choices=list(ESTIMATORS), metavar="NAME",
                   help="estimator name (see the list above)")
    p.add_argument("--out", required=True, help="estimates CSV to write")
    p.add_argument("--sensor-timing", default="rows", metavar="rows|board[:L[:S]]",
                   help="how CSV rows become loop samples: 'rows' (default: row k is the sample "
                   "of step k) or 'board': as the board's loop reads its sensors, each sensor's "
                   "latest conversion on its own ODR grid (the firmware's choice for the model "
                   "and rate, phase 0 = t 0), the CSV linearly interpolated there and rounded to "
                   "the part's counts; 'board:L': row k's sample was read L loop periods before "
                   "the row's t (a float; 0 = the native board, which reads at the loop's "
                   "start; 1 = the AVR build, which pipelines its reads by one period; "
                   "negative = a loop grid that runs after the rows, −phase/period); "
                   "'board:L:S': and sensor i (rig order) read i·S µs after the first (286 on "
                   "the AVR board). jointangle/sim/sensor_timing.py")
    p.add_argument("--json", action="store_true",
                   help="print a one-line JSON summary on stdout")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    refuse_overwrite({"--rig": args.rig, "--input": args.input}, {"--out": args.out})
    timing = parse_sensor_timing(args.sensor_timing)
    rig = load_rig(args.rig)
    rig_model(rig)  # refuse degenerate geometry before reading a large CSV
    data = read_accel_csv(args.input, rig)
    if len(data.t) > 1:
        dt = np.median(np.diff(data.t))
        if abs(dt * rig.sample_rate_hz - 1.0) > 0.05:
            raise InputError(f"the CSV is sampled at {1 / dt:.4g} Hz but the rig file says "
                             f"sample_rate_hz = {rig.sample_rate_hz:g}", path=args.input,
                             field="t")
    est = get_estimator(args.filter)
    try:
        check_inputs(est, rig, data.readings, data.gyro)
    except InputError as exc:
        raise InputError(exc.reason, path=args.input, field=exc.field) from None
    readings = data.readings
    if timing.board:
        readings = board_readings(rig, data.t, readings, timing.latency_periods,
                                  timing.read_spacing_s)
    acc = sensor_to_link(rig, readings)[None]
    gyro = None if data.gyro is None else data.gyro[None]
    result = run_estimator(est, rig, acc, gyro)
    extra = {}
    if result.theta_sigma is not None:
        extra["theta_sigma_deg"] = np.degrees(result.theta_sigma[0])
    seen = observable(rig, acc)[0]
    extra["observable"] = seen.astype(float)
    write_estimates_csv(args.out, data.t, result.theta[0], result.omega_a[0], result.omega_b[0],
                        extra)
    print(f"{est.name}: wrote {len(data.t)} estimates to {args.out}", file=sys.stderr)
    hidden = 1.0 - float(seen.mean())
    if hidden > 0.0:
        print(f"warning: the joint angle was not observable for {hidden:.0%} of the run (the "
              "joint's specific force is within the sensors' noise: a vertical hinge with too "
              "little motion?); those rows have observable = 0 and their θ is a guess",
              file=sys.stderr)
    if args.json:
        print(json.dumps({"filter": est.name, "out": args.out, "samples": len(data.t),
                          "latency_ms": None if (lat := est.latency_s(rig)) is None
                          else lat * 1000.0, "unobservable_fraction": round(hidden, 4)}))
    return 0
