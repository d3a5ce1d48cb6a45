"""`jointangle bench host`: smbus2 path + float EKF on the host at real 400 kHz bus timing."""

from __future__ import annotations

import argparse
import json
import sys

from jointangle.bench.host import TARGET_HZ, run_host_bench
from jointangle.cli.common import positive_float


def register(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    p = sub.add_parser(
        "host", help="the smbus2 I2C path + float EKF on the host (issue 7)",
        description="Read four sensors (TCA9548A + ADXL345s) over the fake I2C bus at real "
        "400 kHz timing with the host's smbus2 driver, calibrate and run the float EKF, as fast "
        "as possible; report the sustained step rate and the cost per step of each stage "
        f"(target ≥ {TARGET_HZ:g} Hz).")
    p.add_argument("--json", action="store_true", help="print one JSON object on stdout")
    p.add_argument("--seconds", type=positive_float, default=5.0,
                   help="how long to run (default 5)")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    doc = run_host_bench(args.seconds)
    if args.json:
        sys.stdout.write(json.dumps(doc) + "\n")
        return 0
    st = doc["stage_us"]
    print(f"{doc['rate_hz']:.0f} Hz sustained ({doc['sensors']} sensors, "
          f"{doc['scl_hz'] // 1000} kHz, target ≥ {doc['target_hz']:.0f} Hz) over "
          f"{doc['steps']} steps")
    print(f"per step: bus {st['bus']:.0f} µs (of which SCL time {doc['bus_time_us']:.0f} µs, "
          f"{doc['transactions_per_step']:.0f} transactions), conversion+calibration "
          f"{st['conversion_calibration']:.0f} µs, filter {st['filter']:.0f} µs; host CPU "
          f"{doc['host_cpu_us']:.0f} µs (CPU + bus time alone: "
          f"{doc['rate_hz_cpu_plus_bus']:.0f} Hz)")
    return 0
