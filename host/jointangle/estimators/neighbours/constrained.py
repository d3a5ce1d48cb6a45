"""`array-ekf-rom`: our `array-ekf` with El-Gohary & McNames' two drift-control devices
(`el-gohary-mcnames-imu-joint-angle-robot-arm.txt`, §II-E and §II-F):

1. Joint range-of-motion constraint. El-Gohary & McNames restrict the UKF's sigma points to the
   natural range of motion. For an EKF the counterpart is estimate projection (Simon 2010, their
   ref. [33]): when the updated θ leaves [lo, hi], the state moves to the bound along the
   covariance-weighted direction, which also corrects the states correlated with θ:

       x⁺ = x − P eᵀ (e P eᵀ)⁻¹ (e x − θ_bound),   e = [1, 0, …, 0]

   P is left as it is (the projection of the estimate only). The range comes from the rig file
   — `[joint] range_deg = [lo, hi]` (degrees, θ_ab = θ_a − θ_b, lo < hi, within ±180°), a fact
   about the build the user states — or from the constructor; no range means no constraint.

2. Stationary-period (zero-velocity) pseudo-measurements. El-Gohary & McNames call a segment
   static when its rate stays below 3 °/s for 0.25 s and then add a pseudo-measurement (a soft
   update) instead of resetting the state. We have no gyro, so a link counts as stationary
   when, over the trailing 0.25 s, its readings stay within noise of their window mean
   (mean normalised squared deviation ≤ `STILL_CHI`) and its array's ω² = G_ω² a averages to
   within three standard errors of zero (a constant spin would also keep the readings still),
   and so does its α = G_α a (at the turning point of a swing the readings barely change and
   ω² ≈ 0, but α is not zero), and only where these tests could see a turn of El-Gohary's 3 °/s
   at all (with gravity in the plane a turn sweeps gravity through the readings; without it the
   array's ω² is the only cue and a short or noisy array cannot tell 3 °/s from still — then no
   update is made).
   A stationary link gets the pseudo-measurements ω_j = 0 and α_j = 0 with σ = `ZUPT_SIGMA_*`.

Everything else — state, process prior, sign-hypothesis bank, causal choice — is `array-ekf`'s
(`array_kf.py`), imported, not copied, except the forward loop that these updates sit inside.
"""

from __future__ import annotations

import numpy as np

from jointangle.estimators.array_kf import (
    DEFAULT_Q_ALPHA,
    DEFAULT_Q_JOINT,
    I_AA,
    I_AB,
    I_TH,
    I_WA,
    I_WB,
    _estimates,
    _pick,
    forward,
)
from jointangle.estimators.base import Estimates, full_noise_variance, wrap
from jointangle.model import rig_model
from jointangle.rig import Rig

STILL_WINDOW_S = 0.25  # El-Gohary & McNames: static for at least 0.25 s
STILL_RATE = np.radians(3.0)  # only where the test could see a turn of 3 °/s (El-Gohary)
STILL_CHI = 1.6  # mean of (a − ā_window)²/σ² over the window and readings (1 when still)
ZUPT_SIGMA_OMEGA = np.radians(0.2)  # rad/s
ZUPT_SIGMA_ALPHA = np.radians(2.0)  # rad/s²


def joint_range_deg(rig: Rig) -> tuple[float, float] | None:
    """`[joint] range_deg = [lo, hi]` of the rig (checked when the rig file was read), if any."""
    return rig.joint_range_deg


def stationary_flags(rig: Rig, acc: np.ndarray, r_var: np.ndarray,
                     window_s: float = STILL_WINDOW_S, chi: float = STILL_CHI) -> np.ndarray:
    """(S, T, 2) booleans: is link a / b stationary over the trailing window ending at k?"""
    m = rig_model(rig)
    W = max(2, round(window_s * rig.sample_rate_hz))
    S, T, _ = acc.shape
    out = np.zeros((S, T, 2), dtype=bool)
    for j, (sl, arr) in enumerate(((slice(0, m.na), m.a), (slice(m.na, None), m.b))):
        a = acc[..., sl]
        var = r_var[sl]
        c1 = np.concatenate([np.zeros((S, 1, a.shape[-1])), np.cumsum(a, 1)], 1)
        c2 = np.concatenate([np.zeros((S, 1, a.shape[-1])), np.cumsum(a**2, 1)], 1)
        k = np.arange(W - 1, T)
        s1 = c1[:, k + 1] - c1[:, k + 1 - W]
        s2 = c2[:, k + 1] - c2[:, k + 1 - W]
        dev = (s2 - s1**2 / W) / (W - 1)  # window variance of each reading
        stat = np.mean(dev / var, axis=-1)
        w2 = a @ arr.G_w2
        cw = np.concatenate([np.zeros((S, 1)), np.cumsum(w2, 1)], 1)
        mean_w2 = (cw[:, k + 1] - cw[:, k + 1 - W]) / W
        se_w2 = np.sqrt(float((arr.G_w2**2) @ var) / W)
        # A still link has no angular acceleration either: at the turning point of a swing the
        # readings barely change over the window (and ω² ≈ 0), but α = G_α a is not zero.
        al = a @ arr.G_alpha
        ca = np.concatenate([np.zeros((S, 1)), np.cumsum(al, 1)], 1)
        mean_al = (ca[:, k + 1] - ca[:, k + 1 - W]) / W
        se_al = np.sqrt(float((arr.G_alpha**2) @ var) / W)
        # Slowest rate each test can see over the window: a turn at ω sweeps the mean specific
        # force f through |f| ω W ΔT, which lifts the statistic by (that)²/12σ² — visible past
        # ≈ 2.7σ (chi = 1.6); the ω² test sees ω past √(3 se).
        f_mean = np.linalg.norm((s1 / W) @ arr.Fm.T, axis=-1)
        w_det_chi = 2.7 * np.sqrt(np.mean(var)) / np.maximum(f_mean * W * rig.dt, 1e-12)
        w_det = np.minimum(w_det_chi, np.sqrt(3.0 * se_w2))
        out[:, k, j] = ((stat <= chi) & (np.abs(mean_w2) <= 3.0 * se_w2)
                        & (np.abs(mean_al) <= 3.0 * se_al) & (w_det <= STILL_RATE))
    return out


class ArrayEKFROM:
    """`array-ekf-rom`: array-ekf + range-of-motion projection + stationary updates."""

    name = "array-ekf-rom"
    description = ("ours + El-Gohary & McNames: array-ekf with the rig's joint range "
                   "([joint] range_deg) and zero-velocity updates in still periods (causal)")

    def __init__(self, range_deg: tuple[float, float] | None = None,
                 q_alpha: float = DEFAULT_Q_ALPHA, q_joint: float = DEFAULT_Q_JOINT,
                 zupt: bool = True) -> None:
        self.range_deg = range_deg
        self.q_alpha = q_alpha
        self.q_joint = q_joint
        self.zupt = zupt

    def latency_s(self, rig: Rig) -> float | None:
        return 0.0

    def estimate(self, rig: Rig, acc: np.ndarray) -> Estimates:
        rng = self.range_deg if self.range_deg is not None else joint_range_deg(rig)
        r_var = full_noise_variance(rig)
        S, T, _ = acc.shape
        still = stationary_flags(rig, acc, r_var) if self.zupt else np.zeros((S, T, 2), bool)

        def constrain(k: int, x: np.ndarray, P: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
            # Zero-velocity pseudo-measurements, one scalar update per quantity.
            for j, (iw, ia) in enumerate(((I_WA, I_AA), (I_WB, I_AB))):
                on = still[:, k, j]
                if not on.any():
                    continue
                for idx, sig in ((iw, ZUPT_SIGMA_OMEGA), (ia, ZUPT_SIGMA_ALPHA)):
                    Pcol = P[..., :, idx]  # (S, H, n)
                    s = P[..., idx, idx] + sig**2
                    Kz = Pcol / s[..., None]
                    innov = -x[..., idx]
                    upd = on[:, None, None]
                    x = np.where(upd, x + Kz * innov[..., None], x)
                    P = np.where(upd[..., None], P - Kz[..., :, None] * Pcol[..., None, :], P)
            if rng is not None:
                lo, hi = np.radians(rng[0]), np.radians(rng[1])
                centre = 0.5 * (lo + hi)
                th = centre + wrap(x[..., I_TH] - centre)
                target = np.clip(th, lo, hi)
                viol = target != th
                if viol.any():
                    # x⁺ = x − P e (e P e)⁻¹ (θ − θ_bound)
                    corr = P[..., :, I_TH] / P[..., I_TH, I_TH][..., None]
                    x = np.where(viol[..., None], x - corr * (th - target)[..., None], x)
            return x, P

        fw = forward(rig, acc, self.q_alpha, self.q_joint, keep_history=False,
                     after_update=constrain)
        best = np.argmax(fw.loglik, axis=1)  # causal choice at every step
        return _estimates(_pick(fw.x, best), _pick(fw.theta_var, best))
