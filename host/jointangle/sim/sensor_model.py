"""Turn ideal specific force into what a sensor reports (in m/s², in its own frame).

Order of effects: mounting rotation about z (sensor frame at `rotation_deg` from the link, plus
the simulation-only `sim_rotation_offset_deg` of a rig as built),
misalignment and cross-axis coupling, scale error and bias (simulation-only rig fields), white
noise from the noise density, saturation at the range, quantisation to the model's LSB.
"""

from __future__ import annotations

from dataclasses import replace

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


def rotation_from_vector_deg(phi_deg: np.ndarray) -> np.ndarray:
    """Rotation matrix of the rotation vector φ (degrees): Rodrigues,
    R = I + sin|φ| [u]× + (1 − cos|φ|) [u]×², u = φ/|φ|."""
    phi = np.radians(np.asarray(phi_deg, dtype=float))
    angle = float(np.linalg.norm(phi))
    if angle == 0.0:
        return np.eye(3)
    u = phi / angle
    ux = np.array([[0.0, -u[2], u[1]], [u[2], 0.0, -u[0]], [-u[1], u[0], 0.0]])
    return np.eye(3) + np.sin(angle) * ux + (1.0 - np.cos(angle)) * ux @ ux


def sensor_distortion(sensor: SensorConfig) -> tuple[np.ndarray, np.ndarray]:
    """The simulated sensor's linear error model (M 3×3, b m/s²): v = M f + b + noise, with f
    the true specific force in the nominal sensor frame.

    M = diag(1 + k) (I + X) R_mᵀ: R_m turns the nominal axes into the real ones (so components
    along the real axes are R_mᵀ f), X holds the cross-axis terms s_mn off its diagonal
    (Madgwick eq. 38), k the scale errors. A perfect calibration is S = M⁻¹, o = −M⁻¹ b.
    """
    m = np.eye(3)
    if sensor.sim_misalignment_deg is not None:
        m = rotation_from_vector_deg(np.asarray(sensor.sim_misalignment_deg)).T
    if sensor.sim_cross_axis is not None:
        xy, xz, yx, yz, zx, zy = sensor.sim_cross_axis
        m = np.array([[1.0, xy, xz], [yx, 1.0, yz], [zx, zy, 1.0]]) @ m
    if sensor.sim_scale_error is not None:
        m = np.diag(1.0 + np.asarray(sensor.sim_scale_error)) @ m
    b = np.zeros(3) if sensor.sim_bias_mps2 is None else np.asarray(sensor.sim_bias_mps2)
    return m, b


def sensor_reading(sensor: SensorConfig, f_link: np.ndarray, rate_hz: float,
                   rng: np.random.Generator) -> np.ndarray:
    """Noisy, saturated, quantised reading (T, 3) of a sensor whose true specific force in the
    link frame is f_link (T, 3)."""
    v = link_to_sensor(sensor.rotation_deg + (sensor.sim_rotation_offset_deg or 0.0), f_link)
    if sensor.sim_misalignment_deg is not None or sensor.sim_cross_axis is not None:
        # (I + X) R_mᵀ of sensor_distortion; scale and bias follow below as before.
        m, _ = sensor_distortion(replace(sensor, sim_scale_error=None, sim_bias_mps2=None))
        v = v @ m.T
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
