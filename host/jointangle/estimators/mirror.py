"""`mirror`: the firmware's filter (firmware/core/FILTER.md) in float64, step for step.

The firmware runs the paper's model (docs/design.md §3; states x = [ω_a, ω_b, θ_ab]) in a form that
is cheap and robust on the ATmega2560. This module does exactly the same arithmetic in float64 —
the same equations, initialisation, covariance form and order of operations — on the same
quantised inputs, so every firmware estimate can be checked against it (docs/design.md §5 parity).

One step with link-frame readings âᵃ, âᵇ (2N each), firmware/core/joint_filter.hpp `Step`:

1. Time update (eqs. 10, 13, 16, 17) with α = G_α â linear over the step, from the previous
   step's readings to these: half increments h = (ΔT/2) G_α â (h⁰ the previous step's),
       x₂ ← x₂ + ΔT (x₀ − x₁) + (ΔT/3)(2(h⁰_a − h⁰_b) + (h_a − h_b));  x₀ ← x₀ + h⁰_a + h_a;
       x₁ ← x₁ + h⁰_b + h_b;  θ wrapped  (missed periods hold α at h⁰)
       P ← Φ P Φᵀ + Q, Φ = I + AΔT, Q = ΔT² B Q̂ Bᵀ = diag(q_a, q_b, 0), with w = P (e₀ − e₁):
       P₂₂ += 2 ΔT w₂ + ΔT (ΔT w₀ − ΔT w₁), P₀₂ += ΔT w₀,  P₁₂ += ΔT w₁,  P₀₀ += q_a,  P₁₁ += q_b.
2. Measurement (eqs. 11, 14, 15) at x⁻: u = Fᵇ âᵇ, z = [G_ω²ᵃ âᵃ, G_ω²ᵇ âᵇ, Fᵃ âᵃ],
       h = [x₀², x₁², R(x₂) u],  H = [[2x₀,0,0],[0,2x₁,0],[0,0,R'(x₂)u]],  y = z − h;
   R_k = V Q̂ Vᵀ (eq. 18) from blocks precomputed at configuration: r₁₁, r₂₂, r₁₃ (G_ω²ᵃQ̂Fᵃᵀ),
   c_b (Fᵇ Q̂ G_ω²ᵇᵀ), M_a = Fᵃ Q̂ Fᵃᵀ, M_b = Fᵇ Q̂ Fᵇᵀ; per step only R(θ) M_b R(θ)ᵀ and −R(θ) c_b.
3. Decorrelation: R_k = L D Lᵀ in the order (z₃, z₄, z₁, z₂) — the two angle rows first, whose H
   rows stay sparse — and ỹ = L⁻¹ y, H̃ = L⁻¹ H (Gram–Schmidt, three reciprocals).
4. Sequential updates on (ỹ_m, H̃_m, D_m), all linearised at x⁻ (equal to the batch EKF update
   K = P⁻Hᵀ S⁻¹, P = (I − KH)P⁻ in exact arithmetic, without a 4×4 solve). The two angle rows
   (H̃ = (0, 0, c₁), (0, 0, c₂)) as one: with ρ = D₀/D₁, g = c₁² + ρc₂², ν = c₁ỹ₃ + ρc₂ỹ₄ and
   s = D₀ + g P₂₂:  x ← x + P[:,2] ν/s,  P_ij ← P_ij − P_i2 P_j2 g/s (i, j < 2),
   P[:,2] ← P[:,2] D₀/s. Then the rows z̃₁, z̃₂ one at a time:
       p = P h̃ᵀ,  s = h̃ p + D_m,  k = p / s,  x ← x + k (ỹ_m − h̃_m (x − x⁻)),
       P ← P − k pᵀ (symmetric).
   An update whose s is not positive is skipped and counted.
5. θ wrapped to (−π, π]; the analytical estimate (eq. 12) from the same z and u alongside.

Initialisation (first sample): x = [0, 0, θ_an] and P = diag(1, 1, P_θ0) when the joint
accelerations are large enough for eq. 12 (|Fᵃâᵃ|·|Fᵇâᵇ| ≥ INIT_MIN_PRODUCT), else θ = 0, P = I
(the paper's start). ω = 0 makes the ω² rows inert (H = 2ω = 0) until θ's motion has given ω its
sign through the cross-covariance, so the filter does not lock onto the mirror-image branch.
In the ω² rows' first step after the hold a measurement of ω_a + ω_b from the readings'
magnitudes √(G_ω² â) and θ's motion may take their place (`release_sum`).

Noise: Q̂ = diag of each axis' white-noise variance plus quantisation LSB²/12
(`full_noise_variance`). Inputs: link-frame readings rounded to the firmware's accelerometer format
(`quantise_inputs`), which is what the device holds after calibration.
"""

from __future__ import annotations

import ctypes
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from jointangle.built import find_built
from jointangle.errors import InputError
from jointangle.estimators.base import Estimates, full_noise_variance, wrap
from jointangle.model import rig_model
from jointangle.rig import Rig

ACCEL_FRACTION_BITS = 16  # firmware accelerometer format: Q15.16 m/s² (FILTER.md Q table)
P_OMEGA0 = 1.0  # (rad/s)² initial ω variance
P_THETA0 = 0.01  # rad² initial θ variance when θ comes from eq. 12
INIT_MIN_PRODUCT = 0.25  # (m/s²)²: |Fᵃâᵃ|·|Fᵇâᵇ| needed to trust eq. 12 at start
DECORRELATION_ORDER = (2, 3, 0, 1)  # z₃, z₄, z₁, z₂
MAX_STEP_PERIODS = 8  # core::kMaxStepPeriods: the most periods one step predicts over
OMEGA2_HOLD_S = 0.25  # s: the ω² rows wait this long after initialisation (sign acquisition)


def step_periods(t_us: np.ndarray, rate_hz: float) -> np.ndarray:
    """Sample periods each step of a filter run predicts over, from its frames' t_us (uint32 µs,
    wrapping): round(Δt / period) of consecutive frames, period = 10⁶ // rate µs, clamped to
    1..MAX_STEP_PERIODS — the app's StepPeriods (firmware/app/app.hpp) on the same grid slots.
    The first frame gets 1 (a filter start initialises; a later chunk of a run passes the
    frame before it first and drops its entry)."""
    period = 1_000_000 // round(rate_hz)  # the board's rate is a whole number of Hz
    t = np.asarray(t_us, dtype=np.int64)
    gap = np.full(t.size, period, dtype=np.int64)
    gap[1:] = (t[1:] - t[:-1]) & 0xFFFFFFFF
    return np.clip((gap + period // 2) // period, 1, MAX_STEP_PERIODS)


def quantise_raw(acc: np.ndarray) -> np.ndarray:
    """Link-frame readings as the firmware's Q15.16 raw counts (round half up, saturated)."""
    scale = float(1 << ACCEL_FRACTION_BITS)
    raw = np.floor(np.asarray(acc, dtype=float) * scale + 0.5)
    return np.clip(raw, -(2.0**31), 2.0**31 - 1).astype(np.int32)


def quantise_inputs(acc: np.ndarray) -> np.ndarray:
    """Link-frame readings as the firmware holds them: Q15.16 m/s², as float64."""
    return quantise_raw(acc).astype(float) / float(1 << ACCEL_FRACTION_BITS)


def hold_steps(dt: float) -> int:
    """Steps the ω² rows wait after initialisation: ⌊OMEGA2_HOLD_S / ΔT + ½⌋."""
    return int(np.floor(OMEGA2_HOLD_S / dt + 0.5))


@dataclass(frozen=True)
class MirrorSettings:
    """What the device derives from the rig at configuration time (FILTER.md "Settings")."""

    dt: float
    g_w2_a: np.ndarray
    g_al_a: np.ndarray
    f_a: np.ndarray  # (2, 2N)
    g_w2_b: np.ndarray
    g_al_b: np.ndarray
    f_b: np.ndarray
    q_a: float  # ΔT² G_αᵃ Q̂ᵃ G_αᵃᵀ
    q_b: float
    r11: float  # G_ω²ᵃ Q̂ᵃ G_ω²ᵃᵀ
    r22: float
    r13: np.ndarray  # (2,) G_ω²ᵃ Q̂ᵃ Fᵃᵀ
    c_b: np.ndarray  # (2,) Fᵇ Q̂ᵇ G_ω²ᵇᵀ
    m_a: np.ndarray  # (2, 2) Fᵃ Q̂ᵃ Fᵃᵀ
    m_b: np.ndarray
    # (τ_i − τ_m) / ΔT per reading (a's then b's), clipped to [−1, 1]: each sensor's sample
    # time after the readings' mean τ_m (the rig's read_delay_s; core::detail::AlignReadings)
    read_lag: np.ndarray
    # −τ_m (s): θ turned from the readings' mean time to the row's time (core::OutputAngle)
    output_lead: float = 0.0

    @property
    def mb_dif(self) -> float:
        """(M_b00 − M_b11) / 2: the rotating part of R(θ) M_b R(θ)ᵀ."""
        return 0.5 * float(self.m_b[0, 0] - self.m_b[1, 1])

    @property
    def r33_0(self) -> float:
        """M_a00 + (M_b00 + M_b11) / 2."""
        return float(self.m_a[0, 0]) + 0.5 * float(self.m_b[0, 0] + self.m_b[1, 1])

    @property
    def r44_0(self) -> float:
        """M_a11 + (M_b00 + M_b11) / 2."""
        return float(self.m_a[1, 1]) + 0.5 * float(self.m_b[0, 0] + self.m_b[1, 1])

    @classmethod
    def from_rig(cls, rig: Rig) -> MirrorSettings:
        m = rig_model(rig)
        q = full_noise_variance(rig)
        qa, qb = q[: m.na], q[m.na :]
        A, B = m.a, m.b
        return cls(
            dt=m.dt, g_w2_a=A.G_w2, g_al_a=A.G_alpha, f_a=A.F, g_w2_b=B.G_w2,
            g_al_b=B.G_alpha, f_b=B.F,
            q_a=m.dt**2 * float(np.sum(A.G_alpha**2 * qa)),
            q_b=m.dt**2 * float(np.sum(B.G_alpha**2 * qb)),
            r11=float(np.sum(A.G_w2**2 * qa)), r22=float(np.sum(B.G_w2**2 * qb)),
            r13=(A.F * qa) @ A.G_w2, c_b=(B.F * qb) @ B.G_w2,
            m_a=(A.F * qa) @ A.F.T, m_b=(B.F * qb) @ B.F.T,
            read_lag=read_lags(rig), output_lead=-mean_sample_delay(rig))


def mean_sample_delay(rig: Rig) -> float:
    """τ_m: the mean of every sensor's `read_delay_s` (both links), as core::Configure forms it."""
    return float(np.mean(rig.read_delays()))


def read_lags(rig: Rig) -> np.ndarray:
    """(τ_i − τ_m) / ΔT per reading (x, y of each sensor in rig order), clipped to [−1, 1] as
    core::Configure does: the weight of the last period's slope in `align_readings`."""
    delays = rig.read_delays()
    return np.repeat(np.clip((delays - np.mean(delays)) / rig.dt, -1.0, 1.0), 2)


def output_theta(cfg: MirrorSettings, xs: np.ndarray) -> np.ndarray:
    """θ at the row's time from states xs (..., 3) at the readings' mean time
    (core::OutputAngle): θ + lead·(ω_a − ω_b), wrapped."""
    return np.asarray(wrap(xs[..., 2] + cfg.output_lead * (xs[..., 0] - xs[..., 1])))


def align_readings(lag: np.ndarray, now: np.ndarray, previous: np.ndarray) -> np.ndarray:
    """The readings at their mean time (core::detail::AlignReadings): sensor i sampled τ_i
    after t_k, a_i(t_k + τ_m) ≈ a_i[k] − ((τ_i − τ_m)/ΔT)(a_i[k] − a_i[k−1])."""
    return now - lag * (now - previous)


@dataclass
class MirrorTrace:
    """Per-step internals for range measurement and diagnostics, each (S, T, ...)."""

    theta_an: np.ndarray
    innovation: np.ndarray  # (S, T, 4) ỹ, decorrelated
    d: np.ndarray  # (S, T, 4) D of the decorrelation
    s: np.ndarray  # (S, T, 4) innovation variances of the scalar updates
    gain: np.ndarray  # (S, T, 4, 3)
    P: np.ndarray  # (S, T, 3, 3)
    skipped: np.ndarray  # (S,) scalar updates skipped (s ≤ 0)


@dataclass
class MirrorState:
    """Where a run of `run_mirror` stopped: passed back in, the run goes on over later readings
    exactly as one call over all of them would (the live view's divergence follows a filter run
    this way instead of re-running it from its start at every refresh)."""

    x: np.ndarray  # (S, 3)
    P: np.ndarray  # (S, 3, 3)
    skipped: np.ndarray  # (S,) scalar updates skipped so far
    steps: int = 0  # sample periods done (health.steps; 0: the next step initialises)
    half_dw: np.ndarray | None = None  # (S, 2) the previous step's half increments (ΔT/2) G_α â
    omega2_on: bool = False  # the ω² rows have had their first update since initialising
    previous: np.ndarray | None = None  # (S, M) the previous step's readings as read

    @classmethod
    def fresh(cls, runs: int) -> MirrorState:
        return cls(np.zeros((runs, 3)), np.zeros((runs, 3, 3)), np.zeros(runs, dtype=int),
                   0, np.zeros((runs, 2)), False)


def release_sum(cfg: MirrorSettings, x: np.ndarray, P: np.ndarray, z_a: np.ndarray,
                z_b: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The ω² rows' first update after the hold as a measurement of ω_a + ω_b
    (core::detail::ReleaseSum): (use, sum, variance), each (S,).

    Held back, the rows leave ω_a + ω_b where θ's motion put it: an even split of d = ω_a − ω_b.
    The readings give the magnitudes r = √(G_ω² â); the sign choices (±r_a, ±r_b) whose
    difference matches d within 2σ of the best are plausible (σ² = var d + var r_a + var r_b,
    var r = r_jj / (4 max(G_ω² â, √r_jj))), and the plausible one whose sum is nearest the
    prior's is the measurement, with variance var r_a + var r_b. Used only when θ's motion has
    fixed d better than the readings fix the magnitudes (var d ≤ var r); else the ω² rows."""
    r_a, r_b = np.sqrt(np.maximum(z_a, 0.0)), np.sqrt(np.maximum(z_b, 0.0))
    d = x[:, 0] - x[:, 1]
    prior_sum = x[:, 0] + x[:, 1]
    misses, sums = [], []
    for k in range(4):  # (+,+), (+,−), (−,+), (−,−): the firmware's order
        ta = -r_a if k & 2 else r_a
        tb = -r_b if k & 1 else r_b
        misses.append(np.abs(ta - tb - d))
        sums.append(ta + tb)
    miss, total = np.stack(misses, 1), np.stack(sums, 1)
    var_d = P[:, 0, 0] + P[:, 1, 1] - 2.0 * P[:, 0, 1]
    var_r = (0.25 * cfg.r11 / np.maximum(z_a, np.sqrt(cfg.r11))
             + 0.25 * cfg.r22 / np.maximum(z_b, np.sqrt(cfg.r22)))
    two_sigma = 2.0 * np.sqrt(np.maximum(var_d + var_r, 0.0))
    plausible = miss <= miss.min(axis=1, keepdims=True) + two_sigma[:, None]
    far = np.where(plausible, np.abs(total - prior_sum[:, None]), np.inf)
    best = np.argmin(far, axis=1)  # ties: the first, as the firmware
    chosen = np.take_along_axis(total, best[:, None], 1)[:, 0]
    return var_d <= var_r, chosen, var_r


def run_mirror(cfg: MirrorSettings, acc: np.ndarray, trace: bool = False,
               state: MirrorState | None = None,
               periods: np.ndarray | None = None) -> tuple[np.ndarray, MirrorTrace | None]:
    """Run the firmware's algorithm on already-quantised readings acc (S, T, M); states (S, T, 3).
    With `state`, go on from it (and leave it where this call stopped). `periods` (T,): sample
    periods each step predicts over (core::Step's `periods`, from the frames' t_us:
    `step_periods`); None = 1 each. The filter's first step takes 1."""
    S, T, _ = acc.shape
    na = cfg.g_w2_a.shape[0]
    dt = cfg.dt
    if state is None:
        state = MirrorState.fresh(S)
    x, P, elapsed = state.x, state.P, state.steps
    half_prev = state.half_dw if state.half_dw is not None else np.zeros((S, 2))
    rows_on = state.omega2_on
    xs = np.empty((S, T, 3))
    tr = None
    if trace:
        nan = np.nan
        tr = MirrorTrace(np.full((S, T), nan), np.full((S, T, 4), nan), np.full((S, T, 4), nan),
                         np.full((S, T, 4), nan), np.full((S, T, 4, 3), nan),
                         np.full((S, T, 3, 3), nan), np.zeros(S, dtype=int))
    skipped = state.skipped.copy()
    hold = hold_steps(dt)
    lag = cfg.read_lag
    aligning = bool(np.any(lag != 0.0))
    previous = state.previous if state.previous is not None else np.zeros((S, acc.shape[2]))
    for k in range(T):
        step = elapsed  # sample periods since the filter's start (health.steps)
        # 0. The readings at the row's time (not on the first step, nor over missed periods).
        read = acc[:, k, :]
        now = read
        if aligning and step > 0 and (periods is None or periods[k] <= 1):
            now = align_readings(lag, read, previous)
        previous = read
        aa, ab = now[:, :na], now[:, na:]
        za = aa @ cfg.f_a.T  # Fᵃ âᵃ  (S, 2)
        u = ab @ cfg.f_b.T  # Fᵇ âᵇ
        # eq. 12: θ = atan2(v₁ᵃv₂ᵇ − v₂ᵃv₁ᵇ, v₁ᵃv₁ᵇ + v₂ᵃv₂ᵇ)
        cross = za[:, 0] * u[:, 1] - za[:, 1] * u[:, 0]
        dot = za[:, 0] * u[:, 0] + za[:, 1] * u[:, 1]
        theta_an = np.arctan2(cross, dot)
        if step == 0:
            # |za|² |u|² = cross² + dot²; trust eq. 12 above INIT_MIN_PRODUCT².
            ok = cross**2 + dot**2 >= INIT_MIN_PRODUCT**2
            x[:, 2] = np.where(ok, theta_an, 0.0)
            P[:, 0, 0] = P_OMEGA0
            P[:, 1, 1] = P_OMEGA0
            P[:, 2, 2] = np.where(ok, P_THETA0, 1.0)
        # 1. Time update, once per sample period since the last step (a missed period holds
        # this step's readings: zero-order hold, as core::Step).
        n_predict = 1 if periods is None or step == 0 else int(periods[k])
        n_predict = min(max(n_predict, 1), MAX_STEP_PERIODS)
        elapsed += n_predict
        half = np.stack([(0.5 * dt) * (aa @ cfg.g_al_a), (0.5 * dt) * (ab @ cfg.g_al_b)], axis=1)
        if step == 0:
            half_prev = half.copy()  # no earlier readings: α constant over the first period
        for i in range(n_predict):
            h0 = half_prev
            h1 = half_prev if i < n_predict - 1 else half  # missed periods hold α at h⁰
            dh0 = h0[:, 0] - h0[:, 1]
            x[:, 2] = wrap(x[:, 2] + (dt * (x[:, 0] - x[:, 1])
                                      + (dt / 3.0) * (dh0 + dh0 + (h1[:, 0] - h1[:, 1]))))
            x[:, 0] = x[:, 0] + (h0[:, 0] + h1[:, 0])
            x[:, 1] = x[:, 1] + (h0[:, 1] + h1[:, 1])
            w = P[:, :, 0] - P[:, :, 1]
            dt_dw = dt * w[:, 0] - dt * w[:, 1]  # dt (w₀ − w₁), formed so it fits Q1.30
            p22 = P[:, 2, 2] + dt * w[:, 2] + dt * w[:, 2] + dt * dt_dw
            p02 = P[:, 0, 2] + dt * w[:, 0]
            p12 = P[:, 1, 2] + dt * w[:, 1]
            P[:, 2, 2] = p22
            P[:, 0, 2] = P[:, 2, 0] = p02
            P[:, 1, 2] = P[:, 2, 1] = p12
            P[:, 0, 0] += cfg.q_a
            P[:, 1, 1] += cfg.q_b
        half_prev = half
        # 2. Measurement at x⁻. In the ω² rows' first step after the hold a measurement of
        # ω_a + ω_b (release_sum) may take their place (`by_sum`, per run).
        omega2_rows = step >= hold
        if step == 0:
            rows_on = False
        by_sum = np.zeros(S, dtype=bool)
        if omega2_rows and not rows_on:
            by_sum, sum_z, sum_var = release_sum(cfg, x, P, aa @ cfg.g_w2_a, ab @ cfg.g_w2_b)
            rows_on = True
        c, s = np.cos(x[:, 2]), np.sin(x[:, 2])
        h3 = c * u[:, 0] + s * u[:, 1]  # R(θ) u
        h4 = c * u[:, 1] - s * u[:, 0]
        j3, j4 = h4, -h3  # R'(θ) u
        y1 = aa @ cfg.g_w2_a - x[:, 0] * x[:, 0]
        y2 = ab @ cfg.g_w2_b - x[:, 1] * x[:, 1]
        y3 = za[:, 0] - h3
        y4 = za[:, 1] - h4
        # R blocks: R₃₃ = M_a + R M_b Rᵀ, R₁,₃₄ = r13, R₂,₃₄ = −R c_b; for the symmetric M_b,
        # R M_b Rᵀ = mean·I + [[e, f], [f, −e]] (double angle):
        # e = dif·cos 2θ + m_b01·sin 2θ, f = m_b01·cos 2θ − dif·sin 2θ.
        c2 = c * c - s * s
        sc = s * c
        s2 = sc + sc
        e = cfg.mb_dif * c2 + cfg.m_b[0, 1] * s2
        R33 = cfg.r33_0 + e
        R44 = cfg.r44_0 - e
        R34 = cfg.m_a[0, 1] + cfg.m_b[0, 1] * c2 - cfg.mb_dif * s2
        R13, R14 = cfg.r13[0], cfg.r13[1]
        R23 = -(c * cfg.c_b[0] + s * cfg.c_b[1])
        R24 = -(c * cfg.c_b[1] - s * cfg.c_b[0])
        # 3. Decorrelation, order (z₃, z₄, z₁, z₂): Gram–Schmidt on the noise.
        zero = np.zeros(S)
        d0 = R33
        i0 = 1.0 / d0
        l10 = R34 * i0
        d1 = R44 - l10 * R34
        i1 = 1.0 / d1
        yt1 = y4 - l10 * y3
        ht1 = j4 - l10 * j3  # H̃ row (0, 0, ht1)
        R14t = R14 - l10 * R13  # cov(z₁, z̃₄)
        R24t = R24 - l10 * R23
        l20 = R13 * i0
        l21 = R14t * i1
        d2 = cfg.r11 - l20 * R13 - l21 * R14t
        i2 = 1.0 / d2
        yt2 = y1 - l20 * y3 - l21 * yt1
        ht2_0 = 2.0 * x[:, 0]
        ht2_2 = -(l20 * j3 + l21 * ht1)  # H̃ row (ht2_0, 0, ht2_2)
        R21t = -(l20 * R23 + l21 * R24t)  # cov(z₂, z̃₁)
        l30 = R23 * i0
        l31 = R24t * i1
        l32 = R21t * i2
        d3 = cfg.r22 - l30 * R23 - l31 * R24t - l32 * R21t
        yt3 = y2 - l30 * y3 - l31 * yt1 - l32 * yt2
        ht3_0 = -(l32 * ht2_0)
        ht3_1 = 2.0 * x[:, 1]
        ht3_2 = -(l30 * j3 + l31 * ht1 + l32 * ht2_2)
        rows: list[tuple[np.ndarray, ...]] = [
            (ht2_0, zero, ht2_2, yt2, d2),
            (ht3_0, ht3_1, ht3_2, yt3, d3),
        ]
        x_prior = x.copy()
        # 4a. The two angle rows (z₃, z̃₄: h̃ = (0, 0, c)) as one update (AngleRowsUpdate):
        # ρ = D₀/D₁, g = c₁² + ρc₂², ν = c₁y₃ + ρc₂ỹ₄, s = D₀ + g P₂₂; x += P[:,2] ν/s,
        # P_ij −= P_i2 P_j2 g/s (i, j < 2), P[:,2] *= D₀/s (the two scalar updates, exactly).
        rho = d0 * i1
        c2w = ht1 * rho
        g = j3 * j3 + c2w * ht1
        nu = j3 * y3 + c2w * yt1
        sa = d0 + P[:, 2, 2] * g
        good = sa > 0.0
        skipped += ~good
        inv = np.where(good, 1.0 / np.where(good, sa, 1.0), 0.0)
        beta = np.where(good, d0 * inv, 1.0)
        nu_s = nu * inv
        p02, p12, p22 = P[:, 0, 2].copy(), P[:, 1, 2].copy(), P[:, 2, 2].copy()
        k0 = (p02 * g) * inv
        k1 = (p12 * g) * inv
        x[:, 0] += p02 * nu_s
        x[:, 1] += p12 * nu_s
        x[:, 2] += p22 * nu_s
        P[:, 0, 0] -= k0 * p02
        P[:, 0, 1] -= k0 * p12
        P[:, 1, 0] = P[:, 0, 1]
        P[:, 1, 1] -= k1 * p12
        P[:, 0, 2] = P[:, 2, 0] = p02 * beta
        P[:, 1, 2] = P[:, 2, 1] = p12 * beta
        P[:, 2, 2] = p22 * beta
        if tr is not None:
            tr.innovation[:, k, 0] = y3
            tr.innovation[:, k, 1] = yt1
            tr.d[:, k, 0] = d0
            tr.d[:, k, 1] = d1
            tr.s[:, k, 0] = sa
            tr.gain[:, k, 0] = np.stack([k0, k1, p22 * g * inv], axis=1)
        # 4b. The scalar rows z̃₁, z̃₂, linearised at x⁻; row m's innovation is taken at the
        # state the earlier rows left: ỹ_m − h̃_m (x − x⁻) (= the batch EKF update exactly).
        # Where by_sum: the sum measurement instead, h = (1, 1, 0), y = sum − (ω_a + ω_b).
        if by_sum.any():
            one = np.where(by_sum, 1.0, 0.0)
            rows = [(one, one, zero, np.where(by_sum, sum_z - (x[:, 0] + x[:, 1]), 0.0),
                     np.where(by_sum, sum_var, 1.0)),
                    *((np.where(by_sum, 0.0, r[0]), np.where(by_sum, 0.0, r[1]),
                       np.where(by_sum, 0.0, r[2]), np.where(by_sum, 0.0, r[3]),
                       np.where(by_sum, 1.0, r[4])) for r in rows)]
            x_prior = np.where(by_sum[:, None], x, x_prior)  # the sum row's y is at x itself
        for m, (h0, h1, h2, ym, dm) in enumerate(rows, start=2):
            if not omega2_rows:
                break
            dx = x - x_prior
            ym = ym - (h2 * dx[:, 2] + (h0 * dx[:, 0] + h1 * dx[:, 1]))
            p = P[:, :, 0] * h0[:, None] + P[:, :, 1] * h1[:, None] + P[:, :, 2] * h2[:, None]
            sm = h0 * p[:, 0] + h1 * p[:, 1] + h2 * p[:, 2] + dm
            good = sm > 0.0
            skipped += ~good
            inv = np.where(good, 1.0 / np.where(good, sm, 1.0), 0.0)
            kg = p * inv[:, None]
            x = x + kg * ym[:, None]
            P = P - kg[:, :, None] * p[:, None, :]
            # keep exact symmetry the way the firmware does (it stores the upper triangle)
            P[:, 1, 0], P[:, 2, 0], P[:, 2, 1] = P[:, 0, 1], P[:, 0, 2], P[:, 1, 2]
            if tr is not None and m < 4:
                tr.innovation[:, k, m] = ym
                tr.d[:, k, m] = dm
                tr.s[:, k, m] = sm
                tr.gain[:, k, m] = kg
        x[:, 2] = wrap(x[:, 2])
        xs[:, k] = x
        if tr is not None:
            tr.theta_an[:, k] = theta_an
            tr.P[:, k] = P
    if tr is not None:
        tr.skipped = skipped
    state.x, state.P, state.skipped, state.steps = x, P, skipped, elapsed
    state.half_dw = half_prev
    state.omega2_on = rows_on
    state.previous = previous
    return xs, tr


class Mirror:
    """`mirror`: the firmware filter's algorithm in float64 (docs/design.md §3)."""

    name = "mirror"
    description = ("the firmware's filter in float64: analytical start, decorrelated sequential "
                   "scalar updates (firmware/core/FILTER.md)")

    def latency_s(self, rig: Rig) -> float | None:
        return 0.0

    def estimate(self, rig: Rig, acc: np.ndarray) -> Estimates:
        cfg = MirrorSettings.from_rig(rig)
        xs, _ = run_mirror(cfg, quantise_inputs(acc))
        return Estimates(theta=output_theta(cfg, xs), omega_a=xs[..., 0], omega_b=xs[..., 1])


# ------------------------------------------------------------------------------------------
# `firmware`: the fixed-point core itself (firmware/core/joint_filter.hpp), replayed on x86
# through the C ABI of firmware/platform/posix/filter_replay.cpp.

LIBRARY_ENV = "JOINTANGLE_FIRMWARE_LIB"
LIBRARY_NAME = "libja_filter_replay.so"
OUTPUTS_PER_STEP = 6
# core::kMaxSensorsPerLink: the replay takes this many slots per link, and the app filters at
# most this many usable sensors of a link (app.hpp kFilterSensorsPerLink), at least the minimum.
MAX_SENSORS_PER_LINK = 4
MIN_SENSORS_PER_LINK = 2
# count, x, y per slot, joint, noise per reading, read delay per slot
GEOMETRY_PER_LINK = 1 + 5 * MAX_SENSORS_PER_LINK + 2


def sensors_per_link(rig: Rig) -> tuple[int, int]:
    """Sensors on links a and b, checked against what the firmware's filter takes (2 to 4)."""
    counts = []
    for name in ("a", "b"):
        n = len(rig.links[name].sensors)
        if not MIN_SENSORS_PER_LINK <= n <= MAX_SENSORS_PER_LINK:
            raise InputError(f"the firmware filter takes {MIN_SENSORS_PER_LINK} to "
                             f"{MAX_SENSORS_PER_LINK} sensors per link; link {name} has {n}",
                             field=f"links.{name}.sensors")
        counts.append(n)
    return counts[0], counts[1]


def slot_readings(raw: np.ndarray, counts: tuple[int, int]) -> np.ndarray:
    """Readings (..., 2 n_a + 2 n_b) spread into the replay's slots (..., 4 MAX_SENSORS_PER_LINK),
    the unused slots 0."""
    out = np.zeros((*raw.shape[:-1], 4 * MAX_SENSORS_PER_LINK), dtype=raw.dtype)
    na = 2 * counts[0]
    out[..., :na] = raw[..., :na]
    out[..., 2 * MAX_SENSORS_PER_LINK: 2 * MAX_SENSORS_PER_LINK + 2 * counts[1]] = raw[..., na:]
    return out


def find_replay_library() -> Path:
    """The replay library: $JOINTANGLE_FIRMWARE_LIB, else the repository's build tree."""
    return find_built(LIBRARY_NAME, "firmware", env=LIBRARY_ENV, target="ja_filter_replay",
                      what="firmware replay library", field="--filter")


def _geometry(rig: Rig) -> np.ndarray:
    """Both links' geometry in the replay's layout (GEOMETRY_PER_LINK values per link)."""
    q = full_noise_variance(rig)
    counts = sensors_per_link(rig)
    parts: list[float] = []
    offset = 0
    for name, n in zip(("a", "b"), counts, strict=True):
        link = rig.links[name]
        pos = np.zeros((MAX_SENSORS_PER_LINK, 2))
        pos[:n] = np.asarray(link.positions(), dtype=float)
        noise = np.zeros(2 * MAX_SENSORS_PER_LINK)
        noise[: 2 * n] = q[offset: offset + 2 * n]
        offset += 2 * n
        delays = np.zeros(MAX_SENSORS_PER_LINK)
        delays[:n] = [s.read_delay_s for s in link.sensors]
        parts += [float(n), *pos.ravel(), *np.asarray(link.joint, dtype=float), *noise, *delays]
    return np.asarray(parts, dtype=np.float64)


@dataclass(frozen=True)
class ReplayResult:
    """Per-step outputs of the core, each (S, T), and per-run counters (S,)."""

    omega_a: np.ndarray
    omega_b: np.ndarray
    theta: np.ndarray
    theta_analytical: np.ndarray
    trace: np.ndarray
    saturations: np.ndarray
    skipped: np.ndarray


def replay_core(rig: Rig, acc: np.ndarray, fixed: bool = True,
                library: Path | None = None) -> ReplayResult:
    """Run the firmware core (fixed point, or its float build) on readings acc (S, T, M), which
    are quantised to Q15.16 exactly as `quantise_inputs` does for `mirror`."""
    lib = ctypes.CDLL(str(library or find_replay_library()))
    fn = lib.ja_filter_replay
    fn.restype = ctypes.c_int
    dbl_p = ctypes.POINTER(ctypes.c_double)
    fn.argtypes = [ctypes.c_int, dbl_p, ctypes.c_double, ctypes.c_int32,
                   ctypes.POINTER(ctypes.c_int32), dbl_p, ctypes.POINTER(ctypes.c_uint32)]
    if (lib.ja_filter_outputs_per_step() != OUTPUTS_PER_STEP
            or lib.ja_filter_sensors_per_link() != MAX_SENSORS_PER_LINK
            or lib.ja_filter_geometry_per_link() != GEOMETRY_PER_LINK):
        raise InputError("the firmware replay library has a different layout: rebuild it",
                         field="--filter")
    geometry = _geometry(rig)
    counts = sensors_per_link(rig)
    raw = quantise_raw(acc)
    if raw.shape[-1] != 2 * sum(counts):
        raise InputError(f"the rig has {sum(counts)} sensors, the readings "
                         f"{raw.shape[-1] // 2}", field="--filter")
    raw = slot_readings(raw, counts)
    S, T, _ = raw.shape
    out = np.empty((S, T, OUTPUTS_PER_STEP))
    stats = np.zeros((S, 2), dtype=np.uint32)
    for s in range(S):
        run = np.ascontiguousarray(raw[s])
        res = np.empty((T, OUTPUTS_PER_STEP))
        st = np.zeros(2, dtype=np.uint32)
        rc = fn(1 if fixed else 0, geometry.ctypes.data_as(dbl_p), rig.dt, T,
                run.ctypes.data_as(ctypes.POINTER(ctypes.c_int32)), res.ctypes.data_as(dbl_p),
                st.ctypes.data_as(ctypes.POINTER(ctypes.c_uint32)))
        if rc != 0:
            raise InputError("the firmware rejected the rig: degenerate array or a derived "
                             "constant outside its Q format (firmware/core/FILTER.md)",
                             field="links")
        out[s] = res
        stats[s] = st
    return ReplayResult(omega_a=out[..., 0], omega_b=out[..., 1], theta=out[..., 2],
                        theta_analytical=out[..., 3], trace=out[..., 4],
                        saturations=stats[:, 0].astype(int), skipped=stats[:, 1].astype(int))


class Firmware:
    """`firmware`: the fixed-point firmware core replayed on x86 (bit-identical to the MCU)."""

    name = "firmware"
    description = "the firmware's fixed-point filter (firmware/core), replayed on x86"

    def latency_s(self, rig: Rig) -> float | None:
        return 0.0

    def estimate(self, rig: Rig, acc: np.ndarray) -> Estimates:
        r = replay_core(rig, acc)
        return Estimates(theta=wrap(r.theta), omega_a=r.omega_a, omega_b=r.omega_b)
