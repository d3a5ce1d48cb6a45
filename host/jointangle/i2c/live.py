"""`jointangle live --i2c BUS`: the joint angle computed on this machine from its own I2C bus.

The loop runs at the rig's sample rate, or as fast as the bus allows when that is too fast
(each step that starts late counts as an overrun; the filter's ΔT stays 1/rate). It prints a
line per second (θ, ω_a, ω_b, loop rate, sensors), or one JSON object per step with
--json-lines, and a JSON summary with --json. Faults (NACK, wrong ID, a mux read-back
mismatch) are shown as they happen and as per-sensor status; the loop keeps going.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from typing import Any

from jointangle.device.describe import flag_names
from jointangle.errors import InputError
from jointangle.i2c.bus import open_bus
from jointangle.i2c.pipeline import I2cPipeline, Step
from jointangle.io.rig_file import load_rig
from jointangle.protocol import messages as msgs
from jointangle.rig import Rig
from jointangle.sim.scenarios import gravity_rig


def _rig(args: argparse.Namespace) -> Rig:
    if args.rig is not None:
        return load_rig(args.rig)
    if args.i2c == "sim":
        return gravity_rig(200.0)  # a rate the host path keeps with margin (bench host)
    raise InputError("reading a real I2C bus needs the rig file of the build (which parts, "
                     "where, on which mux channel)", field="--rig")


def _line(st: Step, rate_hz: float, p: I2cPipeline) -> str:
    head = ("no estimate (fewer than two usable sensors on a link)" if st.theta_deg is None
            else f"t {st.t_s:7.2f} s  θ {st.theta_deg:8.3f}°  ω_a {st.omega_a_dps:7.2f} °/s  "
                 f"ω_b {st.omega_b_dps:7.2f} °/s")
    bad = [f"{s.part.label}:{','.join(flag_names(msgs.SensorStatus, st.status[k]))}"
           for k, s in enumerate(p.sensors) if st.status[k]]
    return f"{head}  {rate_hz:.0f} Hz  sensors {'; '.join(bad) if bad else 'ok'}"


def run_i2c_live(args: argparse.Namespace) -> int:
    rig = _rig(args)
    seconds = args.seconds if args.seconds is not None else 10.0
    if not seconds > 0:
        raise InputError("must be a positive number of seconds", field="--seconds")
    ob = open_bus(args.i2c, rig, getattr(args, "scenario", "gravity-slow-periodic"),
                  getattr(args, "seed", 0))
    out = sys.stdout
    err = sys.stderr
    p = I2cPipeline(ob.bus, rig)
    period = 1.0 / rig.sample_rate_hz
    code = 0
    shown_errors = 0
    steps = overruns = 0
    last: Step | None = None
    t_start = time.perf_counter()
    try:
        err.write(f"{ob.what}: {len(p.sensors)} sensors, {rig.sample_rate_hz:g} Hz\n")
        p.configure()
        t_start = time.perf_counter()
        next_due = t_start
        next_line = t_start + 1.0
        while True:
            now = time.perf_counter()
            if now - t_start >= seconds:
                break
            if now < next_due:
                time.sleep(min(next_due - now, 0.01))
                continue
            last = p.step()
            steps += 1
            next_due += period
            if time.perf_counter() > next_due:  # late for the next step: count, go on at once
                overruns += 1
                next_due = time.perf_counter()
            for e in p.errors[shown_errors:]:
                err.write(f"i2c fault: {e}\n")
            shown_errors = len(p.errors)
            if args.json_lines:
                out.write(json.dumps(last.as_dict()) + "\n")
            elif not args.json and now >= next_line:
                next_line += 1.0
                out.write(_line(last, steps / (now - t_start), p) + "\n")
                out.flush()
    except KeyboardInterrupt:
        code = 130
    finally:
        ob.close()
    wall = max(time.perf_counter() - t_start, 1e-9)
    summary: dict[str, Any] = {
        "bus": ob.what, "steps": steps, "seconds": round(wall, 3),
        "rate_hz": steps / wall, "overruns": overruns,
        "stage_us": p.times.per_step_us(),
        "sensors": [{"sensor": s.part.label, "status": flag_names(msgs.SensorStatus,
                                                                   p.status[k]),
                     "nacks": p.nacks[k]} for k, s in enumerate(p.sensors)],
        "mux_mismatches": 0 if p.mux is None else p.mux.mismatches,
        "errors": p.errors, "filter_resets": p.filter_resets,
        "theta_deg": None if last is None else last.theta_deg,
    }
    if steps and overruns > 0.05 * steps:
        err.write(f"warning: {overruns} of {steps} steps started late: this bus and host keep "
                  f"~{summary['rate_hz']:.0f} Hz, not the rig's {rig.sample_rate_hz:g} Hz (the "
                  "filter assumes the rig's rate); lower sample_rate_hz in the rig file\n")
    if args.json:
        out.write(json.dumps(summary) + "\n")
    elif not args.json_lines and last is not None:
        out.write(_line(last, summary["rate_hz"], p) + "\n")
    return code
