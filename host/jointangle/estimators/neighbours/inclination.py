"""`incl-kf`: dynamic inclination from two accelerometers plus a gyro, per link, fused by a
Kalman filter ("two tri-axial accelerometers and one single-axis rate gyro",
`two-accelerometer-gyro-limb-inclination.txt`); the joint angle is θ_ab = θ_a − θ_b.

Frames. The paper's x runs along the limb, y tangential; our link frame is the same (x along
the link, z out of the plane). With the world y axis up, a link at world angle θ (its x axis
from the world x axis) reads gravity's specific force as f = g [sin θ, cos θ] (our frame),
so θ_ab = θ_a − θ_b (docs/design.md §3).

Kinematics (the paper's eq. 1 in our frame, generalised to N ≥ 2 sensors). The link turns
about an unknown point c on its x axis whose only specific force is gravity (no translation:
the paper's assumption). For sensor i at r_i:

    a_i = g [sin θ, cos θ] + D(r_i − [c, 0]) [ω², α]                    (eq. 1)

The array's pseudoinverse (model.py, eq. 9) gives y = [ω², α] = G a (the paper's eq. 2 for two
sensors: θ̈ = (a₂y − a₁y)/dL), and the frame origin's specific force u = ā − D(r̄) y. Then
u = g [sin θ, cos θ] + c [ω², −α]; taking the cross product with w = [ω², −α] removes c:

    A cos θ + B sin θ = D,   A = −ω²,  B = −α,  D = −(u_x α + u_y ω²) / g        (eqs. 4–8)

(for two sensors A, B are the paper's a₂y − a₁y, a₂x − a₁x up to the factor dL and the frame
change). With C sin(θ + δ) = D, δ = atan2(A, B), C = √(A² + B²):

    θ_dyn = asin(D / C) − δ  or  π − asin(D / C) − δ, the one nearer the prediction θ̂  (eq. 10)
    θ_static = atan2(ā_x, ā_y)                                                    (eq. 3)

Which one to use (the paper's §III-B): the paper fits the variance of each solution against
the dynamic magnitude d = √(θ̈² + θ̇⁴) (eq. 14) and switches where they cross (eq. 15). We
compute both variances per step instead and take the smaller: θ_static's from the noise of ā
across gravity plus its dynamic bias (ρ d / g)², ρ = |r̄ − r_O| (the quadratic-in-d form of
eq. 15); θ_dyn's by linearising eq. 8 in the readings (∂θ = −(∂Φ/∂a) / (∂Φ/∂θ)).

Filtering (§III-A, eqs. 11–13): a first Kalman filter smooths each reading (random walk, H = I),
then per link the state [θ, θ̇, θ̈] with F = [[1, T, T²/2], [0, 1, T], [0, 0, 1]], H = I,
measurements [θ_incl, gyro z, θ̈ = G_α a_smooth], W = diag(σ_θ², σ_θ̇², σ_θ̈²),
V = diag(10⁻⁶, σ_θ̇²/10, σ_θ̈²/10). The paper models no gyro bias; neither do we.

Domain: gravity must lie in the plane of motion (hinge axis horizontal), and a link must turn
about a point that does not accelerate (true for the bench rig's links; not for a slider-crank's
connecting rod, and without gravity in the plane there is no inclination at all).
"""

from __future__ import annotations

import numpy as np

from jointangle.estimators.base import Estimates, full_noise_variance, wrap
from jointangle.estimators.inputs import link_gyro_rate
from jointangle.model import D, link_matrices
from jointangle.rig import Rig
from jointangle.sensors import STANDARD_GRAVITY
from jointangle.sim.gyro import GYRO_NOISE_DPS_RTHZ

SMOOTH_Q_OVER_R = 10.0  # first filter: process/measurement variance ratio (gain ≈ 0.92)
# The paper tunes this by testing ("a balance between phase lag and smooth signals"); 0.1 lags
# ~27 ms and costs 3.5° at 1 Hz. 10 was chosen once on the gravity scenarios (q/r ∈ {0.1, 1,
# 10, 1000}) and is not changed per scenario.
V_THETA = 1e-6  # rad², the paper's V₁₁ (eq. 13)


def smooth_readings(acc: np.ndarray, q_over_r: float = SMOOTH_Q_OVER_R) -> np.ndarray:
    """The first filter (H = F = I, random walk) at its steady-state gain, started from the
    first sample: x_k = x_{k−1} + K (z_k − x_{k−1}), K = (−q + √(q² + 4 q r)) / (2 r)."""
    q = q_over_r
    K = (-q + np.sqrt(q * q + 4 * q)) / 2.0
    out = np.empty_like(acc)
    x = acc[:, 0].copy()
    for k in range(acc.shape[1]):
        x = x + K * (acc[:, k] - x)
        out[:, k] = x
    return out


def inclination_measurements(rig: Rig, link: str, acc_link: np.ndarray, var_link: np.ndarray
                             ) -> dict[str, np.ndarray]:
    """θ_static, θ_dyn (both branches), their variances and y = [ω², α] for one link.

    acc_link (S, T, 2N) link-frame readings; var_link (2N,) their noise variances.
    """
    g = STANDARD_GRAVITY
    cfg = rig.links[link]
    m = link_matrices(cfg, link)
    r = cfg.positions()
    r_bar = r.mean(axis=0)
    U = m.Fm - D(r_bar) @ m.G  # u = ā − D(r̄) y = U a: the frame origin's specific force
    W = np.diag([1.0, -1.0]) @ m.G  # w = [ω², −α] = W a
    abar = acc_link @ m.Fm.T
    y = acc_link @ m.G.T
    u = acc_link @ U.T
    w = acc_link @ W.T
    # eq. 3 and its variance: noise across ā plus the dynamic bias (ρ d / g)² (eq. 15 form).
    th_s = np.arctan2(abar[..., 0], abar[..., 1])
    n2 = np.maximum(np.sum(abar**2, -1), 1e-9)
    var_abar = float(np.mean((m.Fm**2) @ var_link))  # per axis
    rho = float(np.linalg.norm(r_bar - np.array(cfg.joint)))
    dmag2 = y[..., 1] ** 2 + y[..., 0] ** 2  # d² of eq. 14 (ω⁴ + α², ω² from the array)
    mismatch = (np.sqrt(n2) - g) ** 2  # |ā| ≠ g: dynamics or gravity out of the plane
    var_s = (var_abar + rho**2 * dmag2 + mismatch) / n2
    # eqs. 8–10: A cos θ + B sin θ = D.
    A = -w[..., 0]
    B = w[..., 1]  # = −α
    Dd = (u[..., 0] * w[..., 1] - u[..., 1] * w[..., 0]) / g
    C = np.sqrt(A**2 + B**2)
    delta = np.arctan2(A, B)
    ratio = Dd / np.maximum(C, 1e-12)
    ok = (np.abs(ratio) <= 1.0) & (C > 1e-9)
    asn = np.arcsin(np.clip(ratio, -1.0, 1.0))
    th_d1 = asn - delta
    th_d2 = np.pi - asn - delta
    return {"static": th_s, "var_static": var_s, "dyn1": th_d1, "dyn2": th_d2, "ok": ok,
            "A": A, "B": B, "u": u, "w": w, "y": y,
            "dPhi_du": np.stack([w[..., 1], -w[..., 0]], -1) / g,  # ∂Φ/∂u · (−1)
            "U": U, "W": W}


def _dyn_variance(th: np.ndarray, meas: dict[str, np.ndarray], var_link: np.ndarray
                  ) -> np.ndarray:
    """Linearised variance of θ_dyn: Φ = −w_x cos θ + w_y sin θ − (u_x w_y − u_y w_x)/g = 0,
    ∂θ/∂a = −(∂Φ/∂u U + ∂Φ/∂w W) / (∂Φ/∂θ)."""
    g = STANDARD_GRAVITY
    u, w = meas["u"], meas["w"]
    c, s = np.cos(th), np.sin(th)
    dphi_dth = w[..., 0] * s + w[..., 1] * c
    dphi_du = np.stack([-w[..., 1] / g, w[..., 0] / g], -1)
    dphi_dw = np.stack([-c + u[..., 1] / g, s - u[..., 0] / g], -1)
    grad = dphi_du @ meas["U"] + dphi_dw @ meas["W"]  # (S, 2N)
    num = np.sum(grad**2 * var_link, -1)
    return num / np.maximum(dphi_dth**2, 1e-12)


class InclinationKF:
    """`incl-kf`: per-link dynamic inclination + gyro + angular acceleration Kalman filter."""

    name = "incl-kf"
    description = ("neighbour: two accelerometers + gyro per link, dynamic inclination and a "
                   "Kalman filter (needs gyro columns and gravity in the plane; causal)")
    requires = ("gyro", "gravity_in_plane")

    def __init__(self, gyro_noise_dps_rthz: float = GYRO_NOISE_DPS_RTHZ,
                 smooth_q_over_r: float = SMOOTH_Q_OVER_R) -> None:
        self.gyro_noise_dps_rthz = gyro_noise_dps_rthz
        self.smooth_q_over_r = smooth_q_over_r

    def latency_s(self, rig: Rig) -> float | None:
        return 0.0

    def estimate(self, rig: Rig, acc: np.ndarray) -> Estimates:
        """Without gyro rates there is no estimate: all NaN (so a benchmark that passes only
        accelerations shows "—"). `run_estimator` refuses with a clear message instead."""
        nan = np.full(acc.shape[:2], np.nan)
        return Estimates(theta=nan, omega_a=nan.copy(), omega_b=nan.copy())

    def estimate_with_gyro(self, rig: Rig, acc: np.ndarray, gyro: np.ndarray) -> Estimates:
        na = 2 * rig.sensor_count("a")
        var = full_noise_variance(rig)
        sm = smooth_readings(acc, self.smooth_q_over_r)
        out_th, out_w = [], []
        for link, sl in (("a", slice(0, na)), ("b", slice(na, None))):
            rate = link_gyro_rate(rig, gyro, link)
            th, wv = self._link(rig, link, acc[..., sl], sm[..., sl], var[sl], rate)
            out_th.append(th)
            out_w.append(wv)
        theta = wrap(out_th[0] - out_th[1])
        return Estimates(theta=theta, omega_a=out_w[0], omega_b=out_w[1])

    def _link(self, rig: Rig, link: str, raw: np.ndarray, smooth: np.ndarray, var: np.ndarray,
              rate: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        dt = rig.dt
        # Smoothing lowers the noise variance by K/(2 − K) for a first-order filter.
        q = self.smooth_q_over_r
        K = (-q + np.sqrt(q * q + 4 * q)) / 2.0
        var_s = var * K / (2 - K)
        meas = inclination_measurements(rig, link, smooth, var_s)
        m = link_matrices(rig.links[link], link)
        alpha = meas["y"][..., 1]
        var_alpha = float((m.G_alpha**2) @ var_s)
        var_gyro = (np.radians(self.gyro_noise_dps_rthz) ** 2) * rig.sample_rate_hz / 2.0
        Phi = np.array([[1.0, dt, dt * dt / 2], [0.0, 1.0, dt], [0.0, 0.0, 1.0]])
        Vq = np.diag([V_THETA, var_gyro / 10.0, var_alpha / 10.0])  # eq. 13
        S, T = rate.shape
        x = np.zeros((S, 3))
        x[:, 0] = meas["static"][:, 0]
        x[:, 1] = rate[:, 0]
        x[:, 2] = alpha[:, 0]
        P = np.broadcast_to(np.diag([0.1, var_gyro, var_alpha]), (S, 3, 3)).copy()
        th_out = np.empty((S, T))
        w_out = np.empty((S, T))
        eye = np.eye(3)
        for k in range(T):
            if k > 0:
                x = x @ Phi.T
                P = Phi @ P @ Phi.T + Vq
            pred = x[:, 0]
            # eq. 10's branch: the solution nearer the prediction (ζ = sign cos(θ̂ + δ)).
            d1 = np.abs(wrap(meas["dyn1"][:, k] - pred))
            d2 = np.abs(wrap(meas["dyn2"][:, k] - pred))
            th_dyn = np.where(d1 <= d2, meas["dyn1"][:, k], meas["dyn2"][:, k])
            var_dyn = _dyn_variance(th_dyn, {key: meas[key][:, k] if key not in ("U", "W")
                                             else meas[key] for key in ("u", "w", "U", "W")},
                                    var_s)
            var_dyn = np.where(meas["ok"][:, k], var_dyn, np.inf)
            var_st = meas["var_static"][:, k]
            use_dyn = var_dyn < var_st
            th_m = np.where(use_dyn, th_dyn, meas["static"][:, k])
            var_th = np.minimum(np.where(use_dyn, var_dyn, var_st), np.pi**2)
            z = np.stack([pred + wrap(th_m - pred), rate[:, k], alpha[:, k]], -1)
            Wm = np.zeros((S, 3, 3))
            Wm[:, 0, 0] = var_th
            Wm[:, 1, 1] = var_gyro
            Wm[:, 2, 2] = var_alpha
            Sk = P + Wm  # H = I (eq. 13)
            Kk = np.linalg.solve(Sk, P).swapaxes(-1, -2)  # P S⁻¹ (both symmetric)
            x = x + np.einsum("sij,sj->si", Kk, z - x)
            P = (eye - Kk) @ P
            P = 0.5 * (P + P.swapaxes(-1, -2))
            th_out[:, k] = x[:, 0]
            w_out[:, k] = x[:, 1]
        return th_out, w_out
