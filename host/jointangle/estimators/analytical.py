"""The analytical estimate (eq. 12) and its 25-sample moving average ("smooth analytical").

With v = a_O, the joint acceleration computed from each link's array (a_O = F a, eq. 8):
    θ_ab = atan2(v₁ᵃ v₂ᵇ − v₂ᵃ v₁ᵇ, v₁ᵃ v₁ᵇ + v₂ᵃ v₂ᵇ)                               (eq. 12)
"""

from __future__ import annotations

import numpy as np

from jointangle.estimators.base import Estimates, wrap
from jointangle.model import rig_model
from jointangle.rig import Rig

SMOOTH_WINDOW = 25  # samples, the paper's window (§IV, Fig. 3)


def joint_vectors(rig: Rig, acc: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """a_O from link a and from link b, each (S, T, 2)."""
    m = rig_model(rig)
    va = acc[..., : m.na] @ m.a.F.T
    vb = acc[..., m.na :] @ m.b.F.T
    return va, vb


def analytical_theta(va: np.ndarray, vb: np.ndarray) -> np.ndarray:
    """eq. 12 for joint vectors (..., 2)."""
    cross = va[..., 0] * vb[..., 1] - va[..., 1] * vb[..., 0]
    dot = va[..., 0] * vb[..., 0] + va[..., 1] * vb[..., 1]
    return np.arctan2(cross, dot)


def trailing_mean(x: np.ndarray, window: int) -> np.ndarray:
    """Causal moving average along the last axis; the first samples average what exists."""
    c = np.cumsum(x, axis=-1)
    out = np.empty_like(x)
    out[..., :window] = c[..., :window] / np.arange(1, min(window, x.shape[-1]) + 1)
    if x.shape[-1] > window:
        out[..., window:] = (c[..., window:] - c[..., :-window]) / window
    return out


class Analytical:
    name = "analytical"
    description = "eq. 12 on the joint accelerations of both arrays, sample by sample (causal)"
    latency_s: float | None = 0.0

    def estimate(self, rig: Rig, acc: np.ndarray) -> Estimates:
        va, vb = joint_vectors(rig, acc)
        theta = analytical_theta(va, vb)
        nan = np.full_like(theta, np.nan)
        return Estimates(theta, nan, nan.copy())


class SmoothAnalytical:
    name = "smooth"
    description = "analytical θ averaged over the last 25 samples (causal, ≈12-sample group delay)"
    latency_s: float | None = 0.0

    def estimate(self, rig: Rig, acc: np.ndarray) -> Estimates:
        va, vb = joint_vectors(rig, acc)
        theta = np.unwrap(analytical_theta(va, vb), axis=-1)
        smooth = wrap(trailing_mean(theta, SMOOTH_WINDOW))
        nan = np.full_like(smooth, np.nan)
        return Estimates(smooth, nan, nan.copy())
