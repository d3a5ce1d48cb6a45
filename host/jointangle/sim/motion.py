"""Motion profiles: an angle and its first two derivatives in closed form.

Every profile is a function of time returning (θ, ω, α) arrays, so the simulator never
differentiates numerically and its kinematics can be checked against closed forms.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

import numpy as np


class Motion(Protocol):
    def __call__(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(θ rad, ω rad/s, α rad/s²) at times t (s)."""
        ...


@dataclass(frozen=True)
class Constant:
    angle_rad: float

    def __call__(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        z = np.zeros_like(t, dtype=float)
        return z + self.angle_rad, z, z.copy()


@dataclass(frozen=True)
class Sine:
    """θ(t) = offset + amplitude · sin(2π f t + phase)."""

    amplitude_rad: float
    freq_hz: float
    offset_rad: float = 0.0
    phase_rad: float = 0.0

    def __call__(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        w = 2 * np.pi * self.freq_hz
        ph = w * t + self.phase_rad
        return (
            self.offset_rad + self.amplitude_rad * np.sin(ph),
            self.amplitude_rad * w * np.cos(ph),
            -self.amplitude_rad * w * w * np.sin(ph),
        )


@dataclass(frozen=True)
class MinimumJerkMoves:
    """Holds at given angles joined by minimum-jerk moves (Flash & Hogan profile).

    `moves` lists (start time s, duration s, target angle rad); the angle holds between moves.
    s(τ) = 10τ³ − 15τ⁴ + 6τ⁵ on τ ∈ [0, 1] has zero velocity and acceleration at both ends.
    """

    start_rad: float
    moves: tuple[tuple[float, float, float], ...]

    def __call__(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        t = np.asarray(t, dtype=float)
        theta = np.full_like(t, self.start_rad)
        omega = np.zeros_like(t)
        alpha = np.zeros_like(t)
        current = self.start_rad
        for t0, dur, target in self.moves:
            delta = target - current
            tau = np.clip((t - t0) / dur, 0.0, 1.0)
            s = tau**3 * (10 - 15 * tau + 6 * tau**2)
            ds = 30 * tau**2 * (1 - tau) ** 2 / dur
            dds = 60 * tau * (1 - tau) * (1 - 2 * tau) / dur**2
            active = t >= t0
            theta = np.where(active, current + delta * s, theta)
            inside = (t >= t0) & (t <= t0 + dur)
            omega = np.where(inside, delta * ds, omega)
            alpha = np.where(inside, delta * dds, alpha)
            current = target
        return theta, omega, alpha


@dataclass(frozen=True)
class SineSum:
    """θ(t) = offset + Σ of sines (amplitude rad, frequency Hz, phase rad): a rich motion."""

    offset_rad: float
    terms: tuple[tuple[float, float, float], ...]

    def __call__(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        t = np.asarray(t, dtype=float)
        th = np.full_like(t, self.offset_rad)
        om = np.zeros_like(t)
        al = np.zeros_like(t)
        for amp, f, ph in self.terms:
            a, w, b = Sine(amp, f, 0.0, ph)(t)
            th, om, al = th + a, om + w, al + b
        return th, om, al
