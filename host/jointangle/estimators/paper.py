"""The paper's filters, pinned as docs/design.md §3 states: `ekf`, `ekf-decorrelated`, `ukf`.

State x = [ω_a, ω_b, θ_ab]. With â_k = [aᵃ; aᵇ] the link-frame readings of step k:

    x_k⁻ = x_{k−1} + ΔT (A x_{k−1} + B â_k)                           (eqs. 10, 13)
    A = [[0,0,0],[0,0,0],[1,−1,0]],  B = [[G_αᵃ, 0],[0, G_αᵇ],[0, 0]]
    z_k = [G_ω²ᵃ aᵃ, G_ω²ᵇ aᵇ, Fᵃ aᵃ],  h(x) = [x₁², x₂², R(x₃) Fᵇ aᵇ]     (eqs. 11, 14)
    H = [[2x₁,0,0],[0,2x₂,0],[0,0,R'(x₃) Fᵇ aᵇ]]                      (eq. 15)
    Q_k = ΔT² B Q̂ Bᵀ,  R_k = V Q̂ Vᵀ,  V = [[G_ω²ᵃ,0],[0,G_ω²ᵇ],[Fᵃ, −R(x₃)Fᵇ]]   (eqs. 17–18)
    Q̂ = σ² I,  σ = noise density · g · √(fs/2);  x₀ = 0, P₀ = I;  P = (I − KH) P⁻.

R(x₃) in V and h uses the predicted state x_k⁻. All functions are batched over a leading axis.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from jointangle.estimators.base import Estimates, mT, pinned_noise_variance, wrap
from jointangle.model import RigModel, drot, rig_model, rot
from jointangle.rig import Rig

A_MATRIX = np.array([[0.0, 0.0, 0.0], [0.0, 0.0, 0.0], [1.0, -1.0, 0.0]])


@dataclass(frozen=True)
class PaperModel:
    """The paper's process and measurement model for one rig (batched helpers)."""

    m: RigModel
    q_hat: np.ndarray  # (M,) diagonal of Q̂

    @classmethod
    def from_rig(cls, rig: Rig, q_hat: np.ndarray | None = None) -> PaperModel:
        return cls(rig_model(rig), pinned_noise_variance(rig) if q_hat is None else q_hat)

    @property
    def dt(self) -> float:
        return self.m.dt

    @property
    def Phi(self) -> np.ndarray:
        """State transition I + AΔT (eq. 16)."""
        return np.eye(3) + A_MATRIX * self.dt

    def B(self) -> np.ndarray:
        return self.m.B()

    def Q(self) -> np.ndarray:
        """Q_k = ΔT² B Q̂ Bᵀ (eq. 17)."""
        B = self.B()
        return self.dt**2 * (B * self.q_hat) @ B.T

    def predict(self, x: np.ndarray, acc: np.ndarray) -> np.ndarray:
        """x⁻ = x + ΔT (A x + B â) for x (S, 3), acc (S, M)."""
        return x + self.dt * (x @ A_MATRIX.T + acc @ self.B().T)

    def measurement(self, acc: np.ndarray) -> np.ndarray:
        """z = [G_ω²ᵃ aᵃ, G_ω²ᵇ aᵇ, Fᵃ aᵃ] (S, 4)."""
        na = self.m.na
        aa, ab = acc[..., :na], acc[..., na:]
        return np.concatenate(
            [(aa @ self.m.a.G_w2)[..., None], (ab @ self.m.b.G_w2)[..., None],
             aa @ self.m.a.F.T], axis=-1)

    def joint_b(self, acc: np.ndarray) -> np.ndarray:
        """Fᵇ aᵇ (S, 2)."""
        return acc[..., self.m.na :] @ self.m.b.F.T

    def h(self, x: np.ndarray, acc: np.ndarray) -> np.ndarray:
        """h(x) = [x₁², x₂², R(x₃) Fᵇ aᵇ] (S, 4)."""
        u = self.joint_b(acc)
        ru = np.einsum("...ij,...j->...i", rot(x[..., 2]), u)
        return np.concatenate([x[..., :2] ** 2, ru], axis=-1)

    def H(self, x: np.ndarray, acc: np.ndarray) -> np.ndarray:
        """Jacobian of h (eq. 15), (S, 4, 3)."""
        u = self.joint_b(acc)
        out = np.zeros((*x.shape[:-1], 4, 3))
        out[..., 0, 0] = 2 * x[..., 0]
        out[..., 1, 1] = 2 * x[..., 1]
        out[..., 2:, 2] = np.einsum("...ij,...j->...i", drot(x[..., 2]), u)
        return out

    def V(self, x: np.ndarray) -> np.ndarray:
        """V of eq. 11 at θ = x₃, (S, 4, M)."""
        na, nb = self.m.na, self.m.nb
        out = np.zeros((*x.shape[:-1], 4, na + nb))
        out[..., 0, :na] = self.m.a.G_w2
        out[..., 1, na:] = self.m.b.G_w2
        out[..., 2:, :na] = self.m.a.F
        out[..., 2:, na:] = -rot(x[..., 2]) @ self.m.b.F
        return out

    def R(self, x: np.ndarray) -> np.ndarray:
        """R_k = V Q̂ Vᵀ (eq. 18), (S, 4, 4)."""
        V = self.V(x)
        return (V * self.q_hat) @ mT(V)

    def cross_cov(self, x: np.ndarray) -> np.ndarray:
        """E[w_k v_kᵀ] = −ΔT B Q̂ Vᵀ (S, 3, 4): process and measurement noise share ê.

        Erratum: the paper writes w = B ê, but with â = a + ê the true dynamics are
        ẋ = A x + B (â − ê), so w = −B ê, while v = +V ê; the cross-covariance is negative.
        """
        return -self.dt * (self.B() * self.q_hat) @ mT(self.V(x))


def _result(xs: np.ndarray, Ps: np.ndarray | None) -> Estimates:
    sigma = None if Ps is None else np.sqrt(np.maximum(Ps[..., 2, 2], 0.0))
    return Estimates(theta=wrap(xs[..., 2]), omega_a=xs[..., 0], omega_b=xs[..., 1],
                     theta_sigma=sigma)


class PaperEKF:
    """`ekf`: the paper's EKF exactly (§III-B), the fixed baseline."""

    name = "ekf"
    description = "the paper's EKF (§III-B), pinned: x₀=0, P₀=I, P=(I−KH)P⁻, no eq. 20"

    def latency_s(self, rig: Rig) -> float | None:
        return 0.0
    decorrelate = False

    def estimate(self, rig: Rig, acc: np.ndarray) -> Estimates:
        pm = PaperModel.from_rig(rig)
        S, T, _ = acc.shape
        x = np.zeros((S, 3))
        P = np.broadcast_to(np.eye(3), (S, 3, 3)).copy()
        Phi, Q = pm.Phi, pm.Q()
        xs = np.empty((S, T, 3))
        Ps = np.empty((S, T, 3, 3))
        eye = np.eye(3)
        for k in range(T):
            a = acc[:, k]
            z = pm.measurement(a)
            if self.decorrelate:
                # eq. 20, discretised around the plain prediction x_p = f(x_{k−1}, â_k).
                # Adding L (z − h(x) − v) = 0 to the dynamics gives f̃ = f + L (z − h) and
                # w̃ = w − L v, uncorrelated with v for L = E[w vᵀ] R⁻¹ (the paper's "− L" goes
                # with its sign of w; see `cross_cov`). Q̃ = Q − L E[w vᵀ]ᵀ, and the map
                # x_{k−1} ↦ x⁻ has Jacobian (I − L H(x_p)) Φ.
                x_p = pm.predict(x, a)
                C = pm.cross_cov(x_p)
                L = mT(np.linalg.solve(pm.R(x_p), mT(C)))
                Hp = pm.H(x_p, a)
                x_pred = x_p + np.einsum("sij,sj->si", L, z - pm.h(x_p, a))
                Phi_k = (eye - L @ Hp) @ Phi
                P_pred = Phi_k @ P @ mT(Phi_k) + Q - L @ mT(C)
            else:
                x_pred = pm.predict(x, a)
                P_pred = Phi @ P @ Phi.T + Q
            H = pm.H(x_pred, a)
            Rk = pm.R(x_pred)
            Sk = H @ P_pred @ mT(H) + Rk
            PHt = P_pred @ mT(H)
            K = mT(np.linalg.solve(Sk, mT(PHt)))  # K = P⁻Hᵀ S⁻¹ (S symmetric)
            x = x_pred + np.einsum("sij,sj->si", K, z - pm.h(x_pred, a))
            P = (eye - K @ H) @ P_pred
            xs[:, k] = x
            Ps[:, k] = P
        return _result(xs, Ps)


class PaperEKFDecorrelated(PaperEKF):
    """`ekf-decorrelated`: the paper's EKF with its eq. 20 noise decorrelation."""

    name = "ekf-decorrelated"
    description = "the paper's EKF with eq. 20: process noise decorrelated from measurement noise"
    decorrelate = True


# ------------------------------------------------------------------------------------------
# UKF (§III-C) with the paper's sigma points and weights (eqs. 21–22), α = 1, β = 2, κ = 0.

UKF_ALPHA = 1.0
UKF_BETA = 2.0
UKF_KAPPA = 0.0


def ukf_weights(n: int, alpha: float = UKF_ALPHA, beta: float = UKF_BETA,
                kappa: float = UKF_KAPPA) -> tuple[np.ndarray, np.ndarray, float]:
    """Mean and covariance weights of eq. 22 and λ = α²(n + κ) − n."""
    lam = alpha**2 * (n + kappa) - n
    wm = np.full(2 * n + 1, 1.0 / (2 * (n + lam)))
    wc = wm.copy()
    wm[0] = lam / (n + lam)
    wc[0] = wm[0] + (1 - alpha**2 + beta)
    return wm, wc, lam


def matrix_sqrt(P: np.ndarray) -> np.ndarray:
    """Lower Cholesky factor, batched; falls back to a symmetric eigen square root for the
    (rare) batch members whose P lost positive definiteness to rounding."""
    try:
        return np.linalg.cholesky(P)
    except np.linalg.LinAlgError:
        Ps = 0.5 * (P + mT(P))
        w, U = np.linalg.eigh(Ps)
        return U * np.sqrt(np.maximum(w, 0.0))[..., None, :]


def sigma_points(x: np.ndarray, P: np.ndarray, lam: float) -> np.ndarray:
    """eq. 21: χ₀ = μ, χ_i = μ + col_i(√((n+λ)Σ)), χ_{n+i} = μ − col_i(…); (S, 2n+1, n)."""
    n = x.shape[-1]
    L = matrix_sqrt((n + lam) * P)
    cols = mT(L)  # row i = column i of L
    return np.concatenate([x[..., None, :], x[..., None, :] + cols, x[..., None, :] - cols],
                          axis=-2)


def unscented_transform(sig: np.ndarray, wm: np.ndarray, wc: np.ndarray,
                        noise: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Weighted mean and covariance of transformed sigma points (S, 2n+1, m)."""
    mean = np.einsum("k,...ki->...i", wm, sig)
    d = sig - mean[..., None, :]
    cov = np.einsum("k,...ki,...kj->...ij", wc, d, d)
    if noise is not None:
        cov = cov + noise
    return mean, cov


class PaperUKF:
    """`ukf`: the paper's UKF (§III-C), sigma points redrawn before the measurement update."""

    name = "ukf"
    description = "the paper's UKF (eqs. 21–22, α=1, β=2, κ=0), x₀=0, P₀=I"

    def latency_s(self, rig: Rig) -> float | None:
        return 0.0

    def estimate(self, rig: Rig, acc: np.ndarray) -> Estimates:
        pm = PaperModel.from_rig(rig)
        S, T, _ = acc.shape
        n = 3
        wm, wc, lam = ukf_weights(n)
        x = np.zeros((S, n))
        P = np.broadcast_to(np.eye(n), (S, n, n)).copy()
        Q = pm.Q()
        xs = np.empty((S, T, n))
        Ps = np.empty((S, T, n, n))
        for k in range(T):
            a = acc[:, k]
            # Time update: g(χ) = χ + f(χ)ΔT through the sigma points.
            chi = sigma_points(x, P, lam)
            g = pm.predict(chi, a[:, None, :])
            x_pred, P_pred = unscented_transform(g, wm, wc, Q)
            # Measurement update with sigma points redrawn from (x⁻, P⁻).
            chi = sigma_points(x_pred, P_pred, lam)
            hz = pm.h(chi, a[:, None, :])
            h_mean, Pzz = unscented_transform(hz, wm, wc, pm.R(x_pred))
            Pxz = np.einsum("k,ski,skj->sij", wc, chi - x_pred[:, None, :],
                            hz - h_mean[:, None, :])
            K = mT(np.linalg.solve(Pzz, mT(Pxz)))
            z = pm.measurement(a)
            x = x_pred + np.einsum("sij,sj->si", K, z - h_mean)
            P = P_pred - K @ Pzz @ mT(K)
            xs[:, k] = x
            Ps[:, k] = P
        return _result(xs, Ps)
