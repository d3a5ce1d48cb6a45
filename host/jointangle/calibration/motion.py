"""Geometry calibrated from motion: sensor positions, in-plane mountings and joint positions.

From 30-60 s of the user moving the joint freely, the rig's geometry is fitted by maximum a
posteriori over the whole recording: the trajectory and the geometry together, by Gauss-Newton
(Levenberg-Marquardt) on one sparse nonlinear least-squares problem.

Model (docs/design.md §3, link frames; m_i = sensor i's calibrated reading turned into the link
frame by the nominal mounting, `sensor_to_link`):

    R₂(δφ_i) m_i = j + D(ρ_i) [ω_a², α_a]                    sensor i on link a
    R₂(δφ_i) m_i = R(θ)ᵀ j + D(ρ_i) [ω_b², α_b]              sensor i on link b
    ρ_i = (p_i + δp_i) − (o_L + δo_L)                         lever arm from the joint O

with R₂(δφ) the rotation by the mounting error δφ, R(θ) the rotation of docs/design.md §3
(vᵃ = R vᵇ),
j the specific force of O in link a's frame. Unknowns: per sample k the state
x_k = [θ, ω_a, ω_b, α_a, α_b, j_x, j_y]; per sensor δp_i (2) and δφ_i; per link δo_L (2).
Residuals, each divided by its σ:
- every reading (σ² = noise density² · g² · fs/2 + LSB²/12, the rig's figures);
- the kinematics between samples (trapezoid): θ_{k+1} − θ_k − ΔT/2 (ω_a − ω_b)|_k^{k+1},
  ω_{k+1} − ω_k − ΔT/2 (α_k + α_{k+1}) (σ from a white-jerk motion, `MotionPrior`), and loose
  random walks on α and j;
- the drawing: δp, δo with σ = tolerance/√3 (uniform ± tolerance), δφ likewise.
Start: θ, ω from `array-rts` on the nominal rig, α = dω/dt, j from the readings.

What the motion can identify (and what not, whatever the motion):
- Only lever arms ρ_i = p_i − o_L enter: moving a link's sensors and its joint together by the
  same vector changes no reading. The fit moves them by the least the drawing's tolerances
  allow (the prior), so positions and joints are each "identified" only as lever arms.
- Turning a link's frame — all its sensors' mountings by β and its lever arms by β — changes
  no reading but θ_ab by β: the direction of a link's x axis is a convention, which the static
  calibration (link poses along ±g) or the drawing fixes. The fit keeps each link's common
  rotation where the priors put it (σ ≈ the mounting tolerance / √N), and so a constant θ
  offset of that size remains — unless a still pose at a known joint angle gives the joint's
  zero (calibration/reference.py: the maths, and why this offset is all that is left).
- A link that does not turn (ω = α = 0: link a clamped) shows no lever arm at all, and a
  joint motion without ω² and α excitation of both links identifies nothing: the posterior σ
  of each quantity says how much the data said (`identified`: below half its prior σ).
- Read skew between sensors is not fitted: the board's read times are known (the rig's
  `read_delay_s`, docs/as-built.md); the fit takes the samples as simultaneous, which at the
  board's 0.23 ms a sensor moves no lever arm beyond the fit's own floor (3 builds, 60 s:
  with the skew alone the fitted lever arms are 0.21 mm RMS off, with ±2 mm positions alone
  0.20 mm).
The fit is refused (nothing written) when the recording is too short, a reading is clipped,
a link hardly turns, or the residuals are far above the sensors' noise.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field, replace

import numpy as np
import scipy.sparse as sp
from scipy.linalg import LinAlgError, cho_factor, cho_solve, cho_solve_banded, cholesky_banded

from jointangle.estimators.array_kf import ArrayRTS
from jointangle.estimators.base import full_noise_variance, sensor_to_link
from jointangle.model import rot
from jointangle.rig import LINK_NAMES, Rig
from jointangle.sensors import STANDARD_GRAVITY

N_X = 7
I_TH, I_WA, I_WB, I_AA, I_AB, I_JX, I_JY = range(N_X)
MG = STANDARD_GRAVITY * 1e-3


@dataclass(frozen=True)
class MotionPrior:
    """Noise of the motion model and the drawing's tolerances (uniform ± tolerance)."""

    position_tol_m: float = 0.002
    joint_tol_m: float = 0.002
    mounting_tol_deg: float = 0.5
    q_jerk: float = 100.0  # rad²/s⁵: white angular jerk (ω and θ integration)
    q_alpha_walk: float = 1.0e4  # rad²/s³: α random walk per second
    q_joint_walk: float = 400.0  # m²/s³: j random walk per second


@dataclass(frozen=True)
class MotionChecks:
    min_seconds: float = 20.0
    max_samples: int = 6000  # decimated to at most this many samples (speed)
    clip_fraction: float = 0.98  # of the sensor's range
    min_alpha_rms: float = 2.0  # rad/s², each link that is to be fitted
    min_omega2_rms: float = 0.5  # rad²/s²
    max_residual_ratio: float = 3.0  # residual RMS / noise σ
    identified_ratio: float = 0.5  # posterior σ below this × prior σ: identified
    max_moved_tolerances: float = 5.0  # a lever arm moved further than this × the tolerances
    max_iterations: int = 30


@dataclass(frozen=True)
class SensorGeometry:
    label: str
    lever_nominal_m: tuple[float, float]  # p_i − o_L as drawn
    lever_m: tuple[float, float]  # as fitted
    lever_sigma_m: tuple[float, float]
    mounting_deg: float  # δφ fitted
    mounting_sigma_deg: float
    relative_mounting_sigma_deg: float  # of δφ_i − the link's mean δφ
    residual_mg_rms: float
    residual_ratio: float  # residual RMS / noise σ
    grade: str
    length_sigma_m: float = math.nan  # σ along the lever arm (free of the link frame's turn)
    moved_m: float = 0.0  # |fitted − drawn lever arm|


@dataclass(frozen=True)
class LinkGeometry:
    link: str
    joint_offset_m: tuple[float, float]
    alpha_rms: float
    omega2_rms: float
    common_rotation_sigma_deg: float  # posterior σ of the link's mean mounting (not identified)


@dataclass(frozen=True)
class MotionReport:
    accepted: bool
    reasons: list[str]
    seconds: float
    samples: int
    decimation: int
    iterations: int
    cost_start: float
    cost_end: float
    sensors: list[SensorGeometry] = field(default_factory=list)
    links: list[LinkGeometry] = field(default_factory=list)
    dp: np.ndarray | None = None  # (n_sensors, 2) δp
    dphi_deg: np.ndarray | None = None  # (n_sensors,)
    do: np.ndarray | None = None  # (2, 2) δo per link


def _grade(sig_mm: float, ratio: float) -> str:
    if ratio > 3.0:
        return "-"
    return "A" if sig_mm <= 0.2 else "B" if sig_mm <= 0.5 else "C" if sig_mm <= 1.0 else "-"


class _Problem:
    """The sparse least-squares problem: residuals and Jacobian at a parameter vector."""

    def __init__(self, rig: Rig, m: np.ndarray, dt: float, prior: MotionPrior) -> None:
        self.T = m.shape[0]
        self.dt = dt
        self.m = m  # (T, M) link-frame readings
        sens = rig.all_sensors()
        self.n = len(sens)
        self.link_of = np.array([0 if ln == "a" else 1 for ln, _, _ in sens])
        self.p0 = np.array([s.position for _, _, s in sens], dtype=float)
        self.o0 = np.array([rig.links[ln].joint for ln in LINK_NAMES], dtype=float)
        var = full_noise_variance(rig)
        self.sig = np.sqrt(var).reshape(self.n, 2)
        self.nx = N_X * self.T
        self.ng = 3 * self.n + 4
        self.N = self.nx + self.ng
        q = prior
        self.s_th = max(math.sqrt(q.q_jerk * dt**5 / 20.0), 1e-6)
        self.s_w = max(math.sqrt(q.q_jerk * dt**3 / 12.0), 1e-5)
        self.s_a = math.sqrt(q.q_alpha_walk * dt)
        self.s_j = math.sqrt(q.q_joint_walk * dt)
        self.s_p = prior.position_tol_m / math.sqrt(3.0)
        self.s_o = prior.joint_tol_m / math.sqrt(3.0)
        self.s_phi = math.radians(prior.mounting_tol_deg) / math.sqrt(3.0)
        self.prior_sigma = np.concatenate([
            np.tile([self.s_p, self.s_p, self.s_phi], self.n), np.full(4, self.s_o)])

    def g_index(self, i: int) -> int:
        return self.nx + 3 * i

    def o_index(self, link: int) -> int:
        return self.nx + 3 * self.n + 2 * link

    def split(self, v: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        x = v[: self.nx].reshape(self.T, N_X)
        g = v[self.nx:]
        dp = g[: 3 * self.n].reshape(self.n, 3)[:, :2]
        dphi = g[: 3 * self.n].reshape(self.n, 3)[:, 2]
        do = g[3 * self.n:].reshape(2, 2)
        return x, dp, dphi, do

    def levers(self, dp: np.ndarray, do: np.ndarray) -> np.ndarray:
        return self.p0 + dp - (self.o0 + do)[self.link_of]

    def build(self, v: np.ndarray, jac: bool = True
              ) -> tuple[np.ndarray, sp.csr_matrix | None]:
        x, dp, dphi, do = self.split(v)
        T, dt = self.T, self.dt
        rho = self.levers(dp, do)
        kk = np.arange(T)
        res = []
        rows: list[np.ndarray] = []
        cols: list[np.ndarray] = []
        vals: list[np.ndarray] = []
        r0 = 0
        Rt = np.swapaxes(rot(x[:, I_TH]), -1, -2)  # (T, 2, 2) R(θ)ᵀ
        th = x[:, I_TH]
        dRt = np.stack([np.stack([-np.sin(th), -np.cos(th)], -1),
                        np.stack([np.cos(th), -np.sin(th)], -1)], -2)
        j = x[:, I_JX:I_JY + 1]

        def add(r_idx: np.ndarray, c_idx: np.ndarray | int, val: np.ndarray | float) -> None:
            rr = np.asarray(r_idx)
            rows.append(rr)
            cols.append(np.broadcast_to(np.asarray(c_idx), rr.shape))
            vals.append(np.broadcast_to(np.asarray(val, dtype=float), rr.shape))

        for i in range(self.n):
            L = self.link_of[i]
            iw, ia = (I_WA, I_AA) if L == 0 else (I_WB, I_AB)
            w, al = x[:, iw], x[:, ia]
            mi = self.m[:, 2 * i:2 * i + 2]
            c, s = math.cos(dphi[i]), math.sin(dphi[i])
            f = np.stack([c * mi[:, 0] - s * mi[:, 1], s * mi[:, 0] + c * mi[:, 1]], -1)
            df = np.stack([-s * mi[:, 0] - c * mi[:, 1], c * mi[:, 0] - s * mi[:, 1]], -1)
            w2 = w * w
            rx, ry = rho[i]
            jl = j if L == 0 else np.einsum("tab,tb->ta", Rt, j)
            pred = jl + np.stack([-rx * w2 - ry * al, -ry * w2 + rx * al], -1)
            sig = self.sig[i]
            res.append(((f - pred) / sig).T.reshape(-1))  # comp 0 all k, then comp 1
            if not jac:
                r0 += 2 * T
                continue
            g = self.g_index(i)
            oi = self.o_index(int(L))
            for comp in (0, 1):
                ridx = r0 + comp * T + kk
                sc = 1.0 / sig[comp]
                base = kk * N_X
                # ω, α
                dw = np.array([2 * rx, 2 * ry])[comp] * w
                add(ridx, base + iw, dw * sc)
                add(ridx, base + ia, np.array([ry, -rx])[comp] * sc)
                # lever arm: ∂(−pred)/∂ρx = [ω², −α], ∂ρy = [α, ω²]
                dx = (w2 if comp == 0 else -al) * sc
                dy = (al if comp == 0 else w2) * sc
                add(ridx, g, dx)
                add(ridx, g + 1, dy)
                add(ridx, oi, -dx)
                add(ridx, oi + 1, -dy)
                add(ridx, g + 2, df[:, comp] * sc)
                if L == 0:
                    add(ridx, base + I_JX + comp, -sc)
                else:
                    add(ridx, base + I_JX, -Rt[:, comp, 0] * sc)
                    add(ridx, base + I_JY, -Rt[:, comp, 1] * sc)
                    add(ridx, base + I_TH, -(dRt[:, comp, :] * j).sum(-1) * sc)
            r0 += 2 * T
        # kinematics between samples
        k0 = np.arange(T - 1)
        a, b = x[:-1], x[1:]
        proc = [
            ((b[:, I_TH] - a[:, I_TH] - dt / 2 * (a[:, I_WA] - a[:, I_WB] + b[:, I_WA]
                                                    - b[:, I_WB])) / self.s_th,
             [(0, I_TH, -1.0), (1, I_TH, 1.0), (0, I_WA, -dt / 2), (1, I_WA, -dt / 2),
              (0, I_WB, dt / 2), (1, I_WB, dt / 2)], self.s_th),
            ((b[:, I_WA] - a[:, I_WA] - dt / 2 * (a[:, I_AA] + b[:, I_AA])) / self.s_w,
             [(0, I_WA, -1.0), (1, I_WA, 1.0), (0, I_AA, -dt / 2), (1, I_AA, -dt / 2)],
             self.s_w),
            ((b[:, I_WB] - a[:, I_WB] - dt / 2 * (a[:, I_AB] + b[:, I_AB])) / self.s_w,
             [(0, I_WB, -1.0), (1, I_WB, 1.0), (0, I_AB, -dt / 2), (1, I_AB, -dt / 2)],
             self.s_w),
            ((b[:, I_AA] - a[:, I_AA]) / self.s_a, [(0, I_AA, -1.0), (1, I_AA, 1.0)], self.s_a),
            ((b[:, I_AB] - a[:, I_AB]) / self.s_a, [(0, I_AB, -1.0), (1, I_AB, 1.0)], self.s_a),
            ((b[:, I_JX] - a[:, I_JX]) / self.s_j, [(0, I_JX, -1.0), (1, I_JX, 1.0)], self.s_j),
            ((b[:, I_JY] - a[:, I_JY]) / self.s_j, [(0, I_JY, -1.0), (1, I_JY, 1.0)], self.s_j),
        ]
        for r, terms, sg in proc:
            res.append(r)
            if jac:
                ridx = r0 + k0
                for step, idx, coef in terms:
                    add(ridx, (k0 + step) * N_X + idx, coef / sg)
            r0 += T - 1
        # the drawing
        gvec = v[self.nx:]
        res.append(gvec / self.prior_sigma)
        if jac:
            gi = np.arange(self.ng)
            add(r0 + gi, self.nx + gi, 1.0 / self.prior_sigma)
        r0 += self.ng
        rvec = np.concatenate(res)
        if not jac:
            return rvec, None
        J = sp.csr_matrix((np.concatenate([np.ravel(v_) for v_ in vals]),
                           (np.concatenate([np.ravel(r_) for r_ in rows]),
                            np.concatenate([np.ravel(c_) for c_ in cols]))),
                          shape=(r0, self.N))
        return rvec, J

    def n_meas(self) -> int:
        return 2 * self.n * self.T


BAND = 2 * N_X - 1  # a sample's states meet only the next sample's in JᵀJ


class _Normal:
    """JᵀJ (+ damping) solved by its structure: the trajectory block is banded (bandwidth
    `BAND`), the geometry block small and dense; the geometry by its Schur complement."""

    def __init__(self, A: sp.csr_matrix, nx: int, lam: float) -> None:
        A = A.tocoo()
        d = A.diagonal() * (1.0 + lam) + 1e-12
        keep = (A.row < nx) & (A.col < nx) & (A.row >= A.col)
        ab = np.zeros((BAND + 1, nx))
        off = A.row[keep] - A.col[keep]
        if off.size and off.max() > BAND:
            raise ValueError("trajectory block wider than its band")
        np.add.at(ab, (off, A.col[keep]), A.data[keep])
        ab[0] = d[:nx]
        self.nx = nx
        self.cb = cholesky_banded(ab, lower=True)
        Acsr = A.tocsr()
        self.Axg = Acsr[:nx, nx:].toarray()
        Agg = Acsr[nx:, nx:].toarray()
        Agg[np.diag_indices_from(Agg)] = d[nx:]
        self.Y = cho_solve_banded((self.cb, True), self.Axg)
        self.S = Agg - self.Axg.T @ self.Y
        self.Sf = cho_factor(self.S)

    def solve(self, b: np.ndarray) -> np.ndarray:
        yb = cho_solve_banded((self.cb, True), b[: self.nx])
        dg = cho_solve(self.Sf, b[self.nx:] - self.Axg.T @ yb)
        return np.concatenate([yb - self.Y @ dg, dg])

    def geometry_covariance(self) -> np.ndarray:
        return np.asarray(cho_solve(self.Sf, np.eye(self.S.shape[0])))


def _initial_state(rig: Rig, m: np.ndarray, dt: float) -> np.ndarray:
    est = ArrayRTS().estimate(rig, m[None])
    th, wa, wb = est.theta[0], est.omega_a[0], est.omega_b[0]
    th = np.unwrap(th)
    aa, ab = np.gradient(wa, dt), np.gradient(wb, dt)
    x = np.zeros((len(th), N_X))
    x[:, I_TH], x[:, I_WA], x[:, I_WB], x[:, I_AA], x[:, I_AB] = th, wa, wb, aa, ab
    # j: the mean over every sensor of its reading less its lever-arm term, in link a's frame
    R = rot(th)
    acc = np.zeros((len(th), 2))
    n = 0
    for ln in LINK_NAMES:
        w, al = (wa, aa) if ln == "a" else (wb, ab)
        for s in rig.links[ln].sensors:
            rx, ry = np.subtract(s.position, rig.links[ln].joint)
            k = n
            mi = m[:, 2 * k:2 * k + 2]
            v = mi - np.stack([-rx * w * w - ry * al, -ry * w * w + rx * al], -1)
            acc += v if ln == "a" else np.einsum("tab,tb->ta", R, v)
            n += 1
    x[:, I_JX:I_JY + 1] = acc / n
    return x


def _clipped(rig: Rig, readings: np.ndarray, frac: float) -> list[str]:
    out = []
    for k, (ln, i, s) in enumerate(rig.all_sensors()):
        full = s.range_g * STANDARD_GRAVITY
        n = int(np.sum(np.any(np.abs(readings[:, k, :]) >= frac * full, axis=-1)))
        if n:
            out.append(f"{ln}.{i}: {n} samples at its ±{s.range_g} g range (clipped)")
    return out


def calibrate_motion(rig: Rig, t: np.ndarray, readings: np.ndarray,
                     prior: MotionPrior = MotionPrior(), checks: MotionChecks = MotionChecks(),
                     progress: Callable[[int, float], None] | None = None) -> MotionReport:
    """Fit the geometry of `rig` to a recording of free joint motion (readings (T, n, 3), raw
    sensor frames as in an accelerations CSV). The report says what was fitted, how well, and
    why it was refused if it was."""
    t = np.asarray(t, dtype=float)
    seconds = float(t[-1] - t[0]) if len(t) > 1 else 0.0
    empty = MotionReport(False, [], seconds, len(t), 1, 0, math.nan, math.nan)
    reasons: list[str] = []
    if seconds < checks.min_seconds:
        reasons.append(f"the recording is {seconds:.1f} s long; motion calibration needs at "
                       f"least {checks.min_seconds:g} s of free joint motion (30-60 s "
                       "recommended)")
    reasons += _clipped(rig, readings, checks.clip_fraction)
    if reasons:
        return replace(empty, reasons=reasons)
    dec = max(1, math.ceil(len(t) / checks.max_samples))
    t = t[::dec]
    readings = readings[::dec]
    dt = float(np.median(np.diff(t)))
    rig_d = rig.with_sample_rate(1.0 / dt)
    m = sensor_to_link(rig_d, readings)
    prob = _Problem(rig_d, m, dt, prior)
    # a (still nominal) array-rts pass gives the trajectory to start from
    x0 = _initial_state(rig_d, m, dt)
    alpha_rms = [float(np.sqrt(np.mean(x0[:, i] ** 2))) for i in (I_AA, I_AB)]
    omega2_rms = [float(np.sqrt(np.mean(x0[:, i] ** 4))) for i in (I_WA, I_WB)]
    for L, ln in enumerate(LINK_NAMES):
        if alpha_rms[L] < checks.min_alpha_rms or omega2_rms[L] < checks.min_omega2_rms:
            reasons.append(
                f"link {ln} hardly turned (RMS α {alpha_rms[L]:.2f} rad/s², RMS ω² "
                f"{omega2_rms[L]:.2f} rad²/s²; needs ≥ {checks.min_alpha_rms:g} and "
                f"≥ {checks.min_omega2_rms:g}): move both links, briskly and in both "
                "directions, through the joint's range")
    if reasons:
        return replace(empty, reasons=reasons, samples=len(t), decimation=dec)
    v = np.concatenate([x0.reshape(-1), np.zeros(prob.ng)])
    r, J = prob.build(v)
    assert J is not None
    cost = float(r @ r)
    cost0 = cost
    lam = 1e-3
    it = 0
    for it in range(1, checks.max_iterations + 1):
        A = (J.T @ J).tocsr()
        gvec = J.T @ r
        improved = False
        for _ in range(10):
            try:
                step = _Normal(A, prob.nx, lam).solve(-gvec)
            except (LinAlgError, ValueError):
                lam *= 10
                continue
            r_new, _ = prob.build(v + step, jac=False)
            c_new = float(r_new @ r_new)
            if c_new < cost:
                improved = True
                break
            lam *= 10
        if not improved:
            break
        v = v + step
        rel = (cost - c_new) / cost
        cost = c_new
        lam = max(lam / 10, 1e-9)
        r, J = prob.build(v)
        assert J is not None
        if progress:
            progress(it, cost)
        if rel < 1e-7:
            break
    # Posterior covariance of the geometry: the geometry block of (JᵀJ)⁻¹.
    C = _Normal((J.T @ J).tocsr(), prob.nx, 0.0).geometry_covariance()
    C = 0.5 * (C + C.T)
    _, dp, dphi, do = prob.split(v)
    lever0 = prob.levers(np.zeros_like(dp), np.zeros_like(do))
    lever = prob.levers(dp, do)
    meas = r[: prob.n_meas()]
    sensors = []
    labels = [f"{ln}.{i}" for ln, i, _ in rig.all_sensors()]
    for i in range(prob.n):
        g = 3 * i
        oi = 3 * prob.n + 2 * prob.link_of[i]
        # lever arm = δp − δo: its covariance
        Lx = np.zeros(prob.ng)
        Ly = np.zeros(prob.ng)
        Lx[g], Lx[oi] = 1.0, -1.0
        Ly[g + 1], Ly[oi + 1] = 1.0, -1.0
        link_idx = [3 * k + 2 for k in range(prob.n) if prob.link_of[k] == prob.link_of[i]]
        relm = np.zeros(prob.ng)
        relm[link_idx] = -1.0 / len(link_idx)
        relm[g + 2] += 1.0
        ri = meas[2 * i * prob.T:2 * (i + 1) * prob.T]
        ratio = float(np.sqrt(np.mean(ri**2)))
        res_mg = float(np.sqrt(np.mean((ri.reshape(2, -1) * prob.sig[i][:, None]) ** 2))) / MG
        sig_lever = (math.sqrt(Lx @ C @ Lx), math.sqrt(Ly @ C @ Ly))
        # Along the lever arm (its length): free of the turn of the link's frame, which moves
        # the far end of a long arm sideways by what the mounting tolerance allows.
        u = lever[i] / max(float(np.hypot(*lever[i])), 1e-9)
        Lr = u[0] * Lx + u[1] * Ly
        sig_len = math.sqrt(max(Lr @ C @ Lr, 0.0))
        moved = float(np.hypot(*(lever[i] - lever0[i])))
        sensors.append(SensorGeometry(
            label=labels[i], lever_nominal_m=(float(lever0[i, 0]), float(lever0[i, 1])),
            lever_m=(float(lever[i, 0]), float(lever[i, 1])), lever_sigma_m=sig_lever,
            mounting_deg=math.degrees(dphi[i]), mounting_sigma_deg=math.degrees(
                math.sqrt(C[g + 2, g + 2])),
            relative_mounting_sigma_deg=math.degrees(math.sqrt(max(relm @ C @ relm, 0.0))),
            residual_mg_rms=res_mg, residual_ratio=ratio,
            grade=_grade(sig_len * 1e3, ratio), length_sigma_m=sig_len, moved_m=moved))
    links = []
    for L, ln in enumerate(LINK_NAMES):
        idx = [3 * k + 2 for k in range(prob.n) if prob.link_of[k] == L]
        mean = np.zeros(prob.ng)
        mean[idx] = 1.0 / len(idx)
        links.append(LinkGeometry(
            link=ln, joint_offset_m=(float(do[L, 0]), float(do[L, 1])),
            alpha_rms=alpha_rms[L], omega2_rms=omega2_rms[L],
            common_rotation_sigma_deg=math.degrees(math.sqrt(mean @ C @ mean))))
    for s in sensors:
        if s.residual_ratio > checks.max_residual_ratio:
            reasons.append(f"{s.label}: residual {s.residual_mg_rms:.2f} mg RMS is "
                           f"{s.residual_ratio:.1f}× its noise (limit "
                           f"{checks.max_residual_ratio:g}×): not a rigid two-link motion, "
                           "or this sensor's calibration or rig entry is wrong")
        elif s.length_sigma_m > checks.identified_ratio * math.hypot(prob.s_p, prob.s_o):
            reasons.append(f"{s.label}: its lever arm was not identified (σ "
                           f"{s.length_sigma_m * 1e3:.2f} mm along it): the motion did not "
                           "excite enough ω² and α")
        if s.moved_m > checks.max_moved_tolerances * math.hypot(prior.position_tol_m,
                                                                prior.joint_tol_m):
            reasons.append(f"{s.label}: the fit moves it {s.moved_m * 1e3:.1f} mm from where "
                           "the rig file puts it, far beyond the tolerances (±"
                           f"{prior.position_tol_m * 1e3:g} mm sensors, ±"
                           f"{prior.joint_tol_m * 1e3:g} mm joints): check the rig file's "
                           "positions and sensor order, or give larger tolerances")
    return MotionReport(
        accepted=not reasons, reasons=reasons, seconds=seconds, samples=len(t), decimation=dec,
        iterations=it, cost_start=cost0, cost_end=cost, sensors=sensors, links=links,
        dp=dp.copy(), dphi_deg=np.degrees(dphi), do=do.copy())


def motion_calibrated_rig(rig: Rig, report: MotionReport) -> Rig:
    """`rig` with the fitted geometry: positions + δp, rotation_deg + δφ, joints + δo."""
    assert report.dp is not None and report.dphi_deg is not None and report.do is not None
    links = {}
    k = 0
    for L, ln in enumerate(LINK_NAMES):
        link = rig.links[ln]
        sensors = []
        for s in link.sensors:
            sensors.append(replace(
                s, position=(s.position[0] + float(report.dp[k, 0]),
                             s.position[1] + float(report.dp[k, 1])),
                rotation_deg=s.rotation_deg + float(report.dphi_deg[k])))
            k += 1
        links[ln] = replace(link, sensors=tuple(sensors), joint=(
            link.joint[0] + float(report.do[L, 0]), link.joint[1] + float(report.do[L, 1])))
    return replace(rig, links=links)
