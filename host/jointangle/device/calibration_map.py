"""The firmware's calibration of raw counts, reproduced bit for bit on the host.

The board turns raw counts into link-frame Q15.16 readings with a per-sensor map it computes in
float32 at configuration (firmware/app/APP.md, "Calibration in fixed point"; firmware/app/
sensor.cpp `MakeCalibrationMap`), in its own order of operations (IEEE single on both machines;
avr-libc's and x86's +, −, ×, ÷ round to nearest alike):

  rot = f32(µrad)·1e-6f, R = [[cos, −sin, 0], [sin, cos, 0]], M_ij = Σ_l R_il·(f32(S_q24,lj)/2²⁴),
  m_q30 = ⌊f32(M_ij·scale·2³⁰) + ½⌋, b_i = Σ_l (R_il·f32(o_µ,l))·1e-6f, b_q16 = ⌊f32(b_i·2¹⁶) + ½⌋;
  per sample a_r = (b_r·2¹⁴ + Σ_j M_rj·counts_j + 2¹³) >> 14, saturated to int32 (Q15.16).

`device_readings` gives exactly those readings, so `mirror`'s own Q15.16 rounding
(`quantise_inputs`) is the identity on them. Scaling counts by the LSB in float64 and rounding
once (what `sensor_to_link` + mirror do on their own) differs from this by one LSB whenever the
float32 coefficient or the single rounding lands elsewhere.

cos/sin of a non-zero rotation come from numpy here and avr-libc on the board: a 1-ulp difference
can move an m_q30 coefficient by 1 only when the product sits on a rounding boundary.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from jointangle.errors import InputError
from jointangle.rig import Rig

F32 = np.float32
STANDARD_GRAVITY_F32 = F32(9.80665)  # firmware/drivers/conversion.hpp kStandardGravity


def mps2_per_count(model: str, range_g: int) -> np.float32:
    """firmware/app/sensor.cpp `Mps2PerCount`, in float32 as the board computes it."""
    if model == "adxl345":
        return F32(F32(0.0039) * STANDARD_GRAVITY_F32)  # kGPerCountFullRes · g
    if model == "adxl357":
        code = 3 if range_g >= 40 else 2 if range_g >= 20 else 1
        g_per_count = F32(F32(1.0) / F32(F32(51200.0) / F32(1 << (code - 1))))
        return F32(STANDARD_GRAVITY_F32 * g_per_count)
    if model == "bno055":
        return F32(0.01)
    raise InputError(f"the firmware has no sensor model {model!r}", field="model")


def llround(x: float) -> int:
    """C llround: to nearest, halves away from zero (Python's round() goes to even)."""
    return math.floor(abs(x) + 0.5) * (1 if x >= 0 else -1)


def micro(v: float) -> int:
    """rig_toml.cpp `Micro`: llround(v · 1e6)."""
    return llround(v * 1e6)


def from_micro(v: float) -> np.float32:
    """v as the app forms it from the integer µ-units it holds: f32(micro(v)) · 1e-6f."""
    return F32(F32(micro(v)) * F32(1e-6))


def round_to_raw(v: np.float32, scale: float) -> int:
    """sensor.cpp `RoundToRaw`: ⌊f32(v·scale) + 0.5f⌋, saturated."""
    x = F32(v * F32(scale))
    if not (F32(-2147483520.0) < x < F32(2147483520.0)):
        return -(2**31) if x < 0 else 2**31 - 1
    return int(np.floor(F32(x + F32(0.5))))


@dataclass(frozen=True)
class DeviceMaps:
    """Per sensor (rig order): m_q30 (n, 2, 3) and b_q16 (n, 2), int64."""

    m_q30: np.ndarray
    b_q16: np.ndarray

    @classmethod
    def from_rig(cls, rig: Rig) -> DeviceMaps:
        ms, bs = [], []
        for _, _, s in rig.all_sensors():
            rot = from_micro(s.rotation_deg * math.pi / 180.0)
            c, sn = F32(np.cos(rot)), F32(np.sin(rot))
            r = ((c, -sn, F32(0)), (sn, c, F32(0)))
            s_mat = np.eye(3) if s.S is None else np.asarray(s.S, dtype=float)
            s32 = [[F32(F32(llround(s_mat[i, j] * 16777216.0)) / F32(2.0**24)) for j in range(3)]
                   for i in range(3)]
            o = (0.0, 0.0, 0.0) if s.offset is None else s.offset
            o32 = [F32(micro(v)) for v in o]
            scale = mps2_per_count(s.model, s.range_g)
            m = np.zeros((2, 3), dtype=np.int64)
            b = np.zeros(2, dtype=np.int64)
            for i in range(2):
                for j in range(3):
                    acc = F32(0)
                    for k in range(3):
                        acc = F32(acc + F32(r[i][k] * s32[k][j]))
                    m[i, j] = round_to_raw(F32(acc * scale), 2.0**30)
                off = F32(0)
                for k in range(3):
                    off = F32(off + F32(F32(r[i][k] * o32[k]) * F32(1e-6)))
                b[i] = round_to_raw(off, 2.0**16)
            ms.append(m)
            bs.append(b)
        return cls(np.asarray(ms, dtype=np.int64), np.asarray(bs, dtype=np.int64))

    def readings_q16(self, counts: np.ndarray) -> np.ndarray:
        """Q15.16 link-frame x, y (T, n, 2) int32 from counts (T, n, 3), as ApplyCalibration."""
        c = np.asarray(counts, dtype=np.int64)
        acc = (self.b_q16[None] << 14) + np.einsum("nij,tnj->tni", self.m_q30, c)
        return np.clip((acc + (1 << 13)) >> 14, -(2**31), 2**31 - 1).astype(np.int32)


def device_readings(maps: DeviceMaps, counts: np.ndarray) -> np.ndarray:
    """Link-frame x, y readings (T, 2n) in m/s² from raw counts (T, n, 3), bit-exact with the
    firmware's Q15.16 (round half up, saturated to int32)."""
    raw = maps.readings_q16(counts)
    return (raw.reshape(raw.shape[0], -1) / 65536.0).astype(float)


def counts_from_readings(rig: Rig, readings: np.ndarray) -> np.ndarray:
    """Sensor-frame m/s² (T, n, 3) as integer counts (simulators and fakes)."""
    lsb = np.array([float(mps2_per_count(s.model, s.range_g)) for _, _, s in rig.all_sensors()])
    return np.round(np.asarray(readings) / lsb[None, :, None]).astype(np.int64)
