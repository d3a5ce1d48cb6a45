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


def centred_mean(x: np.ndarray, window: int) -> np.ndarray:
    """Centred moving average along the last axis (odd window): sample k averages k−h … k+h,
    h = (window − 1)/2. Near the ends the window is cut to the samples that exist (it never
    reaches past k + h, and it never shrinks to a single noisy sample as a symmetric cut would).
    """
    h = (window - 1) // 2
    n = x.shape[-1]
    c = np.concatenate([np.zeros((*x.shape[:-1], 1)), np.cumsum(x, axis=-1)], axis=-1)
    k = np.arange(n)
    lo = np.maximum(k - h, 0)
    hi = np.minimum(k + h, n - 1)
    return (c[..., hi + 1] - c[..., lo]) / (hi - lo + 1)


class Analytical:
    name = "analytical"
    description = "eq. 12 on the joint accelerations of both arrays, sample by sample (causal)"

    def latency_s(self, rig: Rig) -> float | None:
        return 0.0

    def estimate(self, rig: Rig, acc: np.ndarray) -> Estimates:
        va, vb = joint_vectors(rig, acc)
        theta = analytical_theta(va, vb)
        nan = np.full_like(theta, np.nan)
        return Estimates(theta, nan, nan.copy())


class SmoothAnalytical:
    """The paper's "smooth analytical": eq. 12 through a centred 25-sample moving average.

    The paper's smoothing (its Fig. 3, computed offline) is read here as a centred window, so
    each estimate waits for 12 later samples: a stated lag of 12 sample periods.
    """

    name = "smooth"
    description = "analytical θ through a centred 25-sample moving average (lag: 12 samples)"

    def latency_s(self, rig: Rig) -> float | None:
        return (SMOOTH_WINDOW - 1) // 2 / rig.sample_rate_hz

    def estimate(self, rig: Rig, acc: np.ndarray) -> Estimates:
        va, vb = joint_vectors(rig, acc)
        theta = np.unwrap(analytical_theta(va, vb), axis=-1)
        smooth = wrap(centred_mean(theta, SMOOTH_WINDOW))
        nan = np.full_like(smooth, np.nan)
        return Estimates(smooth, nan, nan.copy())
