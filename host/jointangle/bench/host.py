"""`jointangle bench host`: the smbus2 path plus the float EKF on the host, at real bus timing.

Four sensors (the gravity rig: ADXL345s behind a TCA9548A) on the fake bus (simdev.SimSMBus in
real time at 400 kHz: every transaction costs its SCL periods in wall-clock time) run through
`i2c.pipeline.I2cPipeline` as fast as they can for `seconds`. Reported: the sustained step rate
(steps / wall time), the wall time per step of each stage (bus — including the bus time —,
conversion + calibration, filter), the pure bus time per step from the bus's SCL count
(bits / 400 kHz), the host's CPU time per step, and 1 / (CPU + bus time) — the rate with
the cores to itself. Measured, never asserted: the machine's load changes them.
"""

from __future__ import annotations

import time
from typing import Any

from jointangle.i2c.bus import SIM_SCL_HZ, sim_bus
from jointangle.i2c.pipeline import I2cPipeline, StageTimes
from jointangle.sim.scenarios import gravity_rig

TARGET_HZ = 200.0


def run_host_bench(seconds: float = 5.0, rate_hz: float = 500.0) -> dict[str, Any]:
    rig = gravity_rig(rate_hz)
    ob = sim_bus(rig, seconds=10.0)
    try:
        p = I2cPipeline(ob.bus, rig)
        p.configure()
        if any(p.status):
            raise RuntimeError(f"sensors failed to configure: {p.errors}")
        for _ in range(50):  # warm-up: caches, first filter steps
            p.step()
        p.times = StageTimes()
        bits0 = ob.virtual.bus_counters().scl_bits
        tr0 = ob.virtual.bus_counters().stops
        cpu0 = time.process_time()
        t0 = time.perf_counter()
        while time.perf_counter() - t0 < seconds:
            p.step()
        wall = time.perf_counter() - t0
        cpu = time.process_time() - cpu0
        c = ob.virtual.bus_counters()
    finally:
        ob.close()
    n = p.times.steps
    stage = p.times.per_step_us()
    return {
        "rate_hz": n / wall,
        "target_hz": TARGET_HZ,
        "sensors": len(p.sensors),
        "scl_hz": SIM_SCL_HZ,
        "steps": n,
        "seconds": wall,
        "stage_us": {"bus": stage["bus"], "conversion_calibration": stage["convert"],
                     "filter": stage["filter"]},
        "bus_time_us": (c.scl_bits - bits0) / SIM_SCL_HZ / n * 1e6,
        "transactions_per_step": (c.stops - tr0) / n,
        "host_cpu_us": cpu / n * 1e6,
        # What the step rate would be with the host's CPU time plus the bus time and nothing
        # else (no other process competing for the cores): the load-independent figure.
        "rate_hz_cpu_plus_bus": 1.0 / (cpu / n + (c.scl_bits - bits0) / SIM_SCL_HZ / n),
        "faults": sum(1 for s in p.status if s),
    }
