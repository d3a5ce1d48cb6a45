"""`madgwick-array`: the redundant-array kinematics of Madgwick et al.
(`madgwick-redundant-accelerometer-arrays.txt`) applied to each link, with their angular-rate
complementary filter and a Mahony-style orientation correction.

Forward kinematics (their eqs. 2, 7–9). A triple-axis sensor at d = [d_x, d_y, d_z] on a rigid
body with origin acceleration a, angular velocity ω = [p, q, r] and angular acceleration ω̇:

    α_i = ω̇ × d + ω × (ω × d) + a = G_i s,
    s = [ẍ, ÿ, z̈, p², q², r², ṗ, q̇, ṙ, pq, qr, rp]                                   (eq. 9)

`madgwick_G` builds G_i (3 × 12, their eq. 8) and the pseudoinverse solution s = P⁺ α_P with
P = [G_1; …; G_n] (eqs. 15–18) needs ≥ 4 non-coplanar sensors. For planar motion about z
(p = q = 0) only the columns of ẍ, ÿ, r², ṙ act on the x, y rows and the z rows read z̈ alone,
so the planar reduction is exact:

    [α_x; α_y]_i = [I₂  D(d_i)] [ẍ, ÿ, r², ṙ]ᵀ        (D of Woods & Vikas eq. 2)

We take the body origin at the joint O (d_i = r_i − r_O), so s gives the joint's specific force
directly; any number of sensors, anywhere in the plane (off the link axis too), one
pseudoinverse per link (`planar_pinv`).

Angular rate (eqs. 19–25, one axis): the array gives r² but not the sign of r. With
ε̃ = sign(ω̃) (|ω̃| − √max(r², 0)) (eq. 24 for one axis) the complementary filter is

    ω̃_k = ω̃_{k−1} + ΔT (ṙ_k − K ε̃_k)                                                 (eq. 25)

Orientation (eqs. 27–31, planar): Madgwick's reference vector is gravity, the long-run mean of
the array's acceleration. For a joint we have a better one: the joint's specific force is the
same physical vector seen from both links (vᵃ = R(θ) vᵇ), every sample. The relative angle is
integrated from the two rates and corrected by the normalised cross product, with proportional
and integral gains (eq. 29); the integral also corrects the rate (eq. 31):

    e = (vᵃ × R(θ̂) vᵇ) / (|vᵃ| |vᵇ|)  (= sin(θ − θ̂)),   weighted by |v|² / (|v|² + 9 σ_v²)
    θ̂_k = θ̂_{k−1} + ΔT (ω̃_a − ω̃_b + K_P e + K_I Σ e ΔT)

Gains: K = 2 s⁻¹ (the paper used 0.5 at 1 kHz with a slower pendulum), K_P = 20 s⁻¹,
K_I = 0.5 s⁻², fixed for every scenario (chosen once from a four-point sweep on
paper-table2-L30/L10 and gravity-fast-periodic/impulse).
"""

from __future__ import annotations

import numpy as np

from jointangle.estimators.analytical import analytical_theta
from jointangle.estimators.base import Estimates, full_noise_variance, wrap
from jointangle.model import D
from jointangle.rig import Rig

K_RATE = 2.0  # s⁻¹, eq. 25
K_P = 20.0  # s⁻¹, eq. 29
K_I = 0.5  # s⁻², eq. 29


def madgwick_G(d: np.ndarray) -> np.ndarray:
    """G_i of eq. 8 (3 × 12) for a sensor at d = [d_x, d_y, d_z], columns ordered as s (eq. 9).

    Derived from ω̇ × d + ω × (ω × d) + a:
      x: ẍ − d_x(q² + r²) + d_z ṗ... written out per component below.
    """
    dx, dy, dz = (float(v) for v in d)
    G = np.zeros((3, 12))
    G[:, 0:3] = np.eye(3)
    # ω × (ω × d) = ω (ω·d) − d |ω|²
    # x: p(p dx + q dy + r dz) − dx(p²+q²+r²) = −dx q² − dx r² + dy pq + dz rp
    G[0, 4], G[0, 5], G[0, 9], G[0, 11] = -dx, -dx, dy, dz
    # y: q(p dx + q dy + r dz) − dy|ω|² = −dy p² − dy r² + dx pq + dz qr
    G[1, 3], G[1, 5], G[1, 9], G[1, 10] = -dy, -dy, dx, dz
    # z: r(p dx + q dy + r dz) − dz|ω|² = −dz p² − dz q² + dx rp + dy qr
    G[2, 3], G[2, 4], G[2, 11], G[2, 10] = -dz, -dz, dx, dy
    # ω̇ × d = [q̇ dz − ṙ dy, ṙ dx − ṗ dz, ṗ dy − q̇ dx]
    G[0, 7], G[0, 8] = dz, -dy
    G[1, 8], G[1, 6] = dx, -dz
    G[2, 6], G[2, 7] = dy, -dx
    return G


def pseudoinverse_solution(positions: np.ndarray, readings: np.ndarray) -> np.ndarray:
    """s = P⁺ α_P (eqs. 15–17) for sensors at positions (n, 3), readings (..., n, 3)."""
    P = np.vstack([madgwick_G(d) for d in positions])
    return readings.reshape(*readings.shape[:-2], -1) @ np.linalg.pinv(P).T


def planar_pinv(lever: np.ndarray) -> np.ndarray:
    """(4, 2N) pseudoinverse of the planar reduction [I₂ D(d_i)] for lever arms d_i (N, 2):
    rows give the origin's specific force x, y, then r² and ṙ."""
    P = np.vstack([np.hstack([np.eye(2), D(d)]) for d in lever])
    return np.linalg.pinv(P)


class MadgwickArray:
    """`madgwick-array`: per-link pseudoinverse kinematics, rate complementary filter and a
    joint-referenced Mahony correction (accelerometers only)."""

    name = "madgwick-array"
    description = ("neighbour: Madgwick et al. redundant-array pseudoinverse per link, rate "
                   "complementary filter, Mahony-style angle correction on the joint (causal)")

    def __init__(self, k_rate: float = K_RATE, k_p: float = K_P, k_i: float = K_I) -> None:
        self.k_rate = k_rate
        self.k_p = k_p
        self.k_i = k_i

    def latency_s(self, rig: Rig) -> float | None:
        return 0.0

    def estimate(self, rig: Rig, acc: np.ndarray) -> Estimates:
        na = 2 * rig.sensor_count("a")
        var = full_noise_variance(rig)
        sols = []
        var_v = []
        for link, sl in (("a", slice(0, na)), ("b", slice(na, None))):
            cfg = rig.links[link]
            Pp = planar_pinv(cfg.positions() - np.array(cfg.joint))
            sols.append(acc[..., sl] @ Pp.T)  # (S, T, 4)
            var_v.append(float(np.sum(Pp[:2] ** 2 * var[sl]) / 2.0))  # per axis of v
        sa, sb = sols
        dt = rig.dt
        S, T = acc.shape[:2]
        th = analytical_theta(sa[:, 0, :2], sb[:, 0, :2])
        wa = np.sqrt(np.maximum(sa[:, 0, 2], 0.0))
        wb = np.sqrt(np.maximum(sb[:, 0, 2], 0.0))
        integ = np.zeros(S)
        out = np.empty((3, S, T))
        sig_v2 = var_v[0] + var_v[1]
        for k in range(T):
            if k > 0:
                for w, s_ in ((0, sa), (1, sb)):
                    cur = wa if w == 0 else wb
                    eps = np.sign(cur) * (np.abs(cur) - np.sqrt(np.maximum(s_[:, k, 2], 0.0)))
                    new = cur + dt * (s_[:, k, 3] - self.k_rate * eps)  # eq. 25
                    if w == 0:
                        wa = new
                    else:
                        wb = new
                va, vb = sa[:, k, :2], sb[:, k, :2]
                c, s = np.cos(th), np.sin(th)
                u = np.stack([c * vb[:, 0] + s * vb[:, 1], -s * vb[:, 0] + c * vb[:, 1]], -1)
                na_, nb_ = np.linalg.norm(va, axis=-1), np.linalg.norm(u, axis=-1)
                e = (va[:, 0] * u[:, 1] - va[:, 1] * u[:, 0]) / np.maximum(na_ * nb_, 1e-12)
                n2 = na_ * nb_
                e = e * n2 / (n2 + 9.0 * sig_v2)
                integ = integ + e * dt
                th = th + dt * (wa - wb + self.k_p * e + self.k_i * integ)  # eqs. 27–31
            out[0, :, k] = th
            out[1, :, k] = wa
            out[2, :, k] = wb
        return Estimates(theta=wrap(out[0]), omega_a=out[1], omega_b=out[2])
