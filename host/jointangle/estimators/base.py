"""What every estimator shares: its interface, its result, and the input conditioning.

Estimators run batched: readings of shape (S, T, M) — S independent runs (e.g. noise seeds) of
T samples, M = 2N_a + 2N_b link-frame readings (x, y of each sensor, links a then b) — so the
benchmark runs all seeds of a scenario in one pass.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

import numpy as np

from jointangle.rig import Rig, SensorConfig


@dataclass(frozen=True)
class Estimates:
    """Per-sample estimates, each (S, T). θ is wrapped to (−π, π]."""

    theta: np.ndarray  # rad
    omega_a: np.ndarray  # rad/s
    omega_b: np.ndarray  # rad/s
    theta_sigma: np.ndarray | None = None  # rad, 1σ, where the estimator knows it


class Estimator(Protocol):
    name: str
    description: str

    def latency_s(self, rig: Rig) -> float | None:
        """0 for causal, the lag (s) of a fixed-lag smoother, None for offline (whole run)."""
        ...

    def estimate(self, rig: Rig, acc: np.ndarray) -> Estimates:
        """Estimates for link-frame readings acc (S, T, M)."""
        ...


def wrap(theta: np.ndarray) -> np.ndarray:
    """Wrap angles to (−π, π]."""
    return -((-theta + np.pi) % (2 * np.pi) - np.pi)


def calibrated(sensor: SensorConfig, v: np.ndarray) -> np.ndarray:
    """â = S v + o (calibration, Appendix IV) of one sensor's raw readings v (..., 3); v as it
    is when the rig file gives the sensor no calibration."""
    if sensor.S is not None:
        v = v @ np.asarray(sensor.S).T
    if sensor.offset is not None:
        v = v + np.asarray(sensor.offset)
    return v


def sensor_to_link(rig: Rig, readings: np.ndarray) -> np.ndarray:
    """Calibrated link-frame x, y readings (..., T, M) from raw sensor readings (..., T, n, 3).

    Per sensor: â = S v + o (calibration, Appendix IV, when the rig file has one), then the
    mounting rotation about z undone so x runs along the link. Only x, y enter the planar model.
    """
    sensors = [s for _, _, s in rig.all_sensors()]
    if readings.shape[-2] != len(sensors):
        raise ValueError(f"readings have {readings.shape[-2]} sensors, rig has {len(sensors)}")
    out = np.empty((*readings.shape[:-2], 2 * len(sensors)))
    for k, s in enumerate(sensors):
        v = calibrated(s, readings[..., k, :])
        c = np.cos(np.radians(s.rotation_deg))
        si = np.sin(np.radians(s.rotation_deg))
        out[..., 2 * k] = c * v[..., 0] - si * v[..., 1]
        out[..., 2 * k + 1] = si * v[..., 0] + c * v[..., 1]
    return out


def pinned_noise_variance(rig: Rig) -> np.ndarray:
    """Diagonal of Q̂ for the pinned filters: σ² with σ = density · g · √(fs/2) (docs/design.md §3).
    """
    return np.concatenate([rig.noise_sigma_mps2("a"), rig.noise_sigma_mps2("b")]) ** 2


def full_noise_variance(rig: Rig) -> np.ndarray:
    """Diagonal of Q̂ including quantisation (LSB²/12) for sensors that quantise."""
    var = pinned_noise_variance(rig)
    lsb2 = []
    for _, _, s in rig.all_sensors():
        q = s.lsb_mps2() ** 2 / 12.0 if s.quantize else 0.0
        lsb2 += [q, q]
    return var + np.array(lsb2)


def mT(x: np.ndarray) -> np.ndarray:
    """Batched transpose of the last two axes."""
    return np.swapaxes(x, -1, -2)
