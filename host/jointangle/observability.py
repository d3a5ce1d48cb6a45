"""Is the joint angle observable right now? (docs/design.md §3 and §6)

Every estimator reads θ from the direction of the joint's specific force j, seen from both
links (eq. 12; the filters' measurement z₃ = Fᵃaᵃ against R(θ)Fᵇaᵇ). With the hinge axis
horizontal, gravity keeps |j| ≈ g; with a vertical hinge j is only the joint's own acceleration,
and a rig at rest leaves θ unobservable: the estimate then is a guess and must be shown as one.

Test per sample, causal: the mean of j over the trailing window (0.25 s) from each link must
stand clear of its noise, |j̄| ≥ `MIN_SNR` · σ_j̄, on both links. σ_j̄ = √(tr(F Q̂ Fᵀ)/2 / W) is
the per-axis noise of the window mean.
"""

from __future__ import annotations

import numpy as np

from jointangle.estimators.base import full_noise_variance
from jointangle.model import rig_model
from jointangle.rig import Rig

WINDOW_S = 0.25
MIN_SNR = 5.0  # |j̄| / σ_j̄: an angle error of at most ~1/5 rad from a single window


def observable(rig: Rig, acc: np.ndarray, window_s: float = WINDOW_S,
               min_snr: float = MIN_SNR) -> np.ndarray:
    """Booleans (S, T): is θ observable at each sample, from link-frame readings acc (S, T, M)?"""
    m = rig_model(rig)
    q = full_noise_variance(rig)
    W = max(1, round(window_s * rig.sample_rate_hz))
    ok = np.ones(acc.shape[:2], dtype=bool)
    for F, sl in ((m.a.F, slice(0, m.na)), (m.b.F, slice(m.na, None))):
        j = acc[..., sl] @ F.T  # (S, T, 2)
        c = np.concatenate([np.zeros((j.shape[0], 1, 2)), np.cumsum(j, axis=1)], axis=1)
        k = np.arange(j.shape[1])
        lo = np.maximum(k + 1 - W, 0)
        n = (k + 1 - lo)[None, :, None]
        mean = (c[:, k + 1] - c[:, lo]) / n
        sigma = np.sqrt(np.trace((F * q[sl]) @ F.T) / 2.0 / n[..., 0])
        ok &= np.linalg.norm(mean, axis=-1) >= min_snr * sigma
    return ok
