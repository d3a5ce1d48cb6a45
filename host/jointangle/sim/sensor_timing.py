"""Readings as the board's loop sees them: each sensor's latest conversion on its own ODR grid.

An accelerations CSV gives row k as the sample of loop step k (t_k = the row's `t`). The board's
virtual sensors (firmware/sim/devices: `SampleClock` in sampling.hpp, adxl345/adxl357/bno055.cpp)
do not: each converts on a free-running grid t = O + j·T_odr counted from device time 0 (= the
CSV's t = 0; O and T_odr the part's own clock from its rig's `sim_clock_*` fields,
`part_clock`), every conversion the CSV linearly interpolated at its instant (motion.cpp
`MotionTrack::Sample`, the first/last row held outside the table) and rounded to the part's
counts (`ToCounts`: nearest, halves away from zero, clamped to the output's range); the loop
reads the latest conversion. This module rebuilds exactly those readings for the host's
estimators.

For loop step k (frame t_us = t_k, the loop's start) whose sample was read at t_read = t_k − L·T
(T = 1 / rig rate, L in loop periods, any finite float): L = 0 on the native board, which reads
synchronously at the loop's start — measured: its raw counts equal these in every frame; L = 1
on the AVR build, which pipelines the reads by one period (frame k carries the batch started in
loop k−1, firmware/app/APP.md), a fraction less for the time into that loop at which the bus
reads the first part. A negative L is a loop grid that runs −L periods after the CSV's rows: a
board whose loop grid has phase φ (frames at t_us = φ + k·T; the native board at 400 Hz started
at φ = 1 ms, measured) is replayed with L = −φ/T, its frame k ↔ row k. A board that reads its
sensors one after another reads sensor i (rig order) i·S after the first (`board:L:S`, S in µs):
the AVR board over its I2C batch, S = 286 µs (11 bytes of ~26 µs a sensor, firmware/app/APP.md
"Read times"; on its raw counts the latest conversion before each sensor's own read, every frame
of sensors 0, 1 and 3 and 96 % of sensor 2's, against every sensor at the first one's read).

    j   = ⌊(t_read − O) / T_odr⌋      (the latest conversion, on the integer-ns grid)
    t_c = O + j · T_odr                (T_odr and O the part's own clock, `part_clock`)
    v   = CSV(t_c)                     (linear interpolation per column, ends held)
    c   = clamp(sign(v) ⌊|v| / lsb + ½⌋, lo, hi);  reading = c · lsb   (m/s², sensor frame)
          (ADXL345 at ODR ≥ 1600 Hz: c with bit 0 cleared, as the part outputs it)

ODR per model and loop rate, as the firmware chooses it (firmware/app/sensor.cpp, APP.md):
ADXL345 the slowest of 3200 Hz / 2^(15−code), code 0x0A..0x0F, with ODR ≥ 1.6·rate (compared
in float32 like the firmware); ADXL357 likewise over 4000 Hz / 2^code, code 6..0; BNO055 its
250 Hz bandwidth setting, which the virtual part converts every 64 ms >> 5 = 2 ms.
Gyro columns are not resampled (the firmware reads accelerations only).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from jointangle.errors import InputError
from jointangle.rig import Rig, SensorConfig
from jointangle.sensors import STANDARD_GRAVITY

ROWS = "rows"
BOARD = "board"
ODR_MARGIN = np.float32(1.6)  # the firmware's 1.6f: every frame holds a fresh sample
# ADXL345 at 1600 and 3200 Hz in full resolution: the output's LSB is always 0 (datasheet;
# adxl345.cpp `lsb_zero`), i.e. the counts are rounded, then bit 0 cleared.
ADXL345_LSB_ZERO_PERIOD_NS = 625_000


@dataclass(frozen=True)
class SensorTiming:
    """How the rows of a CSV become loop samples: `rows` (row k is step k) or `board`."""

    kind: str = ROWS
    latency_periods: float = 0.0
    read_spacing_s: float = 0.0  # sensor i (rig order) is read i · this after the first

    @property
    def board(self) -> bool:
        return self.kind == BOARD


def parse_sensor_timing(text: str) -> SensorTiming:
    """`rows`, `board`, `board:L` or `board:L:S` (L: the read's latency in loop periods, a
    finite float; S: the time between consecutive sensors' reads, µs, ≥ 0)."""
    kind, sep, rest = text.partition(":")
    if kind == ROWS and not sep:
        return SensorTiming(ROWS)
    lat, sep2, spacing = rest.partition(":")
    if kind == BOARD and not (sep and not lat) and not (sep2 and not spacing):
        try:
            periods = float(lat) if lat else 0.0
            spacing_us = float(spacing) if spacing else 0.0
        except ValueError:
            periods = spacing_us = float("nan")
        if np.isfinite(periods) and np.isfinite(spacing_us) and spacing_us >= 0.0:
            return SensorTiming(BOARD, periods, spacing_us * 1e-6)
    raise InputError(f"--sensor-timing {text!r}: expected 'rows', 'board', "
                     "'board:LATENCY_PERIODS' or 'board:LATENCY_PERIODS:SPACING_US' (numbers, "
                     "e.g. board:1 for the AVR build's one-period pipelining, board:-0.4 for a "
                     "loop grid 0.4 periods after the rows, board:0.3:286 for sensors read "
                     "286 µs one after another)",
                     field="--sensor-timing")


def _lowest_code(hz: list[float], rate_hz: float) -> int:
    """Index of the slowest rate in hz (ascending) with rate ≥ 1.6·rate_hz in float32, else the
    fastest."""
    need = ODR_MARGIN * np.float32(rate_hz)
    for i, f in enumerate(hz):
        if not np.float32(f) < need:
            return i
    return len(hz) - 1


def odr_period_ns(model: str, rate_hz: float) -> int:
    """Conversion period (ns, the virtual part's integer grid) the firmware sets up for model at
    loop rate rate_hz."""
    if model == "adxl345":
        codes = list(range(0x0A, 0x10))  # 100 .. 3200 Hz
        code = codes[_lowest_code([3200.0 / 2 ** (15 - c) for c in codes], rate_hz)]
        return 312_500 << (15 - code)  # 312.5 µs · 2^(15 − code)
    if model == "adxl357":
        codes = list(range(6, -1, -1))  # 62.5 .. 4000 Hz
        code = codes[_lowest_code([4000.0 / 2**c for c in codes], rate_hz)]
        return 250_000 << code  # 1 / (4000 Hz / 2^code)
    if model == "bno055":
        return 64_000_000 >> 5  # ACC_Config bandwidth 250 Hz (code 5): 2 ms
    raise InputError(f"no conversion timing known for sensor model {model!r}", field="model")


def count_limits(sensor: SensorConfig) -> tuple[int, int]:
    """The part's output range in counts (lo, hi), as the virtual device clamps it."""
    r = int(sensor.range_g)
    if sensor.model == "adxl345":
        return -256 * r, 256 * r - 1  # full resolution: 10 + log2(r/2) bits
    if sensor.model == "adxl357":
        return -(1 << 19), (1 << 19) - 1  # 20 bits
    hi = int(r * STANDARD_GRAVITY / sensor.lsb_mps2() + 0.5)  # BNO055: ±range
    return -hi, hi


def to_counts(v: np.ndarray, lsb: float, lo: int, hi: int) -> np.ndarray:
    """v / lsb rounded to nearest, halves away from zero (std::round), clamped; NaN → 0."""
    x = np.asarray(v, dtype=float) / lsb
    c = np.sign(x) * np.floor(np.abs(x) + 0.5)
    return np.clip(np.nan_to_num(c, nan=0.0), lo, hi)


def part_clock(sensor: SensorConfig, nominal_period_ns: int) -> tuple[int, int]:
    """The part's own conversion grid (period, offset) in integer ns, as the virtual part runs
    it (firmware/sim/devices/sampling.hpp): its oscillator off by `sim_clock_ppm` (+ = fast)
    and its grid shifted by `sim_clock_phase` of a period, conversions at O + j·P, j ≥ 0:

        P = ⌊P_nom / (1 + ppm·10⁻⁶) + ½⌋        O = ⌊phase · P + ½⌋

    Real parts convert on free-running on-chip oscillators, so each has its own phase against
    the board's loop and the phases drift apart; ppm = phase = 0 is the in-step grid."""
    ppm = sensor.sim_clock_ppm or 0.0
    phase = sensor.sim_clock_phase or 0.0
    period = int(np.floor(nominal_period_ns / (1.0 + ppm * 1e-6) + 0.5))
    return period, int(np.floor(phase * period + 0.5))


def conversion_instants(t_loop: np.ndarray, period_ns: int, latency_s: float,
                        offset_ns: int = 0) -> np.ndarray:
    """Latest conversion instant (s) at each read t_loop − latency_s on the grid O + j·T_odr:
    O + ⌊(t_read − O)/T_odr⌋·T_odr, taken on the integer-ns grid (t_read rounded to the nearest
    ns first; a read before the first conversion O takes that one, i.e. at O = 0 the first row;
    one after the last row holds it)."""
    t_ns = np.rint((np.asarray(t_loop, dtype=float) - latency_s) * 1e9).astype(np.int64)
    t_ns = np.maximum(t_ns, offset_ns) - offset_ns
    return (t_ns // period_ns * period_ns + offset_ns).astype(float) * 1e-9


def interpolate(tc: np.ndarray, t: np.ndarray, v: np.ndarray) -> np.ndarray:
    """v (T, ...) at instants tc, as the virtual device computes it (motion.cpp): the row i with
    t_i ≤ tc < t_(i+1), w = (tc − t_i) / (t_(i+1) − t_i), v_i + w (v_(i+1) − v_i); the first row
    at or before t_0, the last at or after t_(T−1). The same double operations, so a conversion
    half-way between two rows (a tie in the rounding to counts) rounds as on the device."""
    n = len(t)
    i = np.clip(np.searchsorted(t, tc, side="right") - 1, 0, max(n - 2, 0))
    i1 = np.minimum(i + 1, n - 1)
    inside = (tc > t[0]) & (tc < t[-1])
    w = np.where(inside, (tc - t[i]) / np.where(i1 > i, t[i1] - t[i], 1.0), 0.0)
    i0 = np.where(tc >= t[-1], n - 1, i)
    i1 = np.where(w > 0.0, i1, i0)
    ext = (slice(None),) + (None,) * (v.ndim - 1)
    return v[i0] + w[ext] * (v[i1] - v[i0])


def board_readings(rig: Rig, t: np.ndarray, readings: np.ndarray,
                   latency_periods: float = 0.0, read_spacing_s: float = 0.0) -> np.ndarray:
    """Sensor-frame readings (T, n_sensors, 3) as the board's loop reads them at the CSV's row
    instants t (T,): each sensor's latest conversion at its own read, interpolated and quantised
    (module doc)."""
    t = np.asarray(t, dtype=float)
    readings = np.asarray(readings, dtype=float)
    sensors = [s for _, _, s in rig.all_sensors()]
    if readings.shape != (len(t), len(sensors), 3):
        raise InputError(f"readings of shape {readings.shape} do not match {len(t)} rows of "
                         f"{len(sensors)} sensors", field="readings")
    out = np.empty_like(readings)
    latency_s = latency_periods / rig.sample_rate_hz
    for i, s in enumerate(sensors):
        nominal = odr_period_ns(s.model, rig.sample_rate_hz)
        period, offset = part_clock(s, nominal)
        tc = conversion_instants(t, period, latency_s - i * read_spacing_s, offset)
        lsb = s.lsb_mps2()
        lo, hi = count_limits(s)
        c = to_counts(interpolate(tc, t, readings[:, i]), lsb, lo, hi)
        if s.model == "adxl345" and nominal <= ADXL345_LSB_ZERO_PERIOD_NS:
            c = (c.astype(np.int64) & ~1).astype(float)  # bit 0 reads 0 (two's complement)
        out[:, i] = c * lsb
    return out
