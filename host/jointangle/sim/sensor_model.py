"""Turn ideal specific force into what a sensor reports (in m/s², in its own frame).

Order of effects: mounting rotation about z (sensor frame at `rotation_deg` from the link),
scale error and bias (simulation-only rig fields), white noise from the noise density,
saturation at the range, quantisation to the model's LSB.
"""

from __future__ import annotations

import numpy as np

from jointangle.rig import SensorConfig
from jointangle.sensors import STANDARD_GRAVITY


def link_to_sensor(rotation_deg: float, v: np.ndarray) -> np.ndarray:
    """Components in the sensor frame of link-frame vectors v (..., 3)."""
    c = np.cos(np.radians(rotation_deg))
    s = np.sin(np.radians(rotation_deg))
    out = v.copy()
    out[..., 0] = c * v[..., 0] + s * v[..., 1]
    out[..., 1] = -s * v[..., 0] + c * v[..., 1]
    return out


def sensor_reading(sensor: SensorConfig, f_link: np.ndarray, rate_hz: float,
                   rng: np.random.Generator) -> np.ndarray:
    """Noisy, saturated, quantised reading (T, 3) of a sensor whose true specific force in the
    link frame is f_link (T, 3)."""
    v = link_to_sensor(sensor.rotation_deg, f_link)
    if sensor.sim_scale_error is not None:
        v = v * (1.0 + np.asarray(sensor.sim_scale_error))
    if sensor.sim_bias_mps2 is not None:
        v = v + np.asarray(sensor.sim_bias_mps2)
    sigma = np.asarray(sensor.density_ug) * 1e-6 * STANDARD_GRAVITY * np.sqrt(rate_hz / 2.0)
    v = v + rng.standard_normal(v.shape) * sigma
    full_scale = sensor.range_g * STANDARD_GRAVITY
    v = np.clip(v, -full_scale, full_scale)
    if sensor.quantize:
        lsb = sensor.lsb_mps2()
        v = np.round(v / lsb) * lsb
    return v
