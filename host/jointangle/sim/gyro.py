"""Gyroscope output for sensors that have one (the BNO055), for the neighbouring methods.

A planar link turning at ω about z reads, in its own (sensor) frame, ω on z and nothing on x, y
(the mounting rotation is about z, so it leaves the z rate unchanged). The model per axis:

    g(t) = ω_true(t) + b₀ + b_rw(t) + n(t)
    b₀   ~ N(0, σ_b0²)                  turn-on bias (the datasheet's zero-rate offset)
    b_rw: random walk, b_rw(t_k) = b_rw(t_{k−1}) + N(0, q_b ΔT)   (bias drift)
    n    ~ N(0, (nd · √(fs/2))²)        white rate noise from the noise density nd

then quantisation to the BNO055's 1/16 °/s (UNIT_SEL = dps) or 1/900 rad/s (rps) LSB; we use
rad/s, i.e. 1/900 rad/s per count. Figures (BNO055 datasheet §3.2 / BMG160): noise density
0.014 °/s/√Hz; zero-rate offset ±1 °/s (σ_b0 taken as 0.5 °/s); bias drift taken as a random walk
of 0.02 °/s/√s (a few tenths of °/s over a minute, the order the datasheet's TCO allows for a
few kelvin of self-heating).

The gyro has its own random stream (derived from the seed), so adding gyro output leaves every
accelerometer reading of `simulate_rig` unchanged.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from jointangle.rig import Rig
from jointangle.sensors import SENSOR_MODELS
from jointangle.sim.mechanism import MechanismState

GYRO_NOISE_DPS_RTHZ = 0.014  # °/s/√Hz
GYRO_BIAS0_DPS = 0.5  # 1σ turn-on bias, °/s
GYRO_BIAS_RW_DPS_RTS = 0.02  # bias random walk, °/s/√s
GYRO_LSB_RPS = 1.0 / 900.0  # rad/s per count (UNIT_SEL rps)
GYRO_STREAM = 0x67  # second word of the gyro's seed sequence


def has_gyro(model: str) -> bool:
    return SENSOR_MODELS[model].has_gyro


def gyro_readings(rig: Rig, mech: MechanismState, seed: int, *,
                  noise_dps_rthz: float = GYRO_NOISE_DPS_RTHZ,
                  bias0_dps: float = GYRO_BIAS0_DPS,
                  bias_rw_dps_rts: float = GYRO_BIAS_RW_DPS_RTS,
                  quantize: bool = True) -> np.ndarray | None:
    """Gyro readings (T, n_sensors, 3) in rad/s, NaN for sensors without a gyro; None when no
    sensor of the rig has one."""
    sensors = rig.all_sensors()
    if not any(has_gyro(s.model) for _, _, s in sensors):
        return None
    rng = np.random.default_rng([seed, GYRO_STREAM])
    T = len(mech.t)
    fs = rig.sample_rate_hz
    out = np.full((T, len(sensors), 3), np.nan)
    sigma_n = np.radians(noise_dps_rthz) * np.sqrt(fs / 2.0)
    for k, (link, _, s) in enumerate(sensors):
        if not has_gyro(s.model):
            continue
        omega = mech.a.omega if link == "a" else mech.b.omega
        true = np.zeros((T, 3))
        true[:, 2] = omega
        b0 = rng.standard_normal(3) * np.radians(bias0_dps)
        steps = rng.standard_normal((T, 3)) * np.radians(bias_rw_dps_rts) * np.sqrt(1.0 / fs)
        steps[0] = 0.0
        bias = b0 + np.cumsum(steps, axis=0)
        g = true + bias + rng.standard_normal((T, 3)) * sigma_n
        if quantize:
            g = np.round(g / GYRO_LSB_RPS) * GYRO_LSB_RPS
        out[:, k, :] = g
    return out


def with_gyros(rig: Rig) -> Rig:
    """The same build with every sensor a BNO055 (accelerometer + gyro) at the same place.

    Each sensor keeps its accelerometer noise density (stated explicitly), quantisation flag
    and simulation-only errors, so the accelerometer data differ only by the BNO055's LSB; the
    range becomes the smallest BNO055 range covering the old one.
    """
    bno = SENSOR_MODELS["bno055"]
    links = {}
    for name, cfg in rig.links.items():
        sensors = tuple(
            # 0x28 or 0x29 are the only BNO055 addresses (COM3 low/high, docs/sensors.md §A3).
            replace(s, model="bno055", noise_density_ug=s.density_ug,
                    address=0x28 if s.address not in (0x28, 0x29) else s.address,
                    range_g=min((r for r in bno.ranges_g if r >= s.range_g),
                                default=max(bno.ranges_g)))
            for s in cfg.sensors)
        links[name] = replace(cfg, sensors=sensors)
    return replace(rig, links=links)
