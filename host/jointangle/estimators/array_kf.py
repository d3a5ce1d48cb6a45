"""`array-ekf`, `array-fls`, `array-rts`: a better model of the same sensors (ours).

The paper feeds each sample's noisy angular acceleration α = G_α a into the process as an input
and compares derived quantities (ω² = G_ω² a, a_O = F a) whose noise is shared with that input
(its eq. 20 patches the resulting correlation). Here every raw link-frame reading is a
measurement with its own independent noise, and the motion gets a generic smoothness prior:

  state  s = [θ_ab, ω_a, ω_b, α_a, α_b, j_x, j_y, j̇_x, j̇_y, ȷ_a, ȷ_b]
         (j = specific force of the joint O in link a's frame, ȷ = angular jerk)
  process (continuous)  θ̇ = ω_a − ω_b,  ω̇ = α,  α̇ = ȷ,  ȷ̇ = w_ȷ,  j̈ = w_j   (white w)
  measurement, sensor i of link a:  aᵃ_i = j + D(r_i − r_Oᵃ) [ω_a², α_a]          (eqs. 1–2)
               sensor i of link b:  aᵇ_i = R(θ)ᵀ j + D(r_i − r_Oᵇ) [ω_b², α_b]    (vᵃ = R vᵇ)

with measurement noise R = diag(σ² + LSB²/12). The discrete process is the exact (Van Loan)
discretisation of the linear continuous model. The prior's noise levels (`DEFAULT_Q_*`) are
chosen once, loose enough for impulsive movements; they are not tuned per scenario.

Start-up: the sign of each ω is not observable from one sample (only ω² is). A bank of four
filters starts from the first sample — θ from eq. 12, |ω_j| = √(G_ω² a), α = G_α a, j = Fᵃ aᵃ —
one per sign combination (±ω_a, ±ω_b); each step reports the member with the highest
accumulated innovation likelihood, so the choice is causal too.

`array-fls` adds a fixed-lag Rauch–Tung–Striebel smoother (lag 100 ms) and `array-rts` the full
RTS smoother over the member with the best whole-run likelihood (offline).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from scipy.linalg import expm

from jointangle.errors import InputError
from jointangle.estimators.base import Estimates, full_noise_variance, mT, wrap
from jointangle.model import ArrayMatrices, RigModel, rig_model
from jointangle.rig import Rig

N_STATE = 11
I_TH, I_WA, I_WB, I_AA, I_AB, I_JX, I_JY, I_VX, I_VY, I_KA, I_KB = range(N_STATE)

DEFAULT_Q_ALPHA = 3.0e4  # rad²/s⁷: snap spectral density (α, jerk chain); loose enough for impulses
DEFAULT_Q_JOINT = 1.0  # m²/s⁵: spectral density of the rate of change of the joint's force
# Robustness of the forward pass (they change nothing at the usual rates, see `forward`):
LIN_TOL = 0.5  # redo an update whose linear model misses a reading by more than this (in σ)
MAX_RELINEARISE = 10  # at most this many re-linearised updates per sample
PRUNE_NATS = 1000.0  # a start-up hypothesis this far behind the best has lost (odds < e⁻¹⁰⁰⁰)
# Below this the filters diverge on the design's faster scenarios (3 Hz: gravity-fast-periodic
# and gravity-impulse; 2 Hz: five of the seven; 1 Hz: all); from it up they track all seven.
MIN_RATE_HZ = 5.0


def discretise(dt: float, q_alpha: float, q_joint: float) -> tuple[np.ndarray, np.ndarray]:
    """Φ = e^{F ΔT} and Q = ∫₀^ΔT e^{Fτ} L Qc Lᵀ e^{Fᵀτ} dτ by Van Loan's method."""
    F = np.zeros((N_STATE, N_STATE))
    F[I_TH, I_WA], F[I_TH, I_WB] = 1.0, -1.0
    F[I_WA, I_AA] = F[I_WB, I_AB] = 1.0
    F[I_JX, I_VX] = F[I_JY, I_VY] = 1.0
    F[I_AA, I_KA] = F[I_AB, I_KB] = 1.0
    Qc = np.diag([0, 0, 0, 0, 0, 0, 0, q_joint, q_joint, q_alpha, q_alpha]).astype(float)
    n = N_STATE
    M = np.zeros((2 * n, 2 * n))
    M[:n, :n] = -F
    M[:n, n:] = Qc
    M[n:, n:] = F.T
    E = expm(M * dt)
    Phi = E[n:, n:].T
    Q = Phi @ E[:n, n:]
    return Phi, 0.5 * (Q + Q.T)


@dataclass(frozen=True)
class _Geometry:
    """Per-reading lever arms relative to each link's joint."""

    ra: np.ndarray  # (N_a, 2) r_i − r_Oᵃ
    rb: np.ndarray  # (N_b, 2) r_i − r_Oᵇ


def _geometry(rig: Rig) -> _Geometry:
    la, lb = rig.links["a"], rig.links["b"]
    return _Geometry(la.positions() - np.array(la.joint), lb.positions() - np.array(lb.joint))


def _d_columns(r: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """D(r) columns for each sensor, flattened to readings: ∂a/∂ω² and ∂a/∂α, each (2N,)."""
    dw2 = np.stack([-r[:, 0], -r[:, 1]], 1).reshape(-1)
    dal = np.stack([-r[:, 1], r[:, 0]], 1).reshape(-1)
    return dw2, dal


class ArrayModel:
    """Measurement function and Jacobian of the raw-reading model, batched over (..., n).

    A sensor read τ_i after the row's time (the rig's `read_delay_s`: a multiplexed board
    reads its sensors one after another) measures the motion at t + τ_i: its rows are h
    evaluated at the state carried forward by the process's own dynamics, Φ(τ_i) s (θ turned by
    (ω_a − ω_b)τ + …, ω by ατ + …, the joint's force by j̇τ), with Jacobian H(Φ(τ_i) s) Φ(τ_i).
    The process noise over τ_i (well under a sample period) is neglected.
    """

    def __init__(self, rig: Rig) -> None:
        g = _geometry(rig)
        self.na = 2 * len(g.ra)
        self.nb = 2 * len(g.rb)
        self.dw2_a, self.dal_a = _d_columns(g.ra)
        self.dw2_b, self.dal_b = _d_columns(g.rb)
        self.lever_a = float(np.max(np.abs(self.dw2_a)))
        self.lever_b = float(np.max(np.abs(self.dw2_b)))
        delays = rig.read_delays()
        # (Φ(τ), the reading columns read at τ) per distinct non-zero delay
        self.delayed: list[tuple[np.ndarray, np.ndarray]] = []
        for tau in np.unique(delays[delays != 0.0]):
            cols = np.flatnonzero(np.repeat(delays == tau, 2))
            self.delayed.append((discretise(float(tau), 0.0, 0.0)[0], cols))

    def h(self, s: np.ndarray) -> np.ndarray:
        out = self._h(s)
        for Phi, cols in self.delayed:
            out[..., cols] = self._h(s @ Phi.T)[..., cols]
        return out

    def H(self, s: np.ndarray) -> np.ndarray:
        out = self._H(s)
        for Phi, cols in self.delayed:
            out[..., cols, :] = self._H(s @ Phi.T)[..., cols, :] @ Phi
        return out

    def miss_bound(self, s: np.ndarray, step: np.ndarray) -> np.ndarray:
        """An upper bound on |h(s + step) − h(s) − H(s) step| over the readings, batched.

        h is quadratic in ω (the miss is step_ω² D) and turns j by θ on link b: there the
        miss is at most |j| step_θ²/2 + |step_j| |step_θ|.
        """
        dth = np.abs(step[..., I_TH])
        rot = (np.hypot(s[..., I_JX], s[..., I_JY]) * 0.5 * dth
               + np.hypot(step[..., I_JX], step[..., I_JY])) * dth
        return np.maximum(step[..., I_WA] ** 2 * self.lever_a,
                          step[..., I_WB] ** 2 * self.lever_b + rot)

    def _h(self, s: np.ndarray) -> np.ndarray:
        th, wa, wb, aa, ab = (s[..., i] for i in range(5))
        jx, jy = s[..., I_JX], s[..., I_JY]
        c, sn = np.cos(th), np.sin(th)
        # R(θ)ᵀ j = [c jx − s jy, s jx + c jy]
        jbx = c * jx - sn * jy
        jby = sn * jx + c * jy
        ha = (wa**2)[..., None] * self.dw2_a + aa[..., None] * self.dal_a
        ha[..., 0::2] += jx[..., None]
        ha[..., 1::2] += jy[..., None]
        hb = (wb**2)[..., None] * self.dw2_b + ab[..., None] * self.dal_b
        hb[..., 0::2] += jbx[..., None]
        hb[..., 1::2] += jby[..., None]
        return np.concatenate([ha, hb], axis=-1)

    def _H(self, s: np.ndarray) -> np.ndarray:
        th, wa, wb = s[..., I_TH], s[..., I_WA], s[..., I_WB]
        jx, jy = s[..., I_JX], s[..., I_JY]
        c, sn = np.cos(th), np.sin(th)
        out = np.zeros((*s.shape[:-1], self.na + self.nb, N_STATE))
        na = self.na
        out[..., :na, I_WA] = 2 * wa[..., None] * self.dw2_a
        out[..., :na, I_AA] = self.dal_a
        out[..., 0:na:2, I_JX] = 1.0
        out[..., 1:na:2, I_JY] = 1.0
        out[..., na:, I_WB] = 2 * wb[..., None] * self.dw2_b
        out[..., na:, I_AB] = self.dal_b
        # ∂(Rᵀj)/∂θ = [−s jx − c jy, c jx − s jy]
        out[..., na::2, I_TH] = (-sn * jx - c * jy)[..., None]
        out[..., na + 1 :: 2, I_TH] = (c * jx - sn * jy)[..., None]
        out[..., na::2, I_JX] = c[..., None]
        out[..., na::2, I_JY] = -sn[..., None]
        out[..., na + 1 :: 2, I_JX] = sn[..., None]
        out[..., na + 1 :: 2, I_JY] = c[..., None]
        return out


SIGNS = np.array([[1.0, 1.0], [1.0, -1.0], [-1.0, 1.0], [-1.0, -1.0]])


def initial_states(m: RigModel, window: np.ndarray, r_var: np.ndarray, dt: float
                   ) -> tuple[np.ndarray, np.ndarray]:
    """Initial states (S, 4, n) and covariances (S, 4, n, n), one per ω-sign hypothesis.

    `window` (S, W, M) holds the first W samples an output at t = 0 may see: W = 1 for a causal
    filter, lag + 1 for a fixed-lag smoother. Over the window: y = [ω², α] = G a averaged per
    link; the joint force j = Fᵃ aᵃ fitted with a straight line (value and rate at t = 0); and for
    each sign hypothesis the θ₀ that best aligns jᵃ_k with R(θ₀ + (ω_a − ω_b) t_k) jᵇ_k — the
    circular mean of eq. 12 over the window, each sample turned back by the hypothesised motion.
    |ω| is floored at one σ of its window estimate so the four hypotheses never collapse onto
    ω = 0 when the first ω² comes out negative.
    """
    S, W, _ = window.shape
    tk = np.arange(W) * dt
    aa, ab = window[..., : m.na], window[..., m.na :]

    def link(arr: ArrayMatrices, a: np.ndarray, var: np.ndarray
             ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        y = (a @ arr.G.T).mean(axis=1)  # (S, 2): mean [ω², α]
        var_y = (arr.G * var) @ arr.G.T / W
        w = np.sqrt(np.maximum(y[:, 0], np.sqrt(var_y[0, 0])))
        return w, y[:, 1], var_y

    wa, al_a, vya = link(m.a, aa, r_var[: m.na])
    wb, al_b, vyb = link(m.b, ab, r_var[m.na :])
    ja = aa @ m.a.F.T  # (S, W, 2)
    jb = ab @ m.b.F.T
    if W > 1:
        fit = np.linalg.pinv(np.stack([np.ones(W), tk], 1))  # (2, W): value and rate at t = 0
        j0, j_rate = np.einsum("pw,swi->psi", fit, ja)
    else:
        j0, j_rate = ja[:, 0], np.zeros((S, 2))
    # eq. 12 per sample as a complex number (dot + i·cross), for the circular mean below.
    z = (ja[..., 0] * jb[..., 0] + ja[..., 1] * jb[..., 1]) + 1j * (
        ja[..., 0] * jb[..., 1] - ja[..., 1] * jb[..., 0])
    t_mid = tk.mean()
    x = np.zeros((S, 4, N_STATE))
    for h, (sa, sb) in enumerate(SIGNS):
        wa_mid, wb_mid = sa * wa, sb * wb  # the window's mean ω, reached at its middle
        theta_rate = wa_mid - wb_mid
        x[:, h, I_TH] = np.angle(np.sum(z * np.exp(-1j * theta_rate[:, None] * tk), axis=1))
        x[:, h, I_WA] = wa_mid - al_a * t_mid
        x[:, h, I_WB] = wb_mid - al_b * t_mid
    x[..., I_AA] = al_a[:, None]
    x[..., I_AB] = al_b[:, None]
    x[..., I_JX] = j0[:, None, 0]
    x[..., I_JY] = j0[:, None, 1]
    x[..., I_VX] = j_rate[:, None, 0]
    x[..., I_VY] = j_rate[:, None, 1]
    var_ja = (m.a.F * r_var[: m.na]) @ m.a.F.T
    var_j = var_ja + (m.b.F * r_var[m.na :]) @ m.b.F.T
    jn2 = np.maximum(np.mean(np.sum(ja**2, -1), axis=1), 1e-6)
    var_th = np.minimum(4.0 * np.trace(var_j) / W / jn2, np.pi**2)
    P = np.zeros((S, 4, N_STATE, N_STATE))
    P[..., I_TH, I_TH] = var_th[:, None]
    # ω from √(ω²): σ_ω ≈ σ_ω² / (2|ω|), capped at √σ_ω²; plus slack for the model's error.
    for i, w, v in ((I_WA, wa, vya[0, 0]), (I_WB, wb, vyb[0, 0])):
        P[..., i, i] = (4.0 * np.minimum(v / np.maximum(4 * w**2, 1e-9), np.sqrt(v)) + 0.02)[
            :, None]
    P[..., I_AA, I_AA] = vya[1, 1] * 16 + 0.1
    P[..., I_AB, I_AB] = vyb[1, 1] * 16 + 0.1
    P[..., I_JX:I_VX, I_JX:I_VX] = var_ja * 4 + np.eye(2) * 1e-4
    P[..., I_VX, I_VX] = P[..., I_VY, I_VY] = 1.0
    P[..., I_KA, I_KA] = P[..., I_KB, I_KB] = 10.0
    return x, P


@dataclass
class FilterState:
    """Where a forward pass stopped: posterior states, covariances and accumulated
    log-likelihoods of every hypothesis, so that the next chunk of samples can continue."""

    x: np.ndarray  # (S, H, n)
    P: np.ndarray  # (S, H, n, n)
    total: np.ndarray  # (S, H)


@dataclass
class ForwardPass:
    x: np.ndarray  # (S, H, T, n) posterior states
    theta_var: np.ndarray  # (S, H, T) posterior variance of θ
    loglik: np.ndarray  # (S, H, T) accumulated innovation log-likelihood
    Phi: np.ndarray
    final: FilterState
    # With history (smoothers only): priors and posterior covariances of every step.
    x_pred: np.ndarray | None = None  # (S, H, T, n)
    P_pred: np.ndarray | None = None  # (S, H, T, n, n)
    P: np.ndarray | None = None  # (S, H, T, n, n)

    def history(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        if self.x_pred is None or self.P_pred is None or self.P is None:
            raise ValueError("this forward pass kept no history")
        return self.x_pred, self.P_pred, self.P


StepHook = Callable[[int, np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray]]


def forward(rig: Rig, acc: np.ndarray, q_alpha: float, q_joint: float,
            keep_history: bool, init_window: int = 1, start: FilterState | None = None,
            only: np.ndarray | None = None, after_update: StepHook | None = None,
            offset: int = 0) -> ForwardPass:
    """Run the hypothesis bank over acc (S, T, M).

    It starts from the first `init_window` samples (see `initial_states`) or, given `start`,
    continues a previous pass whose last sample came just before acc[:, 0] (sample `offset` of
    the run, for messages). `only` (S,) keeps one start-up hypothesis per run.
    `after_update(k, x, P) -> (x, P)` may add pseudo-measurements or constraints after each
    step's update (see `array-ekf-rom`). Memory is O(T·n) without history and O(T·n²) with it.

    Each update is the EKF's, redone linearised at its result where the linearisation was poor
    (`relinearise`, an iterated EKF); members of the bank that have lost are kept finite by
    following the best one (`prune_hypotheses`). At tens of Hz and more neither changes
    anything in steady state. Below `MIN_RATE_HZ`, or when the reported estimate turns by more
    than half a turn between samples (it has lost track, or the motion is too fast for the
    rate), the pass refuses with an InputError naming the rate.
    """
    if rig.sample_rate_hz < MIN_RATE_HZ:
        raise InputError(f"the array filters need sample_rate_hz >= {MIN_RATE_HZ:g} (this rig "
                         f"samples at {rig.sample_rate_hz:g} Hz): samples further apart lose "
                         "track of the motion", field="sample_rate_hz")
    m = rig_model(rig)
    model = ArrayModel(rig)
    r_var = full_noise_variance(rig)
    Phi, Q = discretise(rig.dt, q_alpha, q_joint)
    S, T, M = acc.shape
    if start is None:
        x, P = initial_states(m, acc[:, : max(1, min(init_window, T))], r_var, rig.dt)
        if only is not None:
            rows = np.arange(S)
            x, P = x[rows, only][:, None], P[rows, only][:, None]
        total = np.zeros(x.shape[:2])
    else:
        x, P, total = start.x, start.P, start.total
    n_h = x.shape[1]
    xs = np.empty((S, n_h, T, N_STATE))
    th_var = np.empty((S, n_h, T))
    ll = np.empty((S, n_h, T))
    hist = keep_history
    xps = np.empty_like(xs) if hist else None
    Pps = np.empty((S, n_h, T, N_STATE, N_STATE)) if hist else None
    Ps = np.empty((S, n_h, T, N_STATE, N_STATE)) if hist else None
    Rm = np.diag(r_var)
    r_sd = np.sqrt(r_var)
    log2pi = M * np.log(2 * np.pi)
    for k in range(T):
        if k > 0 or start is not None:
            x, P = prune_hypotheses(x, P, total)
            x = x @ Phi.T
            P = Phi @ P @ Phi.T + Q
        if xps is not None and Pps is not None:
            xps[:, :, k] = x
            Pps[:, :, k] = P
        z = acc[:, k][:, None, :]
        H = model.H(x)
        nu = z - model.h(x)
        PHt = P @ mT(H)
        Sk = H @ PHt + Rm
        try:
            L = np.linalg.cholesky(Sk)
        except np.linalg.LinAlgError:
            raise _lost_track(rig, offset + k) from None
        # K = P Hᵀ S⁻¹; the innovation's log-likelihood scores the hypotheses.
        Sinv_nu = np.linalg.solve(Sk, nu[..., None])[..., 0]
        K = mT(np.linalg.solve(Sk, mT(PHt)))
        x_prior = x
        x = x + np.einsum("shij,shj->shi", K, nu)
        x, K, H = relinearise(model, z, x_prior, P, Rm, r_sd, x, H, z - nu, K)
        IKH = np.eye(N_STATE) - K @ H
        P = IKH @ P @ mT(IKH) + K @ Rm @ mT(K)  # Joseph form: stays symmetric PSD
        logdet = 2 * np.sum(np.log(np.diagonal(L, axis1=-2, axis2=-1)), -1)
        total = total - 0.5 * (np.sum(nu * Sinv_nu, -1) + logdet + log2pi)
        ll[:, :, k] = total
        if after_update is not None:
            x, P = after_update(k, x, P)
        _check_tracking(rig, x, total, offset + k)
        xs[:, :, k] = x
        th_var[:, :, k] = P[..., I_TH, I_TH]
        if Ps is not None:
            Ps[:, :, k] = P
    return ForwardPass(x=xs, theta_var=th_var, loglik=ll, Phi=Phi,
                       final=FilterState(x, P, total), x_pred=xps, P_pred=Pps, P=Ps)


def relinearise(model: ArrayModel, z: np.ndarray, x_prior: np.ndarray, P: np.ndarray,
                Rm: np.ndarray, r_sd: np.ndarray, x: np.ndarray, H: np.ndarray,
                hx: np.ndarray, K: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Iterated-EKF (Gauss–Newton) refinement of the update where the linearisation was poor.

    `x` is the update of the prior `x_prior` (covariance P) linearised at x_prior (H, h(x) = hx,
    gain K). Where the linear model misses h at x by more than `LIN_TOL` σ in some reading, the
    update is redone linearised at x — x⁺ = x⁻ + K_i (z − h(x_i) − H_i (x⁻ − x_i)) — until it
    is consistent (at most `MAX_RELINEARISE` times); the other members keep their update.
    Returns the posterior states and, per member, the gain and Jacobian of its last update
    (for the covariance update).

    At the usual rates (tens of Hz and more) an update moves the state so little that the
    linearisation holds and nothing is redone. Samples far apart (below ~20 Hz) can leave the
    prior far from the truth, and there one linear step is badly wrong: from an ω far from
    √(ω²) it only about halves ω, the α and jerk states absorb the rest through the prior's
    cross-covariances, the next prediction overshoots further and ω grows geometrically (the
    plain EKF diverged, typically in a wrong-sign start-up member, at 10 Hz and below).
    """
    tol = LIN_TOL * r_sd
    if np.all(model.miss_bound(x_prior, x - x_prior) <= tol.min()):
        return x, K, H  # the usual case, without evaluating h
    xi, Hi, hi = x_prior, H, hx
    for _ in range(MAX_RELINEARISE):
        hn = model.h(x)
        miss = hn - hi - np.einsum("...ij,...j->...i", Hi, x - xi)
        b = np.nonzero(np.any(np.abs(miss) > tol, axis=-1))
        if b[0].size == 0:
            break
        xb, xpb, Pb, hb = x[b], x_prior[b], P[b], hn[b]
        Hb = model.H(xb)
        nub = np.broadcast_to(z, hn.shape)[b] - hb - np.einsum("bij,bj->bi", Hb, xpb - xb)
        PHt = Pb @ mT(Hb)
        Kb = mT(np.linalg.solve(Hb @ PHt + Rm, mT(PHt)))
        xi, Hi, hi, x, K, H = xi.copy(), Hi.copy(), hi.copy(), x.copy(), K.copy(), H.copy()
        xi[b], Hi[b], hi[b] = xb, Hb, hb
        x[b] = xpb + np.einsum("bij,bj->bi", Kb, nub)
        K[b], H[b] = Kb, Hb
    return x, K, H


def prune_hypotheses(x: np.ndarray, P: np.ndarray, total: np.ndarray
                     ) -> tuple[np.ndarray, np.ndarray]:
    """Members of the hypothesis bank more than `PRUNE_NATS` behind the best of their run take
    over the best member's state and covariance (they keep their own, low, likelihood).

    Such a member has lost: its odds are below e⁻¹⁰⁰⁰, so it is never the one reported and its
    weight in any blend is exactly zero. Left alone, a losing (wrong-sign) member can diverge
    when samples are far apart, until its innovation covariance is too ill-conditioned to
    factorise and the whole pass fails. Following the best member keeps every member's numbers
    finite and changes no output.
    """
    if x.shape[1] < 2:
        return x, P
    dead = total < total.max(axis=1, keepdims=True) - PRUNE_NATS
    if not dead.any():
        return x, P
    rows = np.arange(x.shape[0])
    best = np.argmax(total, axis=1)
    x = np.where(dead[..., None], x[rows, best][:, None], x)
    P = np.where(dead[..., None, None], P[rows, best][:, None], P)
    return x, P


def _check_tracking(rig: Rig, x: np.ndarray, total: np.ndarray, k: int) -> None:
    """Refuse when the reported member's estimate is not finite or turns by more than half a
    turn between samples: the angle is then aliased (a real motion too fast for the rate, or
    an estimate that has lost track of a slower one) and nothing after it can be trusted."""
    w_any = max(float(np.max(np.abs(x[..., I_WA : I_WB + 1]))),
                float(np.max(np.abs(x[..., I_WA] - x[..., I_WB]))))
    if w_any * rig.dt <= np.pi and np.isfinite(total).all():
        return  # the usual case: no member turns that fast (False for NaN)
    rows = np.arange(x.shape[0])
    best = np.argmax(total, axis=1)
    xb, tb = x[rows, best], total[rows, best]
    w = np.max(np.abs([xb[:, I_WA], xb[:, I_WB], xb[:, I_WA] - xb[:, I_WB]]), axis=0)
    bad = ~(np.isfinite(w) & np.isfinite(tb)) | (w * rig.dt > np.pi)
    if bad.any():
        w_bad = w[bad]
        raise _lost_track(rig, k, f"{np.max(w_bad):.3g} rad/s, more than half a turn per "
                          "sample" if np.isfinite(w_bad).all() else "it is not finite")


def _lost_track(rig: Rig, k: int, what: str = "its covariance is singular") -> InputError:
    return InputError(
        f"the array filter lost track at sample {k} (t = {k * rig.dt:.3g} s) at "
        f"{rig.sample_rate_hz:g} Hz ({what}): the samples are too far apart for this motion "
        f"(these filters need at least {MIN_RATE_HZ:g} Hz, faster motions more)",
        field="sample_rate_hz")


def _pick(arr: np.ndarray, idx: np.ndarray) -> np.ndarray:
    """arr (S, H, T, ...) indexed by hypothesis idx (S, T) -> (S, T, ...)."""
    S, _, T = arr.shape[:3]
    return arr[np.arange(S)[:, None], idx, np.arange(T)[None, :]]


def _estimates(x: np.ndarray, theta_var: np.ndarray) -> Estimates:
    return Estimates(theta=wrap(x[..., I_TH]), omega_a=x[..., I_WA], omega_b=x[..., I_WB],
                     theta_sigma=np.sqrt(np.maximum(theta_var, 0.0)))


class ArrayEKF:
    """`array-ekf`: the raw-reading model with a smooth-motion prior, causal."""

    name = "array-ekf"
    description = ("ours: every raw reading as a measurement, smooth α and joint-force priors, "
                   "ω-sign hypothesis bank at start-up (causal)")

    def latency_s(self, rig: Rig) -> float | None:
        return 0.0

    def __init__(self, q_alpha: float = DEFAULT_Q_ALPHA, q_joint: float = DEFAULT_Q_JOINT):
        self.q_alpha = q_alpha
        self.q_joint = q_joint

    def estimate(self, rig: Rig, acc: np.ndarray) -> Estimates:
        fw = forward(rig, acc, self.q_alpha, self.q_joint, keep_history=False)
        best = np.argmax(fw.loglik, axis=1)  # (S, T): causal choice at every step
        return _estimates(_pick(fw.x, best), _pick(fw.theta_var, best))


def rts(fw: ForwardPass) -> tuple[np.ndarray, np.ndarray]:
    """Rauch–Tung–Striebel pass over a single-hypothesis forward pass with history.

    C_k = P_k Φᵀ (P⁻_{k+1})⁻¹;  x_k^s = x_k + C_k (x_{k+1}^s − x⁻_{k+1});
    P_k^s = P_k + C_k (P_{k+1}^s − P⁻_{k+1}) C_kᵀ.
    Returns the smoothed states (S, T, n) and θ variances (S, T).
    """
    xp, Pp, P = (a[:, 0] for a in fw.history())
    x = fw.x[:, 0]
    T = x.shape[1]
    xs = x.copy()
    Ps = P[:, T - 1]
    th_var = np.empty(x.shape[:2])
    th_var[:, T - 1] = Ps[..., I_TH, I_TH]
    Phi = fw.Phi
    for k in range(T - 2, -1, -1):
        C = mT(np.linalg.solve(Pp[:, k + 1], Phi @ P[:, k]))  # P Φᵀ Pp⁻¹ (Pp symmetric)
        xs[:, k] = x[:, k] + np.einsum("sij,sj->si", C, xs[:, k + 1] - xp[:, k + 1])
        Ps = P[:, k] + C @ (Ps - Pp[:, k + 1]) @ mT(C)
        th_var[:, k] = Ps[..., I_TH, I_TH]
    return xs, th_var


FLS_LAG_S = 0.1  # the real-time budget: at most 100 ms behind the newest sample
CHUNK = 512  # samples per forward chunk of the smoothers: bounds memory on long recordings


def _start_window(rig: Rig) -> int:
    """Samples a smoothed output at t = 0 may see: t = 0 plus the 100 ms lag."""
    return int(np.floor(FLS_LAG_S * rig.sample_rate_hz + 1e-9)) + 1


class ArrayRTS:
    """`array-rts`: offline Rauch–Tung–Striebel smoothing of `array-ekf`."""

    name = "array-rts"
    description = "ours, offline: RTS smoother over array-ekf's best start-up hypothesis"

    def latency_s(self, rig: Rig) -> float | None:
        return None

    def __init__(self, q_alpha: float = DEFAULT_Q_ALPHA, q_joint: float = DEFAULT_Q_JOINT):
        self.q_alpha = q_alpha
        self.q_joint = q_joint

    def estimate(self, rig: Rig, acc: np.ndarray) -> Estimates:
        window = _start_window(rig)
        # Pass 1 (O(T·n) memory) picks the hypothesis with the best whole-run likelihood; pass
        # 2 keeps the history of that one only.
        first = forward(rig, acc, self.q_alpha, self.q_joint, keep_history=False,
                        init_window=window)
        best = np.argmax(first.loglik[:, :, -1], axis=1)
        fw = forward(rig, acc, self.q_alpha, self.q_joint, keep_history=True,
                     init_window=window, only=best)
        return _estimates(*rts(fw))


def smoother_gains(fw: ForwardPass) -> np.ndarray:
    """RTS gains C_k = P_k Φᵀ (P⁻_{k+1})⁻¹ for every hypothesis and step (S, H, T−1, n, n)."""
    _, Pp, P = fw.history()
    PhiP = fw.Phi @ P[:, :, :-1]  # Φ P_k; P⁻ is symmetric, so C = (P⁻⁻¹ Φ P)ᵀ
    return mT(np.linalg.solve(Pp[:, :, 1:], PhiP))


def fixed_lag(fw: ForwardPass, lag: int) -> tuple[np.ndarray, np.ndarray]:
    """Fixed-lag smoothed states (S, T, n) and θ variances (S, T): the estimate of step k from
    data up to k + lag.

    Runs the RTS recursion backwards `lag` steps from every window end at once (the gains do
    not depend on where the window ends). The output blends the ω-sign hypotheses by their
    likelihood at the window's end (a circular mean for θ), so that choice too uses no data
    beyond k + lag. The last `lag` steps of the pass get the longest window available. The θ
    variance is the blended filtered one (an upper bound on the smoothed).
    """
    x_pred, _, _ = fw.history()
    C = smoother_gains(fw)
    T = fw.x.shape[2]
    # After j passes, xs[..., e, :] is the estimate of step e − j given data up to e.
    xs = fw.x.copy()
    tail = [fw.x[:, :, T - 1]]  # tail[j]: estimate of step T−1−j from all the data
    for j in range(1, lag + 1):
        i = np.arange(T - j)  # step being smoothed, window end e = i + j
        d = (xs[:, :, j:] - x_pred[:, :, i + 1])[..., None]
        xs[:, :, j:] = fw.x[:, :, i] + (C[:, :, i] @ d)[..., 0]
        tail.append(xs[:, :, T - 1].copy())
    k = np.arange(T)
    ends = np.minimum(k + lag, T - 1)
    smoothed = xs[:, :, ends]  # (S, H, T, n)
    for kk in k[k > T - 1 - lag]:
        smoothed[:, :, kk] = tail[T - 1 - kk]
    return blend_hypotheses(smoothed, fw.theta_var, fw.loglik[:, :, ends])


def blend_hypotheses(x: np.ndarray, theta_var: np.ndarray, loglik: np.ndarray
                     ) -> tuple[np.ndarray, np.ndarray]:
    """Posterior-weighted mixture over the hypothesis axis: x (S, H, T, n), θ variances and
    log-likelihoods (S, H, T). θ is averaged on the circle."""
    w = np.exp(loglik - loglik.max(axis=1, keepdims=True))
    w /= w.sum(axis=1, keepdims=True)
    out = np.einsum("sht,shtn->stn", w, x)
    out[..., I_TH] = np.angle(np.einsum("sht,sht->st", w, np.exp(1j * x[..., I_TH])))
    return out, np.einsum("sht,sht->st", w, theta_var)


class ArrayFLS:
    """`array-fls`: `array-ekf` followed by a fixed-lag RTS smoother of at most 100 ms."""

    name = "array-fls"
    description = "ours, real-time: array-ekf with a 100 ms fixed-lag smoother"

    def __init__(self, q_alpha: float = DEFAULT_Q_ALPHA, q_joint: float = DEFAULT_Q_JOINT,
                 lag_s: float = FLS_LAG_S, chunk: int = CHUNK):
        self.q_alpha = q_alpha
        self.q_joint = q_joint
        self.lag_s = lag_s
        self.chunk = chunk

    def lag_samples(self, rig: Rig) -> int:
        return int(np.floor(self.lag_s * rig.sample_rate_hz + 1e-9))

    def latency_s(self, rig: Rig) -> float | None:
        return self.lag_samples(rig) / rig.sample_rate_hz

    def estimate(self, rig: Rig, acc: np.ndarray) -> Estimates:
        """Chunks of `chunk` outputs, each from a forward pass over the chunk plus the `lag`
        samples after it, continued from the previous chunk's last posterior: the same numbers
        as one pass over the whole run, in memory bounded by the chunk."""
        lag = self.lag_samples(rig)
        T = acc.shape[1]
        xs, vs = [], []
        state: FilterState | None = None
        begin = 0
        while begin < T:
            end = min(begin + self.chunk, T)
            # The output at t = 0 may see samples 0..lag: the first chunk starts from them all.
            fw = forward(rig, acc[:, begin : min(end + lag, T)], self.q_alpha, self.q_joint,
                         keep_history=True, init_window=lag + 1, start=state, offset=begin)
            x, v = fixed_lag(fw, lag)
            xs.append(x[:, : end - begin])
            vs.append(v[:, : end - begin])
            last = end - begin - 1
            _, _, P = fw.history()
            state = FilterState(fw.x[:, :, last], P[:, :, last], fw.loglik[:, :, last])
            begin = end
        return _estimates(np.concatenate(xs, axis=1), np.concatenate(vs, axis=1))
